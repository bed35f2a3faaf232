"""Spatial DT-TMM: :func:`simulate` (Newmark family or RK4) and :func:`accelerations` (the
forward dynamics at one state) of a spatial arm (docs/spatial.md)."""

from __future__ import annotations

import time
import warnings

import numpy as np

from .. import plumbing
from ..case import Case
from ..errors import InputError
from ..timegrid import step_schedule
from .build import STRAINS, build_model, make_work
from .case import SpatialCase
from .kernel.core import INPUT_COLS, LOAD_COL
from .result import SpatialResult
from .rotation import log_so3
from .scenario import load_inputs

__all__ = ["INTEGRATORS", "accelerations", "as_spatial_case", "simulate"]

INTEGRATORS = ("newmark", "generalized-alpha", "rk4")
ENGINES = ("numba", "python")
_STATUS = {1: "non-finite state", 2: "singular step system", 3: "runaway elastic coordinate"}


def _kernel(engine):
    """(core, loop) modules of the compiled or uncompiled kernel."""
    from .kernel import _jit

    if engine is None:
        engine = "numba" if _jit.HAVE_NUMBA else "python"
    plumbing.choice("engine", engine, ENGINES)
    if engine == "numba" and not _jit.HAVE_NUMBA:
        raise InputError("engine", engine, "numba is not installed; use engine='python'")
    if engine == "numba":
        from .kernel import core, loop
    else:
        from .kernel_python import core, loop
    return engine, core, loop


def as_spatial_case(case) -> SpatialCase:
    """A :class:`SpatialCase`, or a (SpatialManipulator, Scenario) pair made one."""
    if isinstance(case, SpatialCase):
        return case
    if isinstance(case, tuple) and len(case) == 2:
        return SpatialCase(case[0], case[1])
    raise InputError(
        "case", case, "must be a dttmm.spatial.SpatialCase or a (SpatialManipulator, Scenario) pair"
    )


def _motion_flags(case: SpatialCase) -> np.ndarray:
    flags = np.zeros(case.model.n_links, np.int64)
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        if d.closed_loop:
            j = case.model.unlocked.index(i)
            raise InputError(
                f"scenario.drives[{j}].law",
                d.law.name,
                f"closed-loop drive law {d.law.name!r} on joint {j + 1} is not supported by the spatial kernel yet",
            )
        flags[i] = d.kind == "motion"
    return flags


def _drive_values(case: SpatialCase, n: int, t: float, left: bool):
    tau, mot = np.zeros(n), np.zeros((n, INPUT_COLS))
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        if d.kind == "motion":
            mot[i, :3] = d.motion(t, left)
        else:
            tau[i] = d.torque(t, left)
    load_inputs(case, t, left, mot[:, LOAD_COL:])
    return tau, mot


def _tables(case, n, t_end, restart):
    ns = t_end.size
    t_start = np.concatenate(([0.0], t_end[:-1]))
    t_mid = t_start + 0.5 * (t_end - t_start)
    tl, ml = np.zeros((ns, n)), np.zeros((ns, n, INPUT_COLS))
    tr, mr = np.zeros((ns + 1, n)), np.zeros((ns + 1, n, INPUT_COLS))
    tm, mm = np.zeros((ns, n)), np.zeros((ns, n, INPUT_COLS))
    for s in range(ns):
        tl[s], ml[s] = _drive_values(case, n, t_end[s], True)
        tm[s], mm[s] = _drive_values(case, n, t_mid[s], False)
        if restart[s]:
            tr[s], mr[s] = _drive_values(case, n, t_end[s], False)
    # the last row of the right limits holds t = 0
    t0r, m0r = _drive_values(case, n, 0.0, False)
    tr[ns], mr[ns] = t0r, m0r
    return tl, ml, tr, mr, tm, mm, t0r, m0r


def initial_state(case: SpatialCase, md):
    q, qd = np.zeros(md.ndof), np.zeros(md.ndof)
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        if d.kind == "motion":
            a = d.motion(0.0, False)
            q[md.ia[i]], qd[md.ia[i]] = a[0], a[1]
        else:
            q[md.ia[i]], qd[md.ia[i]] = d.initial_angle, d.initial_rate
    return q, qd


def accelerations(
    case,
    elements_per_link: int,
    q,
    qd,
    t: float = 0.0,
    *,
    strain: str = "linear",
    forces=None,
    engine: str | None = None,
    loads: bool = False,
):
    """Forward dynamics of the discretised spatial arm: q̈ (n_dof,) at (q, q̇) and time t.

    Coordinates q = [α_1, e_11, …, e_1k, α_2, …] (no α for a locked joint; e = (u, v, w, φx, φy,
    φz), without u for an inextensible link). Motion-driven joints take the law's α, α̇, α̈.
    ``forces`` (n_dof,): generalized forces on the coordinates besides the drives. With
    ``loads`` returns (q̈, torques (n_links,), cut loads (n_el + n_links, 6)).
    """
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    engine, core, _ = _kernel(engine)
    md = build_model(case.model, k, strain, _motion_flags(case))
    ws = make_work(md)
    q, qd = np.array(q, float), np.array(qd, float)
    if q.shape != (md.ndof,) or qd.shape != (md.ndof,):
        raise InputError("q/qd", (q.shape, qd.shape), f"must both have shape ({md.ndof},)")
    f = np.zeros(md.ndof) if forces is None else np.asarray(forces, float)
    if f.shape != (md.ndof,):
        raise InputError("forces", f.shape, f"must have shape ({md.ndof},)")
    tau, mot = _drive_values(case, md.n, t, False)
    qdd = np.zeros(md.ndof)
    cut = np.zeros((md.nel + md.n, 6))
    ok = core.accelerations(md, ws, q, qd, tau, mot, f, qdd, bool(loads), cut)
    if not ok:
        raise InputError("q", "<state>", "the step system is singular at this state")
    if loads:
        torque = np.where(md.motion == 1, ws.acc[:, 1], tau)
        return qdd, torque, cut
    return qdd


def _outputs(core, md, ws, case, oq, oqd, otau, nt, want_energy, want_loads):
    n = md.n
    root, tip = np.zeros((nt, n, 3)), np.zeros((nt, n, 3))
    Rl, Rt = np.zeros((nt, n, 3, 3)), np.zeros((nt, n, 3, 3))
    en = np.full(nt, np.nan) if want_energy else None
    loads = np.zeros((nt, md.nel + n, 6)) if want_loads else None
    qdd = np.zeros(md.ndof)
    zero = np.zeros(md.ndof)
    el0 = md.el0
    for j in range(nt):
        core.kinematics(md, ws, oq[j], oqd[j])
        root[j] = ws.pw[el0]
        tip[j] = ws.pT[1:]
        Rl[j] = np.einsum("nij,nkj->nik", ws.Rw[el0], md.Q)
        Rt[j] = ws.RT[1:]
        if want_energy:
            en[j] = core.energy(md, ws)
        if want_loads:
            tau, mot = _drive_values(case, n, case.scenario.output_times[j], True)
            core.accelerations(md, ws, oq[j].copy(), oqd[j].copy(), tau, mot, zero, qdd, True, loads[j])
    d = tip - root
    defl = np.stack(
        [np.einsum("tni,tni->tn", d, Rl[..., 1]), np.einsum("tni,tni->tn", d, Rl[..., 2])], axis=-1
    )
    twist = np.zeros((nt, n))
    for j in range(nt):
        for i in range(n):
            twist[j, i] = log_so3(Rl[j, i].T @ Rt[j, i])[0]
    return root, tip, Rl, Rt, defl, twist, en, loads


def simulate(
    case,
    *,
    elements_per_link: int,
    h: float,
    integrator: str = "newmark",
    strain: str = "linear",
    iterations: int | None = None,
    tol: float = 1e-10,
    max_iterations: int = 50,
    beta: float | None = None,
    gamma: float | None = None,
    rho_inf: float | None = None,
    cut_loads: bool = False,
    energy: bool = True,
    engine: str | None = None,
    **planar_options,
):
    """Simulate a spatial case by DT-TMM with k = ``elements_per_link`` elements per link and
    step ``h`` (docs/spatial.md).

    ``case``: a :class:`SpatialCase` or a (SpatialManipulator, Scenario) pair; a planar
    :class:`dttmm.Case` runs on the planar kernel (:func:`dttmm.simulate`, its Result shapes).
    ``integrator``: "newmark" (β = ¼, γ = ½ unless given), "generalized-alpha" (``rho_inf``) or
    "rk4"; ``iterations``: None (each step to max|Δq̈| ≤ tol·max(1, max|q̈|), the suite's stop
    rule, at most ``max_iterations`` sweeps) or m ≥ 0 (m + 1 sweeps per step); ``strain``:
    "linear" or "second-order"; ``cut_loads``, ``energy``: record them on the output grid.
    Returns a :class:`SpatialResult`; raises InputError for bad settings, SimulationError (with
    ``.partial``) when the run diverges.
    """
    if isinstance(case, Case):
        from ..solver import simulate as planar_simulate

        return planar_simulate(
            case,
            elements_per_link=elements_per_link,
            h=h,
            integrator=integrator,
            strain=strain,
            iterations=iterations,
            tol=tol,
            max_iterations=max_iterations,
            beta=beta,
            gamma=gamma,
            rho_inf=rho_inf,
            cut_loads=cut_loads,
            energy=energy,
            engine=engine,
            **planar_options,
        )
    if planar_options:
        key = next(iter(planar_options))
        raise InputError(key, planar_options[key], "is an option of the planar kernel only (dttmm.simulate)")
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    h = plumbing.step_size(h, case.scenario.duration)
    plumbing.choice("integrator", integrator, INTEGRATORS)
    plumbing.choice("strain", strain, STRAINS)
    iters = plumbing.iterations_setting(iterations)
    if iters == "auto":
        raise InputError("iterations", iters, "the spatial kernel iterates to tolerance or a fixed count")
    tol = plumbing.open_fraction("tol", tol)
    max_iterations = plumbing.positive_integer("max_iterations", max_iterations)
    fam = (
        None
        if integrator == "rk4"
        else plumbing.newmark_family(integrator, beta=beta, gamma=gamma, rho_inf=rho_inf)
    )
    engine, core, loop = _kernel(engine)
    md = build_model(case.model, k, strain, _motion_flags(case))
    ws = make_work(md)
    sc = case.scenario
    t_end, restart = step_schedule(sc.duration, h, sc.breakpoints)
    tl, ml, tr, mr, tm, mm, t0r, m0r = _tables(case, md.n, t_end, restart)
    q, qd = initial_state(case, md)
    qdd = np.zeros(md.ndof)
    torque0 = np.zeros(md.n)
    if not loop.accel(md, ws, q, qd, t0r, m0r, np.zeros(md.ndof), qdd, torque0):
        raise InputError("case", case.name or "<case>", "the system is singular at t = 0")
    aux = qdd.copy()
    ts = sc.output_times
    nt = ts.size
    oq, oqd, otau = (
        np.full((nt, md.ndof), np.nan),
        np.full((nt, md.ndof), np.nan),
        np.full((nt, md.n), np.nan),
    )
    stats = np.zeros(6, np.int64)
    b, g, am, af = (0.25, 0.5, 0.0, 0.0) if fam is None else (fam.beta, fam.gamma, fam.alpha_m, fam.alpha_f)
    t_start = time.perf_counter()
    c0 = time.process_time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        n_steps = loop.run(
            md,
            ws,
            loop.INT_RK4 if fam is None else loop.INT_NEWMARK,
            b,
            g,
            am,
            af,
            tol,
            max_iterations,
            -1 if iters is None else iters,
            t_end,
            restart,
            tl,
            ml,
            tr,
            mr,
            tm,
            mm,
            q,
            qd,
            qdd,
            aux,
            ts,
            oq,
            oqd,
            otau,
            stats,
        )
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - c0
    upto = int(stats[5])
    meta = {
        "method": "dttmm-spatial",
        "elements_per_link": k,
        "h": h,
        "integrator": integrator,
        "strain": strain,
        "engine": engine,
        "n_dof": md.ndof,
        "iterations": iters,
        "tol": tol,
        "sweeps_per_step": float(stats[0]) / max(int(n_steps), 1),
        "max_sweeps": int(stats[1]),
        "unconverged_steps": int(stats[2]),
        "cpu_time": cpu,
        "versions": plumbing.versions(),
    }
    if fam is not None:
        meta.update(beta=fam.beta, gamma=fam.gamma, alpha_m=fam.alpha_m, alpha_f=fam.alpha_f)
    status = "ok"
    warns = []
    if iters is not None or stats[2] > 0:
        status = "unconverged"
        warns.append(
            f"{int(stats[2])} steps stopped at max_iterations"
            if iters is None
            else "fixed sweep count per step"
        )

    def result(upto_, meta_, status_):
        sel = slice(0, upto_)
        root, tip, Rl, Rt, defl, twist, en, loads = _outputs(
            core, md, ws, case, oq[sel], oqd[sel], otau[sel], upto_, energy, cut_loads
        )
        unl = list(case.model.unlocked)
        return SpatialResult(
            t=ts[sel],
            joint_angle=oq[sel][:, md.ia[unl]] if unl else np.zeros((upto_, 0)),
            joint_rate=oqd[sel][:, md.ia[unl]] if unl else np.zeros((upto_, 0)),
            joint_torque=otau[sel][:, unl],
            link_root=root,
            link_tip=tip,
            tip_deflection=defl,
            end_effector=tip[:, -1, :].copy(),
            wall_time=wall,
            n_steps=int(n_steps),
            meta=dict(meta_),
            cut_loads=loads,
            cut_load_t=ts[sel] if cut_loads else None,
            energy=en,
            status=status_,
            warnings=tuple(warns),
            twist=twist,
            link_rotation=Rl,
            tip_rotation=Rt,
        )

    if stats[3] != 0:
        s = int(stats[4])
        raise plumbing.simulation_failure(
            _STATUS.get(int(stats[3]), "failure"),
            t=float(t_end[s]),
            step=s,
            component="state",
            meta=meta,
            partial=lambda m: result(upto, m, "failed"),
        )
    return result(nt, meta, status)
