"""Driver of the global-equation solver's time loop, for both engines of its one source.

Checks the options, tabulates the drive values on the step schedule and at the output times
(for closed-loop joints their feedforward and reference, :func:`dttmm.control.time_tables`),
runs the time loop of :mod:`reference_models._global_numba` — compiled (``engine="numba"``) or
the same source uncompiled (:mod:`reference_models._global_python`, ``engine="python"``) — and
turns the recorded (q, q̇, τ) into a :class:`dttmm.Result` with the readable kinematics and
energy of :mod:`reference_models._global_numpy`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from dttmm import make_result
from dttmm.control import time_tables
from dttmm.drives import ControlState
from dttmm.errors import InputError, SimulationError
from dttmm.plumbing import versions
from dttmm.timegrid import step_schedule

from . import _checks
from . import _global_numpy as gn

INTEGRATORS = ("newmark", "generalized-alpha")
#: "numba": compiled; "python": the same source uncompiled ("numpy" is an alias of "python")
ENGINES = ("numba", "python")
_ALIASES = {"numpy": "python"}
_MAX_SOLVES = 50

_OPTIONS = {
    "newmark": {"beta": 0.25, "gamma": 0.5, "iterations": None, "tol": 1e-10, "max_iterations": _MAX_SOLVES},
    "generalized-alpha": {"rho_inf": 0.9, "iterations": None, "tol": 1e-10, "max_iterations": _MAX_SOLVES},
}


# ----------------------------------------------------------------------------------------------
# Options
# ----------------------------------------------------------------------------------------------


def _positive_option(name, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(name, value, "must be a positive number") from None
    if not (math.isfinite(x) and x > 0):
        raise InputError(name, value, "must be a positive number")
    return x


def check_options(integrator, options: dict) -> dict:
    """Validate the integrator name and its options; return options with defaults filled."""
    _checks.integrator(integrator, INTEGRATORS)
    allowed = _OPTIONS[integrator]
    _checks.integrator_options(integrator, options, allowed)
    opt = {**allowed, **options}
    for key in ("beta", "gamma", "tol"):
        if key in opt:
            opt[key] = _positive_option(key, opt[key])
    if "rho_inf" in opt:
        r = opt["rho_inf"]
        if isinstance(r, bool) or not isinstance(r, (int, float, np.floating)) or not 0.0 <= r <= 1.0:
            raise InputError("rho_inf", r, "must be a number in [0, 1]")
    if opt["iterations"] is not None:
        m = opt["iterations"]
        if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 0:
            raise InputError("iterations", m, "must be None or an integer >= 0")
    m = opt["max_iterations"]
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
        raise InputError("max_iterations", m, "must be an integer >= 1")
    return opt


def coefficients(integrator: str, opt: dict) -> tuple[float, float, float, float]:
    """(β, γ, α_m, α_f)."""
    if integrator == "newmark":
        return opt["beta"], opt["gamma"], 0.0, 0.0
    r = float(opt["rho_inf"])
    am = (2 * r - 1) / (r + 1)
    af = r / (r + 1)
    gamma = 0.5 + af - am
    return 0.25 * (gamma + 0.5) ** 2, gamma, am, af


def _have_numba() -> bool:
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


def check_engine(engine) -> str:
    """ "numba" or "python" ("numpy" is its alias); None → "numba" when numba imports."""
    if engine is None:
        return "numba" if _have_numba() else "python"
    if not isinstance(engine, str) or engine not in ENGINES + tuple(_ALIASES):
        raise InputError("engine", engine, f"unknown engine (one of: {', '.join(ENGINES + tuple(_ALIASES))})")
    engine = _ALIASES.get(engine, engine)
    if engine == "numba" and not _have_numba():
        raise InputError("engine", engine, "needs numba, which is not installed (extra 'fast')")
    return engine


# ----------------------------------------------------------------------------------------------
# Output recording
# ----------------------------------------------------------------------------------------------


class _Recorder:
    """Stores (q, q̇, joint torques) at the output times; derived quantities come later."""

    def __init__(self, lay, times: np.ndarray):
        self.t = times
        nt = times.size
        self.q = np.zeros((nt, lay.n_dof))
        self.qd = np.zeros((nt, lay.n_dof))
        self.tau = np.zeros((nt, lay.n_links))
        self.count = 0

    def add(self, q, qd, tau):
        i = self.count
        self.q[i], self.qd[i], self.tau[i] = q, qd, tau
        self.count += 1

    @property
    def next_time(self) -> float:
        return self.t[self.count] if self.count < self.t.size else math.inf

    def result(self, lay, wall, n_steps, meta, status=None, warnings=(), kinetic=None) -> object:
        n = self.count
        nl = lay.n_links
        root = np.zeros((n, nl, 2))
        tip = np.zeros((n, nl, 2))
        root_ang = np.zeros((n, nl))
        en = np.zeros(n)
        for i in range(n):
            fr = gn._link_frames(lay, self.q[i])
            root[i], tip[i], root_ang[i] = fr["root"], fr["tip"], fr["root_angle"]
            e = gn._energy(lay, self.q[i], self.qd[i], kinetic)
            en[i] = e["kinetic"] + e["elastic"] + e["gravity"]
        a = lay.alpha_idx
        shapes = gn._link_shapes(lay, self.q[:n], lay.shape_points) if lay.shape_points else None
        return make_result(
            t=self.t[:n],
            joint_angle=self.q[:n, a],
            joint_rate=self.qd[:n, a],
            joint_torque=self.tau[:n],
            link_root=root,
            link_root_angle=root_ang,
            link_tip=tip,
            wall_time=wall,
            n_steps=n_steps,
            meta=meta,
            energy=en,
            status=status,
            warnings=warnings,
            link_shapes=shapes,
        )


def _base_meta(lay, k, h, integrator, opt) -> dict:
    meta = {
        "method": "global",
        "elements_per_link": k,
        "h": h,
        "integrator": integrator,
        "n_dof": lay.n_dof,
        "strain": lay.strain,
        "success": True,
        "versions": versions(),
    }
    meta.update({key: val for key, val in opt.items()})
    return meta


def convergence(meta: dict, unconverged, t_end, opt, unconverged_solves: int = 0):
    """Record the unconverged steps (and forward-dynamics solves with closed-loop laws, at t = 0
    and restarts) in ``meta``; status and warnings for the Result."""
    meta.update({"unconverged_steps": len(unconverged), "unconverged_step_indices": list(unconverged[:20])})
    warns = []
    if unconverged:
        first = float(t_end[unconverged[0]])
        warns.append(
            f"iteration not converged (tol {opt['tol']:g}) within {opt['max_iterations']} solves at "
            f"{len(unconverged)} step(s), first at t = {first:.6g} s"
        )
    if unconverged_solves:
        meta["unconverged_solves"] = int(unconverged_solves)
        warns.append(
            f"{unconverged_solves} forward-dynamics solves with closed-loop laws (t = 0, restarts) "
            f"not converged (tol {opt['tol']:g}) within {opt['max_iterations']} solves"
        )
    return ("unconverged" if warns else "ok"), tuple(warns)


# ----------------------------------------------------------------------------------------------
# Drive tables
# ----------------------------------------------------------------------------------------------


def _tables(case, times, left: bool, rows=None):
    """(len(times), n_torque) torque and (len(times), n_motion, 3) motion values of the drives."""
    drives = case.scenario.drives
    idx = np.arange(len(times)) if rows is None else rows
    tq = np.zeros((len(times), sum(d.kind == "torque" and not d.closed_loop for d in drives)))
    mo = np.zeros((len(times), sum(d.kind == "motion" for d in drives), 3))
    it = jm = 0
    for d in drives:
        if d.closed_loop:
            continue
        if d.kind == "torque":
            tq[idx, it] = [d.torque(times[i], left) for i in idx]
            it += 1
        else:
            mo[idx, jm] = np.array([d.motion(times[i], left) for i in idx], float).reshape(-1, 3)
            jm += 1
    return tq, mo


def _law_tables(case, C, times, left: bool, rows=None):
    """Feedforward (len(times), nc) and reference (len(times), nc, 2) of the closed-loop
    joints (zero rows outside ``rows``)."""
    nc = C.joint.size
    ff = np.zeros((len(times), nc))
    ref = np.zeros((len(times), nc, 2))
    idx = np.arange(len(times)) if rows is None else rows
    if nc and idx.size:
        f, r = time_tables(case, np.asarray(times)[idx], left)
        ff[idx], ref[idx] = f[:, C.joint], r[:, C.joint]
    return ff, ref


def _user_laws(case, lay):
    """The user laws of ``case`` as one callable (c, t, left, q, q̇, M_root) -> (τ, ∂τ/∂α, ∂τ/∂α̇)
    for closed-loop joint c (the uncompiled engine calls it; see ``Loop.laws``); None without."""
    drives = case.scenario.drives
    joints = [i for i, d in enumerate(drives) if d.closed_loop]
    if not any(d.law.name == "user" for d in drives if d.closed_loop):
        return None
    a = lay.alpha_idx

    def laws(c, t, left, q, qd, moment):
        i = joints[c]
        r = a[i]
        st = ControlState(
            i,
            float(q[r]),
            float(qd[r]),
            float(moment),
            0.0,
            tuple(q[a].tolist()),
            tuple(qd[a].tolist()),
            tuple(np.asarray(gn._tip_deflections(lay, q), float).tolist()),
        )
        tau, da, dv, _ = drives[i].evaluate(t, st, left)
        return tau, da, dv

    return laws


# ----------------------------------------------------------------------------------------------
# The run
# ----------------------------------------------------------------------------------------------


def _engine(engine: str):
    if engine == "numba":
        from . import _global_numba as G  # compiled on first use: numba is optional
    else:
        from . import _global_python as G
    return G


def _initial(G, case, lay, P, C, tol, maxit):
    """State at t = 0 (right limits of the drives), q̈ from the equations (with the closed-loop
    laws, integral states 0), joint torques, the closed-loop joints' z and α_ref − α, and
    whether the closed-loop solve converged."""
    q, qd = gn._initial_state(case, lay)
    pres = gn._prescribed(case, lay, 0.0, False)
    q[lay.presc], qd[lay.presc] = pres[:, 0], pres[:, 1]
    Q = gn._torques(case, lay, 0.0, False)
    nc = C.joint.size
    z = np.zeros(nc)
    if not nc:
        qdd, tau_p = G.forward(P, q, qd, Q, pres[:, 2].copy())
        return q, qd, qdd, gn._joint_torques(case, lay, 0.0, False, tau_p), z, z.copy(), True
    ff, ref = _law_tables(case, C, [0.0], False)
    qdd, tau_p, tau_c, ok = G.forward_closed(
        P, C, 0.0, False, q, qd, Q, pres[:, 2].copy(), ff[0], ref[0], z, np.zeros(nc), tol, maxit
    )
    tau = gn._joint_torques(case, lay, 0.0, False, tau_p)
    tau[C.joint] = tau_c
    return q, qd, qdd, tau, z, ref[0, :, 0] - q[C.row], ok


def _component(lay, bad: int) -> str:
    """Name of entry ``bad`` of [q, q̇, q̈] ("state" when unknown)."""
    if bad < 0:
        return "state"
    names = lay.names + [f"rate of {c}" for c in lay.names] + [f"acceleration of {c}" for c in lay.names]
    return names[bad]


def run(case, lay, k, h, integrator, opt, engine):
    """Fixed-step run of the schedule of :func:`dttmm.timegrid.step_schedule` with ``engine``."""
    G = _engine(engine)
    P = G.pack(lay, case)
    C = G.pack_loop(lay, case, _user_laws(case, lay) if engine == "python" else None)
    coef = np.array(coefficients(integrator, opt), float)
    t_end, restart = step_schedule(case.scenario.duration, h, case.scenario.breakpoints)
    rec = _Recorder(lay, case.scenario.output_times)
    meta = _base_meta(lay, k, h, integrator, opt)
    meta.update(dict(zip(("beta", "gamma", "alpha_m", "alpha_f"), coef)))
    meta["engine"] = engine
    tol_t = 1e-9 * h
    q, qd, qdd, tau, z, err, ok0 = _initial(G, case, lay, P, C, float(opt["tol"]), int(opt["max_iterations"]))
    if rec.next_time <= tol_t:
        rec.add(q, qd, tau)
    tq_l, mo_l = _tables(case, t_end, True)
    tq_r, mo_r = _tables(case, t_end, False, np.flatnonzero(restart))
    tq_o, mo_o = _tables(case, rec.t, False)
    ff_l, ref_l = _law_tables(case, C, t_end, True)
    ff_r, ref_r = _law_tables(case, C, t_end, False, np.flatnonzero(restart))
    itmode = G.IT_TOL if opt["iterations"] is None else G.IT_FIXED
    nfix = 0 if opt["iterations"] is None else int(opt["iterations"])
    stats = np.zeros(7)
    stats[5] = -1
    stats[4] = rec.count
    uncon = np.zeros(t_end.size, np.bool_)

    def kinetic(qq, qqd):
        return G.kinetic(P, qq, qqd)

    tables = (tq_l, mo_l, tq_r, mo_r)
    outputs = (rec.t, tq_o, mo_o, rec.q, rec.qd, rec.tau)
    laws = (ff_l, ref_l, ff_r, ref_r)
    if engine == "numba":
        # compile (or load from the cache) outside the timed loop: the same call with no steps
        t0 = time.perf_counter()
        G.run(
            P,
            C,
            coef,
            itmode,
            nfix,
            1e-10,
            1,
            t_end[:0],
            restart[:0].astype(np.bool_),
            *(a[:0] for a in tables),
            q.copy(),
            qd.copy(),
            qdd.copy(),
            qdd.copy(),
            tau.copy(),
            *(a[:0] for a in outputs),
            uncon[:0],
            np.zeros(7),
            *(a[:0] for a in laws),
            z.copy(),
            err.copy(),
        )
        meta["warmup_time"] = time.perf_counter() - t0
    wall0 = time.perf_counter()
    try:
        status = G.run(
            P,
            C,
            coef,
            itmode,
            nfix,
            float(opt["tol"]),
            int(opt["max_iterations"]),
            t_end,
            restart.astype(np.bool_),
            *tables,
            q,
            qd,
            qdd,
            qdd.copy(),
            tau,
            *outputs,
            uncon,
            stats,
            *laws,
            z,
            err,
        )
        why = "non-finite state"
    except np.linalg.LinAlgError as exc:
        status, why = G.NONFINITE, f"linear solve failed ({exc})"
    wall = time.perf_counter() - wall0
    step = int(stats[3])
    rec.count = int(stats[4])
    if status != G.OK:
        partial = rec.result(lay, wall, step, {**meta, "success": False}, kinetic=kinetic)
        raise SimulationError(
            why, t=float(t_end[step]), step=step, component=_component(lay, int(stats[5])), partial=partial
        )
    n_steps = t_end.size
    meta.update(
        {
            "iterations_mean": stats[0] / n_steps,
            "iterations_max": int(stats[1]),
            "time_per_step": wall / n_steps,
        }
    )
    fd = int(stats[6]) + (not ok0)
    status, warn = convergence(meta, [int(i) for i in np.flatnonzero(uncon)], t_end, opt, fd)
    return rec.result(lay, wall, n_steps, meta, status=status, warnings=warn, kinetic=kinetic)


__all__ = ["INTEGRATORS", "ENGINES", "check_options", "check_engine", "coefficients", "run"]
