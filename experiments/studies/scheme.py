"""The paper's own scheme under test: DT-TMM with the plain (paper) transfer or the Riccati
sweep, and 0, 1 or converged corrections per step, as the mesh and the step are refined.

The plain sweep loses digits exponentially with k; its failures are recorded as NaN with the
reason, and the summary says at which k it breaks. A run the solver itself flags
("unconverged", "ill-conditioned") counts as broken there, like a failed one.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..params import SchemeParams
from ..runs import Task
from ._common import MAIN_ERROR, params, with_task_columns

NAME = "scheme"
METHOD = SchemeParams.method  # the method under test unless the plan names another


def variant_label(sweep, iterations) -> str:
    """Short legend label: ``riccati, converged`` or ``plain, 1 corr.``."""
    it = "converged" if iterations in (None, "None") else f"{iterations} corr."
    return f"{sweep}, {it}"


DEFAULTS = {"sweep": "riccati", "iterations": None}


def _opts(v: dict) -> tuple:
    """Options of a variant, defaults left out so the default run is shared with other studies."""
    return tuple((k, x) for k, x in {**DEFAULTS, **v}.items() if x != DEFAULTS[k])


#: why a spatial arm is not in the study: its variants are options of the planar kernel
SPATIAL_REASON = (
    "a spatial arm: the scheme's variants (the paper's plain transfer, fixed corrections with it) are "
    "options of the planar kernel (the spatial kernel runs the Riccati sweep only)"
)


def _planar(ctx, cases) -> list:
    from .. import methods

    return [c for c in cases if not methods.is_spatial(ctx.cases[c])]


def sitting_out(ctx) -> dict:
    """case -> {method: why} for the plan's cases the study does not run (the spatial arms)."""
    p = params(ctx, NAME)
    return {c: {p.method: SPATIAL_REASON} for c in p.cases if c not in _planar(ctx, p.cases)}


def tasks(ctx) -> list[Task]:
    """Every variant over k at the plan's h and over h at the plan's k, on the planar cases (a
    spatial arm is sat out, :func:`sitting_out`)."""
    p = params(ctx, NAME)
    method = p.method
    out = []
    for c in _planar(ctx, p.cases):
        T = ctx.cases[c].scenario.duration
        for v in p.variants:
            out += [Task(c, method, k, p.h, T, _opts(v)) for k in p.ks]
            out += [Task(c, method, p.k, h, T, _opts(v)) for h in p.hs]
    return out


FLAGGED = ("unconverged", "ill-conditioned")


def _first_reason(fails: pd.DataFrame) -> str:
    """``status: reason`` of the not-ok run at the smallest k ('' when none)."""
    if fails.empty:
        return ""
    r = fails.sort_values("k").iloc[0]
    return f"{r.status}: {r.reason}" if r.status != "failed" else str(r.reason)


def analyse(ctx, table):
    """Tables: runs with ``variant``, ``sweep``, ``iterations`` and ``series`` (k or h), and a
    summary per (case, variant): runs not ok (``failed``: every status but "ok"; ``flagged``:
    those the solver marked unconverged or ill-conditioned) and the smallest k at which the
    error exceeds ten times the converged Riccati error or the run is not ok."""
    p = params(ctx, NAME)
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_summary": table}
    for k, d in DEFAULTS.items():
        col = table[f"opt_{k}"] if f"opt_{k}" in table else None
        table[k] = [
            str(d) if col is None or v != v or v in ("", None) else v
            for v in (col if col is not None else [None] * len(table))
        ]
    table["variant"] = [variant_label(s, i) for s, i in zip(table.sweep, table.iterations)]
    parts = [
        table[np.isclose(table.h, p.h)].assign(series="k"),
        table[table.k == p.k].assign(series="h"),
    ]
    table = pd.concat(parts, ignore_index=True)
    rows = []
    base_label = variant_label("riccati", None)
    for (case, var), g in table[table.series == "k"].groupby(["case", "variant"]):
        base = table[(table.series == "k") & (table.case == case) & (table.variant == base_label)]
        base = base[base.status == "ok"].set_index("k")[MAIN_ERROR]
        bad = [
            k
            for k, e, s in zip(g.k, g[MAIN_ERROR], g.status)
            if s != "ok" or not np.isfinite(e) or (k in base and np.isfinite(base[k]) and e > 10 * base[k])
        ]
        fails = g[g.status != "ok"]
        rows.append(
            {
                "case": case,
                "variant": var,
                "runs": len(g),
                "failed": len(fails),
                "flagged": int(fails.status.isin(FLAGGED).sum()),
                "breaks_at_k": min(bad) if bad else np.nan,
                "first_reason": _first_reason(fails),
            }
        )
    return {NAME: table, f"{NAME}_summary": pd.DataFrame(rows)}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
