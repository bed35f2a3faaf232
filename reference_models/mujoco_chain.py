"""MuJoCo peer: every flexible link a chain of k rigid pieces joined by hinge springs.

The lumping rule (see ``_mujoco_model``): k elastic hinges per link at x = (j − ½)·L/k with
rotational springs EI·k/L and dampers μ·EI·k/L, half pieces at both ends, each piece with its
own mass and rod inertia; hubs join the root piece, payloads the tip piece. Errors are
O(1/k²) in statics, natural frequencies and dynamics (measured, see docs/mujoco.md). The model
is the arm's spatial embedding (:func:`dttmm.spatial.embed_planar`) built by the spatial chain's
builder with one hinge about z per station (:func:`build`, ``_mujoco_model.build_planar``): the
planar degrees of freedom alone; the outputs are read in the plane.

Time integration: MuJoCo's ``implicitfast`` (semi-implicit Euler, velocity forces implicit)
with the fixed step h, no contacts, no constraints. The joint springs are integrated
explicitly: a step above 2/ω_max (ω_max the highest frequency of the chain, ∝ k²) is unstable;
``meta["h_stable"]`` gives that bound, computed from the linearised model at t = 0.

Drives, on the shared step schedule (a step ends exactly at every drive breakpoint):

* torque: a motor on the arm joint with control τ(t_k + Δt/2) (midpoint of the step, so a jump
  at a step end is seen on the correct side). The fast loop is ``mujoco.rollout`` (MuJoCo's C
  loop over ``mj_step``); only steps split by an off-grid breakpoint go through ``mj_step``.
* motion: the motor torque of the joint is solved for in every step so that the joint angle
  at the end of the step equals the law α(t_{k+1}) to 1e-12 rad (Newton on the step map with a
  finite-difference Jacobian; one iteration for the linear-in-torque Euler-type integrators).
  The reported torque is that motor torque, the mean of the two steps around the output time.

* closed loop (``pd``, ``pid``, user laws; docs/control.md): the law is evaluated once per step,
  at its start t_k from the state x_k, and linearised there: the motor force through the step
  is τ_k + ∂τ/∂α (α − α_k) + ∂τ/∂α̇ (α̇ − α̇_k) (MuJoCo's affine actuator bias), whose rate term
  ``implicitfast`` treats implicitly (an explicit rate feedback is unstable against the small
  inertia of the piece behind an inner joint). Reference, feedforward, moment feedback and
  everything else are sampled at t_k: a one-step lag, first order in h. The root bending moment a law sees is the torque the first
  elastic hinge of the link transmits, −(EI/l)·θ₁ − μ(EI/l)·θ̇₁ (θ₁ that hinge's angle, at l/2
  from the root); a ``pid`` integral state is advanced by explicit Euler with the same
  sample. Such runs go through ``mj_step`` one step at a time. The ``computed_torque``
  feedforward is refused (no rigid model here).

Outputs follow the suite's definitions: joint angle i = root piece angle of link i minus tip
piece angle of link i − 1 (the arm joint's coordinate); tip deflection in the clamped-root frame;
energy = kinetic + gravitational + spring energy (MuJoCo's, zero at y = 0).

MuJoCo (``pip install 'dttmm[mujoco]'``) is imported by the MuJoCo modules only; without it this module does
not import and the method is reported unavailable.
"""

from __future__ import annotations

import dataclasses
import math
import time

import mujoco
import mujoco.rollout
import numpy as np

from dttmm import plumbing
from dttmm.drives import ControlState, require_no_computed_torque
from dttmm.errors import InputError, SimulationError
from dttmm.model import require_flexible
from dttmm.plumbing import versions
from dttmm.result import make_result
from dttmm.shapes import polyline_shapes, shape_points, stations
from dttmm.timegrid import step_schedule

from . import _checks
from ._mujoco_model import INTEGRATORS, eig_mk, frequencies, stability_limit
from ._mujoco_model import build_planar as build

__all__ = ["INTEGRATORS", "build", "natural_frequencies", "simulate", "stability_limit"]

_OPTIONS = {"motion_tol": 1e-12, "motion_max_iter": 10}
_BLOCK_BYTES = 8 << 20  # state rows returned per rollout call, at most this many bytes


def _check(case, k, h, integrator, options):
    """Validated (k, h, opts); raises InputError naming the field."""
    k, h = plumbing.discretisation(case, k, h)
    require_flexible(case.model, "the MuJoCo chain (flexible links, bodies on the beam axis)")
    _checks.integrator(integrator, INTEGRATORS)
    _checks.option_names(options, _OPTIONS, "mujoco-chain")
    opts = {**_OPTIONS, **options}
    if not (isinstance(opts["motion_tol"], (int, float)) and opts["motion_tol"] > 0):
        raise InputError("motion_tol", opts["motion_tol"], "must be a positive number")
    mi = opts["motion_max_iter"]
    if isinstance(mi, bool) or not isinstance(mi, int) or mi < 1:
        raise InputError("motion_max_iter", mi, "must be an integer >= 1")
    return int(k), h, opts


def natural_frequencies(link, k: int, n_modes: int = 3) -> np.ndarray:
    """First ``n_modes`` natural frequencies (rad/s) of one link clamped at its root (hub welded,
    no gravity), from the chain's mass matrix and joint stiffnesses."""
    from dttmm.model import Manipulator

    m, d, _ = build(Manipulator((link,)), k, 1e-3, clamp_first=True)
    return frequencies(eig_mk(m, d, vectors=False)[:n_modes])


class _Stepper:
    """Model, data, drives and the state vector handling of one run."""

    def __init__(self, case, k, h, integrator):
        mj = self.mj = mujoco
        self.m, self.d, self.lay = build(case.model, k, h, integrator)
        self.h = h
        self.drives = case.scenario.drives
        self.n = len(self.drives)
        self.free = np.array([i for i, dr in enumerate(self.drives) if dr.kind == "torque"], int)
        self.pres = np.array([i for i, dr in enumerate(self.drives) if dr.kind == "motion"], int)
        self.closed = np.array([i for i in self.free if self.drives[i].closed_loop], int)
        self._feedback_setup(case, k)
        self._affine_motors()
        self.spec = mj.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mj.mj_stateSize(self.m, self.spec)
        self.messages = []

    def _feedback_setup(self, case, k):
        """Constants of the closed-loop state: first-hinge stiffness/damping, segment lengths."""
        require_no_computed_torque(case, "mujoco-chain")
        links = case.model.links
        self.k = k
        self.hinge_k = np.array([lk.beam.EI * k / lk.beam.length for lk in links])
        self.hinge_c = np.array([lk.beam.damping for lk in links]) * self.hinge_k
        seg = np.ones(k)
        seg[-1] = 0.5
        self.seg = np.array([lk.beam.length / k for lk in links])[:, None] * seg  # (n, k)

    def control_states(self, x):
        """ControlState of every closed-loop joint from a state row x (time, qpos, qvel)."""
        lay, nq = self.lay, self.m.nq
        qpos, qvel = x[1 : 1 + nq], x[1 + nq : 1 + 2 * self.m.nv]
        flex, flexv = qpos[lay.flex_qpos], qvel[lay.flex_qpos]  # (n, k)
        moment = -self.hinge_k * flex[:, 0] - self.hinge_c * flexv[:, 0]
        tipdef = tuple((self.seg * np.sin(np.cumsum(flex, axis=1))).sum(axis=1).tolist())
        angles, rates = tuple(qpos[lay.arm_qpos].tolist()), tuple(qvel[lay.arm_qpos].tolist())
        return [
            ControlState(
                joint=int(i),
                angle=angles[i],
                rate=rates[i],
                moment=float(moment[i]),
                angles=angles,
                rates=rates,
                tip_deflections=tipdef,
            )
            for i in self.closed
        ]

    def feedback(self, t, x, z):
        """The closed-loop laws at t from the state row x and the integral states z: torques,
        integral rates (n_closed,), and the affine control (n_closed,) with its slopes
        (n_closed, 2) that reproduce the torques at x (see :meth:`set_slopes`)."""
        nc = self.closed.size
        tau, zdot, ctrl, slopes = np.empty(nc), np.empty(nc), np.empty(nc), np.empty((nc, 2))
        for c, s in enumerate(self.control_states(x)):
            law = self.drives[s.joint].law
            s = dataclasses.replace(s, integral=float(z[c]))
            tau[c], da, dr, _ = law.evaluate(t, s)
            zdot[c] = law.error_rate(t, s)
            slopes[c] = da, dr
            ctrl[c] = tau[c] - da * s.angle - dr * s.rate
        return tau, zdot, ctrl, slopes

    def set_slopes(self, slopes):
        """Motor force of closed-loop joint i = ctrl + ∂τ/∂α·α + ∂τ/∂α̇·α̇ within the step (MuJoCo's
        affine bias): equal to the law at the step start, and the rate term enters
        ``implicitfast``'s implicit velocity update — an explicit rate feedback would be
        unstable against the tiny inertia of the piece behind an inner joint."""
        self.m.actuator_biasprm[self.closed, 1:3] = slopes

    def _affine_motors(self):
        m = self.m
        for i in self.closed:
            m.actuator_biastype[i] = self.mj.mjtBias.mjBIAS_AFFINE
            m.actuator_biasprm[i, :3] = 0.0
            lim = getattr(self.drives[i].law, "limit", math.inf)
            if math.isfinite(lim):  # keeps the affine force within the law's saturation
                m.actuator_forcelimited[i] = 1
                m.actuator_forcerange[i] = (-lim, lim)

    def initial_state(self):
        """Straight links, joint angles and rates from the drives (rigid initial rotation)."""
        d, lay = self.d, self.lay
        d.qpos[:] = 0.0
        d.qvel[:] = 0.0
        d.time = 0.0
        for i, dr in enumerate(self.drives):
            d.qpos[lay.arm_qpos[i]] = dr.initial_angle
            d.qvel[lay.arm_qpos[i]] = dr.initial_rate  # hinges only: qvel index = qpos index
        self.mj.mj_forward(self.m, d)
        x = np.empty(self.nstate)
        self.mj.mj_getState(self.m, d, x, self.spec)
        return x

    def step(self, x, dt, ctrl):
        """One mj_step of size dt from the state x with the motor controls ctrl; returns the new state."""
        mj, m, d = self.mj, self.m, self.d
        mj.mj_setState(m, d, x, self.spec)
        m.opt.timestep = dt
        d.ctrl[:] = ctrl
        mj.mj_step(m, d)
        m.opt.timestep = self.h
        out = np.empty(self.nstate)
        mj.mj_getState(m, d, out, self.spec)
        return out


def _free_controls(st, T):
    """Motor controls (N, n) of the torque drives at the step midpoints (motion joints 0)."""
    mid = 0.5 * (T[:-1] + T[1:])
    u = np.zeros((mid.size, st.n))
    for i in st.free:
        if not st.drives[i].closed_loop:
            u[:, i] = [st.drives[i].torque(float(t)) for t in mid]
    return u


def _bad_rows(X, T, h):
    """Indices of state rows (time first) that are non-finite or whose time is not the node's
    (MuJoCo resets the data, time included, when it finds the state unstable: its time then
    falls back by at least one step). MuJoCo's time is a running sum of steps, so after 1e5 and
    more steps it drifts from the node's by many ulps; half a step is the tolerance."""
    off = np.abs(X[:, 0] - T) > 0.5 * h
    return np.flatnonzero(off | ~np.isfinite(X).all(axis=1))


def _run_torque(st, x0, T, keep, ctrl, stats):
    """All drives torque: rollout over runs of regular steps, mj_step for split steps.
    Returns the states at the kept nodes (rows in node order) and the steps done."""
    mj, h = st.mj, st.h
    N = T.size - 1
    dt = np.diff(T)
    regular = np.abs(dt - h) <= 1e-9 * h
    block = max(1, _BLOCK_BYTES // (8 * st.nstate))
    saved = [x0[None]] if keep[0] else []
    x, j = x0, 0
    while j < N:
        if regular[j]:
            r = j + 1
            while r < N and regular[r] and r - j < block:
                r += 1
            X = mj.rollout.rollout(st.m, st.d, x, ctrl[None, j:r], nstep=r - j)[0][0]
        else:
            r = j + 1
            X = st.step(x, dt[j], ctrl[j])[None]
        bad = _bad_rows(X, T[j + 1 : r + 1], h)
        if bad.size:
            b = int(bad[0])
            saved.append(X[:b][keep[j + 1 : j + 1 + b]])
            stats["fail"] = (j + b, T[j + 1 + b])
            return np.concatenate(saved), j + b
        saved.append(X[keep[j + 1 : r + 1]])
        x, j = X[-1], r
    return np.concatenate(saved), N


def _run_motion(st, x0, T, keep, ctrl, opts, stats):
    """Step by step: closed-loop torques from the state at the step start (held through the
    step), then, if some joints are prescribed, Newton on their motor torques so that their
    angles at the step end equal the law. Returns the kept states, the steps done, and the
    motor torques per step (N, n); ``stats["feedback"]`` holds the closed-loop torques at
    every node (N + 1, n_closed)."""
    N = T.size - 1
    p = st.pres
    qi = st.lay.arm_qpos[p] + 1  # state row: [time, qpos..., qvel...]
    laws = [st.drives[i] for i in p]
    tol, max_iter = opts["motion_tol"], opts["motion_max_iter"]
    u_p = np.zeros(p.size)
    saved = [x0[None]] if keep[0] else []
    x = x0
    iters = 0
    cl = st.closed
    z = np.zeros(cl.size)  # integral states, 0 at t = 0
    fb = stats["feedback"] = np.full((N + 1, cl.size), np.nan)
    for j in range(N):
        dtj = T[j + 1] - T[j]
        target = np.array([dr.motion(float(T[j + 1]), True)[0] for dr in laws])
        if cl.size:
            fb[j], zdot, ctrl[j, cl], slopes = st.feedback(float(T[j]), x, z)
            st.set_slopes(slopes)
            z = z + dtj * zdot
        u = ctrl[j].copy()
        J = None
        for it in range(1, max_iter + 2):
            u[p] = u_p
            xn = st.step(x, dtj, u)
            r = target - xn[qi]
            if not np.isfinite(xn).all() or abs(xn[0] - T[j + 1]) > 1e-6 * dtj:
                stats["fail"] = (j, T[j + 1])
                break
            if np.all(np.abs(r) <= tol * (1.0 + np.abs(target))):
                break
            if it > max_iter:
                why = (
                    f"motion drive not imposed in {max_iter} iterations "
                    f"(angle residual {np.abs(r).max():.3g} rad)"
                )
                stats["fail"] = (j, T[j + 1], why)
                break
            if J is None:  # the step map is linear in the torque for the Euler-type integrators
                J = np.empty((p.size, p.size))
                for c in range(p.size):
                    du = 1.0 + abs(u_p[c])
                    uc = u.copy()
                    uc[p[c]] += du
                    J[:, c] = (st.step(x, dtj, uc)[qi] - xn[qi]) / du
            u_p = u_p + np.linalg.solve(J, r)
        iters += it
        if "fail" in stats:
            stats["motion_iterations_mean"] = iters / (j + 1)
            return (np.concatenate(saved) if saved else np.empty((0, st.nstate))), j, ctrl
        ctrl[j, p] = u_p
        x = xn
        if keep[j + 1]:
            saved.append(x[None])
    if cl.size:  # the torque the law asks for at the last node (no step applies it)
        fb[N] = st.feedback(float(T[N]), x, z)[0]
    stats["motion_iterations_mean"] = iters / max(N, 1)
    return np.concatenate(saved), N, ctrl


def _kinematics_and_energy(mj, m, d):
    """Positions and energies only (no dynamics): about half of mj_forward's cost at large k."""
    mj.mj_kinematics(m, d)
    mj.mj_comPos(m, d)
    mj.mj_makeM(m, d)  # the mass matrix for the kinetic energy
    mj.mj_energyPos(m, d)
    mj.mj_energyVel(m, d)


def _drive_outputs(st, t, node, ctrl, q, v, tau):
    """The open-loop drives' entries of one output row at time t (step node ``node``): a torque
    drive's torque is the law's (left limit; right limit at t = 0), as every method reports it;
    a prescribed joint's angle and rate are the law's, its torque the mean of the motor torques
    ``ctrl`` of the steps around the node."""
    for i in st.free:
        if not st.drives[i].closed_loop:
            tau[i] = st.drives[i].torque(t, t > 0)
    for i in st.pres:
        q[i], v[i], _ = st.drives[i].motion(t)
        around = ctrl[max(node - 1, 0) : min(node + 1, ctrl.shape[0]), i]
        tau[i] = around.mean() if around.size else 0.0


def _outputs(st, X, t, ctrl, T, fb=None):
    """Result fields at the output times t from the kept states X (rows); fb: closed-loop
    torques at the step nodes (N + 1, n_closed)."""
    mj, m, d, lay = st.mj, st.m, st.d, st.lay
    nt, n = t.size, st.n
    q = np.empty((nt, n))
    v = np.empty((nt, n))
    tau = np.empty((nt, n))
    root = np.empty((nt, n, 2))
    tip = np.empty((nt, n, 2))
    th = np.empty((nt, n))
    energy = np.empty(nt)
    node = np.clip(np.searchsorted(T, t - 1e-9 * st.h), 0, T.size - 1)
    for s in range(nt):
        mj.mj_setState(m, d, X[s], st.spec)
        _kinematics_and_energy(mj, m, d)
        qa = d.qpos[lay.arm_qpos]
        q[s], v[s] = qa, d.qvel[lay.arm_qpos]
        bend = d.qpos[lay.flex_qpos].sum(axis=1)
        th[s] = np.cumsum(qa + bend) - bend  # root angle of link i: everything inboard + α_i
        root[s] = d.xpos[lay.hub_body, :2]
        tip[s] = d.site_xpos[lay.tip_site, :2]
        energy[s] = d.energy[0] + d.energy[1]
        for c, i in enumerate(st.closed):  # the torque the law gives at this node's state
            tau[s, i] = fb[node[s], c]
        _drive_outputs(st, float(t[s]), node[s], ctrl, q[s], v[s], tau[s])
    fields = {
        "joint_angle": q,
        "joint_rate": v,
        "joint_torque": tau,
        "link_root": root,
        "link_root_angle": th,
        "link_tip": tip,
    }
    return fields, energy


def simulate(case, *, elements_per_link, h, integrator="implicitfast", **options):
    """Simulate a case with MuJoCo, every link a chain of ``elements_per_link`` hinge springs.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
        k, the number of elastic hinges (segments of length L/k) per link.
    h : float
        Step size (s); it must divide the case's output step (outputs are step nodes).
    integrator : ``"implicitfast"`` (default) | ``"euler"`` | ``"implicit"`` | ``"rk4"``
        MuJoCo's integrator.
    **options
        motion_tol (1e-12, relative angle tolerance of a motion drive), motion_max_iter (10);
        shape_points (0): p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2) m, the chain of
        pieces as a polyline (:func:`piece_shapes`).

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``; ``wall_time`` covers the time stepping only
    (not the model compilation), ``meta["cpu_time_solve"]`` the CPU time of the same span.
    ``meta`` carries ``omega_max`` and ``h_stable`` (rad/s, s); a step above ``h_stable`` adds
    a warning.

    Raises
    ------
    dttmm.InputError
        bad k, h, integrator or option; h not dividing the output step.
    dttmm.SimulationError
        non-finite state, MuJoCo's instability reset, or a motion drive that could not be
        imposed; ``partial`` holds the outputs up to the last good step.
    """
    options = dict(options)
    p = shape_points(options.pop("shape_points", 0))
    k, h, opts = _check(case, elements_per_link, h, integrator, options)
    T, t_out, keep = step_nodes(case.scenario, h)
    st = _Stepper(case, k, h, integrator)
    X, n_steps, ctrl, wall, meta, stats, warnings = _run(st, T, keep, integrator, k, opts, "mujoco-chain")
    tg = t_out[: X.shape[0]]
    fields, energy = _outputs(st, X, tg, ctrl[:n_steps], T, stats.get("feedback"))  # the steps taken
    res = make_result(
        t=tg,
        **fields,
        wall_time=wall,
        n_steps=n_steps,
        meta=meta,
        energy=energy,
        warnings=warnings,
        link_shapes=piece_shapes(st, case, X[: tg.size], p) if p else None,
    )
    _raise_failure(st, stats, "mujoco-chain", res)
    return res


def _run(st, T, keep, integrator, k, opts, method):
    """Step the chain ``st`` from its initial state over the nodes T (both chains): (kept
    states X, steps taken, motor controls per step, wall time, the Result's meta, the run's
    stats, warnings: the step above the stability limit, MuJoCo's own). The stability limit is
    that of the hinges (None with ball joints)."""
    h = st.h
    x0 = st.initial_state()
    wmax, h_stable = stability_limit(st.m, st.d, integrator) if st.m.nq == st.m.nv else (None, None)
    warnings = _step_warning(h, wmax, h_stable)
    ctrl = _free_controls(st, T)
    if st.m.nu > st.n:  # the ball stations' spring actuators: control 0
        ctrl = np.hstack([ctrl, np.zeros((ctrl.shape[0], st.m.nu - st.n))])
    stats = {}
    X, n_steps, ctrl, wall, cpu = _rollout(st, x0, T, keep, ctrl, opts, stats, st.pres.size or st.closed.size)
    meta = _meta(method, st, h, integrator, k, wmax, h_stable, n_steps, cpu, stats, opts)
    if st.closed.size:
        meta["feedback"] = "zero-order hold: law evaluated at the step start"
    if "motion_iterations_mean" in stats and st.pres.size:
        meta["motion_iterations_mean"] = stats["motion_iterations_mean"]
    return X, n_steps, ctrl, wall, meta, stats, warnings + [f"MuJoCo: {w}" for w in st.messages]


def _raise_failure(st, stats, method, res):
    """The SimulationError of a failed run (``stats["fail"]``), its partial result ``res``."""
    if "fail" in stats:
        j, tf, *why = stats["fail"]
        msg = why[0] if why else ("; ".join(st.messages) or "non-finite state")
        raise SimulationError(f"{method}: {msg}", t=float(tf), step=int(j), component="state", partial=res)


def step_nodes(scen, h):
    """(T, t_out, keep): the step nodes T (0 and the step ends), the output times and which nodes
    they are; InputError unless h divides the output step."""
    T_end, _ = step_schedule(scen.duration, h, scen.breakpoints)
    T = np.concatenate([[0.0], T_end])
    t_out = scen.output_times
    node = np.clip(np.searchsorted(T, t_out - 1e-9 * h), 0, T.size - 1)
    if np.any(np.abs(T[node] - t_out) > 1e-9 * h):
        raise InputError("h", h, f"must divide the output step {scen.output_step} (outputs are step nodes)")
    keep = np.zeros(T.size, bool)
    keep[node] = True
    return T, t_out, keep


def _step_warning(h, wmax, h_stable) -> list:
    """The warning of a step above the joint springs' explicit stability limit (none without one)."""
    if h_stable is not None and h > h_stable:
        return [
            f"h = {h:g} s exceeds the explicit stability limit {h_stable:.3g} s of the "
            f"joint springs (ω_max = {wmax:.4g} rad/s)"
        ]
    return []


def _rollout(st, x0, T, keep, ctrl, opts, stats, motion):
    """Step the chain from x0 over the nodes T, with motion drives (``motion``:
    :func:`_run_motion`) or torques only (:func:`_run_torque`), MuJoCo's warnings collected in
    ``st.messages``: (kept states X, steps taken, controls, wall time, CPU time (s))."""
    old = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(st.messages.append)  # MuJoCo would write a log file otherwise
    try:
        t0, c0 = time.perf_counter(), time.process_time()
        if motion:
            X, n_steps, ctrl = _run_motion(st, x0, T, keep, ctrl, opts, stats)
        else:
            X, n_steps = _run_torque(st, x0, T, keep, ctrl, stats)
        wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    finally:
        mujoco.set_mju_user_warning(old)
    return X, n_steps, ctrl, wall, cpu


def _meta(method, st, h, integrator, k, wmax, h_stable, n_steps, cpu, stats, opts) -> dict:
    """The Result's meta of a chain's run."""
    return {
        "method": method,
        "h": h,
        "integrator": integrator,
        "elements_per_link": k,
        "versions": {**versions(), "mujoco": mujoco.__version__},
        "n_dof": int(st.m.nv),
        "omega_max": wmax,
        "h_stable": h_stable,
        "n_steps": int(n_steps),
        "cpu_time_solve": cpu,
        "success": "fail" not in stats,
        **opts,
    }


def piece_shapes(st, case, X, p: int, dim: int = 2) -> np.ndarray:
    """Link shapes (nt, n, p, dim) m from the kept states X (rows): per link the polyline
    through its root, its k elastic stations (at the reference arc lengths (j − ½)·L/k) and its
    tip — the rigid pieces themselves — sampled at the p shape points; ``dim`` 2 (a planar arm:
    the plane's coordinates) or 3 (a spatial arm)."""
    mj, m, d, lay = st.mj, st.m, st.d, st.lay
    nt, n, k = X.shape[0], lay.hub_body.size, st.k
    bodies = np.array(
        [[mj.mj_name2id(m, mj.mjtObj.mjOBJ_BODY, f"link{i}_{j}") for j in range(1, k + 1)] for i in range(n)]
    )
    pts = np.empty((nt, n, k + 2, dim))
    for s in range(nt):
        mj.mj_setState(m, d, X[s], st.spec)
        mj.mj_kinematics(m, d)
        pts[s, :, 0] = d.xpos[lay.hub_body, :dim]
        pts[s, :, 1:-1] = d.xpos[bodies, :dim]
        pts[s, :, -1] = d.site_xpos[lay.tip_site, :dim]
    return polylines(case, k, pts, p)


def polylines(case, k, pts, p: int) -> np.ndarray:
    """Link shapes (nt, n, p, dim) from the points ``pts`` (nt, n, k + 2, dim) of each link's
    root, its k hinges (at (j − ½)·L/k) and its tip, sampled at the p shape points."""
    out = np.empty((*pts.shape[:2], p, pts.shape[-1]))
    for i, link in enumerate(case.model.links):
        L = link.beam.length
        x_nodes = np.concatenate(([0.0], (np.arange(1, k + 1) - 0.5) * L / k, [L]))
        out[:, i] = polyline_shapes(x_nodes, pts[:, i], stations(L, p))
    return out
