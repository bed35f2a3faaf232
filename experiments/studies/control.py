"""Closed-loop drives: tracking and residual vibration per method, moment feedback against its
gain, and natural frequencies of the arm.

The study has its own case (``experiments/cases/control/closed_loop_three_link.toml``: a
rest-to-rest move of a three-link arm under PD laws with root-moment feedback), added to
``ctx.cases`` by :func:`tasks`, and variants of it that differ only in ``moment_gain``. Every
method of the plan is tried on it through the sweep runner (cached, resumable); a method that
refuses closed-loop drives (an ``InputError`` naming the drive) is kept as a row with status
"not supported" and the refusal's text. The natural frequencies need no time integration:
``dttmm.modes`` against Exudyn's eigenvalue computation, skipped (with the reason) where either
is missing.

Plan parameters (:class:`experiments.params.ControlParams`, defaults there):

* ``case_file``: the case file, relative to ``experiments/cases`` (default the three-link arm);
  ``duration``: s, None keeps the file's value (the move and at least 1.5 s after it must fit);
* ``k``, ``h``: every method that takes part (its registry record) runs on the case as written
  at k and h (an explicit method at its record's ``max_step``); the rigid methods also run on
  the variant without moment feedback at ``rigid_h`` (a rigid link has no root moment to feed
  back). ``runs`` [(method, k, h)] and ``rigid_runs`` [(method, h)] name the runs instead (tests);
* ``reference``: (k, h) of the reference of the tip-position differences, computed and cached
  by ``experiments.references`` with the registry's reference candidates; or [(method, k, h)]
  candidates;
* ``gains``: the moment gains of the gain sweep, run by every method taking part in
  ``control:gains`` at k and h (or ``gain_runs`` [(method, k, h)]);
* ``window``: s, length of the residual-vibration windows (default 1 s);
* ``modes`` (:class:`experiments.params.ControlModes`): k (elements per link), exudyn_k
  (Exudyn's), n (modes per system), systems (case files relative to ``experiments/cases``).
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..params import ControlModes, ControlParams, study_params
from ..runs import WITH_HISTORY, Task
from ..timing import COST_REPEATS
from ._common import params

NAME = "control"
REPEATS = COST_REPEATS  # timed calls per run: the table's CPU time is the least of them
CASES = Path(__file__).resolve().parents[1] / "cases"
CASE_FILE = ControlParams.case_file
WINDOW = ControlParams.window  # s: residual vibration is measured on the last WINDOW s of the run
MAX_POINTS = 1000  # time samples kept per curve in the stored series
NOT_SUPPORTED = "not supported"
NO_VIBRATION = 1e-9  # m: below this a tip deflection is round-off (a rigid link), not vibration


# ----------------------------------------------------------------------------- cases
def load(p):
    """The study's case (dttmm.Case) of the parameters ``p`` (a ControlParams or a dict of its
    fields), shortened to ``p.duration`` when given."""
    import dttmm

    p = study_params(NAME, p)
    case = dttmm.load_case(CASES / p.case_file)
    T = p.duration
    if T is not None and T != case.scenario.duration:
        case = replace(case, scenario=replace(case.scenario, duration=float(T)))
    return case


def moment_gain(case) -> float:
    """The moment gain of the case's first closed-loop drive that has one (0 if none)."""
    gains = [getattr(d.law, "moment_gain", None) for d in case.scenario.drives if d.closed_loop]
    return float(next((g for g in gains if g is not None), 0.0))


def with_gain(case, gain: float):
    """The case with ``moment_gain = gain`` on every pd/pid drive, named ``<name>_gm<gain>``
    (the case itself, name unchanged, when every such drive already has that gain)."""
    drives, changed = [], False
    for d in case.scenario.drives:
        if d.closed_loop and hasattr(d.law, "moment_gain") and d.law.moment_gain != gain:
            d = replace(d, law=replace(d.law, moment_gain=float(gain)))
            changed = True
        drives.append(d)
    if not changed:
        return case
    return replace(
        case, name=f"{case.name}_gm{gain:g}", scenario=replace(case.scenario, drives=tuple(drives))
    )


def move_end(case) -> float:
    """End of the move (s): the last breakpoint of the closed-loop drives' references."""
    ts = [max(d.law.reference.breakpoints, default=0.0) for d in case.scenario.drives if _ref(d)]
    return float(max(ts, default=0.0))


def _ref(drive):
    return getattr(drive.law, "reference", None) if drive.closed_loop else None


def reference_angles(case, t) -> np.ndarray:
    """(nt, n) reference angles α_ref(t) (rad) of the closed-loop joints; NaN for the others."""
    out = np.full((len(t), case.n_joints), np.nan)
    for j, d in enumerate(case.scenario.drives):
        ref = _ref(d)
        if ref is not None:
            out[:, j] = [ref.motion(float(x))[0] for x in t]
    return out


# ----------------------------------------------------------------------------- tasks
def _active(ctx) -> bool:
    """False for a report on case files given by the user: this study has its own case."""
    return NAME in ctx.plan.studies and not getattr(ctx.plan, "case_files", None)


def _cases(ctx) -> dict:
    """role -> Case of the study: the case, its variant without moment feedback ("rigid") and
    the gain variants ("gain <g>"). Nothing is changed."""
    p = params(ctx, NAME)
    base = load(p)
    out = {base.name: base, "rigid": with_gain(base, 0.0)}
    for g in p.gains:
        out[f"gain {g:g}"] = with_gain(base, g)
    return out


def cases(ctx) -> dict:
    """The study's own cases by case name, which ``experiments.study.add_cases`` puts into
    ``ctx.cases`` before tasks are listed."""
    if not _active(ctx):
        return {}
    return {c.name: c for c in _cases(ctx).values()}


def planned(ctx) -> dict:
    """The study's runs by role: "runs" (the case as written), "rigid" (the variant without
    moment feedback), "reference" (candidates) and "gains" (gain -> runs of that variant)."""
    p, cases = params(ctx, NAME), _cases(ctx)
    base = next(iter(cases.values()))
    T = base.scenario.duration
    run_specs = p.runs if p.runs is not None else _derived(p, ctx.plan.name)
    rigid_specs = p.rigid_runs if p.rigid_runs is not None else _derived_rigid(p, ctx.plan.name)
    gain_specs = p.gain_runs if p.gain_runs is not None else _derived(p, ctx.plan.name, "gains")
    runs = [Task(base.name, m, k, h, T) for m, k, h in run_specs]
    rigid = [Task(cases["rigid"].name, m, 0, h, T) for m, h in rigid_specs]
    return {
        "runs": runs,
        "rigid": [t for t in rigid if t not in runs],  # a case without moment feedback has no variant
        "gains": {
            float(g): [Task(cases[f"gain {g:g}"].name, m, k, h, T) for m, k, h in gain_specs] for g in p.gains
        },
    }


def _derived(p, size, kind=None) -> list:
    """(method, k, h) of every method taking part (explicit ones at their max_step; rigid ones
    at ``rigid_h``, default h, k = 0)."""
    from .. import methods
    from ._common import step_for

    p = study_params(NAME, p)
    out = []
    for m in methods.takes_part(NAME, kind=kind, size=size):
        if methods.uses_k(m):
            out.append((m, p.k, step_for(m, p.k, p.h)))
        elif kind is None:
            out.append((m, 0, _rigid_h(p)))
    return out


def _derived_rigid(p, size) -> list:
    from .. import methods

    return [(m, _rigid_h(p)) for m in methods.takes_part(NAME, size=size, flexible=False)]


def _rigid_h(p) -> float:
    return p.h if p.rigid_h is None else p.rigid_h


def reference_specs(p) -> list:
    """RefSpec candidates of the study's reference (see the module docstring)."""
    from .. import methods
    from ..references import RefSpec

    ref = study_params(NAME, p).reference
    if len(ref) == 2 and all(isinstance(x, (int, float)) for x in ref):
        return [RefSpec(m, int(ref[0]), float(ref[1])) for m in methods.reference_candidates()]
    return [RefSpec(m, int(k), float(h)) for m, k, h in ref]


def tasks(ctx) -> list:
    """Every run of the study (see the module docstring for the plan parameters)."""
    if not _active(ctx):
        return []
    by = planned(ctx)
    out = by["runs"] + by["rigid"] + [t for ts in by["gains"].values() for t in ts]
    return list(dict.fromkeys(out))


# ----------------------------------------------------------------------------- metrics
def tracking(t, angle, ref, t_move: float) -> tuple[float, float]:
    """(largest |α − α_ref| over joints and t ≤ t_move, largest |α − α_ref| over joints at the
    last sample), rad; joints without a reference (NaN columns of ``ref``) are left out."""
    e = np.abs(np.asarray(angle, float) - np.asarray(ref, float))
    cols = ~np.all(np.isnan(e), axis=0)
    if not cols.any():
        return math.nan, math.nan
    e = e[:, cols]
    during = np.asarray(t) <= t_move + 1e-12
    return float(np.max(e[during])) if during.any() else math.nan, float(np.max(e[-1]))


def peak(t, y) -> tuple[float, float]:
    """(time, value) of the largest interior local maximum of ``y``, refined by the parabola
    through it and its neighbours; the largest sample (maybe at an end) when there is none."""
    t, y = np.asarray(t, float), np.asarray(y, float)
    inner = np.flatnonzero((y[1:-1] >= y[:-2]) & (y[1:-1] >= y[2:]) & (y[1:-1] > 0)) + 1
    if inner.size == 0:
        i = int(np.argmax(y))
        return float(t[i]), float(y[i])
    i = int(inner[np.argmax(y[inner])])
    a, b, c = y[i - 1], y[i], y[i + 1]
    curv = a - 2 * b + c
    if curv >= 0:  # flat top
        return float(t[i]), float(b)
    x = 0.5 * (a - c) / curv  # offset in samples, in [-0.5, 0.5]
    dt = 0.5 * (t[i + 1] - t[i - 1])
    return float(t[i] + x * dt), float(b - 0.25 * (a - c) * x)


def windows(t_move: float, T: float, window: float = WINDOW) -> tuple[tuple, tuple]:
    """The early ([t_move, t_move + W]) and late ([T − W, T]) windows of the residual
    vibration; W = ``window``, shortened to (T − t_move)/2 when both would not fit."""
    W = min(window, 0.5 * (T - t_move))
    return (t_move, t_move + W), (T - W, T)


def decay_rate(t, w, t_move: float, window: float = WINDOW) -> tuple[float, float, float]:
    """(decay rate ln(A_early/A_late)/Δt (1/s), A_early, A_late (units of ``w``)) of the
    vibration ``w`` after the move: A the largest peak of |w| in each of the two
    :func:`windows`, Δt the time between those peaks. Exact for a damped sine whose windows
    hold a peak each. NaN when the run ends before the move or has no vibration (a peak below
    NO_VIBRATION)."""
    t, w = np.asarray(t, float), np.abs(np.asarray(w, float))
    T = float(t[-1])
    if not T > t_move:
        return math.nan, math.nan, math.nan
    (a0, a1), (b0, b1) = windows(t_move, T, window)
    e, late = (t >= a0) & (t <= a1), (t >= b0) & (t <= b1)
    if e.sum() < 3 or late.sum() < 3:
        return math.nan, math.nan, math.nan
    te, ae = peak(t[e], w[e])
    tl, al = peak(t[late], w[late])
    if not (ae > NO_VIBRATION and al > NO_VIBRATION and tl > te):
        return math.nan, ae, al
    return float(np.log(ae / al) / (tl - te)), ae, al


def residual(t, w, window: float = WINDOW) -> np.ndarray:
    """Largest |w| on the last ``window`` s, per column of ``w`` (nt, n)."""
    t = np.asarray(t, float)
    last = t >= t[-1] - window - 1e-12
    return np.max(np.abs(np.asarray(w, float)[last]), axis=0)


def path_difference(res, ref) -> float:
    """Largest distance (m) between the end effectors of two runs on the same output grid."""
    if len(res.t) != len(ref.t) or not np.allclose(res.t, ref.t):
        raise ValueError("run and reference are on different output grids")
    return float(np.max(np.linalg.norm(np.asarray(res.end_effector) - np.asarray(ref.end_effector), axis=1)))


def status_of(row) -> tuple[str, str]:
    """(status, reason) of a run row for the tables: a refusal of the closed-loop drives (or of
    a setting of them) by the method is "not supported" with the refusal's text."""
    status, reason = str(row["status"]), row.get("reason", "")
    reason = reason if isinstance(reason, str) else ""  # NaN or None: no reason recorded
    if status == "failed" and reason.startswith("InputError: ") and "scenario.drives[" in reason:
        return NOT_SUPPORTED, reason.removeprefix("InputError: ")
    return status, reason


# ----------------------------------------------------------------------------- analysis
def _task(r) -> Task:
    return Task(r["case"], r["method"], r["k"], r["h"], r["duration"])


def _select(table, tasks) -> pd.DataFrame:
    """The rows of ``table`` that belong to ``tasks``, in the order of the tasks."""
    if table is None or not len(table):
        return pd.DataFrame(columns=["case", "method", "k", "h", "duration", "status", "reason"])
    keyed = {_task(r): r for _, r in table.iterrows()}
    return pd.DataFrame([keyed[t] for t in tasks if t in keyed])


def _history(ctx, r):
    return ctx.store.history(_task(r)) if r["status"] in WITH_HISTORY else None


def _reference(ctx, case, specs):
    """(Result, its name) of the study's reference, computed and cached like every reference
    (``experiments.references``: the first candidate that finishes "ok"), else (None, why)."""
    from ..references import reference

    if not specs:
        return None, "no reference run finished (none planned)"
    folder = Path(ctx.data) / "references" / ctx.plan.name
    res, prov = reference(case, specs, folder, size=ctx.plan.name)
    if res is None:
        return None, "no reference run finished (" + "; ".join(prov.get("failures", [])) + ")"
    return res, f"{prov['method']} k={prov['k']} h={prov['h']:g}"


def run_metrics(res, case, t_move: float, window: float) -> dict:
    """Tracking, deflection, vibration and torque measures of one finished run: tracking errors
    (rad), per link the peak and residual |tip deflection| (m) and decay rate (1/s), per joint
    the peak |torque| (N·m)."""
    n = case.n_joints
    t, w = np.asarray(res.t, float), np.asarray(res.tip_deflection, float)
    move, final = tracking(t, res.joint_angle, reference_angles(case, t), t_move)
    out = {"track_move_max": move, "track_final": final}
    rest = residual(t, w, window)
    for i in range(n):
        out[f"peak_w{i + 1}"] = float(np.max(np.abs(w[:, i])))
        out[f"residual_w{i + 1}"] = float(rest[i])
        out[f"decay_rate{i + 1}"] = decay_rate(t, w[:, i], t_move, window)[0]
    tau = np.abs(np.asarray(res.joint_torque, float))
    out.update({f"peak_tau{i + 1}": float(np.max(tau[:, i])) for i in range(n)})
    return out


def _difference(res, ref) -> float:
    """path_difference, NaN without a reference or on another output grid (a run cut short)."""
    try:
        return path_difference(res, ref) if ref is not None else math.nan
    except ValueError:
        return math.nan


def _measured(ctx, rows, case, gain, t_move, window, ref=None) -> list:
    out = []
    for _, r in rows.iterrows():
        status, reason = status_of(r)
        row = {
            "case": r["case"],
            "method": r["method"],
            "moment_gain": float(gain),
            "k": int(r["k"]),
            "h": float(r["h"]),
            "status": status,
            "reason": reason,
            "cpu_time": float(r.get("timing_cpu_min", math.nan)),
            "cpu_repeats": r.get("timing_repeats", math.nan),
            "cpu_noisy": r.get("timing_noisy", math.nan),
        }
        res = _history(ctx, r)
        if res is not None:
            row.update(run_metrics(res, case, t_move, window))
            row["ee_diff_max"] = _difference(res, ref)
        out.append(row)
    return out


def analyse(ctx, table):
    """Tables ``control`` (per run on the case and on the variant without moment feedback:
    status, tracking errors, peak and residual tip deflections, decay rates, largest
    tip-position difference to the reference (m, NaN on the variant), least CPU time of
    REPEATS calls), ``control_gains`` (the same measures over the gain sweep),
    ``control_series`` (histories for the figures), ``control_pairs`` (DT-TMM against the
    global solver: methods.same_equations), ``control_modes`` (natural frequencies) and ``control_info``
    (move end, windows, reference)."""
    if not _active(ctx):
        return {}
    p, cases, by = params(ctx, NAME), _cases(ctx), planned(ctx)
    base, rigid = next(iter(cases.values())), cases["rigid"]
    window = float(p.window)
    t_move, T = move_end(base), base.scenario.duration
    ref, ref_name = _reference(ctx, base, reference_specs(p))
    rows = _measured(ctx, _select(table, by["runs"]), base, moment_gain(base), t_move, window, ref)
    rows += _measured(ctx, _select(table, by["rigid"]), rigid, 0.0, t_move, window)
    gain_rows = []
    for g, ts in by["gains"].items():
        gain_rows += _measured(ctx, _select(table, ts), cases[f"gain {g:g}"], g, t_move, window)
    early, late = windows(t_move, T, window)
    info = {
        "case": base.name,
        "duration": T,
        "move_end": t_move,
        "early_window": f"{early[0]:g}–{early[1]:g} s",
        "late_window": f"{late[0]:g}–{late[1]:g} s",
        "moment_gain": moment_gain(base),
        "reference": ref_name if ref is not None else "",
        "reference_note": "" if ref is not None else ref_name,
    }
    series = _select(table, by["runs"] + by["rigid"])
    gain_runs = _select(table, [t for ts in by["gains"].values() for t in ts])
    pairs = pair_differences(
        ctx, pd.concat([series, gain_runs]).drop_duplicates(subset=["case", "method", "k", "h"])
    )
    return {
        NAME: pd.DataFrame(rows),
        f"{NAME}_gains": pd.DataFrame(gain_rows),
        f"{NAME}_series": _series(ctx, series, cases, ref, ref_name),
        f"{NAME}_modes": modes_table(p.modes, base),
        f"{NAME}_info": pd.DataFrame([info]),
        f"{NAME}_pairs": pairs,
    }


def pair_differences(ctx, rows) -> pd.DataFrame:
    """Largest end-effector distance (m) and joint-angle difference (rad) between the runs of
    each pair solving the same discrete equations (``methods.same_equations``) that both
    finished (same case, k and h)."""
    from .. import methods

    out = []
    ok = rows[rows.status == "ok"] if len(rows) else rows
    for a, b in methods.same_equations():
        ra, rb = ok[ok.method == a], ok[ok.method == b]
        for _, x in ra.iterrows():
            y = rb[(rb.case == x["case"]) & (rb.k == x["k"]) & np.isclose(rb.h.astype(float), x["h"])]
            if not len(y):
                continue
            p, q = ctx.store.history(_task(x)), ctx.store.history(_task(y.iloc[0]))
            da = np.max(np.abs(np.asarray(p.joint_angle) - np.asarray(q.joint_angle)))
            out.append(
                {
                    "a": a,
                    "b": b,
                    "case": x["case"],
                    "k": int(x["k"]),
                    "h": float(x["h"]),
                    "ee_max": path_difference(p, q),
                    "angle_max": float(da),
                }
            )
    return pd.DataFrame(out, columns=["a", "b", "case", "k", "h", "ee_max", "angle_max"])


SERIES_COLUMNS = ["method", "case", "t", "w1", "track_error", "ee_diff"]


def _curve(res, case, method, ref) -> pd.DataFrame:
    t = np.asarray(res.t, float)
    step = max(1, math.ceil(len(t) / MAX_POINTS))
    err = np.abs(np.asarray(res.joint_angle, float) - reference_angles(case, t))
    ok = ~np.all(np.isnan(err), axis=0)
    track = np.max(err[:, ok], axis=1) if ok.any() else np.full(len(t), np.nan)
    ee = np.asarray(res.end_effector, float)
    diff = np.linalg.norm(ee - np.asarray(ref.end_effector), axis=1) if ref is not None else np.nan + ee[:, 0]
    return pd.DataFrame(
        {
            "method": method,
            "case": case.name,
            "t": t[::step],
            "w1": np.asarray(res.tip_deflection, float)[::step, 0],
            "track_error": track[::step],
            "ee_diff": diff[::step],
        }
    )


def _series(ctx, rows, cases, ref, ref_name) -> pd.DataFrame:
    """Histories for the figures, at most MAX_POINTS samples each: tip deflection of link 1
    (m), the largest joint tracking error |α − α_ref| (rad) and the end-effector distance to
    the reference (m), per finished run and for the reference (method "reference")."""
    by_name = {c.name: c for c in cases.values()}
    parts = []
    for _, r in rows.iterrows():
        res = _history(ctx, r)
        if res is not None and r["status"] == "ok":
            case = by_name[r["case"]]
            parts.append(_curve(res, case, r["method"], ref if case.name == next(iter(by_name)) else None))
    if ref is not None:
        parts.append(_curve(ref, next(iter(cases.values())), "reference", ref).assign(note=ref_name))
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=SERIES_COLUMNS)


# ----------------------------------------------------------------------------- natural frequencies
MODE_SYSTEMS = ControlModes.systems
MODES_COLUMNS = ["system", "mode", "dttmm_hz", "exudyn_hz", "rel_diff", "k", "exudyn_k", "note"]
ZERO_HZ = 1e-6  # frequencies below this (Hz) are the rigid-body modes of free joints


def elastic(freqs, n: int) -> np.ndarray:
    """The lowest ``n`` non-zero frequencies (Hz), ascending; rigid-body modes (< ZERO_HZ) dropped."""
    f = np.sort(np.asarray(freqs, float))
    return f[f >= ZERO_HZ][:n]


def _attempt(fn, *args):
    try:
        return fn(*args), ""
    except Exception as exc:  # noqa: BLE001 - any failure is reported in the table, with its reason
        return None, f"{type(exc).__name__}: {str(exc).splitlines()[0][:200] if str(exc) else ''}"


def modes_table(modes: ControlModes, case) -> pd.DataFrame:
    """Per system (the study's arm with its torque joints free, then the clamped De Luca links)
    and elastic mode: DT-TMM's frequency (``dttmm.modes`` at ``k``), Exudyn's eigenvalue
    computation at ``exudyn_k``, their relative difference. A system whose frequencies cannot be
    computed gets one row with the reason in ``note``."""
    from .problems import frequencies, load_problem

    k, ke, n = int(modes.k), int(modes.exudyn_k), int(modes.n)
    systems = [case] + [load_problem(CASES / f)[0] for f in modes.systems]
    rows = []
    for c in systems:
        fd, why_d = _attempt(frequencies, c, k, "dttmm", None)  # each method's own linearisation
        fe, why_e = _attempt(frequencies, c, ke, "exudyn-ancf", n + c.n_joints)
        if fd is None:
            rows.append(
                dict.fromkeys(MODES_COLUMNS, math.nan) | {"system": c.name, "note": f"DT-TMM: {why_d}"}
            )
            continue
        fd = elastic(fd, n)
        fe = elastic(fe, n) if fe is not None else np.array([])
        for i, f in enumerate(fd):
            g = float(fe[i]) if i < fe.size else math.nan
            rows.append(
                {
                    "system": c.name,
                    "mode": i + 1,
                    "dttmm_hz": float(f),
                    "exudyn_hz": g,
                    "rel_diff": abs(f - g) / g if g > 0 else math.nan,
                    "k": k,
                    "exudyn_k": ke,
                    "note": f"Exudyn: {why_e}" if why_e else "",
                }
            )
    return pd.DataFrame(rows, columns=MODES_COLUMNS)


if __name__ == "__main__":  # python -m experiments.studies.control [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
