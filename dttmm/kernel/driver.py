"""The Python side of the kernel: builds the records of a discretised case, evaluates the
drive laws on the step schedule, runs the time loop (compiled or not) in chunks, and turns
what it recorded into a :class:`dttmm.Result` — or a SimulationError with the partial result.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, replace

import numpy as np

from .. import control, plumbing
from ..case import Case
from ..drives import Constant, Drive, Sine
from ..errors import InputError
from ..model import Hub, Link, Manipulator, Payload, Section
from ..result import make_result
from ..scenario import Scenario
from ..structure import Structure, build_structure
from ..timegrid import step_schedule
from ..timeloop import PROGRESS_AFTER, residual_meta, run_chunked, step_options
from ..verdict import energy_growth, verdict
from . import _jit, loop, userlaw
from .layout import (
    INT_NEWMARK,
    INT_RK4,
    IT_AUTO,
    IT_FIXED,
    IT_TOL,
    ST_NONFINITE,
    ST_SINGULAR,
    SWEEP_CODES,
    build_model,
    make_data,
)
from .recorder import Record

ENGINES = ("numba", "python")


def resolve_engine(engine) -> str:
    """None → "numba" when numba imports, else "python"; "numpy" is a deprecated alias of
    "python" (the numpy time loop is gone; the uncompiled kernel replaces it)."""
    if engine == "numpy":
        warnings.warn(
            'engine="numpy" is deprecated: the numpy time loop was replaced by the uncompiled '
            'kernel, engine="python"',
            DeprecationWarning,
            stacklevel=3,
        )
        engine = "python"
    if engine is None:
        return "numba" if _jit.HAVE_NUMBA else "python"
    plumbing.choice("engine", engine, ENGINES)
    if engine == "numba" and not _jit.HAVE_NUMBA:
        raise InputError(
            "engine", engine, "numba is not installed (pip install 'dttmm[fast]'); use engine='python'"
        )
    return engine


def _modules(engine: str):
    """(loop, recorder) modules of the engine: compiled, or the uncompiled copy."""
    if engine == "numba" or _jit.PURE:
        from . import recorder

        return loop, recorder
    from ..kernel_python import loop as ploop
    from ..kernel_python import recorder as precorder

    return ploop, precorder


@dataclass(frozen=True)
class Settings:
    """Validated settings of one run (see :func:`dttmm.simulate`)."""

    h: float
    integrator: str
    sweep: str
    iterations: int | str | None
    tol: float
    max_iterations: int
    family: plumbing.NewmarkFamily | None
    auto_fraction: float
    cut_loads: bool
    energy: bool
    progress: bool | None
    engine: str
    strain: str
    shape_points: int = 0

    def options(self, closed: bool = False, coupled: bool = False) -> loop.Options:
        """The kernel's run options (``closed``: the case has closed-loop joints; ``coupled``:
        one past the first has moment feedback)."""
        rk4 = dict(beta=0.0, gamma=0.0, alpha_m=0.0, alpha_f=0.0, lte=0.0, iteration=IT_FIXED, n_fixed=3)
        return loop.Options(
            integrator=INT_RK4 if self.family is None else INT_NEWMARK,
            sweep=SWEEP_CODES[self.sweep],
            tol=float(self.tol),
            max_iterations=int(self.max_iterations),
            auto_fraction=float(self.auto_fraction),
            closed=bool(closed),
            coupled=bool(coupled),
            **step_options(self.family, self.iterations, (IT_TOL, IT_AUTO, IT_FIXED), rk4),
        )


#: the open-loop fields of :class:`loop.Drives`: torques and motions at the step ends (left
#: limits), at restarts (right limits), at mid-step (RK4)
_OPEN_LOOP = ("tau_left", "mot_left", "tau_right", "mot_right", "tau_mid", "mot_mid")


def drive_tables(structure: Structure, t_end, restart, need_loads, rk4: bool) -> loop.Drives:
    """Drive values the kernel needs, per step: torques and motion (α, α̇, α̈) at the step end
    (left limits), at restart steps also the right limits, and for RK4 at the mid-step."""
    n, ns = structure.n_links, t_end.size
    t_start = np.concatenate(([0.0], t_end[:-1]))
    t_mid = t_start + 0.5 * (t_end - t_start)
    taul, motl = np.zeros((ns, n)), np.zeros((ns, n, 3))
    taur, motr = np.zeros((ns, n)), np.zeros((ns, n, 3))
    taum, motm = (np.zeros((ns, n)), np.zeros((ns, n, 3))) if rk4 else (np.zeros((1, n)), np.zeros((1, n, 3)))
    rs = np.flatnonzero(restart)
    for i, (d, m) in enumerate(zip(structure.case.scenario.drives, structure.motion)):
        if d.closed_loop:
            continue  # its tables: control_tables
        law, tau_or_mot = (d.motion, (motl, motr, motm)) if m else (d.torque, (taul, taur, taum))
        left, right, mid = tau_or_mot
        left[:, i] = [law(t, True) for t in t_end]
        if rs.size:
            right[rs, i] = [law(t, False) for t in t_end[rs]]
        if rk4:
            mid[:, i] = [law(t, False) for t in t_mid]
    return loop.Drives(
        t_end=t_end,
        restart=np.asarray(restart, np.bool_),
        need_loads=need_loads,
        **dict(zip(_OPEN_LOOP, (taul, motl, taur, motr, taum, motm))),
        **control_tables(structure, t_end, restart, rk4),
    )


def control_tables(structure: Structure, t_end, restart, rk4: bool) -> dict:
    """The closed-loop fields of :class:`loop.Drives`: per joint the code (1: pd/pid, 2: user
    law, whose laws are in ``user``, a tuple; the compiled kernel takes them as
    :class:`userlaw.UserTables`; else an empty array) and the
    constants (kp, kd, ki, g_M, limit, J_hub), per step the feedforward torque and the
    reference (α_ref, α̇_ref) at the step end (left limits), at restart steps the right limits,
    at mid-step (RK4). Without closed-loop joints: zeros, the tables one row."""
    n, ns = structure.n_links, t_end.size
    g = control.gains(structure.case)
    code = np.ascontiguousarray(g.code, np.int64)
    gain = np.ascontiguousarray(np.column_stack([g.kp, g.kd, g.ki, g.moment_gain, g.limit, g.j_hub]), float)
    one = lambda: (np.zeros((1, n)), np.zeros((1, n, 2)))
    (ffl, refl), (ffr, refr), (ffm, refm) = one(), one(), one()
    if code.any():
        ffl, refl = control.time_tables(structure.case, t_end, left=True)
        ffr, refr = np.zeros((ns, n)), np.zeros((ns, n, 2))
        rs = np.flatnonzero(restart)
        if rs.size:
            ffr[rs], refr[rs] = control.time_tables(structure.case, t_end[rs], left=False)
        if rk4:
            t_start = np.concatenate(([0.0], t_end[:-1]))
            ffm, refm = control.time_tables(structure.case, t_start + 0.5 * (t_end - t_start), left=False)
    c = lambda a: np.ascontiguousarray(a, float)
    user = (
        tuple(d.law if c == control.CODE_USER else None for d, c in zip(structure.case.scenario.drives, code))
        if np.any(code == control.CODE_USER)
        else np.zeros(0)
    )
    names = ("ff_left", "ref_left", "ff_right", "ref_right", "ff_mid", "ref_mid")
    return {
        "user": user,
        "code": code,
        "gain": gain,
        **dict(zip(names, map(c, (ffl, refl, ffr, refr, ffm, refm)))),
    }


def drive_values(structure: Structure, t: float, left: bool = False):
    """(torques (n,), motions (n, 3)) of all joints at time t (zeros where not applicable)."""
    n = structure.n_links
    tau, mot = np.zeros(n), np.zeros((n, 3))
    for i, (d, m) in enumerate(zip(structure.case.scenario.drives, structure.motion)):
        if m:
            mot[i] = d.motion(t, left)
        elif not d.closed_loop:  # closed loop: the kernel evaluates the law
            tau[i] = d.torque(t, left)
    return tau, mot


def new_record(structure: Structure, times, want_loads: bool, want_energy: bool) -> Record:
    """NaN-filled output arrays on the grid ``times``; cut loads every stride-th sample so
    that they hold at most ~2e6 cut-samples; no coordinates (see :func:`with_coordinates`)."""
    nt, n = times.size, structure.n_links
    ncuts = structure.n_elements + n
    stride = max(1, math.ceil(nt * ncuts / 2.0e6)) if want_loads else 0
    full = lambda *shape: np.full((nt, *shape), np.nan)
    loads = np.full(((nt - 1) // stride + 1, ncuts, 3), np.nan) if want_loads else np.zeros((0, ncuts, 3))
    return Record(
        t=times,
        angle=full(n),
        rate=full(n),
        torque=full(n),
        root=full(n, 2),
        tip=full(n, 2),
        root_angle=full(n),
        energy=full() if want_energy else np.zeros(0),
        loads=loads,
        load_stride=stride,
        q=np.zeros((0, structure.n_dof)),
    )


def load_plan(rec: Record, t_end, i0: int):
    """Step ends whose cut loads the recorder needs (samples j ≡ 0 mod load_stride, and the
    step end before a sample that is interpolated)."""
    need = np.zeros(t_end.size, np.bool_)
    if rec.load_stride == 0:
        return need
    stride = rec.load_stride
    j = np.arange(((i0 + stride - 1) // stride) * stride, rec.t.size, stride)
    t_start = np.concatenate(([0.0], t_end[:-1]))
    eps = 1e-9 * (t_end - t_start)
    nj = np.searchsorted(t_end + eps, rec.t[j], side="left")
    ok = nj < t_end.size
    j, nj = j[ok], nj[ok]
    need[nj] = True
    inexact = np.abs(rec.t[j] - t_end[nj]) > eps[nj]
    prev = nj[inexact] - 1
    need[prev[prev >= 0]] = True
    return need


def to_result(rec: Record, upto: int, wall: float, n_steps: int, meta: dict, status=None, warnings=()):
    """The Result of the first ``upto`` output samples."""
    sl = slice(0, upto)
    want_loads = rec.load_stride > 0
    loads = rec.loads[: (upto - 1) // rec.load_stride + 1] if want_loads and upto else None
    return make_result(
        t=rec.t[sl],
        joint_angle=rec.angle[sl],
        joint_rate=rec.rate[sl],
        joint_torque=rec.torque[sl],
        link_root=rec.root[sl],
        link_root_angle=rec.root_angle[sl],
        link_tip=rec.tip[sl],
        wall_time=wall,
        n_steps=n_steps,
        meta=meta,
        cut_loads=loads,
        cut_load_t=rec.t[sl][:: rec.load_stride] if want_loads else None,
        energy=rec.energy[sl] if rec.energy.size else None,
        status=status,
        warnings=warnings,
    )


def initial_state(structure: Structure):
    """(q, q̇) at t = 0 from the drives' initial angles and rates (elastic coordinates zero)."""
    q, qd = np.zeros(structure.n_dof), np.zeros(structure.n_dof)
    for i, d in enumerate(structure.case.scenario.drives):
        q[structure.links[i].i_alpha], qd[structure.links[i].i_alpha] = d.initial_angle, d.initial_rate
    return q, qd


def base_meta(structure: Structure, s: Settings) -> dict:
    meta = {
        "method": "dttmm",
        "sweep": s.sweep,
        "elements_per_link": structure.k,
        "h": float(s.h),
        "integrator": s.integrator,
        "iterations": s.iterations,
        "tol": s.tol,
        "n_dof": structure.n_dof,
        "final_system_size": 3,
        "versions": plumbing.versions(),
        "success": True,
        "engine": s.engine,
        "strain": s.strain,
    }
    if s.iterations == "auto":
        meta["auto_fraction"] = s.auto_fraction
    return meta


#: compiled runs of at most this many element-steps take < 1 s (≤ 50 sweeps of ≤ 0.1 µs per
#: element): one kernel call, no estimate (the second call costs ~5 % of a 200-step run at k = 8)
SHORT_RUN = 2e5


def simulate_structure(structure: Structure, s: Settings):
    """Run the time loop on the discretised case ``structure`` with settings ``s`` (validated)."""
    lp, rp = _modules(s.engine)
    compile_time = warmup() if s.engine == "numba" and not _WARM else None
    scen = structure.case.scenario
    t_end, restart = step_schedule(scen.duration, s.h, scen.breakpoints)
    md = build_model(structure)
    data = make_data(md, s.sweep == "plain")
    meta = base_meta(structure, s)
    if compile_time is not None:
        meta["compile_time"] = compile_time
    rec = new_record(structure, scen.output_times, s.cut_loads, s.energy)
    if s.shape_points:
        rec = with_coordinates(rec)
    n_steps = t_end.size
    wall0 = time.perf_counter()
    ncuts = structure.n_elements + structure.n_links
    ws = lp.new_work(structure.n_dof, structure.n_links, ncuts)
    stats = lp.new_stats()

    # initial accelerations (closed-loop laws at z = 0), and the samples at t = 0
    q, qd = initial_state(structure)
    tau0, mot0 = drive_values(structure, 0.0)
    qdd, loads = np.empty(structure.n_dof), np.empty((ncuts, 3))
    drv = drive_tables(structure, t_end, restart, np.zeros(n_steps, np.bool_), s.integrator == "rk4")
    if s.engine == "numba" and isinstance(drv.user, tuple):  # numba-jitted user laws
        drv = drv._replace(user=userlaw.tables(drv.user, structure.n_links))
    closed = bool(drv.code.any())
    coupled = bool(np.any((drv.code[1:] == control.CODE_PD) & (drv.gain[1:, 3] * drv.gain[1:, 5] != 0.0)))
    opts = s.options(closed, coupled)
    z0 = np.zeros(structure.n_links)
    if closed:
        ff0, ref0 = control.time_tables(structure.case, [0.0], left=False)
        ok, cond0 = lp.accel_closed(
            md,
            data,
            opts,
            0.0,
            q,
            qd,
            tau0,
            mot0,
            drv,
            ff0[0],
            ref0[0],
            z0,
            ws,
            qdd,
            ws.torque,
            loads,
            True,
            True,
        )
        zerr0 = np.where(drv.code == control.CODE_PD, ref0[0, :, 0] - q[structure.alpha_index], 0.0)
    else:
        ok, cond0 = lp.accel(
            md, data, SWEEP_CODES[s.sweep], q, qd, tau0, mot0, ws, qdd, ws.torque, loads, True
        )
        zerr0 = np.zeros(structure.n_links)
    partial = lambda m, upto=0: to_result(rec, upto, time.perf_counter() - wall0, int(stats.steps_done[0]), m)
    if not ok:
        raise plumbing.simulation_failure(
            "Singular matrix",
            t=0.0,
            step=0,
            component="step system",
            meta=meta,
            partial=partial,
            message="initial acceleration solve failed (Singular matrix)",
        )
    lp.apply_motion(md.motion, md.im, mot0, q, qd)
    state = loop.State(
        q=q,
        qd=qd,
        qdd=qdd,
        aux=qdd.copy(),
        q_prev=q.copy(),
        qd_prev=qd.copy(),
        torque_prev=ws.torque.copy(),
        loads_prev=loads.copy(),
        z=z0,
        zerr=zerr0,
    )
    s0 = (state.q_prev, state.qd_prev, state.torque_prev, state.loads_prev)
    stats.ptr[0] = rp.record(md, -1.0, 0.0, s0, s0, (ws.qs, ws.qds), 0, rec)
    stats.cond_max[0] = 0.0 if math.isnan(cond0) else cond0
    drv = drv._replace(need_loads=load_plan(rec, t_end, int(stats.ptr[0])))

    short = s.engine == "numba" and n_steps * max(structure.n_elements, 1) <= SHORT_RUN and not s.progress
    cpu0 = time.process_time()
    status = run_chunked(
        lambda first, stop: lp.run(md, data, opts, drv, state, rec, stats, ws, first, stop),
        n_steps,
        False if short else s.progress,
        lambda _: int(stats.steps_done[0]),
        bool,
        PROGRESS_AFTER,
    )
    cpu_loop = time.process_time() - cpu0
    wall = time.perf_counter() - wall0
    meta["loop_cpu_time"] = cpu_loop  # CPU time of the time loop alone (s)
    upto = int(stats.ptr[0])
    if status:
        _raise_failure(
            structure,
            status,
            stats,
            t_end,
            meta,
            lambda m: with_shapes(
                to_result(rec, upto, wall, int(stats.steps_done[0]), m), structure, rec, s.shape_points
            ),
            float(rec.t[upto - 1]) if upto else 0.0,
        )
    _add_stats(meta, stats, s, n_steps, wall, t_end)
    if ws.fd_unconverged[0]:
        meta["unconverged_solves"] = int(ws.fd_unconverged[0])
    if rec.energy.size and not any(structure.motion):
        _energy_growth(meta, structure, rec.t[:upto], rec.energy[:upto], rec.torque[:upto], rec.rate[:upto])
    status, warns = verdict(
        meta, iterations=s.iterations, tol=s.tol, max_iterations=s.max_iterations, n_steps=n_steps
    )
    return with_shapes(
        to_result(rec, upto, wall, n_steps, meta, status, warns), structure, rec, s.shape_points
    )


def with_coordinates(rec: Record) -> Record:
    """``rec`` recording the coordinates q (nt, n_dof) at the output times too (NaN-filled)."""
    return rec._replace(q=np.full((rec.t.size, rec.q.shape[1]), np.nan))


def with_shapes(res, structure: Structure, rec: Record, p: int):
    """``res`` with its link shapes (p points per link) from the recorded coordinates; ``res``
    itself when none were asked for (p = 0)."""
    if p == 0 or rec.q.shape[0] == 0:
        return res
    from ..shapes import element_shapes

    return replace(res, link_shapes=element_shapes(structure, rec.q[: res.t.size], p))


def _energy_growth(meta: dict, structure: Structure, t, energy, torque, rate) -> None:
    """The energy check (:func:`dttmm.verdict.energy_growth`) of a planar run into
    ``meta["energy_growth"]``, ``meta["energy_growth_t"]``."""
    mass = sum(lk.mass for lk in structure.links)
    mgl = mass * float(np.linalg.norm(structure.gravity)) * sum(lk.length for lk in structure.links)
    meta["energy_growth"], meta["energy_growth_t"] = energy_growth(mgl, t, energy, torque, rate)


def _raise_failure(structure, status, stats, t_end, meta, partial, t_last):
    step = int(stats.steps_done[0])
    if status == ST_SINGULAR:
        raise plumbing.simulation_failure(
            "Singular matrix",
            t=t_end[step],
            step=step,
            component="step system",
            meta=meta,
            partial=partial,
            message="linear solve failed (Singular matrix)",
        )
    bad = int(stats.bad_index[0])
    name = structure.coordinate_names()[bad]
    if status == ST_NONFINITE:
        why, detail = "non-finite state", "non-finite value"
    else:
        why = "runaway elastic displacement"
        value, bound = float(stats.bad_value[0]), md_lim(structure, bad)
        el = next(
            lk.length / lk.k for i, lk in enumerate(structure.links) if name.startswith(f"link {i + 1},")
        )
        detail = (
            f"elastic rotation {value:.4g} rad beyond ±{bound:.4g} rad"
            if name.endswith("phi")
            else f"elastic displacement {value:.4g} m beyond {bound / el:.3g} element lengths, {bound:.4g} m"
        )
    raise plumbing.simulation_failure(
        why,
        t=t_end[step],
        step=step,
        component=name,
        meta=meta,
        partial=partial,
        message=f"simulation diverged ({why}: {detail}; the partial result "
        f"ends at t = {t_last:.6g} s, before the failed step)",
    )


def md_lim(structure: Structure, index: int) -> float:
    """The runaway bound of coordinate ``index`` (see :func:`dttmm.kernel.layout.build_model`)."""
    return float(build_model(structure).lim[index])


def _add_stats(meta, stats, s: Settings, n_steps: int, wall: float, t_end) -> None:
    if s.integrator == "rk4":  # four solves per step (more sweeps with closed-loop laws)
        meta.update(
            {
                "iterations_mean": float(stats.sweeps[0]) / max(n_steps, 1),
                "iterations_max": int(stats.max_sweeps[0]),
                "unconverged_steps": 0,
            }
        )
    else:
        meta.update(
            {
                "iterations_mean": float(stats.sweeps[0]) / max(n_steps, 1),
                "iterations_max": int(stats.max_sweeps[0]),
                "unconverged_steps": int(stats.unconverged[0]),
            }
        )
    if s.sweep == "plain":
        meta["final_system_cond"] = float(stats.cond_max[0])
    residual_meta(
        meta,
        t_end,
        stats.checks[0],
        stats.flagged[0],
        stats.first_flag[0],
        stats.worst_step[0],
        stats.worst_ratio[0],
        stats.worst_resid[0],
    )
    meta["time_per_step"] = wall / n_steps


def accelerations_at(structure: Structure, q, qd, t: float, sweep: str, engine: str):
    """q̈ (n_dof,) of the discretised case at (q, q̇) and time t by the kernel."""
    lp, _ = _modules(engine)
    if engine == "numba":
        warmup()
    md = build_model(structure)
    data = make_data(md, sweep == "plain")
    ncuts = structure.n_elements + structure.n_links
    ws = lp.new_work(structure.n_dof, structure.n_links, ncuts)
    tau, mot = drive_values(structure, t)
    qdd = np.empty(structure.n_dof)
    ok, _ = lp.accel(
        md,
        data,
        SWEEP_CODES[sweep],
        np.ascontiguousarray(q, float),
        np.ascontiguousarray(qd, float),
        tau,
        mot,
        ws,
        qdd,
        ws.torque,
        ws.loads,
        True,
    )
    if not ok:
        raise np.linalg.LinAlgError("singular matrix")
    return qdd


# ---------------------------------------------------------------------------------------------
_WARM = False


def _tiny_case() -> Case:
    """Two links (extensible with a hub, inextensible with a payload), a torque and a motion
    drive with a jump: every code path of the loop."""
    links = (
        Link(Section(0.5, 2.0, 0.3, 7e6), hub=Hub(0.1, 0.01)),
        Link(Section(0.5, 2.0, 0.3, None), payload=Payload(0.1, 0.0)),
    )
    drives = (Drive("torque", Sine(1.0, 1.0, until=0.0025)), Drive("motion", Constant(0.0)))
    return Case(Manipulator(links, gravity=(0.0, -9.81)), Scenario(0.004, 0.002, drives))


def _tiny_closed_case() -> Case:
    """Two links under pd laws with moment feedback: the closed-loop entry points."""
    from ..drives import PD

    link = Link(Section(0.5, 2.0, 0.3, 7e6), hub=Hub(0.1, 0.01))
    drives = tuple(Drive("torque", PD(1.0, 0.1, Constant(0.1), moment_gain=0.5)) for _ in range(2))
    return Case(Manipulator((link, link), gravity=(0.0, -9.81)), Scenario(0.004, 0.002, drives))


def warmup() -> float:
    """Compile (or load from the on-disk cache) every kernel entry point on a tiny case and
    return the seconds it took. A no-op returning 0.0 once done in this process, or without
    numba."""
    global _WARM
    if _WARM or _jit.PURE:
        return 0.0
    t = time.perf_counter()
    # one run compiles every branch (integrators and sweeps are run-time codes of one signature)
    s = Settings(
        h=1e-3,
        integrator="newmark",
        sweep="riccati",
        iterations=None,
        tol=1e-10,
        max_iterations=50,
        family=plumbing.newmark_family("newmark"),
        auto_fraction=0.1,
        cut_loads=True,
        energy=True,
        progress=False,
        engine="numba",
        strain="linear",
    )
    _WARM = True  # simulate_structure must not recurse into warmup
    try:
        simulate_structure(build_structure(_tiny_case(), 1), s)
        simulate_structure(build_structure(_tiny_closed_case(), 1), s)
    except BaseException:
        _WARM = False
        raise
    return time.perf_counter() - t
