"""Rigid-link baseline of a spatial case by Pinocchio: the limit of infinitely stiff links.

The model is built programmatically (a ``pinocchio.Model``) from the spatial case
(docs/spatial.md §1), with the links rigid:

* joint i: ``JointModelRevoluteUnaligned(axis)`` placed at (R_rpy, o) in its parent frame (the
  base frame (R_base, p_base) for joint 1, the undeformed tip frame of link i−1 — the link
  frame moved by L along x — otherwise); a locked joint adds no joint: its link is welded to
  the parent body at the origin's placement;
* link i as one rigid body in its link frame: the beam as a slender rod (mass ρA L at
  (L/2, 0, 0), inertia diag(0, mL²/12, mL²/12) about its centre) plus the sections' rotary
  inertia L · Rx(roll) diag(ρJ, ρIy, ρIz) Rx(roll)ᵀ — a rigid link (``SpatialRigidBody``) its
  own body (mass at its centre of mass, inertia about it) and its length; the hub (mass at the root, inertia J_h
  about it); the payload (mass at (L, 0, 0) + c, inertia J_p about its centre — the rigid tip
  frame has the link frame's axes);
* frames ``link{i}`` (the link frame) and ``link{i}_tip`` (the tip frame), and ``tip``;
* ``model.gravity.linear`` = the case's gravity (Pinocchio's default −z is replaced).

A tree places each joint in its parent link's tip frame. Closed loops (docs/spatial.md §11
"Peers on trees and loops") run on ``pinocchio.constraintDynamics`` with one
``RigidConstraintModel`` per closure (:func:`closure_models`: a 3-D point contact for a spherical
closure and for a revolute one about an axis parallel to every joint axis, a 6-D contact for a
weld; other revolute closures are refused, :func:`require_rigid_closures`), Baumgarte-corrected,
RK4 only; motion drives' torques are solved so that their joints follow the laws.

q is the vector of the unlocked joints' angles. Torque drives give τ(t); motion drives follow
their law and their torque is the inverse dynamics (RNEA); the free accelerations solve
M_ff q̈_f = τ_f − b_f (b = RNEA(q, q̇, q̈ with q̈_f = 0)), by ``pinocchio.aba`` when every joint
is free. Closed-loop drives (``pd``, ``pid``, user laws; docs/control.md) are evaluated at every
RK4 stage with the stage's state, a ``pid`` law's integral of the angle error integrated by the
same RK4 (0 at t = 0); a rigid link has no bending moment to feed back (``moment_gain != 0`` is
refused, user laws see ``moment = nan``), and the ``computed_torque`` feedforward is the RNEA of
this model along every joint's reference. Integrators: ``"rk4"`` and ``"newmark"`` (β = ¼,
γ = ½, Newton on the RNEA residual with ``computeRNEADerivatives``), both on the shared step
schedule (the step ending at a drive jump sees the left limit), and ``"dop853"`` (scipy's
adaptive solver on the torque joints, restarted at every drive jump, dense output at the output
times); closed-loop drives and closed loops run with ``"rk4"`` only. Outputs on the scenario's
grid (cubic Hermite of (q, q̇) and of (q̇, q̈) between step ends, the torques of the forward
dynamics at the sampled state),
a :class:`dttmm.spatial.SpatialResult` like those of :mod:`reference_models.spatial_global`:
``link_root``/``link_tip`` (nt, n, 3), ``end_effector`` (nt, 3), ``tip_deflection`` (nt, n, 2)
and ``twist`` (nt, n), both zero, ``link_rotation``/``tip_rotation`` (nt, n, 3, 3).

A planar case runs here as its spatial embedding (:mod:`reference_models.pinocchio_rigid`).
Pinocchio is imported here only.
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
from dttmm.shapes import shape_points as check_shape_points
from dttmm.shapes import straight_shapes
from dttmm.spatial import SpatialCase, SpatialResult
from dttmm.spatial.scenario import require_no_loads
from dttmm.spatial.topology import (
    closure_gaps,
    initial_angles,
    resolve_closures,
    rigid_tip_frames,
)
from dttmm.timegrid import step_schedule

from . import _checks
from ._spatial_mechanics import rot_axis, rpy_matrix

__all__ = [
    "INTEGRATORS",
    "build_model",
    "check_case",
    "closure_models",
    "link_inertia",
    "require_rigid_closures",
    "simulate",
]

#: integrator name -> its options and their defaults
INTEGRATORS = {
    "rk4": {},
    "newmark": {"tol": 1e-12, "max_iter": 25},
    "dop853": {"rtol": 1e-12, "atol": 1e-12, "max_step": math.inf},
}


def link_inertia(link) -> pin.Inertia:
    """The rigid-body inertia of one link in its link frame: rod + rotary inertia + hub +
    payload (see the module notes)."""
    b = link.beam
    L = b.length
    if link.rigid:  # a rigid link's own body: mass at its centre c, inertia about c
        total = pin.Inertia(b.mass, b.com_vector, b.inertia_matrix)
    else:
        m = b.rhoA * b.length
        Rr = rot_axis((1.0, 0.0, 0.0), b.roll)
        rot = L * Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
        total = pin.Inertia(
            m, np.array([L / 2, 0.0, 0.0]), np.diag([0.0, m * L * L / 12, m * L * L / 12]) + rot
        )
    if link.hub is not None:
        total = total + pin.Inertia(link.hub.mass, np.zeros(3), link.hub_inertia)
    if link.payload is not None:
        c = np.array([L, 0.0, 0.0]) + link.payload_offset
        total = total + pin.Inertia(link.payload.mass, c, link.payload_inertia)
    return total


def build_model(manipulator) -> pin.Model:
    """The rigid spatial arm as a Pinocchio model with gravity set (joint ids 1..n_joints, one
    per unlocked joint, base first). A tree: each joint is placed in its parent link's tip frame
    (the base frame for a link on the base). Closures are not part of the model
    (:func:`closure_models`)."""
    return _build(manipulator)[0]


def _build(manipulator):
    """(model, tips): the model and, per link, (joint id, placement of its tip frame in that
    joint's frame)."""
    model = pin.Model()
    # per link: the joint that carries it and the placement of its tip frame in that joint's frame
    tips = {-1: (0, pin.SE3(rpy_matrix(manipulator.base_rpy), np.array(manipulator.base_xyz, float)))}
    for i, link in enumerate(manipulator.links, start=1):
        parent, place = tips[manipulator.parents[i - 1]]
        j = link.joint
        origin = pin.SE3(rpy_matrix(j.origin_rpy), np.array(j.origin_xyz, float))
        place = place * origin
        if not j.locked:
            axis = np.array(j.axis, float)
            parent = model.addJoint(parent, pin.JointModelRevoluteUnaligned(axis), place, f"joint{i}")
            model.addJointFrame(parent)
            place = pin.SE3.Identity()
        model.appendBodyToJoint(parent, link_inertia(link), place)
        model.addFrame(pin.Frame(f"link{i}", parent, place, pin.FrameType.OP_FRAME), False)
        place = place * pin.SE3(np.eye(3), np.array([link.beam.length, 0.0, 0.0]))
        model.addFrame(pin.Frame(f"link{i}_tip", parent, place, pin.FrameType.OP_FRAME), False)
        tips[i - 1] = (parent, place)
    parent, place = tips[manipulator.end_effector_index]
    model.addFrame(pin.Frame("tip", parent, place, pin.FrameType.OP_FRAME), False)
    model.gravity.linear = np.array(manipulator.gravity, float)
    return model, tips


#: the closures' Baumgarte correction (Pinocchio's corrector: the constraint's acceleration
#: −Kd ġ − Kp g), a critically damped 2 ms time scale: the drift of the position gap, O(h⁴) per
#: RK4 step, is held at round-off without stiffening the step
CLOSURE_KP, CLOSURE_KD = 2.5e5, 1.0e3
#: Pinocchio's proximal constraint solver (constraintDynamics): accuracy, μ, iterations; μ > 0
#: regularises a redundant row (the out-of-plane row of a planar loop's point contact)
PROXIMAL = (1e-13, 1e-8, 100)


def _parallel_axes(manipulator, axis_world, angles) -> bool:
    """Whether every unlocked joint's axis is parallel to ``axis_world`` with the links rigid at
    the joint angles ``angles`` (a mechanism that turns about one direction only: a revolute
    closure about it needs no constraint on its axis)."""
    R, _ = rigid_tip_frames(manipulator, angles)
    Rb = rpy_matrix(manipulator.base_rpy)
    for i, link in enumerate(manipulator.links):
        if link.joint.locked:
            continue
        par = manipulator.parents[i]
        Rp = Rb if par < 0 else R[par]
        u = Rp @ rpy_matrix(link.joint.origin_rpy) @ np.array(link.joint.axis, float)
        if np.linalg.norm(np.cross(u, axis_world)) > 1e-12:
            return False
    return True


def require_rigid_closures(manipulator, angles=None) -> None:
    """Refuse (one-line InputError) a closure Pinocchio's rigid constraints cannot hold: a
    revolute closure is 5 equations and ``RigidConstraintModel`` has the 3-D point contact and
    the 6-D weld only, so it runs as a 3-D point contact only where every joint axis is parallel
    to the closure's axis (the rigid mechanism then turns about that direction only and the axis
    constraint holds by itself)."""
    if not manipulator.closures:
        return
    angles = np.zeros(manipulator.n_joints) if angles is None else angles
    R, p = rigid_tip_frames(manipulator, angles)
    rc = resolve_closures(manipulator, R, p)
    for j, cl in enumerate(manipulator.closures):
        if cl.kind != "revolute":
            continue
        a = int(rc.a[j])
        u = R[a] @ rc.ua[j]
        if not _parallel_axes(manipulator, u, angles):
            raise InputError(
                f"model.closures[{j}].axis",
                list(cl.axis),
                "a revolute closure whose axis is not parallel to every joint axis is not supported by "
                "pinocchio-spatial (its rigid constraints are the 3-D point and the 6-D weld; the "
                "revolute needs 5 equations)",
            )


def closure_models(model, tips, manipulator, angles):
    """The closures as Pinocchio ``RigidConstraintModel``s between the two links' joints: a
    spherical or (planar, :func:`require_rigid_closures`) revolute closure a 3-D point contact at
    the closure point, a weld a 6-D contact whose two placements coincide at the initial state;
    the frames are those of :func:`dttmm.spatial.topology.resolve_closures`, the constraint's
    reference frame LOCAL (the placement on `link`)."""
    require_rigid_closures(manipulator, angles)
    R, p = rigid_tip_frames(manipulator, angles)
    rc = resolve_closures(manipulator, R, p)
    out = []
    for j, cl in enumerate(manipulator.closures):
        a, b = int(rc.a[j]), int(rc.b[j])
        ja, tip_a = tips[a]
        kind = pin.ContactType.CONTACT_6D if cl.kind == "weld" else pin.ContactType.CONTACT_3D
        pa = tip_a * pin.SE3(np.eye(3), rc.pa[j])
        if b < 0:
            jb, pb = 0, pin.SE3(R[a], rc.pb[j])  # the world: the attachment frame parallel to a's
        else:
            jb, tip_b = tips[b]
            pb = tip_b * pin.SE3(rc.R0[j].T, rc.pb[j])
        cm = pin.RigidConstraintModel(kind, model, ja, pa, jb, pb, pin.ReferenceFrame.LOCAL)
        cm.name = manipulator.closure_names[j]
        bp = cm.m_baumgarte_parameters
        bp.Kp, bp.Kd = CLOSURE_KP, CLOSURE_KD
        cm.setBaumgarteCorrectorParameters(bp)
        out.append(cm)
    return out


class _Arm:
    """Model, scratch data, the drive partition (f: torque joints, p: motion joints) and the
    closed-loop drives' integral states; ``method`` names the baseline in refusals."""

    def __init__(self, case, method="pinocchio-spatial"):
        self.case = case
        self.method = method
        self.model, tips = _build(case.model)
        self.data = self.model.createData()
        self.drives = case.scenario.drives
        self.ee = case.model.end_effector_index
        self.cms = ()
        if case.model.closures:
            self.cms = pin.StdVec_RigidConstraintModel()
            for cm in closure_models(self.model, tips, case.model, initial_angles(case)):
                self.cms.append(cm)
            self.cds = pin.StdVec_RigidConstraintData()
            for cm in self.cms:
                self.cds.append(cm.createData())
            pin.initConstraintDynamics(self.model, self.data, self.cms, self.cds)
            self.prox = pin.ProximalSettings(*PROXIMAL)
            self.loads = np.zeros((len(self.cms), 6))
        self.n = len(self.drives)
        self.f = np.array([i for i, d in enumerate(self.drives) if d.kind == "torque"], int)
        self.p = np.array([i for i, d in enumerate(self.drives) if d.kind == "motion"], int)
        self._closed_loop_setup()
        M = pin.crba(self.model, self.data, np.linspace(0.3, 1.1, self.n))
        self.mirror = not np.array_equal(M, M.T)  # older versions fill the upper triangle only
        nl = case.model.n_links
        self.frames = [
            (self.model.getFrameId(f"link{i}"), self.model.getFrameId(f"link{i}_tip"))
            for i in range(1, nl + 1)
        ]

    def _closed_loop_setup(self):
        """Closed-loop drives (all on torque joints): their joints and one integral state each
        (``self.z0``, zero at t = 0); the computed-torque feedforward's references."""
        self.closed = {int(i): c for c, i in enumerate(i for i in self.f if self.drives[i].closed_loop)}
        self.z0 = np.zeros(len(self.closed))
        self.ct = False
        for i, d in enumerate(self.drives):
            if not d.closed_loop:
                continue
            if getattr(d.law, "moment_gain", 0.0):
                raise InputError(
                    f"scenario.drives[{i}].moment_gain",
                    d.law.moment_gain,
                    f"is not supported by {self.method}: a rigid link has no root bending "
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

    def _sym(self, M):
        return np.triu(M) + np.triu(M, 1).T if self.mirror else M

    def computed_torque(self, t, left=False):
        """RNEA of the rigid model along the references at t, (n,) N·m."""
        m = np.array([r.motion(t, left) for r in self.refs])
        return pin.rnea(self.model, self.data, m[:, 0].copy(), m[:, 1].copy(), m[:, 2].copy()).copy()

    def _state(self, i, q, v, z, tct):
        """The ControlState of closed-loop joint i: no bending moment (nan), no deflection."""
        return ControlState(
            joint=int(i),
            angle=float(q[i]),
            rate=float(v[i]),
            moment=math.nan,
            integral=float(z[self.closed[i]]),
            angles=tuple(q),
            rates=tuple(v),
            tip_deflections=(0.0,) * self.n,
            computed_torque=None if tct is None else float(tct[i]),
        )

    def torque(self, t, left, q=None, v=None, z=None):
        """Applied torques (n,), zero on the motion joints; closed-loop drives evaluated at the
        state (q, v) (n,) (motion joints prescribed) and integral states z."""
        tau = np.zeros(self.n)
        tct = self.computed_torque(t, left) if self.ct else None
        for i in self.f:
            d = self.drives[i]
            tau[i] = (
                d.evaluate(t, self._state(i, q, v, z, tct), left)[0] if d.closed_loop else d.torque(t, left)
            )
        return tau

    def z_rate(self, t, left, q, v):
        """d/dt of the integral states: α_ref − α of each closed-loop joint."""
        if not self.closed:
            return self.z0
        return np.array(
            [self.drives[i].law.error_rate(t, ControlState(i, q[i], v[i]), left) for i in self.closed]
        )

    def prescribe(self, t, left, q, v, a=None):
        for i in self.p:
            q[i], v[i], acc = self.drives[i].motion(t, left)
            if a is not None:
                a[i] = acc

    def _constrained(self, q, v, tau):
        a = pin.constraintDynamics(self.model, self.data, q, v, tau, self.cms, self.cds, self.prox)
        return a.copy()

    def closure_loads(self) -> np.ndarray:
        """(nc, 6): the closures' loads of the last constrained solve, world components, force and
        moment about the closure point, that `to` exerts on `link` (``data.lambda_c`` is the load
        on joint 1's placement in its frame: the generalised force is J_cᵀλ, J_c the placement's
        LOCAL Jacobian on `link` minus the other's)."""
        lam = self.data.lambda_c
        out, r = np.zeros((len(self.cms), 6)), 0
        for c, (cm, cd) in enumerate(zip(self.cms, self.cds)):
            R = cd.oMc1.rotation
            m = cm.residualSize()
            out[c, :3] = R @ lam[r : r + 3]
            if m == 6:
                out[c, 3:] = R @ lam[r + 3 : r + 6]
            r += m
        return out

    def _loop_forward(self, t, left, q, v, z):
        """q̈ and torques with closures: Pinocchio's constraintDynamics (its proximal solver), the
        motion joints' torques u found so that their accelerations are the laws' (q̈ is affine in
        u: one solve at u = 0 and one per motion joint give the map, a last one the result)."""
        a_p = np.zeros(self.n)
        self.prescribe(t, left, q, v, a_p)
        tau = self.torque(t, left, q, v, z)
        p = self.p
        if p.size:
            tau[p] = 0.0
            a0 = self._constrained(q, v, tau)
            A = np.empty((p.size, p.size))
            for c, i in enumerate(p):
                e = tau.copy()
                e[i] = 1.0
                A[:, c] = self._constrained(q, v, e)[p] - a0[p]
            if not np.linalg.cond(A) < 1e12:
                raise InputError(
                    "scenario.drives",
                    [int(i) for i in p],
                    "motion drives that the closed loop locks (their joints' accelerations do not "
                    "follow their torques) are not supported by pinocchio-spatial",
                )
            tau[p] = np.linalg.solve(A, a_p[p] - a0[p])
        a = self._constrained(q, v, tau)
        self.loads = self.closure_loads()
        return a, tau

    def forward(self, t, left, q, v, z=None):
        """q̈ (n,) with the motion joints prescribed (in q, v, in place), and the joint torques
        (n,); z: the closed-loop drives' integral states."""
        if len(self.cms):
            return self._loop_forward(t, left, q, v, z)
        if not self.p.size:
            tau = self.torque(t, left, q, v, z)
            return pin.aba(self.model, self.data, q, v, tau).copy(), tau
        a = np.zeros(self.n)
        self.prescribe(t, left, q, v, a)
        tau_f = self.torque(t, left, q, v, z)[self.f]
        F = self.f
        if F.size:
            b = pin.rnea(self.model, self.data, q, v, a)
            M = self._sym(pin.crba(self.model, self.data, q))
            a[F] = np.linalg.solve(M[np.ix_(F, F)], tau_f - b[F])
        tau = pin.rnea(self.model, self.data, q, v, a).copy()
        tau[F] = tau_f
        return a, tau


def _rk4(arm, T, restart, q, v, opts, nodes):
    """RK4 on the step ends T; the closed-loop drives' integral states z integrated alongside."""
    z = arm.z0
    a = arm.forward(0.0, False, q.copy(), v.copy(), z)[0]
    e = arm.z_rate(0.0, False, q, v)
    nodes.append([0.0, q.copy(), v.copy(), z, e, a, a])
    for n in range(T.size):
        t0 = nodes[-1][0]
        t1 = T[n]
        dt = t1 - t0
        tm = t0 + 0.5 * dt
        q2, v2, z2 = q + 0.5 * dt * v, v + 0.5 * dt * a, z + 0.5 * dt * e
        a2 = arm.forward(tm, False, q2, v2, z2)[0]
        e2 = arm.z_rate(tm, False, q2, v2)
        q3, v3, z3 = q + 0.5 * dt * v2, v + 0.5 * dt * a2, z + 0.5 * dt * e2
        a3 = arm.forward(tm, False, q3, v3, z3)[0]
        e3 = arm.z_rate(tm, False, q3, v3)
        q4, v4, z4 = q + dt * v3, v + dt * a3, z + dt * e3
        a4 = arm.forward(t1, True, q4, v4, z4)[0]
        e4 = arm.z_rate(t1, True, q4, v4)
        q = q + (dt / 6) * (v + 2 * v2 + 2 * v3 + v4)
        v = v + (dt / 6) * (a + 2 * a2 + 2 * a3 + a4)
        z = z + (dt / 6) * (e + 2 * e2 + 2 * e3 + e4)
        a = arm.forward(t1, True, q, v, z)[0]
        e = arm.z_rate(t1, True, q, v)
        _check(arm, nodes, n, t1, q, v)
        nodes.append([t1, q.copy(), v.copy(), z, e, a, a])
        if restart[n]:
            a = nodes[-1][6] = arm.forward(t1, False, q, v, z)[0]
            e = arm.z_rate(t1, False, q, v)
    return {}


def _newmark(arm, T, restart, q, v, opts, nodes):
    """Newmark (β = ¼, γ = ½) on the step ends T, Newton on the RNEA residual (open-loop drives)."""
    a = arm.forward(0.0, False, q.copy(), v.copy())[0]
    nodes.append([0.0, q.copy(), v.copy(), arm.z0, arm.z0, a, a])
    F = arm.f
    its, unconverged = [], []
    for n in range(T.size):
        t1 = T[n]
        dt = t1 - nodes[-1][0]
        qp = q + dt * v + dt * dt * 0.25 * a
        vp = v + 0.5 * dt * a
        cq, cv = 0.25 * dt * dt, 0.5 * dt
        an = a.copy()
        arm.prescribe(t1, True, qp, vp, an)
        tau1 = arm.torque(t1, True)
        for it in range(1, opts["max_iter"] + 1):  # noqa: B007 (the count is read after the loop)
            qi, vi = qp + cq * an, vp + cv * an
            arm.prescribe(t1, True, qi, vi)
            r = pin.rnea(arm.model, arm.data, qi, vi, an) - tau1
            dq, dv, M = pin.computeRNEADerivatives(arm.model, arm.data, qi, vi, an)
            J = arm._sym(M) + cq * dq + cv * dv
            da = np.linalg.solve(J[np.ix_(F, F)], -r[F])
            an[F] += da
            if np.abs(da).max(initial=0.0) <= opts["tol"] * (1.0 + np.abs(an).max(initial=0.0)):
                break
        else:
            unconverged.append(n)
        its.append(it)
        q, v = qp + cq * an, vp + cv * an
        arm.prescribe(t1, True, q, v)
        a = an
        _check(arm, nodes, n, t1, q, v)
        nodes.append([t1, q.copy(), v.copy(), arm.z0, arm.z0, a, a])
        if restart[n]:
            a = nodes[-1][6] = arm.forward(t1, False, q.copy(), v.copy())[0]
    return {
        "iterations_mean": float(np.mean(its)),
        "iterations_max": int(np.max(its)),
        "unconverged_steps": len(unconverged),
    }


def _dop853(arm, T, restart, q, v, opts, nodes):
    """DOP853 (scipy's adaptive solver) on the torque joints, restarted at every drive jump
    (the first trial step of each restart h); nodes at the output times reached (dense output),
    their torques from the forward dynamics there. Open-loop drives."""
    scen = arm.case.scenario
    f, nf, h = arm.f, arm.f.size, arm.meta["h"]
    t_out = scen.output_times
    if not nf:  # everything prescribed: nothing to integrate
        for t in t_out:
            _node(arm, nodes, t, q, v)
        return {"nfev": 0, "n_steps": 0}
    q0, v0 = q.copy(), v.copy()
    y = np.concatenate([q[f], v[f]])
    steps = nfev = 0
    done = np.zeros(t_out.size, bool)
    for a, b in itertools.pairwise([0.0, *scen.breakpoints, scen.duration]):

        def fun(t, y, b=b):
            qs, vs = q.copy(), v.copy()
            qs[f], vs[f] = y[:nf], y[nf:]
            return np.concatenate([y[nf:], arm.forward(t, t >= b, qs, vs)[0][f]])

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
        sel = (~done) & (t_out >= a - 1e-12 * scen.duration) & (t_out <= end + 1e-12 * scen.duration)
        if sel.any() and sol.sol is not None:
            for t, ys in zip(t_out[sel], sol.sol(np.clip(t_out[sel], a, b)).T):
                q[f], v[f] = ys[:nf], ys[nf:]
                _node(arm, nodes, t, q, v)
            done |= sel
        if not ok:
            if not nodes:  # nothing reached: the initial state
                _node(arm, nodes, 0.0, q0, v0)
            arm.meta["nfev"] = nfev
            partial = _result(arm, nodes, t_out, h, steps, {**arm.meta, "success": False}, "failed")
            raise SimulationError(
                f"solve_ivp failed: {sol.message}",
                t=float(sol.t[-1]),
                step=steps,
                component="state",
                partial=partial,
            )
        y = sol.y[:, -1]
    return {"nfev": nfev, "n_steps": steps}


def _node(arm, nodes, t, q, v):
    """Append the output node at t of the state (q, v) (motion joints prescribed there)."""
    qs, vs = q.copy(), v.copy()
    a = arm.forward(t, False, qs, vs)[0]
    nodes.append([float(t), qs, vs, arm.z0, arm.z0, a, a])


def _check(arm, nodes, n, t, q, v):
    x = np.concatenate([q, v])
    if np.all(np.isfinite(x)):
        return
    bad = int(np.flatnonzero(~np.isfinite(x))[0])
    comp = f"joint {bad % arm.n + 1} {'angle' if bad < arm.n else 'rate'}"
    meta = {**arm.meta, "success": False}
    partial = _result(arm, nodes, arm.case.scenario.output_times, 0.0, n, meta, "failed")
    raise SimulationError("non-finite state", t=t, step=n, component=comp, partial=partial)


def _sample(arm, nodes, times, h):
    """(q, v, τ) at the output times: node values on a node, else cubic Hermite of (q, q̇), of
    (q̇, q̈) with the one-sided accelerations of each step, of the integral states with their
    rates, and the torques of the forward dynamics at the sampled state."""
    T, Q, V, Z, E, Al, Ar = (np.array(x) for x in zip(*nodes))
    times = times[times <= T[-1] + 1e-9 * h]
    if T.size == 1:
        times, q, v, z = times[:1], Q[:1], V[:1], Z[:1]
    else:
        snap = 1e-9 * h
        q = plumbing.hermite_sample(times, T, Q, V, snap=snap)
        v = plumbing.hermite_sample(times, T, V, Ar, Al, snap=snap)
        z = plumbing.hermite_sample(times, T, Z, E, snap=snap) if arm.closed else np.zeros((times.size, 0))
    tau = np.empty((times.size, arm.n))
    loads = np.zeros((times.size, len(arm.cms), 6))
    for r, t in enumerate(times):
        tau[r] = arm.forward(t, False, q[r], v[r], z[r])[1]  # prescribes the motion joints
        if len(arm.cms):
            loads[r] = arm.loads
    return times, q, v, tau, loads


def _result(arm, nodes, times, h, n_steps, meta, status="ok", wall=0.0, shape_points=0) -> SpatialResult:
    times, q, v, tau, loads = _sample(arm, nodes, times, h if h else 1.0)
    nt, nl = times.size, len(arm.frames)
    root, tip, energy = np.zeros((nt, nl, 3)), np.zeros((nt, nl, 3)), np.zeros(nt)
    Rl, Rt = np.zeros((nt, nl, 3, 3)), np.zeros((nt, nl, 3, 3))
    for r in range(nt):
        energy[r] = pin.computeMechanicalEnergy(arm.model, arm.data, q[r], v[r])
        pin.updateFramePlacements(arm.model, arm.data)
        for i, (fr, ft) in enumerate(arm.frames):
            root[r, i] = arm.data.oMf[fr].translation
            tip[r, i] = arm.data.oMf[ft].translation
            Rl[r, i] = arm.data.oMf[fr].rotation
            Rt[r, i] = arm.data.oMf[ft].rotation
    closures = {}
    if len(arm.cms):
        model = arm.case.model
        rc = resolve_closures(model, *rigid_tip_frames(model, initial_angles(arm.case)))
        gap, ang = np.zeros((nt, len(arm.cms))), np.zeros((nt, len(arm.cms)))
        for r in range(nt):
            gap[r], ang[r] = closure_gaps(rc, Rt[r], tip[r])
        closures = {"closure_loads": loads, "closure_residual": gap, "closure_angle_residual": ang}
    return SpatialResult(
        **closures,
        t=times,
        joint_angle=q,
        joint_rate=v,
        joint_torque=tau,
        link_root=root,
        link_tip=tip,
        tip_deflection=np.zeros((nt, nl, 2)),
        end_effector=tip[:, arm.ee].copy(),
        wall_time=wall,
        n_steps=int(n_steps),
        meta=dict(meta),
        energy=energy,
        status=status,
        twist=np.zeros((nt, nl)),
        link_rotation=Rl,
        tip_rotation=Rt,
        link_shapes=straight_shapes(root, tip, shape_points) if shape_points else None,
    )


def check_case(case):
    """Refuse (InputError) what this baseline cannot run, on the case alone (what
    :func:`simulate` refuses whatever its h and options): not a spatial case, external loads,
    a closed-loop drive with moment feedback, an arm :func:`build_model` refuses."""
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase")
    require_no_loads(case, "pinocchio-spatial")
    _Arm(case)  # the model, the closures' constraints, the closed-loop drives


def simulate(
    case, *, h, integrator="rk4", elements_per_link=None, shape_points=0, **options
) -> SpatialResult:
    """Simulate a spatial case with rigid links (Pinocchio).

    Parameters
    ----------
    case : dttmm.spatial.SpatialCase
    h : float
        Step size (s); for ``"dop853"`` the first trial step of each restart (the step size is
        adaptive; limit it with the option ``max_step``).
    integrator : {"rk4", "newmark", "dop853"}
        Newmark options: ``tol`` (1e-12, relative Newton correction), ``max_iter`` (25).
        DOP853 (scipy's adaptive solver, restarted at every drive jump) options: ``rtol``
        (1e-12), ``atol`` (1e-12), ``max_step`` (inf). Closed-loop drives (docs/control.md)
        and closed loops run with ``"rk4"`` only.
    elements_per_link : ignored (rigid links); accepted for the common call.
    shape_points : p ≥ 2 records ``link_shapes`` (nt, n, p, 3): straight links from root to tip
        (:func:`dttmm.shapes.straight_shapes`); 0 (default): none.

    Returns
    -------
    dttmm.spatial.SpatialResult
        On the scenario's output grid; ``energy`` is kinetic + gravitational potential
        (Pinocchio's, zero at the world origin).

    Raises
    ------
    dttmm.InputError
        Bad case, h, integrator or option; a closed-loop drive with moment feedback.
    dttmm.SimulationError
        Non-finite state (``partial`` holds the outputs so far).
    """
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase")
    return run(case, h, integrator, options, check_shape_points(shape_points))


def _options(integrator, options):
    """The integrator's options with their defaults, checked."""
    _checks.integrator(integrator, INTEGRATORS)
    known = INTEGRATORS[integrator]
    _checks.integrator_options(integrator, options, known)
    opts = {**known, **options}
    if "tol" in opts:
        opts["tol"] = plumbing.positive_number("tol", opts["tol"])
        opts["max_iter"] = plumbing.positive_integer("max_iter", opts["max_iter"])
    for key in ("rtol", "atol", "max_step"):
        if key in opts:
            try:
                x = float(opts[key])
            except (TypeError, ValueError):
                raise InputError(key, opts[key], "must be a number") from None
            if not x > 0:
                raise InputError(key, opts[key], "must be positive")
            opts[key] = x
    return opts


def run(case, h, integrator, options, shape_points=0, method="pinocchio-spatial") -> SpatialResult:
    """:func:`simulate` on a checked spatial case; ``method`` names the run in its meta and
    refusals (the planar baseline :mod:`reference_models.pinocchio_rigid` runs here)."""
    h = plumbing.step_size(h, case.scenario.duration)
    opts = _options(integrator, options)
    require_no_loads(case, method)
    if case.model.closures and integrator != "rk4":
        raise InputError(
            "integrator", integrator, f"closed loops run with rk4 only in {method} (constraintDynamics)"
        )
    arm = _Arm(case, method)
    if arm.closed and integrator != "rk4":
        raise InputError("integrator", integrator, f"closed-loop drives run with rk4 only in {method}")
    scen = case.scenario
    T, restart = step_schedule(scen.duration, h, scen.breakpoints)
    q = np.array([d.initial_angle for d in arm.drives], float)
    v = np.array([d.initial_rate for d in arm.drives], float)
    arm.prescribe(0.0, False, q, v)
    nodes = []
    arm.meta = {
        "method": method,
        "h": float(h),
        "integrator": integrator,
        "elements_per_link": None,
        "versions": {**plumbing.versions(), "pinocchio": pin.__version__},
        **opts,
    }
    step = {"rk4": _rk4, "newmark": _newmark, "dop853": _dop853}[integrator]
    wall0 = time.perf_counter()
    with np.errstate(over="ignore", invalid="ignore"):  # non-finite states are caught and reported
        stats = step(arm, T, restart, q, v, opts, nodes)
    wall = time.perf_counter() - wall0
    n_steps = stats.pop("n_steps", T.size)
    meta = {**arm.meta, **stats, "time_per_step": wall / max(n_steps, 1)}
    status = "unconverged" if meta.get("unconverged_steps") else "ok"
    return _result(arm, nodes, scen.output_times, h, n_steps, meta, status, wall, shape_points)
