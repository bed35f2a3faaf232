"""Benchmark problems of the field with published, closed-form or recorded values.

The study's name is ``benchmarks`` (:data:`NAME`: the plans' key, the table names, the methods
registry's skip entries ``benchmarks:<kind>`` and ``python -m experiments.studies.benchmarks``
keep it); the module is named for what it holds, the problems (docs/architecture.md, "Three
meanings of benchmark").

Each problem is a case file in ``experiments/cases/benchmarks/`` with a ``[provenance]`` table
(source, parameters, the quantity compared, its value, the tolerance). This study runs every
method that can model a problem at a few k through the sweep runner (cached, parallel), extracts
the compared quantity from each run and reports the error, pass/fail at the stated tolerance and
the observed order in k. The clamped-link frequencies need no time integration: they come from
the linearised forward dynamics of the methods that expose it.

The spatial problems (:data:`SPATIAL_PROBLEMS`, case files in ``experiments/cases/spatial/``
with the same ``[provenance]`` table) run with every method that runs spatial arms
(:func:`experiments.methods.runs_on`). Their static problems are equilibria and are solved by
the method's own statics (:func:`statics_of`: ``dttmm.spatial.statics``, Exudyn's
``SolveStatic``), not by a damped run to rest: the equilibrium is then exact to Newton's
tolerance at any k, and a load sweep (the Princeton beam's 14 load points) costs a few Newton
solves instead of 14 settling runs. A method with no statics sits them out.
"""

from __future__ import annotations

import importlib
import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from ..methods import uses_k
from ..params import ProblemsParams
from ..runs import Task
from ._common import fit_orders, k_limit, params

NAME = "benchmarks"
CASE_DIR = Path(__file__).resolve().parents[1] / "cases" / "benchmarks"
SPATIAL_DIR = CASE_DIR.parent / "spatial"
#: the spatial benchmark problems (case files in SPATIAL_DIR, with a [provenance] table)
SPATIAL_PROBLEMS = ("princeton_beam", "bend_45deg", "right_angle_cantilever", "bang_bang_arm")
#: kinds solved by the method's own statics (no time integration, no sweep run)
STATIC_KINDS = ("static_tip_displacement_3d", "static_tip_position_error")

#: The step of each kind of problem. Which methods run a kind comes from their registry records
#: (a method sits a kind out with the reason: ``skip`` entries ``benchmarks:<kind>``); the
#: frequencies need a method's own linearisation (the "modes" capability).
SETTINGS = {
    "peak_tip_deflection": {"h": 2e-3},
    "static_tip_displacement": {"h": 1e-2},
    "tip_deflection_rms": {"h": 1e-3},
    "tip_path_rms": {"h": 1e-3},
    "frequencies": {},
    "static_tip_displacement_3d": {},
    "static_tip_position_error": {},
    "tip_extrema": {"h": 5e-3},
}
REQUIRED = (
    "source",
    "parameters",
    "quantity",
    "compared",
    "value_kind",
    "units",
    "tolerance",
    "tolerance_kind",
)
SETTLE_WINDOW = 1.0  # s: a static run is at rest when its tip moved < SETTLE_TOL over this window
SETTLE_TOL = 1e-6  # m


# ----------------------------------------------------------------------------- case files
def load_problem(path) -> tuple:
    """(dttmm.Case, provenance dict) of one benchmark-problem case file.

    The ``[provenance]`` table is removed before the case is built, so the case loader never
    sees it (whether or not it accepts the table).
    """
    import dttmm

    path = Path(path)
    with path.open("rb") as f:
        data = tomllib.load(f)
    prov = data.pop("provenance", {})
    data.setdefault("name", path.stem)
    if data.get("kind") == "spatial":
        from dttmm.spatial.case import case_from_dict

        return case_from_dict(data), prov
    return dttmm.case_from_dict(data), prov


def _paths(case_dir) -> list:
    paths = sorted(Path(case_dir).glob("*.toml"))
    if Path(case_dir) == CASE_DIR:
        paths += [SPATIAL_DIR / f"{n}.toml" for n in SPATIAL_PROBLEMS]
    return paths


def problems(names=None, case_dir=CASE_DIR) -> dict:
    """Problem name -> (Case, provenance), for every case file (or the given names): the planar
    problems of ``case_dir`` and, for the default folder, the spatial ones (:data:`SPATIAL_PROBLEMS`)."""
    out = {p.stem: load_problem(p) for p in _paths(case_dir)}
    if names is not None:
        missing = [n for n in names if n not in out]
        if missing:
            raise KeyError(f"no benchmark-problem case file for {missing} in {case_dir}")
        out = {n: out[n] for n in names}
    return out


def missing_provenance(prov: dict) -> list:
    """Keys a provenance table lacks: the REQUIRED ones, a value, and a reference where needed."""
    miss = [k for k in REQUIRED if k not in prov]
    own = _VALUE_KEYS.get(prov.get("quantity"))
    if own is not None:
        miss += [k for k in own if k not in prov]
    elif "value" not in prov and "values" not in prov:
        miss.append("value")
    if prov.get("value_kind") == "reference run" and "reference" not in prov:
        miss.append("reference")
    return miss


#: the provenance keys holding the published values, for the kinds that have no ``value(s)``
_VALUE_KEYS = {
    "static_tip_displacement_3d": ("beta_deg", "force", "components", "load_steps"),
    "static_tip_position_error": ("P", "tip_position", "load_time", "load_steps", "scale"),
    "tip_extrema": ("extrema", "time_tolerance"),
}


def targets(prov: dict) -> list:
    """[(quantity label, target value)] of a problem."""
    return [(t["quantity"], t["target"]) for t in target_rows(prov)]


def _princeton_key(component: str, force: float) -> str:
    return f"{component}_F{round(force * 1000):d}"


def target_rows(prov: dict) -> list:
    """Every compared quantity of a problem: dicts with ``quantity``, ``target``, ``group`` (the
    family it is plotted and summarised in) and ``scale`` (what a relative error is divided by;
    None: the target itself)."""
    kind = prov["quantity"]
    if kind == "frequencies":
        return [_t(f"f{i + 1}", v) for i, v in enumerate(prov["values"])]
    if kind == "static_tip_displacement_3d":
        out = []
        for F in prov["force"]:
            for comp, label in prov["components"]:
                vals = prov[_princeton_key(comp, F)]
                for j, b in enumerate(prov["beta_deg"]):
                    # a zero entry is measured against the component's other end of the sweep
                    scale = None if vals[j] else abs(vals[-1 - j])
                    out.append(_t(f"{label} F={F:g} N β={b:g}°", vals[j], label, scale))
        return out
    if kind == "static_tip_position_error":
        return [_t(f"tip position error P={P:g}", 0.0, "tip position error") for P in prov["P"]]
    if kind == "tip_extrema":
        out = []
        for e in prov["extrema"]:
            name = f"{e['signal']} {e['kind']}"
            out += [_t(name, e["value"], "extremum"), _t(f"{name} time", e["time"], "extremum time")]
        return out
    return [_t(kind, prov["value"])]


def _t(quantity, target, group=None, scale=None) -> dict:
    return {"quantity": quantity, "target": float(target), "group": group or quantity, "scale": scale}


def tolerance_of(prov: dict, quantity: str) -> tuple:
    """(tolerance, "relative" or "absolute") a quantity of a problem is judged by: the energy
    drift by its ``energy_tolerance`` (absolute), the times of extrema by ``time_tolerance``
    (absolute, s), every other quantity by ``tolerance`` and ``tolerance_kind``."""
    if quantity == "energy_drift":
        return float(prov.get("energy_tolerance")), "absolute"
    if quantity.endswith(" time") and "time_tolerance" in prov:
        return float(prov["time_tolerance"]), "absolute"
    return float(prov["tolerance"]), "relative" if prov["tolerance_kind"] == "relative" else "absolute"


def _shortened(case, duration):
    if duration is None or duration == case.scenario.duration:
        return case
    return replace(case, scenario=replace(case.scenario, duration=float(duration)))


def _reference(ctx, case, task):
    """The problem's reference run, computed and cached like every reference
    (``experiments.references``, under ``<data>/references/<size>/``); None when it fails."""
    from ..references import RefSpec, reference

    folder = Path(ctx.data) / "references" / ctx.plan.name
    spec = RefSpec(task.method, task.k, task.h, task.options)
    res, _ = reference(case, [spec], folder, size=ctx.plan.name)
    return res


def step_of(prov: dict) -> float:
    """The step (s) a problem's runs take: its provenance's ``step`` (with the reason in
    ``step_note``), else the step of its kind (:data:`SETTINGS`)."""
    h = prov.get("step", SETTINGS[prov["quantity"]].get("h"))
    if isinstance(h, bool) or not isinstance(h, (int, float)) or not h > 0:
        raise ValueError(f"step = {h!r}: must be a positive step (s)")
    return float(h)


def peer_options(prov: dict, method: str) -> tuple:
    """The (name, value) options a problem gives ``method`` (its ``peer_options`` table: method
    name -> options, with the reason in ``peer_options_note``), for its runs and its reference
    run; () when it gives none."""
    table = prov.get("peer_options") or {}
    if not isinstance(table, dict) or not all(isinstance(v, dict) for v in table.values()):
        raise ValueError(f"peer_options = {table!r}: must map method names to tables of options")
    return tuple(sorted(table.get(method, {}).items()))


def _ref_task(name, case, prov):
    r = prov.get("reference")
    if not r:
        return None
    m = r["method"]
    return Task(name, m, int(r["k"]), float(r["h"]), case.scenario.duration, peer_options(prov, m))


# ----------------------------------------------------------------------------- tasks
def _methods(p, kind: str, size: str | None = None, case=None) -> list:
    """The methods run on a problem of this kind (every registered method that takes part,
    :func:`experiments.methods.takes_part`, and runs ``case``: :func:`experiments.methods.runs_on`),
    narrowed to the plan's ``methods`` when it names some. The frequencies need the method's
    linearisation, the static spatial problems its statics (:func:`statics_of`)."""
    from .. import methods

    every = methods.takes_part(NAME, kind=kind, size=size)
    if kind == "frequencies":
        every = [m for m in every if methods.frequencies_of(m)]
    if case is not None:
        every = [m for m in every if methods.runs_on(m, case)]
    if kind in STATIC_KINDS:
        every = [m for m in every if statics_of(m) is not None]
    chosen = p.methods
    return [m for m in every if chosen is None or m in chosen]


def _active(ctx) -> bool:
    """False for a report on case files given by the user (``plan.case_files``): the benchmark
    problems belong to the default report only."""
    return not getattr(ctx.plan, "case_files", None)


def cases(ctx) -> dict:
    """The problems' cases (shortened to the plan's durations), by problem name: the study's own
    cases, which ``experiments.study.add_cases`` puts into ``ctx.cases`` before tasks are listed."""
    if not _active(ctx):
        return {}
    p = params(ctx, NAME)
    return {
        name: _shortened(case, p.durations.get(name))
        for name, (case, prov) in problems(p.problems).items()
        if prov["quantity"] != "frequencies" and prov["quantity"] not in STATIC_KINDS
    }


def tasks(ctx) -> list:
    """Every applicable method at every k of the plan (one run for the rigid baseline) on the
    problems' cases (:func:`cases`, in ``ctx.cases``); listing them changes nothing.

    Plan parameters (:class:`experiments.params.ProblemsParams`): ``ks`` (elements per link),
    ``problems`` (case-file names, default all), ``durations`` (name -> shortened duration, s),
    ``methods`` (optional: only these of each problem's methods), ``ks_by_problem`` (name -> ks
    replacing ``ks`` for that problem)."""
    if not _active(ctx):
        return []
    p = params(ctx, NAME)
    out = []
    for name, (_case, prov) in problems(p.problems).items():
        kind = prov["quantity"]
        if kind == "frequencies" or kind in STATIC_KINDS:
            continue
        T, h = ctx.cases[name].scenario.duration, step_of(prov)
        for m in _methods(p, kind, ctx.plan.name, ctx.cases[name]):
            ks = [0] if not uses_k(m) else p.ks_by_problem.get(name, p.ks)
            ks = [k for k in ks if k <= k_limit(m, NAME, ctx.plan.name)]
            out += [Task(name, m, k, h, T, peer_options(prov, m)) for k in ks]
    return list(dict.fromkeys(out))


# ----------------------------------------------------------------------------- quantities
def peak_tip_deflection(res) -> float:
    """Most negative tip deflection of the last link (m), the sampled minimum refined by the
    parabola through it and its two neighbours."""
    v = np.asarray(res.tip_deflection[:, -1], float)
    i = int(np.argmin(v))
    if i == 0 or i == v.size - 1:
        return float(v[i])
    a, b, c = v[i - 1], v[i], v[i + 1]
    curv = a - 2 * b + c
    if curv <= 0:
        return float(b)
    return float(b - (a - c) ** 2 / (8 * curv))


def tip_displacement(res, case, component: str) -> tuple:
    """(displacement of the end effector from the straight arm at the last output time (m),
    its movement over the last SETTLE_WINDOW s (m))."""
    ee = np.asarray(res.end_effector, float)
    straight = sum(link.beam.length for link in case.model.links)
    i = {"x": 0, "y": 1}[component]
    start = np.array([straight, 0.0])
    j = int(np.searchsorted(res.t, res.t[-1] - SETTLE_WINDOW))
    moved = float(np.max(np.linalg.norm(ee[j:] - ee[-1], axis=1)))
    return float(ee[-1, i] - start[i]), moved


def elastica_tip(alpha: float) -> tuple:
    """Tip of the inextensible cantilever elastica under a transverse end load (Bisshopp &
    Drucker 1945): (x/L, deflection/L, tip angle in rad) for the load parameter
    alpha = P L² / EI > 0.

    With p = sin(π/4 + θ_L/2) and sin φ₁ = 1/(p√2): √alpha = K(p) − F(φ₁, p),
    x/L = √(2(2p² − 1)/alpha), deflection/L = 1 − (2/√alpha)(E(p) − E(φ₁, p)), θ_L = asin(2p² − 1).
    """
    from scipy.optimize import brentq
    from scipy.special import ellipe, ellipeinc, ellipk, ellipkinc

    if not alpha > 0:
        raise ValueError(f"elastica: alpha = {alpha!r} must be positive")

    def phi1(p):
        return np.arcsin(min(1.0, 1 / (p * np.sqrt(2))))

    def gap(p):
        return ellipk(p * p) - ellipkinc(phi1(p), p * p) - np.sqrt(alpha)

    p = brentq(gap, 1 / np.sqrt(2), 1 - 1e-15, xtol=1e-15, rtol=4 * np.finfo(float).eps)
    m, f1 = p * p, phi1(p)
    x = np.sqrt(2 * (2 * m - 1) / alpha)
    defl = 1 - 2 / np.sqrt(alpha) * (ellipe(m) - ellipeinc(f1, m))
    return float(x), float(defl), float(np.arcsin(2 * m - 1))


def _on_grid(res, ref):
    n = min(len(res.t), len(ref.t))
    if not np.allclose(res.t[:n], ref.t[:n]) or n < 2:
        raise ValueError("run and reference are on different output grids")
    return n


def tip_deflection_rms(res, ref) -> float:
    """RMS over time of the last link's tip-deflection difference to ``ref``, divided by the
    reference's largest |tip deflection| (dimensionless)."""
    n = _on_grid(res, ref)
    d = res.tip_deflection[:n, -1] - ref.tip_deflection[:n, -1]
    return float(np.sqrt(np.mean(d**2)) / np.max(np.abs(ref.tip_deflection[:n, -1])))


def reach(case) -> float:
    """The sum of the link lengths (m)."""
    return float(sum(link.beam.length for link in case.model.links))


def tip_path_rms(res, ref, length: float) -> float:
    """RMS over time of the distance between the two end effectors, divided by ``length``."""
    n = _on_grid(res, ref)
    d = np.linalg.norm(res.end_effector[:n] - ref.end_effector[:n], axis=1)
    return float(np.sqrt(np.mean(d**2)) / length)


def energy_drift(res, case) -> float:
    """max |E(t) − E(0)| / (m g L / 2) of a one-link arm; NaN when no energy is recorded."""
    if res.energy is None or not np.all(np.isfinite(res.energy)):
        return math.nan
    b = case.model.links[0].beam
    scale = b.rhoA * b.length * np.hypot(*case.model.gravity) * b.length / 2
    return float(np.max(np.abs(res.energy - res.energy[0])) / scale)


def frequencies(case, k: int, method: str = "dttmm", n: int = 2) -> np.ndarray:
    """Lowest ``n`` natural frequencies (Hz) of a case at rest, held joints clamped, by the
    method's own linearisation (its registry record's ``frequencies`` function: DT-TMM's
    :func:`dttmm.linear.frequencies`, the global solver's M and K, Exudyn's eigenvalues)."""
    from .. import methods

    fn = methods.frequencies_of(method)
    if fn is None:
        raise ValueError(f"frequencies: no linearisation for method {method!r}")
    return np.asarray(fn(case, int(k), n=n), float)


def _parabola_peak(t, y, j, sign: float) -> tuple:
    """(value, time) of the extremum at sample j of y (a maximum for sign = 1, a minimum for
    −1), refined by the parabola through it and its two neighbours (uniform output grid t); the
    sample itself at either end of the run or where the three samples do not bend its way."""
    if j == 0 or j == len(y) - 1:
        return float(y[j]), float(t[j])
    y0, y1, y2 = y[j - 1 : j + 2]
    curv = y0 - 2.0 * y1 + y2
    if sign * curv >= 0:
        return float(y1), float(t[j])
    d = (y0 - y2) / (2.0 * curv)
    return float(y1 - 0.25 * (y0 - y2) * d), float(t[j] + d * (t[1] - t[0]))


def tip_extrema(res) -> dict:
    """Extrema of a spatial run's out-of-plane (z) displacements from the initial position: the
    last link's tip (``tip_z``) and the first link's tip (``elbow_z``): signal -> {"max", "min"}
    -> (value (m, or the case's length unit), time (s)), each refined by a parabola through the
    sample and its two neighbours (:func:`_parabola_peak`; at an end of the run, the sample)."""
    t = np.asarray(res.t, float)
    tip = np.asarray(res.end_effector, float)
    tips = np.asarray(res.link_tip, float)
    ys = {"tip_z": tip[:, 2] - tip[0, 2], "elbow_z": tips[:, 0, 2] - tips[0, 0, 2]}
    return {
        n: {
            "max": _parabola_peak(t, y, int(np.argmax(y)), 1.0),
            "min": _parabola_peak(t, y, int(np.argmin(y)), -1.0),
        }
        for n, y in ys.items()
    }


# ----------------------------------------------------------------------------- spatial statics
def _dttmm_statics(case, k, steps, strain="linear"):
    from dttmm.spatial import statics
    from dttmm.spatial.rotation import log_so3

    r = statics(case, elements_per_link=k, steps=steps, strain=strain)
    return {"tip": r.tip_position, "twist": float(log_so3(r.tip_rotation)[0])}


def _exudyn_statics(module):
    def f(case, k, steps):
        mod = importlib.import_module(module)
        r = mod.statics(case, elements_per_link=k, load_steps=steps)
        return {"tip": np.asarray(r["link_tip"][-1], float), "twist": float(r["twist"][-1])}

    return f


def tip_and_twist(out) -> tuple:
    """(tip position (3,), twist (rad, NaN when not given)) of a statics answer: a dict with
    ``tip`` and ``twist``, or the tip position alone."""
    if isinstance(out, dict):
        return np.asarray(out["tip"], float).reshape(3), float(out.get("twist", math.nan))
    return np.asarray(out, float).reshape(3), math.nan


#: statics of the built-in spatial engines, by their records' ``spatial`` entry: f(case, k,
#: steps) -> {"tip": the last link's tip position (3,), "twist": the x component (rad) of the
#: rotation vector of its tip section (the twist of a clamped link along x)} at equilibrium
#: under the case's gravity and loads at t = its duration, the loads applied in ``steps``
#: increments
_STATICS = {
    "reference_models.exudyn_beam3d:simulate": _exudyn_statics("reference_models.exudyn_beam3d"),
    "reference_models.exudyn_ancf3d:simulate": _exudyn_statics("reference_models.exudyn_ancf3d"),
}


def statics_of(name: str):
    """A method's spatial statics ``f(case, k, steps) -> {"tip": (3,), "twist": rad}`` (see
    :data:`_STATICS`; an outside one may return the tip position alone), or None: DT-TMM methods
    ``dttmm.spatial.statics`` with their strain option, the Exudyn peers their ``SolveStatic``;
    an outside method the ``statics`` attribute of its spatial function."""
    import functools

    from .. import methods

    try:
        rec = methods.get(name)
    except methods.MethodUnavailable:
        return None
    if not rec.spatial or rec.physics.strain == "rigid":
        return None
    if rec.spatial == "dttmm.spatial:simulate":
        opts = dict(rec.options if rec.spatial_options is None else rec.spatial_options)
        return functools.partial(_dttmm_statics, strain=opts.get("strain", "linear"))
    if rec.spatial in _STATICS:
        return _STATICS[rec.spatial]
    mod, fn = rec.spatial.split(":")
    try:
        return getattr(getattr(importlib.import_module(mod), fn), "statics", None)
    except Exception:  # noqa: BLE001 - a spatial entry that does not load has no statics here
        return None


def static_points(case, prov) -> list:
    """The equilibria a static spatial problem compares: [(case, load steps, [(target row, value
    of the tip position))])]. The Princeton beam: its load replaced by F [0, −cos β, sin β]
    (world, fixed direction) at every published (F, β), compared |u_y| and u_z of the tip from
    the straight beam; the 45° bend: the case at each load time (its load ramp), compared the
    distance of the tip from the published position over ``scale`` (R)."""
    from dttmm.spatial import SpatialLoad

    kind = prov["quantity"]
    rows = {t["quantity"]: t for t in target_rows(prov)}
    out = []
    if kind == "static_tip_displacement_3d":
        L = sum(link.beam.length for link in case.model.links)
        for F in prov["force"]:
            for b in prov["beta_deg"]:
                r = np.radians(b)
                load = SpatialLoad(force=(0.0, -F * np.cos(r), F * np.sin(r)))
                c = replace(case, scenario=replace(case.scenario, loads=(load,)))
                q = []
                for comp, label in prov["components"]:
                    t = rows[f"{label} F={F:g} N β={b:g}°"]
                    axis = {"uy_abs": 1, "uz": 2}[comp]
                    fn = abs if comp.endswith("_abs") else float
                    q.append((t, lambda tip, a=axis, fn=fn: fn(float(tip[a] - (L if a == 0 else 0.0)))))
                out.append((c, int(prov["load_steps"]), q))
        return out
    if kind == "static_tip_position_error":
        R = float(prov["scale"])
        for P, ref, T, n in zip(prov["P"], prov["tip_position"], prov["load_time"], prov["load_steps"]):
            c = _shortened(case, T)
            t = rows[f"tip position error P={P:g}"]
            x = np.asarray(ref, float)
            out.append((c, int(n), [(t, lambda tip, x=x: float(np.linalg.norm(tip - x) / R))]))
        return out
    raise ValueError(f"not a static spatial problem: {kind!r}")


def static_rows(name, case, prov, ks, plan_params=None, size=None) -> list:
    """Rows of a static spatial problem: every method with its own statics (:func:`statics_of`)
    that runs the case, at each k of ``ks`` (up to its ``spatial_max_k``); a solve that fails is a
    failed row with the reason."""
    from .. import console, methods

    rows, points = [], static_points(case, prov)
    for m in _methods(plan_params or ProblemsParams(), prov["quantity"], size, case):
        fn = statics_of(m)
        for k in (k for k in ks if methods.runs_on(m, case, k)):
            for c, steps, quantities in points:
                r = {"method": m, "k": k, "h": math.nan, "status": "ok", "reason": ""}
                try:
                    # an engine's own messages (Exudyn's "STATIC SOLVER FAILED") go into the row
                    with console.captured() as printed:
                        tip, _ = tip_and_twist(fn(c, k, steps))
                    vals = [f(tip) for _, f in quantities]
                except Exception as exc:  # noqa: BLE001 - reported, not dropped (InputError, SimulationError, an engine's own)
                    msg = " ".join(str(exc).split())[:200]
                    said = f"; it printed: {printed.last_line()}" if printed.last_line() else ""
                    r.update(status="failed", reason=f"{type(exc).__name__}: {msg}{said}")
                    vals = [math.nan] * len(quantities)
                for (t, _), v in zip(quantities, vals):
                    rows.append(_row(name, prov, t["quantity"], t["target"], r, v, t["scale"], t["group"]))
    return rows


# ----------------------------------------------------------------------------- analysis
def _row(name, prov, quantity, target, r, value, scale=None, group=None, **extra) -> dict:
    """One result row: the value against its target, error, relative error (to ``scale`` where
    given, else to the target), pass/fail by :func:`tolerance_of`."""
    err = abs(value - target) if np.isfinite(value) else math.nan
    tol, kind = tolerance_of(prov, quantity)
    relative = kind == "relative"
    rel = err / scale if scale else (err / abs(target) if target else err)
    measure = rel if relative else err
    return {
        "problem": name,
        "quantity": quantity,
        "group": group or quantity,
        "method": r["method"],
        "k": int(r["k"]),
        "h": float(r["h"]),
        "status": r["status"],
        "reason": r.get("reason", ""),
        "target": target,
        "value": value,
        "error": err,
        "rel_error": rel,
        "tolerance": tol,
        "tolerance_kind": "relative" if relative else "absolute",
        "passed": bool(np.isfinite(measure) and measure <= tol),
        "order_error": err,
        **extra,
    }


def _values(name, case, prov, res, ref) -> list:
    """[(quantity, value, extra columns)] of one finished run."""
    kind = prov["quantity"]
    if kind == "peak_tip_deflection":
        return [(kind, peak_tip_deflection(res), {})]
    if kind == "static_tip_displacement":
        v, moved = tip_displacement(res, case, prov["component"])
        return [(kind, v, {"settle_motion": moved, "settled": moved < SETTLE_TOL})]
    if kind == "tip_extrema":
        got = tip_extrema(res)
        out = []
        for e in prov["extrema"]:
            v, t = got[e["signal"]][e["kind"]]
            name = f"{e['signal']} {e['kind']}"
            out += [(name, v, {}), (f"{name} time", t, {})]
        return out
    if ref is None:
        return [(kind, math.nan, {"reason": "no reference run"})]
    if kind == "tip_deflection_rms":
        return [(kind, tip_deflection_rms(res, ref), {})]
    if kind == "tip_path_rms":
        out = [(kind, tip_path_rms(res, ref, reach(case)), {})]
        drift = energy_drift(res, case) if "energy_tolerance" in prov else math.nan
        if np.isfinite(drift):
            out.append(("energy_drift", drift, {}))
        return out
    raise ValueError(f"{name}: unknown quantity {kind!r}")


def _run_rows(ctx, name, case, prov, runs) -> list:
    ref_task = _ref_task(name, case, prov)
    ref = _reference(ctx, case, ref_task) if ref_task is not None else None
    rows = []
    for _, r in runs.iterrows():
        if ref_task is not None and (r["method"], r["k"], r["h"]) == (
            ref_task.method,
            ref_task.k,
            ref_task.h,
        ):
            continue  # the reference itself
        res = ctx.store.history(_task_of(r, prov)) if r["status"] == "ok" else None
        every = {t["quantity"]: t for t in target_rows(prov)}
        if res is not None:
            vals = _values(name, case, prov, res, ref)
        else:
            vals = [(q, math.nan, {}) for q in every]
        for quantity, value, extra in vals:
            t = every.get(quantity, {"target": 0.0, "group": quantity, "scale": None})
            target = 0.0 if quantity == "energy_drift" else t["target"]
            rows.append(_row(name, prov, quantity, target, r, value, t["scale"], t["group"], **extra))
    return rows


def _task_of(r, prov=None):
    opts = peer_options(prov, r["method"]) if prov else ()
    return Task(r["case"], r["method"], r["k"], r["h"], r["duration"], opts)


_FAILS = (ImportError, ValueError, ArithmeticError, np.linalg.LinAlgError)


def frequency_rows(name, case, prov, ks, plan_params=None, size=None) -> list:
    """Rows of the clamped-link frequency problems: every method with its own linearisation, each k."""
    rows, n = [], len(prov["values"])
    for m in _methods(plan_params or ProblemsParams(), "frequencies", size):
        fine = _fine_frequencies(case, m, n)
        for k in ks:
            r = {"method": m, "k": k, "h": math.nan, "status": "ok", "reason": ""}
            try:
                f = frequencies(case, k, m, n=n)
            except _FAILS as exc:  # reported, not dropped
                r.update(status="failed", reason=f"{type(exc).__name__}: {exc}")
                f = [math.nan] * n
            for (quantity, target), value, ref in zip(targets(prov), f, fine):
                diff = abs(value - ref)
                # below the linearisation's round-off the difference is not a discretisation error
                diff = diff if diff > FD_NOISE * abs(ref) else math.nan
                rows.append(_row(name, prov, quantity, target, r, float(value), order_error=diff))
    return rows


# relative differences below this are round-off of the linearisation (DT-TMM's lowest De Luca
# link-1 frequency carries ~2e-7 at k = 32: its ω² is ~1e-10 of the highest one)
FD_NOISE = 1e-6
K_FINE = 32  # elements per link of the converged frequencies the observed order is fitted against


def _fine_frequencies(case, method, n):
    try:
        return frequencies(case, K_FINE, method, n=n)
    except _FAILS:
        return [math.nan] * n


def analyse(ctx, table):
    """Tables: ``benchmarks`` (one row per problem, quantity, method, k: value, target, error,
    pass/fail), ``benchmarks_orders`` (observed order in k of the error) and
    ``benchmarks_problems`` (each problem's source, compared quantity, target and tolerance)."""
    if not _active(ctx):
        return {}
    p = params(ctx, NAME)
    rows, info = [], []
    for name, (case, prov) in problems(p.problems).items():
        info.append(_problem_info(name, prov))
        if prov["quantity"] == "frequencies":
            rows += frequency_rows(name, case, prov, p.ks, p, ctx.plan.name)
            continue
        if prov["quantity"] in STATIC_KINDS:
            rows += static_rows(name, case, prov, p.ks_by_problem.get(name, p.ks), p, ctx.plan.name)
            continue
        runs = table[table.case == name] if len(table) else table
        rows += _run_rows(ctx, name, ctx.cases.get(name, case), prov, runs)
    res = pd.DataFrame(rows)
    out = {NAME: res, f"{NAME}_orders": _orders(res), f"{NAME}_problems": pd.DataFrame(info)}
    out[f"{NAME}_series"] = _series(ctx, table)
    return out


MAX_POINTS = 800  # time samples kept per curve in the stored series


def _series(ctx, table) -> pd.DataFrame:
    """Tip-deflection histories of the spin-up problems: DT-TMM (linear strain) at every k, and
    the second-order element and the first reference method (Exudyn ANCF) at the largest k."""
    from .. import methods

    subjects = methods.by_role("subject")
    every_k = subjects[:1]
    at_kmax = [m for m in subjects if methods.get(m).physics.strain == "nonlinear"][:1]
    at_kmax += [m for m in methods.reference_candidates() if m not in subjects][:1]
    cols = ["problem", "method", "k", "t", "tip_deflection"]
    if table is None or table.empty:
        return pd.DataFrame(columns=cols)
    parts = []
    for name, g in table[table.status == "ok"].groupby("case", sort=True):
        if not str(name).startswith("spin_up"):
            continue
        kmax = g.k.max()
        keep = g[g.method.isin(every_k) | (g.method.isin(at_kmax) & (g.k == kmax))]
        for _, r in keep.iterrows():
            res = ctx.store.history(_task_of(r))
            step = max(1, len(res.t) // MAX_POINTS)
            parts.append(
                pd.DataFrame(
                    {
                        "problem": name,
                        "method": r["method"],
                        "k": int(r["k"]),
                        "t": res.t[::step],
                        "tip_deflection": res.tip_deflection[::step, -1],
                    }
                )
            )
    return pd.concat(parts, ignore_index=True) if parts else pd.DataFrame(columns=cols)


def _orders(res: pd.DataFrame) -> pd.DataFrame:
    """Observed order in k of each (problem, quantity, method)'s ``order_error`` (the error
    against the target; for the frequencies, quoted to 0.01 Hz, the difference to k = K_FINE),
    the rigid baseline left out."""
    cols = ["problem", "quantity", "method", "order", "n_points", "k_min", "k_max"]
    if res.empty:
        return pd.DataFrame(columns=cols)
    flex = res[res.method.map(uses_k)].rename(columns={"quantity": "compared"})
    o = fit_orders(flex, "k", "order_error", ["problem", "compared", "method"], refine_descending=False)
    o = o.drop(columns="quantity").rename(
        columns={"compared": "quantity", "x_min": "k_min", "x_max": "k_max"}
    )
    return o[cols]


def _targets_text(prov) -> str:
    t = targets(prov)
    if len(t) > 8:  # a load sweep: the range, the values are in the problem's table
        return f"{len(t)} values ({prov.get('value_kind', '')}), see the problem's table"
    return ", ".join(f"{q} = {v:.6g}" for q, v in t)


def _problem_info(name, prov) -> dict:
    return {
        "problem": name,
        "space": "spatial" if name in SPATIAL_PROBLEMS else "planar",
        "source": prov.get("source", ""),
        "compared": prov.get("compared", ""),
        "target": _targets_text(prov),
        "value_kind": prov.get("value_kind", ""),
        "units": prov.get("units", ""),
        "tolerance": f"{prov.get('tolerance')} ({prov.get('tolerance_kind')})",
    }


if __name__ == "__main__":  # python -m experiments.studies.problems (or .benchmarks) [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
