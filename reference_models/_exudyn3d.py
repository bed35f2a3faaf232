"""The spatial arm of the Exudyn peers (the family's skeleton: :mod:`reference_models._exudyn_common`),
shared by :mod:`exudyn_beam3d` and :mod:`exudyn_ancf3d`: the undeformed frames at t = 0, the
tip loads, the system under construction (:class:`Arm`: ground, rigid markers, rigid bodies,
Euler-parameter nodes, the joints with their drives, the loads at the link tips and the drive
inputs), the dynamic run (:class:`Run`: the sensors of the link frames, motion joints and beam
nodes, the segmented ``SolveDynamic`` run, the conversion of what they stored into the
:class:`dttmm.spatial.SpatialResult` fields: link frames, tip deflections, twist, joint angles,
rates and torques, link shapes) and the static solution's fields.

An adapter builds its own links (elements, nodes, bodies) on an :class:`Arm` and hands over the
nodes whose frame is the link's root and tip frame (``rolls``: the section roll Rx(roll) of the
node frames, None where the node frame is the link frame itself; ``reach``: a rigid link's tip
beyond its node).
"""

from __future__ import annotations

import numpy as np

from dttmm.errors import InputError, SimulationError
from dttmm.shapes import straight_shapes
from dttmm.spatial import SpatialCase, SpatialResult, load_case
from dttmm.spatial.rotation import log_so3

from ._exudyn_common import (
    gravity_loads,
    import_exudyn,
    link_shapes,
    node_sensors,
    set_pre_step,
    shape_sensors,
    solve,
)
from ._spatial_mechanics import rot_axis, rpy_matrix

__all__ = [
    "Arm",
    "Run",
    "all_loads",
    "as_case",
    "axis_frame",
    "check_tip_loads",
    "frame_outputs",
    "initial_joint_states",
    "joint_outputs",
    "reference_frames",
    "solve_static",
    "static_frames",
]


def as_case(case) -> SpatialCase:
    """The case itself, or the spatial case read from a path; anything else is refused."""
    if isinstance(case, str) or hasattr(case, "__fspath__"):
        case = load_case(case)
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase or a path to one")
    return case


def axis_frame(a) -> np.ndarray:
    """A rotation A with A·e_z = a (columns: two unit vectors normal to a, then a)."""
    a = np.asarray(a, float)
    t = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(t, a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


def initial_joint_states(case: SpatialCase):
    """The joint angles and rates at t = 0, one per link (0 for a locked joint)."""
    alpha, rate = [], []
    drives = iter(case.scenario.drives)
    for link in case.model.links:
        if link.joint.locked:
            alpha.append(0.0)
            rate.append(0.0)
            continue
        d = next(drives)
        if d.kind == "motion":
            a = d.motion(0.0, False)
            alpha.append(float(a[0]))
            rate.append(float(a[1]))
        else:
            alpha.append(float(d.initial_angle))
            rate.append(float(d.initial_rate))
    return alpha, rate


def reference_frames(case: SpatialCase):
    """Undeformed frames at t = 0: per link (R_J, p_J, R_link, p_link, R_tip, p_tip, ω, a_W)
    with ω the rigid angular velocity of the link (world) from the initial joint rates and a_W
    the joint axis in the world; a link's joint hangs on its parent's tip frame (the base for a
    root link)."""
    m = case.model
    alpha, rate = initial_joint_states(case)
    out = []
    for i, link in enumerate(m.links):
        par = m.parents[i]
        if par < 0:
            R_par, p_par, om = rpy_matrix(m.base_rpy), np.array(m.base_xyz, float), np.zeros(3)
        else:
            R_par, p_par, om = out[par]["R_tip"], out[par]["p_tip"], out[par]["omega"]
        j = link.joint
        R_J = R_par @ rpy_matrix(j.origin_rpy)
        p_J = p_par + R_par @ np.array(j.origin_xyz, float)
        a = np.array(j.axis, float)
        aw = R_J @ a
        R_l = R_J @ rot_axis(a, alpha[i])
        om = om + aw * rate[i]
        L = link.beam.length
        p_t = p_J + R_l @ np.array([L, 0.0, 0.0])
        out.append(
            dict(R_J=R_J, p_J=p_J, R_link=R_l, p_link=p_J, R_tip=R_l, p_tip=p_t, omega=om.copy(), a_w=aw)
        )
    return out


def _piecewise(times, values):
    times = np.asarray(times, float)
    values = np.asarray(values, float)
    return lambda t: float(np.interp(t, times, values))


def _case_load(ld, n: int):
    """(link, F, T, law(t, left=False)) of a SpatialLoad of the case's scenario."""
    law = lambda t, left=False, f=ld.factor: float(f(t, left))  # noqa: E731
    return ld.link_index(n), np.array(ld.force, float), np.array(ld.moment, float), law


def check_tip_loads(case, tip_loads, followers=False):
    """The world loads at link tips: the case's ``scenario.loads`` in the world frame, then the
    option ``tip_loads``, as (link, F, T, law(t, left=False)) per load. A follower load of the
    case (frame "tip") is refused unless ``followers`` (then it is left to
    :func:`follower_loads`)."""
    out = []
    n = case.model.n_links
    for j, ld in enumerate(getattr(case.scenario, "loads", ())):
        if not ld.follower:
            out.append(_case_load(ld, n))
        elif not followers:
            raise InputError(
                f"scenario.loads[{j}].frame", ld.frame, "follower loads are not supported by this peer"
            )
    for n_, item in enumerate(tip_loads or ()):
        where = f"tip_loads[{n_}]"
        if not isinstance(item, dict) or set(item) - {"link", "force", "torque", "times", "factors"}:
            raise InputError(where, item, "must be a dict with keys link, force, torque, times, factors")
        i = item.get("link")
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < case.model.n_links:
            raise InputError(f"{where}.link", i, f"must be a link index in 0..{case.model.n_links - 1}")
        vecs = []
        for key in ("force", "torque"):
            v = np.asarray(item.get(key, (0.0, 0.0, 0.0)), float)
            if v.shape != (3,) or not np.isfinite(v).all():
                raise InputError(f"{where}.{key}", item.get(key), "must be 3 finite numbers (world frame)")
            vecs.append(v)
        tt = np.asarray(item.get("times", (0.0, case.scenario.duration)), float)
        ff = np.asarray(item.get("factors", (1.0, 1.0)), float)
        if tt.ndim != 1 or tt.shape != ff.shape or tt.size < 1 or np.any(np.diff(tt) <= 0):
            raise InputError(f"{where}.times", item.get("times"), "must increase and match factors in length")
        pw = _piecewise(tt, ff)
        out.append((i, vecs[0], vecs[1], lambda t, left=False, f=pw: f(t)))
    return out


def follower_loads(case):
    """The case's follower loads (frame "tip"), as (link, F, T, law(t, left=False)) with F, T in
    the tip frame."""
    n = case.model.n_links
    return [_case_load(ld, n) for ld in getattr(case.scenario, "loads", ()) if ld.follower]


def all_loads(case, tip_loads):
    """(link, F, T, law, follower) of every tip load of a run."""
    world = [(*x, False) for x in check_tip_loads(case, tip_loads, followers=True)]
    return world + [(*x, True) for x in follower_loads(case)]


def _ancestors(model, i) -> list:
    """Link i and the links it hangs from, base first."""
    out = [i]
    while model.parents[out[-1]] >= 0:
        out.append(model.parents[out[-1]])
    return out[::-1]


class Arm:
    """The Exudyn system of a spatial case under construction (not assembled): the ground, the
    rigid bodies and markers, the joints and drives, the tip loads and the drive inputs; an
    adapter adds its links and fills ``root_nodes``, ``tip_nodes`` (the nodes whose frames are
    the link's root and tip frames) and ``kmax`` (its largest element stiffness)."""

    def __init__(self, case, who: str):
        exu, ii = import_exudyn(who)
        self.exu, self.ii, self.case = exu, ii, case
        self.frames = reference_frames(case)
        self.rates = initial_joint_states(case)[1]
        self.g = np.array(case.model.gravity, float)
        self.has_g = bool(np.any(self.g != 0.0))
        self.SC = exu.SystemContainer()
        mbs = self.mbs = self.SC.AddSystem()
        self.ground = mbs.AddNode(ii.NodePointGround())
        self.ground_body = mbs.AddObject(ii.ObjectGround())
        self.carrier = {}  # node -> rigid body on it (for markers away from the node)
        self.bodies = []  # (body, node, centre of mass, mass)
        self.inputs = []  # (load, law, vector): what set_inputs sets
        self.motion_joints = {}
        self.root_nodes, self.tip_nodes = [], []
        self.kmax = 0.0

    def velocity(self, i, p) -> np.ndarray:
        """Rigid velocity at t = 0 of the point p of link i (from the initial joint rates)."""
        fr = self.frames
        terms = (
            np.cross(fr[m]["a_w"], p - fr[m]["p_J"]) * self.rates[m] for m in _ancestors(self.case.model, i)
        )
        return sum(terms, np.zeros(3))

    def ep_node(self, i, p, R):
        """A NodeRigidBodyEP at p with the frame R, moving rigidly with link i at t = 0."""
        from exudyn.rigidBodyUtilities import (
            AngularVelocity2EulerParameters_t,
            RotationMatrix2EulerParameters,
        )

        ep = np.array(RotationMatrix2EulerParameters(R))
        ep_t = AngularVelocity2EulerParameters_t(self.frames[i]["omega"], ep)
        return self.mbs.AddNode(
            self.ii.NodeRigidBodyEP(
                referenceCoordinates=list(p) + list(ep),
                initialVelocities=list(self.velocity(i, p)) + list(ep_t),
            )
        )

    def add_body(self, nd, mass, c, J):
        """A rigid body on node ``nd``: mass, centre c and inertia J about the node (node frame)."""
        mbs, ii = self.mbs, self.ii
        body = mbs.AddObject(
            ii.ObjectRigidBody(
                nodeNumber=nd,
                mass=float(mass),
                inertia=[J[0, 0], J[1, 1], J[2, 2], J[1, 2], J[0, 2], J[0, 1]],
                centerOfMass=list(c),
            )
        )
        self.bodies.append((body, nd, c, float(mass)))
        self.carrier.setdefault(nd, body)
        if self.has_g and mass > 0:
            gravity_loads(mbs, ii, [body], list(self.g))
        return body

    def rigid_marker(self, nd, R=None, p=None):
        """A rigid marker on node ``nd`` with the frame R at the point p (node frame)."""
        mbs, ii, exu = self.mbs, self.ii, self.exu
        R = np.eye(3) if R is None else R
        p = np.zeros(3) if p is None else p
        if not np.any(p):
            return mbs.AddMarker(ii.MarkerNodeRigid(nodeNumber=nd, localHT=exu.HT(rotation=R)))
        if nd == self.ground:
            body = self.ground_body
        elif nd in self.carrier:
            body = self.carrier[nd]
        else:  # a massless body on the node carries the offset marker
            body = self.carrier[nd] = mbs.AddObject(ii.ObjectRigidBody(nodeNumber=nd, mass=0.0))
        return mbs.AddMarker(
            ii.MarkerBodyRigid(bodyNumber=body, localHT=exu.HT(rotation=R, translation=list(p)))
        )

    def add_joints(self, child, rolls=None, reach=None) -> None:
        """The joints and their drives: an ``ObjectJointGeneric`` between the parent's marker
        (ground, or the parent's tip node, at the joint origin with the joint frame R_J·A, A
        taking z to the axis) and link i's root node, whose marker frame is ``child[i]``·A in
        the node frame; locked: all six axes; motion drive: all six, the angle prescribed by
        the offset user function; torque drive: the rotation about the axis free, a body-fixed
        ``LoadTorqueVector`` pair ±τ·a set by :meth:`set_inputs`."""
        mbs, ii, model, frames = self.mbs, self.ii, self.case.model, self.frames
        drives = iter(self.case.scenario.drives)
        for i, link in enumerate(model.links):
            fr, j = frames[i], link.joint
            par = model.parents[i]
            if par < 0:
                parent, R_pn, p_pn = self.ground, np.eye(3), np.zeros(3)
            else:
                parent, R_pn, p_pn = self.tip_nodes[par], frames[par]["R_tip"], frames[par]["p_tip"]
                if rolls is not None:
                    R_pn = R_pn @ rolls[par]
                if reach is not None:
                    p_pn = p_pn - frames[par]["R_tip"] @ reach[par]  # the node's position
            A = np.eye(3) if j.locked else axis_frame(j.axis)
            # marker 0: the joint frame R_J·A at p_J in the parent's node frame
            m0 = self.rigid_marker(parent, R_pn.T @ fr["R_J"] @ A, R_pn.T @ (fr["p_J"] - p_pn))
            m1 = self.rigid_marker(self.root_nodes[i], child[i] @ A)
            if j.locked:
                mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1] * 6))
                continue
            d = next(drives)
            if d.kind == "motion":

                def offset(mbs_, t, item, par, law=d.motion):
                    return [0.0, 0.0, 0.0, 0.0, 0.0, law(t, True)[0]]

                self.motion_joints[i] = mbs.AddObject(
                    ii.ObjectJointGeneric(
                        markerNumbers=[m0, m1], constrainedAxes=[1] * 6, offsetUserFunction=offset
                    )
                )
                continue
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1, 1, 1, 1, 1, 0]))
            a = np.array(j.axis, float)
            targets = [(self.root_nodes[i], child[i] @ a)]
            if par >= 0:
                targets.append((parent, -(R_pn.T @ fr["R_J"] @ a)))
            for nd, vec in targets:
                ld = mbs.AddLoad(
                    ii.LoadTorqueVector(
                        markerNumber=self.rigid_marker(nd), loadVector=[0.0, 0.0, 0.0], bodyFixed=True
                    )
                )
                self.inputs.append((ld, d.torque, vec))

    def add_loads(self, loads, rolls=None, reach=None) -> None:
        """The loads (link, F, T, law, follower) at the link tips: world components, or a
        follower's tip-frame ones turned into the node frame R_tip·Rx(roll), body-fixed."""
        for i, F, T, law, follower in loads:
            mk = self.rigid_marker(self.tip_nodes[i], None, None if reach is None else reach[i])
            if follower:  # tip-frame components -> the node frame R_tip Rx(roll)
                F, T = rolls[i].T @ F, rolls[i].T @ T
            for vec, Load in ((F, self.ii.LoadForceVector), (T, self.ii.LoadTorqueVector)):
                if np.any(vec):
                    ld = self.mbs.AddLoad(
                        Load(markerNumber=mk, loadVector=[0.0] * 3, bodyFixed=bool(follower))
                    )
                    self.inputs.append((ld, law, vec))

    def set_inputs(self, t, left) -> None:
        """Every drive torque and tip load at its law's value at t (left or right limit)."""
        for ld, law, vec in self.inputs:
            self.mbs.SetLoadParameter(ld, "loadVector", list(law(t, left) * vec))


class Run:
    """A dynamic run of an :class:`Arm`: the sensors of the link frames (position, rotation
    matrix, angular velocity of the root and tip nodes), of the motion joints (reaction torque)
    and, for the link shapes, of the beam nodes of the links ``shape_links`` (their elements
    ``shape_elements``, sensor ``variables``); an adapter adds its own sensors to ``sensors``
    before :meth:`solve`."""

    def __init__(self, arm, shape_links=(), shape_elements=None, variables=()):
        mbs, ii = arm.mbs, arm.ii
        self.arm, self.seg_start, self.shape_links = arm, [0.0], list(shape_links)
        if arm.inputs:
            set_pre_step(mbs, arm.set_inputs, self.seg_start)
        OV = self.OV = arm.exu.OutputVariableType
        frame = (OV.Position, OV.RotationMatrix, OV.AngularVelocity)
        self.s_root = node_sensors(mbs, ii, arm.root_nodes, frame)
        self.s_tip = node_sensors(mbs, ii, arm.tip_nodes, frame)
        self.s_mot = {
            i: mbs.AddSensor(
                ii.SensorObject(
                    objectNumber=c, outputVariableType=OV.TorqueLocal, storeInternal=True, writeToFile=False
                )
            )
            for i, c in arm.motion_joints.items()
        }
        self.s_shape = shape_sensors(mbs, ii, shape_elements, variables) if shape_elements is not None else []
        self.sensors = [x for tr in self.s_root + self.s_tip for x in tr] + list(self.s_mot.values())
        self.sensors += [x for link in self.s_shape for node in link for x in node]

    def solve(self, method, h, rho_inf, rel_tol, abs_tol, max_iterations, modified_newton, quiet=False):
        """Assemble, run the segments; returns None, or why the run stopped. Afterwards
        :meth:`stored` reads a sensor on the output grid."""
        arm, sc = self.arm, self.arm.case.scenario
        arm.mbs.Assemble()
        newton = (rho_inf, rel_tol, abs_tol, max_iterations, modified_newton)
        run, grid = solve(
            arm.mbs, arm.exu, sc, h, self.sensors, arm.set_inputs, self.seg_start, newton, quiet=quiet
        )
        self.run, t_out = run, sc.output_times

        def stored(sn):  # the values on the output grid (nt, width); a count that misses it is an error
            d = grid(sn)
            if len(d) != len(t_out):
                raise SimulationError(
                    f"Exudyn {method}: {len(d)} sensor rows for {len(t_out)} outputs",
                    t=run.n_steps * h,
                    step=run.steps,
                    component="sensors",
                )
            return d[:, 1:]

        self.stored = stored
        if not run.ok:
            return f"SolveDynamic failed at t = {run.t_reached}" + (f": {run.error}" if run.error else "")
        return run.short

    def fail(self, method, failure):
        raise SimulationError(
            f"Exudyn {method}: {failure}", t=self.run.t_reached, step=self.run.steps, component="newton"
        )

    def meta(self, method, k, h, rho_inf, rel_tol, abs_tol, modified_newton, **specific) -> dict:
        """The run's meta: its settings and counts (and ``specific``, the adapter's)."""
        run, sd = self.run, self.arm.mbs.systemData
        return dict(
            method=method,
            elements_per_link=k,
            h=h,
            **specific,
            integrator="generalized-alpha",
            rho_inf=float(rho_inf),
            newton_rel_tol=rel_tol,
            newton_abs_tol=abs_tol,
            modified_newton=bool(modified_newton),
            jacobian_per_step=True,
            linear_solver="EigenSparse",
            newton_iterations_per_step=run.newton / max(run.steps, 1),
            ode2_size=int(sd.ODE2Size()),
            ae_size=int(sd.AEsize()),
            restarts=[float(x) for x in run.restarts],
            wall_time_solve=run.wall,
            cpu_time=run.cpu,
            exudyn=self.arm.exu.__version__,
        )

    def fields(self, end_effector, rolls=None, reach=None, shape_points=0) -> dict:
        """The SpatialResult's fields from the stored sensors (``rolls``, ``reach``: as
        :func:`frame_outputs`); the links without beam nodes are drawn straight."""
        case, stored = self.arm.case, self.stored
        t_out = case.scenario.output_times
        nt = len(t_out)
        root, tip, Rl, Rt, w_root, w_tip, defl, twist = frame_outputs(
            stored, self.s_root, self.s_tip, nt, rolls, reach
        )
        ja, jr, jt = joint_outputs(case, Rl, Rt, w_root, w_tip, stored, self.s_mot, t_out)
        shapes = None
        if shape_points:
            nodes = [[np.hstack([stored(x) for x in node]) for node in link] for link in self.s_shape]
            shapes = straight_shapes(root, tip, shape_points)  # the rigid links'
            if self.shape_links:
                links = [case.model.links[i] for i in self.shape_links]
                shapes[:, self.shape_links] = link_shapes(links, nodes, shape_points)
        return dict(
            t=t_out,
            link_shapes=shapes,
            joint_angle=ja,
            joint_rate=jr,
            joint_torque=jt,
            link_root=root,
            link_tip=tip,
            tip_deflection=defl,
            end_effector=tip[:, end_effector].copy(),
            twist=twist,
            link_rotation=Rl,
            tip_rotation=Rt,
        )

    def result(self, fields, meta, **extra) -> SpatialResult:
        return SpatialResult(**fields, wall_time=self.run.wall, n_steps=self.run.steps, meta=meta, **extra)


def frame_outputs(stored, s_root, s_tip, nt: int, rolls=None, reach=None):
    """Link roots and tips (nt, n, 3), link and tip frames (nt, n, 3, 3) (the node frames with
    their section roll taken off), the root and tip angular velocities (nt, n, 3), the tip
    deflections (nt, n, 2) and the twist (nt, n). ``reach``: per link the tip's offset from its
    tip node in the tip frame (a rigid link's L·x), None where the tip node is the tip."""
    root = np.stack([stored(x[0]) for x in s_root], axis=1)
    if rolls is None:
        Rl = np.stack([stored(x[1]).reshape(nt, 3, 3) for x in s_root], axis=1)
        Rt = np.stack([stored(x[1]).reshape(nt, 3, 3) for x in s_tip], axis=1)
    else:
        Rl = np.stack([stored(x[1]).reshape(nt, 3, 3) @ rolls[i].T for i, x in enumerate(s_root)], axis=1)
        Rt = np.stack([stored(x[1]).reshape(nt, 3, 3) @ rolls[i].T for i, x in enumerate(s_tip)], axis=1)
    if reach is None:
        tip = np.stack([stored(x[0]) for x in s_tip], axis=1)
    else:
        tip = np.stack([stored(x[0]) + Rt[:, i] @ reach[i] for i, x in enumerate(s_tip)], axis=1)
    w_root = np.stack([stored(x[2]) for x in s_root], axis=1)
    w_tip = np.stack([stored(x[2]) for x in s_tip], axis=1)
    d = tip - root
    defl = np.stack(
        [np.einsum("tni,tni->tn", d, Rl[..., 1]), np.einsum("tni,tni->tn", d, Rl[..., 2])], axis=-1
    )
    n = root.shape[1]
    twist = np.array([[log_so3(Rl[t_, i].T @ Rt[t_, i])[0] for i in range(n)] for t_ in range(nt)])
    return root, tip, Rl, Rt, w_root, w_tip, defl, twist


def joint_outputs(case, Rl, Rt, w_root, w_tip, stored, s_mot, t_out):
    """Angles (unwrapped, continuing the initial angle), rates and torques (nt, m) of the
    unlocked joints: the angle from the relative rotation of the joint frame and the link frame
    about the axis; a motion drive's torque is its joint's reaction moment about the axis (0 at
    t = 0: no multiplier before the first step), a torque drive's its law."""
    model, sc = case.model, case.scenario
    nt = len(t_out)
    unl = list(model.unlocked)
    ja, jr, jt = np.zeros((nt, len(unl))), np.zeros((nt, len(unl))), np.zeros((nt, len(unl)))
    alpha0, _ = initial_joint_states(case)
    for c_, (i, dr) in enumerate(zip(unl, sc.drives)):
        j = model.links[i].joint
        a = np.array(j.axis, float)
        par = model.parents[i]
        if par < 0:
            R_par = np.broadcast_to(rpy_matrix(model.base_rpy), (nt, 3, 3))
            w_par = np.zeros((nt, 3))
        else:
            R_par, w_par = Rt[:, par], w_tip[:, par]
        R_J = R_par @ rpy_matrix(j.origin_rpy)
        rel = np.einsum("tji,tjk->tik", R_J, Rl[:, i])
        vee = 0.5 * np.stack(
            [rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]], -1
        )
        ang = np.unwrap(np.arctan2(vee @ a, 0.5 * (np.trace(rel, axis1=1, axis2=2) - 1.0)))
        ang += 2 * np.pi * round((alpha0[i] - ang[0]) / (2 * np.pi))
        ja[:, c_] = ang
        jr[:, c_] = np.einsum("ti,ti->t", w_root[:, i] - w_par, R_J @ a)
        if dr.kind == "motion":
            jt[:, c_] = stored(s_mot[i])[:, 2]
            jt[0, c_] = 0.0  # no multiplier before the first step (as the planar peers)
        else:
            jt[:, c_] = [dr.torque(float(t_), t_ > 0) for t_ in t_out]
    return ja, jr, jt


def solve_static(mbs, exu, kmax: float, steps: int, method: str) -> None:
    """``SolveStatic`` in ``steps`` load steps, Newton to 1e-12 relative (1e-14·kmax absolute);
    a failure is a SimulationError."""
    s = exu.SimulationSettings()
    s.staticSolver.newton.relativeTolerance = 1e-12
    s.staticSolver.newton.absoluteTolerance = 1e-14 * kmax
    s.staticSolver.numberOfLoadSteps = steps
    s.staticSolver.verboseMode = 0
    s.solution.file.write = False
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    if not mbs.SolveStatic(s):
        raise SimulationError(f"Exudyn {method}: SolveStatic failed", t=0.0, step=0, component="newton")


def static_frames(mbs, OV, root_nodes, tip_nodes, rolls=None, reach=None) -> dict:
    """The static solution's ``link_root``, ``link_tip`` (n, 3), ``tip_deflection`` (n, 2) (tip
    − root along the root frame's y and z) and ``twist`` (n,) (``rolls``, ``reach``: as
    :func:`frame_outputs`)."""
    root = np.array([mbs.GetNodeOutput(nd, OV.Position) for nd in root_nodes])

    def frame(nd, i):
        R = np.reshape(mbs.GetNodeOutput(nd, OV.RotationMatrix), (3, 3))
        return R if rolls is None else R @ rolls[i].T

    Rl = [frame(nd, i) for i, nd in enumerate(root_nodes)]
    Rt = [frame(nd, i) for i, nd in enumerate(tip_nodes)]
    if reach is None:
        tip = np.array([mbs.GetNodeOutput(nd, OV.Position) for nd in tip_nodes])
    else:
        tip = np.array([mbs.GetNodeOutput(nd, OV.Position) + R @ c for nd, R, c in zip(tip_nodes, Rt, reach)])
    d = tip - root
    return dict(
        link_root=root,
        link_tip=tip,
        tip_deflection=np.array([[di @ R[:, 1], di @ R[:, 2]] for di, R in zip(d, Rl)]),
        twist=np.array([log_so3(a.T @ b)[0] for a, b in zip(Rl, Rt)]),
    )
