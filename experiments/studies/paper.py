"""Paper figures: time histories of every method with the reference, and their differences.

For each case: joint angles and tip deflections of every method with the reference, each
method minus the reference against time, and the loads (root bending moment of link 1, torques
of motion-driven joints, total energy) compared the same way (see ``metrics.load_series``).
Exudyn records no energy, so energies are compared against the plan's ``energy_reference`` run
(a method that records it, at the reference's k and h) unless the reference has one itself.

On a planar arm the root moment of every method (and of the reference) comes from the hub
balance (``metrics.comparable_loads`` drops the cut loads: like for like across engines). On a
spatial arm it is the bending part of the cut load at link 1's root, so the spatial runs of the
methods whose record has ``spatial_cut_loads`` get ``cut_loads=True`` here; a method without
them, or a reference without them, leaves the moment uncompared, with the reason in the
``moment1_note`` column of ``paper_loads``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import methods, metrics
from ..runs import Task, task_from_row
from ._common import MAIN_ERROR, params, step_for, study_methods, tip_col, with_task_columns

NAME = "paper"
MAX_POINTS = 1000  # time samples kept per curve in the stored series
COMPARED, ENERGY_REF = "compared", "energy reference"


def _energy_task(p, case, T) -> Task | None:
    e = p.energy_reference
    if e is None:
        return None
    method = e.method or next(iter(methods.takes_part(NAME, needs=("energy",))), None)
    return Task(case, method, e.k, e.h, T) if method else None


def _compared(ctx) -> list[Task]:
    p = params(ctx, NAME)
    out = []
    for c in p.cases:
        case = ctx.cases[c]
        for m in study_methods(ctx, NAME):
            rec = methods.get(m)
            h = (
                (p.h if p.explicit_h is None else p.explicit_h)
                if rec.explicit and rec.max_step is None
                else step_for(m, p.k, p.h, case)
            )
            out.append(Task(c, m, p.k, h, case.scenario.duration, _options(rec, case)))
    return out


def _options(rec, case) -> tuple:
    """Extra options of a run: the cut loads of a spatial run that can record them (planar
    runs record theirs by default)."""
    return (("cut_loads", True),) if methods.is_spatial(case) and rec.spatial_cut_loads else ()


def tasks(ctx) -> list[Task]:
    """Every method at the plan's k and h (or its own h) on every case, and the energy reference."""
    p = params(ctx, NAME)
    out = _compared(ctx)
    for c in p.cases:
        e = _energy_task(p, c, ctx.cases[c].scenario.duration)
        if e is not None and e not in out:
            out.append(e)
    return out


def _thin(df: pd.DataFrame) -> pd.DataFrame:
    return df.iloc[:: max(1, len(df) // MAX_POINTS)]


def _series(res, ref, case, label) -> pd.DataFrame:
    """Angles and tip deflections of ``res``, with ``d_…`` = res minus ref (NaN for the ref)."""
    df = res.to_frame()
    keep = ["t"] + [c for c in df.columns if c.startswith(("joint_angle_", "tip_deflection_"))]
    df = df[keep].copy()
    if ref is not None and res is not ref:
        t, d = metrics.difference_series(res, ref)
        on = np.isin(df.t.to_numpy(), t)
        for i in range(res.n_joints):
            for q, col in (
                (f"angle{i + 1}", f"joint_angle_{i + 1}"),
                (f"tip{i + 1}", f"tip_deflection_{i + 1}"),
            ):
                df.loc[on, f"d_{col}"] = d[q]
        df.loc[on, "d_ee"] = d["ee"]
    return _thin(df).assign(case=case, method=label)


def _moment_note(res, ref, label) -> str:
    """Why a spatial run's root bending moment is not compared ('' when it is)."""
    if not metrics.has_spatial_cut_loads(res):
        try:
            return methods.get(label).why_no_spatial_moment()
        except methods.MethodUnavailable:
            return "the run records no cut loads"
    if ref is None:
        return "no reference"
    if not metrics.has_spatial_cut_loads(ref):
        return "the reference was run without cut loads"
    return ""


def _load_series(res, ref, eref, case_obj, case, label) -> tuple[pd.DataFrame, dict]:
    """(sampled load histories with ``d_…`` columns, load error row) of one run."""
    s = metrics.load_series(metrics.comparable_loads(res), case_obj)
    if ref is None and "energy" not in s and eref is not None and eref.energy is not None:
        s["energy"] = np.interp(res.t, eref.t, eref.energy)  # the reference row shows the energy reference
    df = pd.DataFrame({"t": res.t, **s})
    row = {}
    for other, only in ((ref, lambda q: q != "energy"), (eref, lambda q: q == "energy")):
        if other is None or other is res:
            continue
        a, b = metrics.comparable_loads(res), metrics.comparable_loads(other)
        t, d = metrics.load_differences(a, b, case_obj)
        on = np.isin(df.t.to_numpy(), t)
        err = metrics.load_errors(a, b, case_obj)
        for q in filter(only, d):
            df.loc[on, f"d_{q}"] = d[q]
            scale = err[f"{q}_scale"]
            row.update(
                {
                    f"{q}_l2": err[f"{q}_l2"],
                    f"{q}_linf": err[f"{q}_linf"],
                    f"{q}_rel": err[f"{q}_l2"] / scale if scale > 0 else np.nan,
                }
            )
    if ref is not None and metrics.is_spatial_result(res):
        row["moment1_note"] = _moment_note(res, ref, label)
    return _thin(df).assign(case=case, method=label), row


def _energy_reference(ctx, p, case, ref):
    """(Result with energy or None, description) used for the energy errors of ``case``."""
    if ref is not None and ref.energy is not None:
        return ref, "the reference"
    e = _energy_task(p, case, ctx.cases[case].scenario.duration)
    if e is None or not ctx.store.has(e):
        return None, "none"
    res = ctx.store.history(e) if ctx.store.row(e)["status"] == "ok" else None
    if res is None or res.energy is None:
        return None, "none"
    return res, f"{e.method} k={e.k} h={e.h:g}"


def _summary_row(r, res) -> dict:
    n = int(r.n_joints)
    return {
        "case": r.case,
        "method": r.method,
        "status": r.status,
        "reason": r.reason,
        "k": r.k,
        "h": r.h,
        "peak_tip": float(np.max(np.abs(res.tip_deflection[:, -1]))) if res is not None else np.nan,
        MAIN_ERROR: r[MAIN_ERROR],
        tip_col(n): r[tip_col(n)],
    }


def analyse(ctx, table):
    """Tables: the runs (``role``: compared or energy reference); ``paper_summary`` per (case,
    method): peak tip deflection and errors; ``paper_series``: sampled angle and deflection
    histories with their differences to the reference; ``paper_loads``: load and energy errors
    per (case, method); ``paper_load_series``: the sampled load histories and differences."""
    p = params(ctx, NAME)
    table = with_task_columns(table)
    keys = {t.key for t in _compared(ctx)}
    if len(table):
        table["role"] = [COMPARED if k in keys else ENERGY_REF for k in table.task]
    series, rows, loads, load_rows = [], [], [], []
    for case in p.cases:
        case_obj = ctx.cases[case]
        ref = ctx.references.get(case, (None, ""))[0]
        eref, eref_name = _energy_reference(ctx, p, case, ref)
        if ref is not None:
            series.append(_series(ref, None, case, "reference"))
            ls, _ = _load_series(ref, None, eref, case_obj, case, "reference")
            loads.append(ls)
            rows.append(
                {
                    "case": case,
                    "method": "reference",
                    "status": "ok",
                    "reason": "",
                    "peak_tip": float(np.max(np.abs(ref.tip_deflection[:, -1]))),
                    MAIN_ERROR: 0.0,
                }
            )
        compared = table[(table.case == case) & (table.role == COMPARED)] if len(table) else table
        for _, r in compared.iterrows():
            res = ctx.store.history(task_from_row(r)) if r.status == "ok" else None
            rows.append(_summary_row(r, res))
            if res is None:
                continue
            series.append(_series(res, ref, case, r.method))
            ls, err = _load_series(res, ref, eref, case_obj, case, r.method)
            loads.append(ls)
            load_rows.append(
                {"case": case, "method": r.method, "k": r.k, "h": r.h, **err, "energy_reference": eref_name}
            )
    empty = pd.DataFrame(columns=["t", "case", "method"])
    return {
        NAME: table,
        f"{NAME}_summary": pd.DataFrame(rows),
        f"{NAME}_series": pd.concat(series, ignore_index=True) if series else empty,
        f"{NAME}_loads": pd.DataFrame(load_rows),
        f"{NAME}_load_series": pd.concat(loads, ignore_index=True) if loads else empty,
    }


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
