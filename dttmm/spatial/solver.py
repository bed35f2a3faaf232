"""Spatial DT-TMM: :func:`simulate` (Newmark family or RK4) and :func:`accelerations` (the
forward dynamics at one state) of a spatial arm (docs/spatial.md)."""

from __future__ import annotations

import dataclasses
import time
import warnings

import numpy as np

from .. import control, plumbing, shapes
from ..case import Case
from ..control_state import is_jitted
from ..drives import UserLaw, require_open_loop
from ..errors import InputError
from ..resources import check_run_size
from ..timegrid import step_schedule
from ..timeloop import residual_meta, run_chunked, step_options
from ..verdict import energy_growth, verdict
from .build import STRAINS, build_model, make_work
from .case import SpatialCase
from .kernel.core import INPUT_COLS, LOAD_COL
from .model import require_open_chain
from .result import SpatialResult
from .rotation import log_so3
from .scenario import load_inputs
from .shapes import from_frames
from .topology import closure_gaps, initial_angles, resolve_closures, rigid_tip_frames

__all__ = ["INTEGRATORS", "accelerations", "as_spatial_case", "link_shapes", "simulate"]

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
    """A :class:`SpatialCase`, a (SpatialManipulator, Scenario) pair made one, or a planar
    :class:`dttmm.Case` embedded (:meth:`SpatialCase.from_planar`, docs/spatial.md §1)."""
    if isinstance(case, SpatialCase):
        return case
    if isinstance(case, Case):
        return SpatialCase.from_planar(case)
    if isinstance(case, tuple) and len(case) == 2:
        return SpatialCase(case[0], case[1])
    raise InputError(
        "case",
        type(case).__name__,
        "must be a dttmm.spatial.SpatialCase, a dttmm.Case or a (SpatialManipulator, Scenario) pair",
    )


def _motion_flags(case: SpatialCase) -> np.ndarray:
    flags = np.zeros(case.model.n_links, np.int64)
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        flags[i] = d.kind == "motion"
    return flags


def _check_closed_loop(case: SpatialCase, engine: str) -> None:
    """Refuse the closed-loop drives the kernel does not run: user laws that are plain Python
    functions with the compiled kernel (numba-jitted ones run). A ``computed_torque``
    feedforward is tabulated by :func:`dttmm.control.computed_torque` (the spatial rigid arm's
    recursive Newton–Euler)."""
    for j, d in enumerate(case.scenario.drives):
        if not d.closed_loop:
            continue
        if isinstance(d.law, UserLaw) and engine != "python" and not is_jitted(d.law.fn):
            raise InputError(
                f"scenario.drives[{j}].law",
                d.law.label,
                f"user law on joint {j + 1} is a plain Python function: it runs with "
                "engine='python' only (the compiled kernel calls no Python function; write the law "
                "as a numba-jitted function of (t, JitState) to run it compiled)",
            )


def _drive_values(case: SpatialCase, n: int, t: float, left: bool):
    """(torques (n,), inputs (n, INPUT_COLS): the motion laws and the tip loads) per link at time
    t; torque 0 for closed-loop joints (the kernel evaluates their laws)."""
    tau, mot = np.zeros(n), np.zeros((n, INPUT_COLS))
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        if d.kind == "motion":
            mot[i, :3] = d.motion(t, left)
        elif not d.closed_loop:
            tau[i] = d.torque(t, left)
    load_inputs(case, t, left, mot[:, LOAD_COL:])
    return tau, mot


def _gains(case: SpatialCase, md):
    """Per link: the law code (dttmm.control.CODE_*) and the constants of loop.Drives.gain (kp,
    kd, ki, g_M, limit, 1 where the hub has an inertia)."""
    n = md.n
    code = np.zeros(n, np.int64)
    gain = np.zeros((n, 6))
    gain[:, 4] = np.inf
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        law = d.law
        gain[i, 5] = float(np.any(case.model.links[i].hub_inertia != 0.0))
        if isinstance(law, UserLaw):
            code[i] = control.CODE_USER
        elif getattr(law, "closed_loop", False):  # pd, pid
            code[i] = control.CODE_PD
            gain[i, :5] = law.kp, law.kd, law.gain_integral, law.moment_gain, law.limit
    return code, gain


def _law_tables(case: SpatialCase, n: int, times, left: bool):
    """Feedforward (nt, n) and reference (α_ref, α̇_ref) (nt, n, 2) per link of the pd/pid
    joints on ``times`` (:func:`dttmm.control.time_tables`, open-loop torques removed)."""
    times = np.asarray(times, float)
    ff, ref = np.zeros((times.size, n)), np.zeros((times.size, n, 2))
    if times.size == 0:
        return ff, ref
    f, r = control.time_tables(case, times, left)
    for j, (d, i) in enumerate(zip(case.scenario.drives, case.model.unlocked)):
        if d.closed_loop:
            ff[:, i], ref[:, i] = f[:, j], r[:, j]
    return ff, ref


def _user_tables(case: SpatialCase, md, code, engine: str):
    """``loop.Drives.user``: the user laws per link (engine "python": a tuple, None where not;
    compiled: a :class:`dttmm.kernel.userlaw.UserTables` of the jitted laws), else an empty
    array."""
    if not np.any(code == control.CODE_USER):
        return np.zeros(0)
    laws = [None] * md.n
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        if isinstance(d.law, UserLaw):
            laws[i] = d.law
    if engine == "python":
        return tuple(laws)
    from ..kernel import userlaw

    fns, slot, seen = [], np.full(md.n, -1, np.int64), {}
    for j, (d, i) in enumerate(zip(case.scenario.drives, case.model.unlocked)):
        if not isinstance(d.law, UserLaw):
            continue
        key = id(d.law.fn)
        if key not in seen:
            seen[key] = len(fns)
            fns.append(userlaw.compiled(d.law.fn, f"scenario.drives[{j}].law"))
        slot[i] = seen[key]
    m = len(case.model.unlocked)
    return userlaw.UserTables(
        fns=tuple(fns),
        slot=slot,
        angles=np.zeros(m),
        rates=np.zeros(m),
        tips=np.zeros(md.n),
        root=np.zeros((1, md.n, 2)),
        tip=np.zeros((1, md.n, 2)),
        root_angle=np.zeros((1, md.n)),
        energy=np.zeros(0),
    )


def _tables(loop, case, md, t_end, restart, engine):
    """The :class:`loop.Drives` of a run: open-loop torques and motions at the step ends (left
    limits), the right limits at restarts (row n_steps: t = 0), the mid-step values (RK4); the
    closed-loop codes, gains, feedforwards and references at the same instants."""
    n = md.n
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
    tr[ns], mr[ns] = _drive_values(case, n, 0.0, False)
    code, gain = _gains(case, md)
    one = lambda: (np.zeros((1, n)), np.zeros((1, n, 2)))
    (ffl, refl), (ffm, refm) = one(), one()
    ffr, refr = np.zeros((ns + 1, n)), np.zeros((ns + 1, n, 2))
    if code.any():
        ffl, refl = _law_tables(case, n, t_end, True)
        ffm, refm = _law_tables(case, n, t_mid, False)
        rs = np.flatnonzero(restart)
        ffr[rs], refr[rs] = _law_tables(case, n, t_end[rs], False)
        ffr[ns], refr[ns] = (a[0] for a in _law_tables(case, n, [0.0], False))
    c = lambda a: np.ascontiguousarray(a, float)
    laws = dict(
        zip(("ff_l", "ref_l", "ff_r", "ref_r", "ff_m", "ref_m"), map(c, (ffl, refl, ffr, refr, ffm, refm)))
    )
    return loop.Drives(
        t_end=c(t_end),
        restart=np.asarray(restart, np.bool_),
        tau_l=tl,
        mot_l=ml,
        tau_r=tr,
        mot_r=mr,
        tau_m=tm,
        mot_m=mm,
        code=code,
        gain=gain,
        user=_user_tables(case, md, code, engine),
        **laws,
    )


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
    """Forward dynamics of the discretised spatial arm: q̈ (n_dof,) at (q, q̇) and time t
    (``case``: as :func:`as_spatial_case` takes it; a planar :class:`dttmm.Case` embedded).

    Coordinates q = [α_1, e_11, …, e_1k, α_2, …] (no α for a locked joint; e = (u, v, w, φx, φy,
    φz), without u for an inextensible link). Motion-driven joints take the law's α, α̇, α̈.
    ``forces`` (n_dof,): generalized forces on the coordinates besides the drives. With
    ``loads`` returns (q̈, torques (n_links,), cut loads (n_el + n_links, 6)).
    """
    case = as_spatial_case(case)
    require_open_loop(case, "dttmm.spatial.accelerations")
    require_open_chain(case.model, "dttmm.spatial.accelerations")
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


def link_shapes(case, elements_per_link: int, q, p: int, *, strain: str = "linear", engine=None):
    """Link shapes (nt, n, p, 3) m of the discretised spatial arm at coordinates q (nt, n_dof)
    or (n_dof,) (the layout of docs/spatial.md §3): p ≥ 2 points per link from root to tip at
    equal reference arc lengths, from the kernel's element frames (:func:`shapes.from_frames`)."""
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    p = shapes.shape_points(p)
    _, core, _ = _kernel(engine)
    md = build_model(case.model, k, strain, _motion_flags(case))
    ws = make_work(md)
    q = np.atleast_2d(np.asarray(q, float))
    nt = q.shape[0]
    RI, rI, e = np.zeros((nt, md.nel, 3, 3)), np.zeros((nt, md.nel, 3)), np.zeros((nt, md.nel, 6))
    zero = np.zeros(md.ndof)
    for j in range(nt):
        core.kinematics(md, ws, q[j], zero)
        RI[j], rI[j], e[j] = ws.Rw, ws.pw, ws.e
    return from_frames(case.model, k, RI, rI, e, p)


def _check_closures(case: SpatialCase, integrator: str, iters) -> None:
    """What a run with loop closures takes: the Newmark family, each step to the stop rule,
    open-loop drives and pd/pid laws without moment feedback (docs/spatial.md "Trees and
    closed loops")."""
    if integrator == "rk4":
        raise InputError("integrator", integrator, "closed loops run with the Newmark family only (not rk4)")
    if iters is not None:
        raise InputError("iterations", iters, "closed loops run each step to the stop rule (iterations=None)")
    for j, d in enumerate(case.scenario.drives):
        if not d.closed_loop:
            continue
        if isinstance(d.law, UserLaw):
            raise InputError(
                f"scenario.drives[{j}].law",
                d.law.label,
                "a user law on a mechanism with closures is not supported (pd and pid laws are)",
            )
        if getattr(d.law, "moment_gain", 0.0):
            raise InputError(
                f"scenario.drives[{j}].law.moment_gain",
                d.law.moment_gain,
                "moment feedback on a mechanism with closures is not supported (pd and pid laws "
                "without it are)",
            )


def _closure_samples(ts, t_end, lam0, lamh, nc):
    """The closure loads (nt, nc, 6) on the output grid: λ_0 at t = 0, λ of each step end,
    linear between them."""
    tt = np.concatenate(([0.0], t_end))
    out = np.zeros((ts.size, 6 * nc))
    for c in range(6 * nc):
        out[:, c] = np.interp(ts, tt, np.concatenate(([lam0[c]], lamh[:, c])))
    return out.reshape(ts.size, nc, 6)


def _outputs(core, md, ws, case, oq, oqd, otau, nt, want_energy, want_loads, p=0, lam=None, cw=None):
    """Positions, frames, tip deflections, twist, energy, cut loads and (p ≥ 2) link shapes
    (nt, n, p, 3) at the sampled states."""
    n = md.n
    root, tip = np.zeros((nt, n, 3)), np.zeros((nt, n, 3))
    Rl, Rt = np.zeros((nt, n, 3, 3)), np.zeros((nt, n, 3, 3))
    en = np.full(nt, np.nan) if want_energy else None
    loads = np.zeros((nt, md.nel + n, 6)) if want_loads else None
    qdd = np.zeros(md.ndof)
    zero = np.zeros(md.ndof)
    el0 = md.el0
    ws.slope[:] = 0.0
    closed = np.zeros(n, bool)
    for d, i in zip(case.scenario.drives, case.model.unlocked):
        closed[i] = d.closed_loop
    if p:
        RI, rI, ee = np.zeros((nt, md.nel, 3, 3)), np.zeros((nt, md.nel, 3)), np.zeros((nt, md.nel, 6))
    for j in range(nt):
        core.kinematics(md, ws, oq[j], oqd[j])
        if p:
            RI[j], rI[j], ee[j] = ws.Rw, ws.pw, ws.e
        root[j] = ws.pw[el0]
        tip[j] = ws.pT[1:]
        Rl[j] = np.einsum("nij,nkj->nik", ws.Rw[el0], md.Q)
        Rt[j] = ws.RT[1:]
        if want_energy:
            en[j] = core.energy(md, ws)
        if want_loads:
            tau, mot = _drive_values(case, n, case.scenario.output_times[j], True)
            tau[closed] = otau[j][closed]  # the laws' torques as recorded
            if lam is not None:  # the closure loads at the sampled state
                cw[0](ws, cw[1].cl, mot, lam[j].ravel())
                mot = cw[1].cl.motc.copy()
            core.accelerations(md, ws, oq[j].copy(), oqd[j].copy(), tau, mot, zero, qdd, True, loads[j])
    d = tip - root
    defl = np.stack(
        [np.einsum("tni,tni->tn", d, Rl[..., 1]), np.einsum("tni,tni->tn", d, Rl[..., 2])], axis=-1
    )
    twist = np.zeros((nt, n))
    for j in range(nt):
        for i in range(n):
            twist[j, i] = log_so3(Rl[j, i].T @ Rt[j, i])[0]
    link_shapes = from_frames(case.model, int(md.k[0]), RI, rI, ee, p) if p else None
    return root, tip, Rl, Rt, defl, twist, en, loads, link_shapes


#: compiled runs of at most this many element-steps take well under a second (measured about
#: 30 µs per element-step, outputs included, on three_joint_arm and right_angle_cantilever):
#: one kernel call, no estimate (the planar kernel's rule, :data:`dttmm.kernel.driver.SHORT_RUN`)
SHORT_RUN = 2e4


def _energy_growth(case: SpatialCase, t, energy, torque, rate):
    """The energy check (:func:`dttmm.verdict.energy_growth`) of a spatial run: (largest growth
    relative to the energy scale, its time or None)."""
    links = case.model.links
    mass = sum(lk.beam.mass + lk.hub_mass + lk.payload_mass for lk in links)
    mgl = mass * float(np.linalg.norm(case.model.gravity)) * sum(lk.beam.length for lk in links)
    return energy_growth(mgl, t, energy, torque, rate)


def simulate(
    case,
    *,
    elements_per_link: int,
    h: float,
    integrator: str = "newmark",
    strain: str = "linear",
    iterations: int | str | None = None,
    tol: float = 1e-10,
    max_iterations: int = 50,
    beta: float | None = None,
    gamma: float | None = None,
    rho_inf: float | None = None,
    cut_loads: bool = False,
    energy: bool = True,
    engine: str | None = None,
    auto_fraction: float = 0.1,
    shape_points: int = 0,
    progress: bool | None = None,
    **planar_options,
):
    """Simulate a spatial case by DT-TMM with k = ``elements_per_link`` elements per link and
    step ``h`` (docs/spatial.md).

    ``case``: a :class:`SpatialCase` or a (SpatialManipulator, Scenario) pair; a planar
    :class:`dttmm.Case` runs on the planar kernel (:func:`dttmm.simulate`, its Result shapes).
    ``integrator``: "newmark" (β = ¼, γ = ½ unless given), "generalized-alpha" (``rho_inf``) or
    "rk4"; ``iterations``: None (each step to max|Δq̈| ≤ tol·max(1, max|q̈|), the suite's stop
    rule, at most ``max_iterations`` sweeps), m ≥ 0 (m + 1 sweeps per step) or "auto" (the
    planar kernel's rule: at least 2 sweeps, then stop once the iteration error predicted from
    the contraction ρ = |Δq̈_m|/|Δq̈_{m−1}|, |Δq̈_m|·ρ/(1 − ρ), is below ``auto_fraction`` × the
    local truncation error estimate |β − 1/6|/β · max|q̈_{n+1} − q̈_n|, or the ``tol`` rule is
    met; a residual check every 64 steps); ``strain``: "linear" or "second-order";
    ``cut_loads``, ``energy``: record them on the output grid; ``shape_points`` p ≥ 2 records
    ``link_shapes`` (nt, n, p, 3), the deflected centre line of every link from the element
    shape functions (:func:`dttmm.shapes.frame_shapes`; 0, the default: none); ``progress``: a
    progress bar (tqdm, on stderr; None: on when the run, estimated after its first chunk,
    takes over 2 s, as the planar kernel). Closed-loop drives (pd, pid, user laws;
    docs/control.md) run as in the planar kernel. The run-size guard
    (:func:`dttmm.check_run_size`) refuses a run whose arrays would not fit in memory.
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
            auto_fraction=auto_fraction,
            shape_points=shape_points,
            progress=progress,
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
    tol = plumbing.open_fraction("tol", tol)
    max_iterations = plumbing.positive_integer("max_iterations", max_iterations)
    auto_fraction = plumbing.positive_number("auto_fraction", auto_fraction)
    p = shapes.shape_points(shape_points)
    fam = (
        None
        if integrator == "rk4"
        else plumbing.newmark_family(integrator, beta=beta, gamma=gamma, rho_inf=rho_inf)
    )
    engine, core, loop = _kernel(engine)
    _check_closed_loop(case, engine)
    if case.model.closures:
        _check_closures(case, integrator, iters)
    check_run_size(case, k, h, cut_loads=cut_loads, energy=energy, shape_points=p)
    md = build_model(case.model, k, strain, _motion_flags(case))
    ws = make_work(md)
    sc = case.scenario
    t_end, restart = step_schedule(sc.duration, h, sc.breakpoints)
    drv = _tables(loop, case, md, t_end, restart, engine)
    closed = bool(drv.code.any())
    coupled = bool(np.any((drv.code == control.CODE_PD) & (drv.gain[:, 3] != 0.0) & (drv.gain[:, 5] != 0.0)))
    rk4 = dict(beta=0.25, gamma=0.5, alpha_m=0.0, alpha_f=0.0, lte=0.0)
    opts = loop.Options(
        integrator=loop.INT_RK4 if fam is None else loop.INT_NEWMARK,
        tol=float(tol),
        max_it=int(max_iterations),
        auto_fraction=float(auto_fraction),
        closed=closed,
        coupled=coupled,
        **step_options(fam, iters, (loop.IT_TOL, loop.IT_AUTO, loop.IT_FIXED), rk4),
    )
    rc = None
    if case.model.closures:
        rc = resolve_closures(case.model, *rigid_tip_frames(case.model, initial_angles(case)))
        cl = loop.new_closures(
            md.n, md.ndof, INPUT_COLS, t_end.size, rc.a, rc.b, rc.kind, rc.pa, rc.pb, rc.ua, rc.ub, rc.R0,
            case.model.n_closure_equations,
        )  # fmt: skip
        cw = loop.new_loop(md.n, md.ndof, cl)
    else:
        cw = loop.new_loop(md.n, md.ndof)
    q, qd = initial_state(case, md)
    qdd = np.zeros(md.ndof)
    torque0 = np.zeros(md.n)
    z, zerr = np.zeros(md.n), np.zeros(md.n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ok0 = loop.start(md, ws, opts, drv, cw, q, qd, qdd, torque0, z, zerr)
    if not ok0:
        raise InputError("case", case.name or "<case>", "the system is singular at t = 0")
    lam0 = cw.cl.lam.copy()  # the closure loads at t = 0 (none without closures)
    aux = qdd.copy()
    ts = sc.output_times
    nt = ts.size
    oq, oqd, otau = (
        np.full((nt, md.ndof), np.nan),
        np.full((nt, md.ndof), np.nan),
        np.full((nt, md.n), np.nan),
    )
    stats = np.zeros(loop.N_STATS, np.int64)
    stats[loop.S_FIRST_FLAG] = stats[loop.S_WORST] = -1
    fstats = np.zeros(2)
    t_start = time.perf_counter()
    c0 = time.process_time()
    with warnings.catch_warnings():
        # numpy's warnings of a diverging state (caught and reported below); numba's note that
        # its first-class function type (the calls of jitted user laws) is experimental
        warnings.simplefilter("ignore")
        args = (md, ws, opts, drv, cw, q, qd, qdd, aux, torque0, z, zerr, ts, oq, oqd, otau, stats, fstats)
        short = engine == "numba" and t_end.size * md.nel <= SHORT_RUN and not progress
        n_steps = run_chunked(
            lambda first, stop: loop.run(*args, first, stop),
            t_end.size,
            False if short else progress,
            int,
            lambda _: stats[loop.S_STATUS] != 0,
        )
    wall = time.perf_counter() - t_start
    cpu = time.process_time() - c0
    upto = int(stats[loop.S_SAMPLES])
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
        "sweeps_per_step": float(stats[loop.S_SWEEPS]) / max(int(n_steps), 1),
        "max_sweeps": int(stats[loop.S_MAX]),
        "unconverged_steps": int(stats[loop.S_UNCONV]),
        "cpu_time": cpu,
        "versions": plumbing.versions(),
    }
    if iters == "auto":
        meta["auto_fraction"] = auto_fraction
    if fam is not None:
        meta.update(beta=fam.beta, gamma=fam.gamma, alpha_m=fam.alpha_m, alpha_f=fam.alpha_f)
    if cw.fd[0]:
        meta["unconverged_solves"] = int(cw.fd[0])
    residual_meta(
        meta,
        t_end,
        *stats[[loop.S_CHECKS, loop.S_FLAGGED, loop.S_FIRST_FLAG, loop.S_WORST]],
        *fstats,
    )

    def result(upto_, meta_, status_, warns_):
        sel = slice(0, upto_)
        lam = None
        if rc is not None:
            lam = _closure_samples(ts[sel], t_end, lam0, cw.cl.lamh, len(case.model.closures))
        root, tip, Rl, Rt, defl, twist, en, loads, link_shapes = _outputs(
            core,
            md,
            ws,
            case,
            oq[sel],
            oqd[sel],
            otau[sel],
            upto_,
            energy,
            cut_loads,
            p,
            lam,
            (loop.closure_inputs, cw),
        )
        extra = {}
        if rc is not None:
            gaps = [closure_gaps(rc, Rt[j], tip[j]) for j in range(upto_)]
            extra = dict(
                closure_loads=lam,
                closure_residual=np.array([g[0] for g in gaps]).reshape(upto_, -1),
                closure_angle_residual=np.array([g[1] for g in gaps]).reshape(upto_, -1),
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
            end_effector=tip[:, case.model.end_effector_index, :].copy(),
            wall_time=wall,
            n_steps=int(n_steps),
            meta=dict(meta_),
            cut_loads=loads,
            cut_load_t=ts[sel] if cut_loads else None,
            energy=en,
            status=status_,
            warnings=tuple(warns_),
            twist=twist,
            link_rotation=Rl,
            tip_rotation=Rt,
            link_shapes=link_shapes,
            **extra,
        )

    if stats[loop.S_STATUS] != 0:
        st = int(stats[loop.S_FAILED])
        reason = _STATUS.get(int(stats[loop.S_STATUS]), "failure")
        raise plumbing.simulation_failure(
            reason,
            t=float(t_end[st]),
            step=st,
            component="state" + _undamped_loop_hint(rc, fam),
            meta=meta,
            partial=lambda m: result(upto, m, "failed", ()),
        )
    res = result(nt, meta, "ok", ())
    status, warns = _verdict(meta, case, res, iters, tol, max_iterations, int(n_steps))
    return dataclasses.replace(res, status=status, warnings=tuple(warns), meta=dict(meta))


def _undamped_loop_hint(closures, fam) -> str:
    """The hint a failed run with loop closures under the undamped trapezoidal rule (Newmark
    β = ¼, γ = ½, no α) carries: its closure loads, index-3 constraints, are weakly unstable
    without numerical damping (docs/spatial.md, "Long loop runs")."""
    if closures is None or fam is None or fam.alpha_m != 0.0 or fam.alpha_f != 0.0 or fam.gamma != 0.5:
        return ""
    return (
        " (closed loops under the undamped trapezoidal rule: the closure loads oscillate with"
        " growing amplitude; integrator='generalized-alpha' with rho_inf < 1 damps them)"
    )


def _verdict(meta, case, res, iters, tol, max_iterations, n_steps):
    """(status, warnings) by the one rule of both kernels (:func:`dttmm.verdict.verdict`), the
    energy check (a run with energy and no motion drive) into ``meta`` first."""
    if res.energy is not None and not any(d.kind == "motion" for d in case.scenario.drives):
        meta["energy_growth"], meta["energy_growth_t"] = _energy_growth(
            case, res.t, res.energy, res.joint_torque, res.joint_rate
        )
    return verdict(meta, iterations=iters, tol=tol, max_iterations=max_iterations, n_steps=n_steps)
