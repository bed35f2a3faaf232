"""Rigid-link baseline by Pinocchio: the limit of infinitely stiff links.

Every flexible link is a uniform rigid rod (mass ρA·L, inertia mL²/12 about its centre), a rigid
link its own body (mass, centre of mass (x, y) in the link frame, inertia J about it); a hub is a
rigid body at the link root (mass at the joint, inertia J about it), a payload one at the link
tip (its centre of mass at its offset in the tip frame, J about it). Joint i is revolute about
z at the tip of link i−1 (joint 1 at the origin); q is the vector of joint angles (CCW).
Gravity is ``model.gravity`` in the x–y plane.

Torque-driven joints follow forward dynamics with τ = drive.torque(t); motion-driven joints
follow their law and their torque comes from inverse dynamics (RNEA). With both kinds the free
accelerations solve M_ff q̈_f = τ_f − b_f − M_fp q̈_p.

Closed-loop drives (``pd``, ``pid``, user laws; docs/control.md) are evaluated at every RK4
stage with the stage's state; a ``pid`` law's integral of the angle error is an extra state
integrated by the same RK4 (0 at t = 0). A rigid link transmits no bending moment the model
can resolve (hub and rod are one body), so ``moment_gain != 0`` is refused and user laws see
``moment = nan``; tip deflections are 0. The ``computed_torque`` feedforward is τ_ct(t) =
RNEA(α_ref(t), α̇_ref(t), α̈_ref(t)) of this rigid model, with every joint's reference (a motion
drive's law or a closed-loop drive's reference). Only ``"rk4"`` supports closed-loop drives.

Integrators: ``"rk4"`` on the shared step schedule (a step ends exactly at each drive jump;
the step ending there sees the left limit), and ``"dop853"`` (scipy's adaptive solver,
restarted at every jump; the rigid reference of ``dttmm validate``). Other fixed-step
schemes plug into :func:`_simulate` (the tests' Newmark step does).

Pinocchio is imported here only; ``dttmm`` itself never needs it.
"""

from __future__ import annotations

import itertools
import math
import time

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from dttmm import plumbing
from dttmm.drives import ComputedTorque, ControlState, reference_of
from dttmm.errors import InputError, SimulationError
from dttmm.plumbing import versions
from dttmm.result import make_result
from dttmm.shapes import shape_points, straight_shapes
from dttmm.timegrid import step_schedule

from . import _checks

__all__ = ["INTEGRATORS", "build_model", "simulate"]

#: integrator name -> its options and their defaults
INTEGRATORS = {
    "rk4": {},
    "dop853": {"rtol": 1e-12, "atol": 1e-12, "max_step": math.inf},
}


def build_model(manipulator) -> pin.Model:
    """The rigid arm as a Pinocchio model with gravity set (joint ids 1..n, ``JointModelRZ``).

    Frames ``link{i}_tip`` (i = 1..n) mark the link tips, ``tip`` the end-effector.
    """
    model = pin.Model()
    parent, placement = 0, pin.SE3.Identity()
    for i, link in enumerate(manipulator.links, start=1):
        L, m = link.beam.length, link.beam.mass
        jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"joint{i}")
        if link.rigid:  # the case's body: centre of mass (x, y) in the link frame, J about it
            b = link.beam
            rod = pin.Inertia(m, np.array([b.com[0], b.com[1], 0.0]), np.diag([b.inertia] * 3))
        else:
            rod = pin.Inertia(m, np.array([L / 2, 0.0, 0.0]), np.diag([0.0, m * L * L / 12, m * L * L / 12]))
        model.appendBodyToJoint(jid, rod, pin.SE3.Identity())
        if link.hub is not None:
            hub = pin.Inertia(link.hub.mass, np.zeros(3), np.diag([0.0, 0.0, link.hub.inertia]))
            model.appendBodyToJoint(jid, hub, pin.SE3.Identity())
        tip = pin.SE3(np.eye(3), np.array([L, 0.0, 0.0]))
        if link.payload is not None:
            off = np.array([*link.payload.offset, 0.0])  # its centre of mass in the tip frame
            pay = pin.Inertia(link.payload.mass, off, np.diag([0.0, 0.0, link.payload.inertia]))
            model.appendBodyToJoint(jid, pay, tip)
        model.addJointFrame(jid)
        # pure marker frames: append_inertia=False leaves the body untouched
        model.addFrame(pin.Frame(f"link{i}_tip", jid, tip, pin.FrameType.OP_FRAME), False)
        parent, placement = jid, tip
    model.addFrame(pin.Frame("tip", parent, placement, pin.FrameType.OP_FRAME), False)
    gx, gy = manipulator.gravity
    model.gravity.linear = np.array([gx, gy, 0.0])  # Pinocchio's default is −z: no effect in the plane
    return model


class _Arm:
    """Model, scratch data and the drive partition (free = torque joints, p = motion joints)."""

    def __init__(self, case):
        self.model = build_model(case.model)
        self.data = self.model.createData()
        self.drives = case.scenario.drives
        self.n = len(self.drives)
        self.f = np.array([i for i, d in enumerate(self.drives) if d.kind == "torque"], int)
        self.p = np.array([i for i, d in enumerate(self.drives) if d.kind == "motion"], int)
        self.free_drives = [self.drives[i] for i in self.f]
        self.motion_drives = [self.drives[i] for i in self.p]
        self.all_free = self.p.size == 0
        self.ff = slice(None) if self.all_free else np.ix_(self.f, self.f)
        self._closed_loop_setup()
        # some Pinocchio versions fill only the upper triangle of M; test once, mirror if so
        M = pin.crba(self.model, self.data, np.linspace(0.3, 1.1, self.n))
        self.mirror = not np.array_equal(M, M.T)

    def _closed_loop_setup(self):
        """Closed-loop drives: their joints (all torque joints), one integral state each."""
        self.closed = [j for j, i in enumerate(self.f) if self.drives[i].closed_loop]  # in free order
        self.nz = len(self.closed)
        self.z0 = np.zeros(self.nz)
        self.ct = False
        for i, d in enumerate(self.drives):
            if not d.closed_loop:
                continue
            if getattr(d.law, "moment_gain", 0.0):
                raise InputError(
                    f"scenario.drives[{i}].moment_gain",
                    d.law.moment_gain,
                    "is not supported by pinocchio-rigid: a rigid link has no root bending "
                    "moment to feed back (set it to 0)",
                )
            self.ct |= isinstance(d.law.feedforward, ComputedTorque)
        if self.ct:
            self.refs = [reference_of(d) for d in self.drives]
            for i, r in enumerate(self.refs):
                if r is None:
                    raise InputError(
                        f"scenario.drives[{i}].law",
                        self.drives[i].law.name,
                        "the computed_torque feedforward needs a reference motion on "
                        "every joint (a motion drive or a pd/pid drive)",
                    )

    def computed_torque(self, t, left=False):
        """RNEA of the rigid model along the references at t, (n,) N·m."""
        m = np.array([r.motion(t, left) for r in self.refs])
        return pin.rnea(self.model, self.data, m[:, 0].copy(), m[:, 1].copy(), m[:, 2].copy()).copy()

    def _state(self, j, q, v, z, tct):
        i = int(self.f[j])
        c = self.closed.index(j)
        return ControlState(
            joint=i,
            angle=float(q[i]),
            rate=float(v[i]),
            moment=math.nan,
            integral=float(z[c]),
            angles=tuple(q),
            rates=tuple(v),
            tip_deflections=(0.0,) * self.n,
            computed_torque=None if tct is None else float(tct[i]),
        )

    def _sym(self, M):
        return np.triu(M) + np.triu(M, 1).T if self.mirror else M

    def tau_f(self, t, left=False, q=None, v=None, z=None):
        """Torques of the free joints at t; closed-loop ones from the full state (q, v) (n,) and
        the integral states z (nz,)."""
        if not self.nz:
            return np.array([d.torque(t, left) for d in self.free_drives])
        tct = self.computed_torque(t, left) if self.ct else None
        return np.array(
            [
                d.evaluate(t, self._state(j, q, v, z, tct), left)[0] if d.closed_loop else d.torque(t, left)
                for j, d in enumerate(self.free_drives)
            ]
        )

    def z_rate(self, t, left, qf, vf):
        """d/dt of the integral states: α_ref − α of each closed-loop joint (nz,)."""
        if not self.nz:
            return self.z0
        q, v, _ = self.full(t, left, qf, vf)
        return np.array(
            [
                self.free_drives[j].law.error_rate(
                    t, ControlState(int(self.f[j]), q[self.f[j]], v[self.f[j]]), left
                )
                for j in self.closed
            ]
        )

    def prescribed(self, t, left=False):
        """(α, α̇, α̈) of the motion joints at t, each (n_p,)."""
        m = np.array([d.motion(t, left) for d in self.motion_drives]).reshape(-1, 3)
        return m[:, 0], m[:, 1], m[:, 2]

    def full(self, t, left, qf, vf, af=None):
        """Full (q, v, a) from the free part and the motion laws."""
        if self.all_free:
            return qf, vf, af
        q, v, a = np.empty(self.n), np.empty(self.n), np.empty(self.n)
        q[self.p], v[self.p], a[self.p] = self.prescribed(t, left)
        q[self.f], v[self.f] = qf, vf
        a[self.f] = 0.0 if af is None else af
        return q, v, a

    def acc(self, t, left, qf, vf, z=None):
        """Free accelerations q̈_f at t (left limit of the laws when ``left``); z: integral
        states of the closed-loop drives."""
        if self.all_free:
            return pin.aba(self.model, self.data, qf, vf, self.tau_f(t, left, qf, vf, z))
        q, v, a = self.full(t, left, qf, vf)
        if self.f.size == 0:
            return np.zeros(0)
        tau = self.tau_f(t, left, q, v, z)
        b = pin.rnea(self.model, self.data, q, v, a)  # = b + M[:, p] q̈_p with q̈_f = 0
        M = self._sym(pin.crba(self.model, self.data, q))
        return np.linalg.solve(M[self.ff], tau - b[self.f])


def _check_options(integrator, options, integrators=INTEGRATORS):
    _checks.integrator(integrator, integrators)
    known = integrators[integrator]
    _checks.option_names(options, known, f"integrator {integrator!r}")
    opts = {**known, **options}
    for key, val in opts.items():
        try:
            x = float(val)
        except (TypeError, ValueError):
            raise InputError(key, val, "must be a number") from None
        if not x > 0:
            raise InputError(key, val, "must be positive")
    if "max_iter" in opts:
        opts["max_iter"] = int(opts["max_iter"])
    return opts


def _nonfinite(step, t, qf, vf, arm):
    """stats["fail"] entry (message, step, t, component) for a non-finite state."""
    bad = np.flatnonzero(~np.isfinite(np.concatenate([qf, vf])))
    i = int(bad[0]) if bad.size else 0
    what = "angle" if i < qf.size else "rate"
    return "non-finite state", step, t, f"joint {int(arm.f[i % qf.size]) + 1} {what}"


# -- fixed-step integrators: each returns node arrays (T, Q, V, A_right, A_left) -------------


def _rk4(arm, q, v, T, restart, opts, stats):
    N = T.size - 1
    Q, V = np.empty((N + 1, q.size)), np.empty((N + 1, q.size))
    Ar, Al = np.empty_like(Q), np.empty_like(Q)
    jump = np.zeros(N + 1, bool)  # nodes where the left-limit acceleration differs
    Q[0], V[0] = q, v
    acc = arm.acc
    for k in range(N):
        t0, t1 = T[k], T[k + 1]
        dt = t1 - t0
        tm = t0 + 0.5 * dt
        a1 = acc(t0, False, q, v)
        q2, v2 = q + 0.5 * dt * v, v + 0.5 * dt * a1
        a2 = acc(tm, False, q2, v2)
        q3, v3 = q + 0.5 * dt * v2, v + 0.5 * dt * a2
        a3 = acc(tm, False, q3, v3)
        q4, v4 = q + dt * v3, v + dt * a3
        a4 = acc(t1, True, q4, v4)  # left limit: a jump at t1 belongs to the next step
        q = q + (dt / 6) * (v + 2 * v2 + 2 * v3 + v4)
        v = v + (dt / 6) * (a1 + 2 * a2 + 2 * a3 + a4)
        Ar[k] = a1
        Q[k + 1], V[k + 1] = q, v
        if not math.isfinite(float(q.sum() + v.sum())):
            stats["fail"] = _nonfinite(k, t1, q, v, arm)
            N = k
            break
        if restart[k] or k == N - 1:
            Al[k + 1] = acc(t1, True, q, v)
            jump[k + 1] = True
    if "fail" not in stats:
        Ar[N] = Al[N]  # no step starts at the last node
    Al[~jump] = Ar[~jump]
    return T[: N + 1], Q[: N + 1], V[: N + 1], Ar[: N + 1], Al[: N + 1]


def _rk4_closed(arm, q, v, T, restart, opts, stats):
    """RK4 with the integral states of closed-loop drives integrated alongside (q, v)."""
    N = T.size - 1
    Q, V = np.empty((N + 1, q.size)), np.empty((N + 1, q.size))
    Ar, Al = np.empty_like(Q), np.empty_like(Q)
    z = arm.z0  # integral states of closed-loop drives (nz,), integrated alongside
    Z, E = np.empty((N + 1, z.size)), np.empty((N + 1, z.size))
    jump = np.zeros(N + 1, bool)  # nodes where the left-limit acceleration differs
    Q[0], V[0], Z[0] = q, v, z
    acc, zr = arm.acc, arm.z_rate
    for k in range(N):
        t0, t1 = T[k], T[k + 1]
        dt = t1 - t0
        tm = t0 + 0.5 * dt
        a1, e1 = acc(t0, False, q, v, z), zr(t0, False, q, v)
        q2, v2, z2 = q + 0.5 * dt * v, v + 0.5 * dt * a1, z + 0.5 * dt * e1
        a2, e2 = acc(tm, False, q2, v2, z2), zr(tm, False, q2, v2)
        q3, v3, z3 = q + 0.5 * dt * v2, v + 0.5 * dt * a2, z + 0.5 * dt * e2
        a3, e3 = acc(tm, False, q3, v3, z3), zr(tm, False, q3, v3)
        q4, v4, z4 = q + dt * v3, v + dt * a3, z + dt * e3
        # left limit: a jump at t1 belongs to the next step
        a4, e4 = acc(t1, True, q4, v4, z4), zr(t1, True, q4, v4)
        q = q + (dt / 6) * (v + 2 * v2 + 2 * v3 + v4)
        v = v + (dt / 6) * (a1 + 2 * a2 + 2 * a3 + a4)
        z = z + (dt / 6) * (e1 + 2 * e2 + 2 * e3 + e4)
        Ar[k], E[k] = a1, e1
        Q[k + 1], V[k + 1], Z[k + 1] = q, v, z
        if not math.isfinite(float(q.sum() + v.sum())):
            stats["fail"] = _nonfinite(k, t1, q, v, arm)
            N = k
            break
        if restart[k] or k == N - 1:
            Al[k + 1] = acc(t1, True, q, v, z)
            jump[k + 1] = True
    if "fail" not in stats:
        Ar[N] = Al[N]  # no step starts at the last node
        E[N] = zr(T[N], True, q, v)
    Al[~jump] = Ar[~jump]
    stats["z_nodes"] = (Z[: N + 1], E[: N + 1])
    return T[: N + 1], Q[: N + 1], V[: N + 1], Ar[: N + 1], Al[: N + 1]


def _hermite(T, Q, V, Ar, Al, t, h):
    """States at times t from the step nodes: node values where t hits a node, otherwise
    cubic Hermite on (q, q̇) and on (q̇, q̈) with the one-sided accelerations of the step."""
    snap = 1e-9 * h
    q = plumbing.hermite_sample(t, T, Q, V, snap=snap)
    return q, plumbing.hermite_sample(t, T, V, Ar, Al, snap=snap)


def _hermite_z(T, Z, E, t, h):
    """Integral states at times t: cubic Hermite on (z, ż) between the nodes."""
    return plumbing.hermite_sample(t, T, Z, E)


def _dop853(arm, q, v, T_out, duration, h, breakpoints, opts, stats):
    nf = q.size
    edges = [0.0, *breakpoints, duration]
    Qo, Vo = np.full((T_out.size, nf), np.nan), np.full((T_out.size, nf), np.nan)
    y = np.concatenate([q, v])
    steps = nfev = 0
    done = np.zeros(T_out.size, bool)
    for a, b in itertools.pairwise(edges):

        def fun(t, y, b=b):
            return np.concatenate([y[nf:], arm.acc(t, t >= b, y[:nf], y[nf:])])

        sol = solve_ivp(
            fun,
            (a, b),
            y,
            method="DOP853",
            rtol=opts["rtol"],
            atol=opts["atol"],
            max_step=opts["max_step"],
            first_step=min(h, b - a),
            dense_output=True,
        )
        steps += sol.t.size - 1
        nfev += sol.nfev
        ok = sol.status == 0 and np.all(np.isfinite(sol.y[:, -1]))
        good_t = np.flatnonzero(np.isfinite(sol.y).all(axis=0))  # accepted steps before a failure
        end = b if ok else (float(sol.t[good_t[-1]]) if good_t.size else a)
        sel = (~done) & (T_out >= a - 1e-12 * duration) & (T_out <= end + 1e-12 * duration)
        if sel.any() and sol.sol is not None:
            ys = sol.sol(np.clip(T_out[sel], a, b))
            Qo[sel], Vo[sel] = ys[:nf].T, ys[nf:].T
            done |= sel
        if not ok:
            stats["fail"] = (f"solve_ivp failed: {sol.message}", steps, float(sol.t[-1]), "state")
            break
        y = sol.y[:, -1]
    stats["nfev"], stats["steps"] = nfev, steps
    return Qo, Vo, done


def _outputs(arm, t, qf, vf, z):
    """Everything the Result holds at the output times t (nt,), from the free states and the
    integral states z (nt, nz)."""
    model, data = arm.model, arm.data
    n, nt = arm.n, t.size
    q, v, tau = np.empty((nt, n)), np.empty((nt, n)), np.empty((nt, n))
    root, tip = np.empty((nt, n, 2)), np.empty((nt, n, 2))
    energy = np.empty(nt)
    tips = [model.getFrameId(f"link{i}_tip") for i in range(1, n + 1)]
    for s in range(nt):
        qs, vs, as_ = arm.full(t[s], False, qf[s], vf[s])
        q[s], v[s] = qs, vs
        if arm.p.size:
            a = as_.copy()
            a[arm.f] = arm.acc(t[s], False, qf[s], vf[s], z[s])
            tau[s] = pin.rnea(model, data, qs, vs, a)
        if arm.f.size:  # the applied torques exactly (RNEA returns them up to round-off)
            tau[s, arm.f] = arm.tau_f(t[s], False, qs, vs, z[s])
        energy[s] = pin.computeMechanicalEnergy(model, data, qs, vs)  # also runs forward kinematics
        pin.updateFramePlacements(model, data)
        for i in range(n):
            root[s, i] = data.oMi[i + 1].translation[:2]
            tip[s, i] = data.oMf[tips[i]].translation[:2]
    return q, v, tau, root, tip, energy


def _integrate(arm, scen, h, T_end, restart, integrator, stepper, opts, stats):
    """Run the integrator (``stepper``: the fixed-step one); return output times reached, free
    states there, steps, wall time."""
    t_out = scen.output_times
    qf0 = np.array([arm.drives[i].initial_angle for i in arm.f], float)
    vf0 = np.array([arm.drives[i].initial_rate for i in arm.f], float)
    nothing = arm.f.size == 0  # everything prescribed: nothing to integrate
    t0 = time.perf_counter()
    if integrator == "dop853":
        if nothing:
            stats["steps"] = stats["nfev"] = 0
            z = np.zeros((t_out.size, 0))
            return t_out, z, z, z, 0, time.perf_counter() - t0
        qf, vf, good = _dop853(arm, qf0, vf0, t_out, scen.duration, float(h), scen.breakpoints, opts, stats)
        wall = time.perf_counter() - t0
        return t_out[good], qf[good], vf[good], np.zeros((int(good.sum()), 0)), stats["steps"], wall
    T = np.concatenate([[0.0], T_end])
    if nothing:
        z = np.zeros((T.size, 0))
        nodes = (T, z, z, z, z)
    else:
        nodes = stepper(arm, qf0, vf0, T, restart, opts, stats)
    wall = time.perf_counter() - t0
    n_steps = nodes[0].size - 1
    tg = t_out[t_out <= nodes[0][-1] + 1e-9 * h]
    Z, E = stats.pop("z_nodes", (np.zeros((n_steps + 1, 0)),) * 2)
    if n_steps == 0:  # failed in the first step
        return tg, nodes[1][:1], nodes[2][:1], Z[:1], 0, wall
    qf, vf = _hermite(*nodes, tg, float(h))
    return tg, qf, vf, _hermite_z(nodes[0], Z, E, tg, float(h)), n_steps, wall


def simulate(case, *, h, integrator="rk4", elements_per_link=None, **options):
    """Simulate a case with rigid links.

    Parameters
    ----------
    case : dttmm.Case
    h : float
        Step size (s). For ``"dop853"`` the first trial step of each restart (the step size
        is adaptive; limit it with the option ``max_step``).
    integrator : ``"rk4"`` | ``"dop853"``
    elements_per_link : ignored (rigid links); accepted for the common call.
    **options
        dop853: rtol (1e-12), atol (1e-12), max_step (inf); every integrator: shape_points
        (0): p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2) m, straight links.

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``; tip deflections are exactly 0, ``energy``
    is kinetic + gravitational potential (zero at y = 0). ``wall_time`` covers the time
    stepping only.

    Raises
    ------
    dttmm.InputError
        h ≤ 0 or h > duration, unknown integrator or option.
    dttmm.SimulationError
        non-finite state; ``partial`` holds the output samples up to the last good step.
    """
    return _simulate(case, h, integrator, elements_per_link, options)


def _rk4_stepper(arm, q, v, T, restart, opts, stats):
    return (_rk4_closed if arm.nz else _rk4)(arm, q, v, T, restart, opts, stats)


def _simulate(case, h, integrator, elements_per_link, options, stepper=_rk4_stepper, integrators=INTEGRATORS):
    """:func:`simulate` with the fixed-step integrator ``stepper(arm, q_f, v_f, T, restart,
    opts, stats)`` -> node arrays (T, Q, V, A_right, A_left) for every name of ``integrators``
    (name -> its options and defaults) but "dop853"; only "rk4" takes closed-loop drives."""
    _, h = plumbing.discretisation(case, elements_per_link, h, uses_k=False)
    scen = case.scenario
    options = dict(options)
    p = shape_points(options.pop("shape_points", 0))
    opts = _check_options(integrator, options, integrators)
    T_end, restart = step_schedule(scen.duration, h, scen.breakpoints)
    arm = _Arm(case)
    if arm.nz and integrator != "rk4":
        raise InputError(
            "integrator",
            integrator,
            "closed-loop drives are supported by pinocchio-rigid with integrator 'rk4' only",
        )
    stats = {}
    meta = {
        "method": "pinocchio-rigid",
        "h": float(h),
        "integrator": integrator,
        "elements_per_link": None,
        "versions": {**versions(), "pinocchio": pin.__version__},
        **opts,
    }

    with np.errstate(over="ignore", invalid="ignore"):  # non-finite states are caught and reported
        tg, qf, vf, zf, n_steps, wall = _integrate(
            arm, scen, h, T_end, restart, integrator, stepper, opts, stats
        )
    for key in ("nfev", "iterations_mean"):
        if key in stats:
            meta[key] = stats[key]
    meta["success"] = "fail" not in stats
    meta["n_steps"] = int(n_steps)
    q, v, tau, root, tip, energy = _outputs(arm, tg, qf, vf, zf)
    res = make_result(
        t=tg,
        joint_angle=q,
        joint_rate=v,
        joint_torque=tau,
        link_root=root,
        link_root_angle=np.cumsum(q, axis=1),
        link_tip=tip,
        wall_time=wall,
        n_steps=n_steps,
        meta=meta,
        energy=energy,
        link_shapes=straight_shapes(root, tip, p) if p else None,
    )
    if "fail" in stats:
        msg, k, tf, comp = stats["fail"]
        raise SimulationError(msg, t=tf, step=k, component=comp, partial=res)
    return res
