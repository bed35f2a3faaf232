"""Driver of the compiled engine of the global-equation solver (``engine="numba"``).

Tabulates the drive values on the step schedule and at the output times (for closed-loop
joints their feedforward and reference, :func:`dttmm.control.time_tables`), runs the compiled
time loop of :mod:`reference_models._global_numba`, and turns the recorded (q, q̇, τ) into a
:class:`dttmm.Result` with the same recorder as the numpy engine.
"""

from __future__ import annotations

import time

import numpy as np

from dttmm.control import time_tables
from dttmm.errors import SimulationError
from dttmm.timegrid import step_schedule

from . import _global_numba as G
from . import _global_numpy as gn


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


def _initial(case, lay, P, C, tol, maxit):
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
    qdd, tau_p, tau_c, ok = G.forward_closed(P, C, q, qd, Q, pres[:, 2].copy(), ff[0], ref[0], z, tol, maxit)
    tau = gn._joint_torques(case, lay, 0.0, False, tau_p)
    tau[C.joint] = tau_c
    return q, qd, qdd, tau, z, ref[0, :, 0] - q[C.row], ok


def _component(lay, bad: int) -> str:
    """Name of entry ``bad`` of [q, q̇, q̈] ("state" when unknown)."""
    if bad < 0:
        return "state"
    names = lay.names + [f"rate of {c}" for c in lay.names] + [f"acceleration of {c}" for c in lay.names]
    return names[bad]


def run(case, lay, k, h, integrator, opt):
    """Fixed-step run with the compiled engine; same contract as the numpy engine's."""
    P = G.pack(lay, case)
    C = G.pack_loop(lay, case)
    coef = np.array(gn._coefficients(integrator, opt), float)
    t_end, restart = step_schedule(case.scenario.duration, h, case.scenario.breakpoints)
    rec = gn._Recorder(lay, case.scenario.output_times)
    meta = gn._base_meta(lay, k, h, integrator, opt)
    meta.update(dict(zip(("beta", "gamma", "alpha_m", "alpha_f"), coef)))
    meta["engine"] = "numba"
    tol_t = 1e-9 * h
    q, qd, qdd, tau, z, err, ok0 = _initial(case, lay, P, C, float(opt["tol"]), int(opt["max_iterations"]))
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
        tq_l[:0],
        mo_l[:0],
        tq_r[:0],
        mo_r[:0],
        q.copy(),
        qd.copy(),
        qdd.copy(),
        qdd.copy(),
        tau.copy(),
        rec.t[:0],
        tq_o[:0],
        mo_o[:0],
        rec.q[:0],
        rec.qd[:0],
        rec.tau[:0],
        uncon[:0],
        np.zeros(7),
        ff_l[:0],
        ref_l[:0],
        ff_r[:0],
        ref_r[:0],
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
            tq_l,
            mo_l,
            tq_r,
            mo_r,
            q,
            qd,
            qdd,
            qdd.copy(),
            tau,
            rec.t,
            tq_o,
            mo_o,
            rec.q,
            rec.qd,
            rec.tau,
            uncon,
            stats,
            ff_l,
            ref_l,
            ff_r,
            ref_r,
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
    status, warn = gn._convergence(meta, [int(i) for i in np.flatnonzero(uncon)], t_end, opt, fd)
    return rec.result(lay, wall, n_steps, meta, status=status, warnings=warn, kinetic=kinetic)
