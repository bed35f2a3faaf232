"""The planar chain of the Exudyn peers (the family's skeleton: :mod:`reference_models._exudyn_common`).

``exudyn_ancf`` (ObjectANCFCable2D) and ``exudyn_beam`` (ObjectBeamGeometricallyExact2D) differ
only in how one link's beam is meshed and how its ends are tied to the hub and tip bodies; the
hubs, tip bodies, joints, drives, gravity, the sensors' conversion to :class:`dttmm.Result` and
the failure with a partial Result live here, in the passes of the spatial side
(:mod:`reference_models._exudyn3d`): the system under construction (:class:`Arm`: ground, the
links meshed by the element with their hub and tip bodies, the joints with their drives and the
drive inputs) and the dynamic run (:class:`Run`: the sensors, the segmented ``SolveDynamic``
run, its meta, the Result or the failure).

Model conventions (the suite's, see docs/architecture.md and docs/cases.md):

* Planar, counter-clockwise angles, joint 1 at the origin. In the reference configuration every
  link is straight along its root direction θ_root,i = θ_tip,i−1 + α_i(0) (θ_tip,0 = 0).
* Every link owns a rigid **hub** body at its root (``link.hub``: mass, inertia about the joint;
  mass and inertia 0 when absent) and a rigid **tip body** at its tip carrying ``link.payload``
  (mass 0 when absent); the tip body rotates with the tip cross-section.
* Joint i is a revolute joint between the tip body of link i−1 (ground for i = 1) and hub i.
  Torque drive: +τ(t) on hub i, −τ(t) on the tip body of link i−1 (nothing on the ground).
  Motion drive: the relative rotation coordinate is prescribed by an ObjectConnectorCoordinate
  whose offset user function gives α(t) − α(0) (node rotation coordinates are displacements
  from the reference angle); its Lagrange multiplier equals minus the motor torque.
* Initial velocities: rigid rotation of the whole chain with the initial joint rates.
* Gravity: mass-proportional loads on every element and every rigid body with mass.
* Kelvin–Voigt damping D = μK of the link: bending damping μ·EI, axial μ·EA (and shear μ·κGA).

Time integration: Exudyn's generalized-α (spectral radius ``rho_inf``, default 0.8) with a fixed
step h (adaptive step off: a Newton failure is an error, not a silent step halving), modified
Newton with one Jacobian per step (``jacobian_per_step``), EigenSparse linear solver, one
thread, nothing written to files, no graphics.

Drive inputs (``drive_input``): by default the torques are plain loads and the prescribed
angles plain coordinate-constraint offsets, whose values a PreStepUserFunction sets once per
step at the step end time, the way Exudyn's documentation recommends prescribing forces and
actuator values; ``"user-function"`` evaluates them in load/offset user functions at every
residual evaluation instead (same results to round-off, more Python calls per step).

Drive breakpoints (switches of bang-bang torques, the end of a sine law, …): a breakpoint that
lies on the step grid ends an integration segment, and the next segment restarts the integrator
there (state carried over, initial accelerations recomputed), as the suite's step schedule does
(dttmm.timegrid): the step that ends at the switch sees the left limit of the law, the restart
and the steps after it the right limit. Without the restart generalized-α drags a jump in the
acceleration over several steps (O(h) error; measured 0.0125 rad/s in the hub rate of a rigid
rotor with J = 0.1 kg·m² after a 2 N·m jump at h = 1e-3). A breakpoint off the step grid causes
no restart: the law is evaluated as a left limit at step ends, so the jump takes effect at the
first step end after it (listed in ``meta["breakpoints_off_grid"]``). The reported torque of a
torque drive is the value that acted on the step ending at the output time (left limit; at
t = 0 the right limit).

Closed-loop drives (``pd``, ``pid``, user laws): the law is the user function of a coordinate
spring-damper between the joint's two rotation coordinates, evaluated implicitly at the step end
(no lag; generalized-α keeps its second order); moment feedback enters partly as constant mass
coupling. Details: :mod:`reference_models._exudyn_control`. The reported torque of such a joint
is the law's τ at the converged step.

Torque of a motion drive: minus the multiplier of the coordinate constraint (index-3 generalized-α).
It is less accurate than the positions (it carries the high-frequency content of the stiff
links; measured first order in h on a soft strip) and at t = 0 it reads 0, because no multiplier
exists before the first step. The initial accelerations Exudyn computes ignore the prescribed
α̈(0); for laws with α̈(0) ≠ 0 the start is slightly inconsistent (tip deflections still converge
at second order in h, measured).

Output grid: sensors are stored internally (every output step, or every step when a restart lies
off the output grid); h must divide ``scenario.output_step`` (else :class:`dttmm.InputError`;
no interpolation), and the run ends at the last output time.

Newton: absolute tolerance scaled to the residual's round-off floor (see ``_default_abs_tol``),
relative 1e-8, at most 25 iterations; a Newton failure, a short run, a sensor grid mismatch or a
non-finite output raises :class:`dttmm.SimulationError` (with a partial Result when possible).
"""

from __future__ import annotations

import math

import numpy as np

from dttmm import InputError, SimulationError, make_result, plumbing
from dttmm.case import Case
from dttmm.model import require_flexible
from dttmm.shapes import shape_points as _shape_points

from ._exudyn_common import (
    gravity_loads,
    import_exudyn,
    link_shapes,
    node_sensors,
    output_grid,
    set_pre_step,
    shape_sensors,
    solve,
)
from ._exudyn_control import ClosedLoop

__all__ = [
    "simulate_exudyn",
    "Arm",
    "Run",
    "check_discretisation",
    "stiff_axial_stiffness",
    "INEXTENSIBLE_AXIAL_RATIO",
    "DRIVE_INPUTS",
]

#: How drive values reach Exudyn: set once per step by a PreStepUserFunction (default), or by
#: load/offset user functions evaluated at every residual evaluation (the slower, older way).
DRIVE_INPUTS = ("pre-step", "user-function")

#: EA used for links given as inextensible (EA None): EA = ratio · EI / L².
#: 1e6 corresponds to a slenderness L/r = 1000 (r the radius of gyration); the axial strain
#: is then below F·L²/(1e6·EI), negligible against the bending deflections of the suite.
INEXTENSIBLE_AXIAL_RATIO = 1.0e6

_EPS = np.finfo(float).eps


def stiff_axial_stiffness(beam, ratio: float = INEXTENSIBLE_AXIAL_RATIO) -> float:
    """Axial stiffness EA (N) used for ``beam``: its own EA, or ratio·EI/L² when inextensible."""
    if beam.EA is not None:
        return float(beam.EA)
    return float(ratio) * beam.EI / beam.length**2


def check_discretisation(case, elements_per_link, h) -> tuple[int, float, int, int]:
    """Validate (k, h) against the case. Returns (k, h, n_steps, steps_per_output)."""
    k, h = plumbing.discretisation(case, elements_per_link, h)
    require_flexible(case.model, "the Exudyn beams (flexible links, bodies on the beam axis)")
    per_out, n_steps = output_grid(
        case.scenario, h, " (the Exudyn models sample on the step grid, no interpolation)"
    )
    return k, h, n_steps, per_out


def _rot(a: float) -> np.ndarray:
    return np.array([math.cos(a), math.sin(a)])


def _rigid_velocity(p, joints, rates) -> np.ndarray:
    """Velocity of point p moving rigidly with joints (positions) turning at the given rates."""
    v = np.zeros(2)
    for r, w in zip(joints, rates):
        d = np.asarray(p) - r
        v += w * np.array([-d[1], d[0]])
    return v


class _Layout:
    """Reference geometry and rigid initial velocities of the chain."""

    def __init__(self, case: Case):
        self.root, self.theta, self.omega, self.joint_pos, self.alpha0 = [], [], [], [], []
        th, om, pos = 0.0, 0.0, np.zeros(2)
        rates = []
        for link, drive in zip(case.model.links, case.scenario.drives):
            th += drive.initial_angle
            om += drive.initial_rate
            self.joint_pos.append(pos.copy())
            rates.append(drive.initial_rate)
            self.root.append(pos.copy())
            self.theta.append(th)
            self.omega.append(om)
            self.alpha0.append(drive.initial_angle)
            pos = pos + link.beam.length * _rot(th)
        self._rates = rates

    def point(self, i: int, s: float) -> np.ndarray:
        """Reference position of arc length s along link i."""
        return self.root[i] + s * _rot(self.theta[i])

    def velocity(self, i: int, s: float) -> np.ndarray:
        """Rigid initial velocity of arc length s along link i."""
        return _rigid_velocity(self.point(i, s), self.joint_pos[: i + 1], self._rates[: i + 1])

    def rigid_node(self, mbs, ii, i: int, s: float):
        """A NodeRigidBody2D at arc length s of link i (reference configuration, rigid velocity)."""
        p, v = self.point(i, s), self.velocity(i, s)
        return mbs.AddNode(
            ii.NodeRigidBody2D(
                referenceCoordinates=[p[0], p[1], self.theta[i]],
                initialVelocities=[v[0], v[1], self.omega[i]],
            )
        )


def clamp(mbs, ii, body, beam_node) -> None:
    """Clamp a rigid body to a beam node: x, y and the rotation about z locked."""
    m0 = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=body))
    m1 = mbs.AddMarker(ii.MarkerNodeRigid(nodeNumber=beam_node))
    mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1, 1, 0, 0, 0, 1]))


def joint_markers(mbs, ii, i, m_ground_pos, m_ground_coord, tip_bodies, hub_bodies, tip_nodes, hub_nodes):
    """The revolute joint i between the tip body of link i−1 (the ground for i = 0) and hub i;
    returns the markers of the rotation coordinates it turns (a drive's connector acts on them)."""
    m_in = (
        m_ground_pos
        if i == 0
        else mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=tip_bodies[i - 1], localPosition=[0, 0, 0]))
    )
    m_out = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=hub_bodies[i], localPosition=[0, 0, 0]))
    mbs.AddObject(ii.ObjectJointRevolute2D(markerNumbers=[m_in, m_out]))

    def coordinates():
        c_in = (
            m_ground_coord
            if i == 0
            else mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=tip_nodes[i - 1], coordinate=2))
        )
        return c_in, mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=hub_nodes[i], coordinate=2))

    return coordinates


def _default_abs_tol(case, k, axial) -> float:
    """Newton absolute tolerance on the residual (force units), scaled to its round-off floor.

    The residual cannot fall below ~eps·K·|q| with K ≈ EA·k/L the stiffest element stiffness and
    |q| ≈ the extent of the chain; the tolerance sits 10³ above that floor (for the aluminium
    strip, L = 1 m, k = 64: 1e-4; k = 4: 6e-6), and never below 1e-8.
    """
    kmax = max(ea * k / link.beam.length for ea, link in zip(axial, case.model.links))
    extent = sum(link.beam.length for link in case.model.links)
    return max(1e3 * _EPS * kmax * max(extent, 1.0), 1e-8)


def _check_options(
    rho_inf, newton_rel_tol, newton_abs_tol, newton_max_iterations, drive_input, jacobian_per_step, ratio
):
    try:
        rho_inf = float(rho_inf)
    except (TypeError, ValueError):
        raise InputError("rho_inf", rho_inf, "must be a number in [0, 1]") from None
    if not 0.0 <= rho_inf <= 1.0:
        raise InputError("rho_inf", rho_inf, "must be in [0, 1]")
    for name, val in (("newton_rel_tol", newton_rel_tol),) + (
        (("newton_abs_tol", newton_abs_tol),) if newton_abs_tol is not None else ()
    ):
        if not (isinstance(val, (int, float)) and math.isfinite(val) and val > 0):
            raise InputError(name, val, "must be a positive number")
    if (
        isinstance(newton_max_iterations, bool)
        or not isinstance(newton_max_iterations, int)
        or newton_max_iterations < 1
    ):
        raise InputError("newton_max_iterations", newton_max_iterations, "must be an integer >= 1")
    if drive_input not in DRIVE_INPUTS:
        raise InputError("drive_input", drive_input, f"must be one of {', '.join(DRIVE_INPUTS)}")
    if not isinstance(jacobian_per_step, bool):
        raise InputError("jacobian_per_step", jacobian_per_step, "must be True or False")
    if not (isinstance(ratio, (int, float)) and ratio > 0):
        raise InputError("inextensible_axial_ratio", ratio, "must be positive")
    return rho_inf


class Arm:
    """The Exudyn system of a planar case under construction (not assembled): the ground, the
    links meshed by an element (:meth:`add_links`: their beams, hub and tip bodies, clamps and
    gravity), the joints with their drives and the drive inputs (:meth:`add_drives`).

    ``seg_start`` holds the start time of the running integration segment, read by the drives'
    user functions (right limit of a law at a segment start, left limit after it)."""

    def __init__(self, case, who: str):
        exu, ii = import_exudyn(who)
        self.exu, self.ii, self.case = exu, ii, case
        gravity = case.model.gravity
        self.g = [float(gravity[0]), float(gravity[1]), 0.0]
        self.has_g = self.g[0] != 0.0 or self.g[1] != 0.0
        self.layout = _Layout(case)
        self.SC = exu.SystemContainer()
        mbs = self.mbs = self.SC.AddSystem()
        ground = mbs.AddObject(ii.ObjectGround())
        ground_node = mbs.AddNode(ii.NodePointGround())
        self.m_ground_pos = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
        self.m_ground_coord = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
        self.hub_nodes, self.tip_nodes, self.hub_bodies, self.tip_bodies = [], [], [], []
        self.elements = []  # per link, its beam objects
        self.constraints = [None] * case.model.n_links  # per joint, its motion constraint
        self.inputs = []  # (kind, item, law, sign, a0): what set_inputs sets
        self.closed = None  # the closed-loop laws (reference_models._exudyn_control.ClosedLoop)
        self.seg_start = [0.0]

    def add_body(self, node, mass, inertia):
        """A rigid body on ``node`` (mass, inertia about the node), with its gravity load."""
        mbs, ii = self.mbs, self.ii
        body = mbs.AddObject(ii.ObjectRigidBody2D(nodeNumber=node, mass=float(mass), inertia=float(inertia)))
        if self.has_g and mass > 0:
            gravity_loads(mbs, ii, [body], self.g)
        return body

    def add_links(self, element, k, axial, element_options=None) -> None:
        """Every link meshed by ``element`` (see :func:`simulate_exudyn`) with k elements and the
        axial stiffness ``axial[i]``: its beam, the hub body at its root and the tip body at its
        tip (clamped to the beam's end nodes where the element asks for it), gravity on its
        elements."""
        mbs, exu, ii = self.mbs, self.exu, self.ii
        for i, link in enumerate(self.case.model.links):
            hub_node, tip_node, elements, clamps = element.add_link(
                mbs, exu, ii, link, self.layout, i, k, axial[i], **(element_options or {})
            )
            self.elements.append(elements)
            self.hub_nodes.append(hub_node)
            self.tip_nodes.append(tip_node)
            self.hub_bodies.append(self.add_body(hub_node, link.hub_mass, link.hub_inertia))
            self.tip_bodies.append(self.add_body(tip_node, link.payload_mass, link.payload_inertia))
            if clamps is not None:
                for body, beam_node in zip((self.hub_bodies[-1], self.tip_bodies[-1]), clamps):
                    clamp(mbs, ii, body, beam_node)
            if self.has_g:
                gravity_loads(mbs, ii, elements, self.g)

    def add_drives(self, drive_input: str) -> None:
        """The revolute joints (:func:`joint_markers`) and their drives: a closed-loop law as a
        coordinate spring-damper whose user function is the law (implicit at the step end; see
        :mod:`reference_models._exudyn_control`), a torque drive by :meth:`_torque_drive`, a
        motion drive by :meth:`_motion_drive`.

        ``drive_input`` "pre-step" (default): plain loads / constant offsets whose values a
        PreStepUserFunction sets once per step at the step end time (Exudyn's recommended way to
        prescribe forces and actuator values; ``inputs`` lists them for :meth:`set_inputs`);
        "user-function": load and offset user functions that Exudyn calls at every residual
        evaluation (~35 Python calls per step measured)."""
        mbs, ii, case = self.mbs, self.ii, self.case
        if any(d.closed_loop for d in case.scenario.drives):
            self.closed = ClosedLoop(case, self.layout.alpha0, self.hub_nodes, self.tip_nodes)
        for i, drive in enumerate(case.scenario.drives):
            coordinates = joint_markers(
                mbs,
                ii,
                i,
                self.m_ground_pos,
                self.m_ground_coord,
                self.tip_bodies,
                self.hub_bodies,
                self.tip_nodes,
                self.hub_nodes,
            )
            if drive.closed_loop:
                self.closed.add_joint(mbs, self.exu, ii, i, *coordinates())
            elif drive.kind == "torque":
                self._torque_drive(i, drive, drive_input)
            else:
                self._motion_drive(i, drive, *coordinates(), drive_input)

    def _torque_drive(self, i, drive, drive_input: str) -> None:
        """Torque drive i: +τ(t) on hub i, −τ(t) on the tip body of link i−1 (nothing on the
        ground), as loads set by :meth:`set_inputs` or as load user functions."""
        mbs, ii, seg_start = self.mbs, self.ii, self.seg_start
        targets = [(self.hub_bodies[i], 1.0)] + ([(self.tip_bodies[i - 1], -1.0)] if i > 0 else [])
        for body, sign in targets:
            marker = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=body))
            if drive_input == "pre-step":
                load = mbs.AddLoad(ii.LoadTorqueVector(markerNumber=marker, loadVector=[0, 0, 0]))
                self.inputs.append(("load", load, drive.torque, sign, 0.0))
            else:
                # right limit at the segment start, left limit everywhere after it (see module doc)
                def tau_user(mbs_, t, load, tau=drive.torque, sign=sign):
                    return [0.0, 0.0, sign * tau(t, t > seg_start[0])]

                mbs.AddLoad(
                    ii.LoadTorqueVector(
                        markerNumber=marker, loadVector=[0, 0, 0], loadVectorUserFunction=tau_user
                    )
                )

    def _motion_drive(self, i, drive, c_in, c_out, drive_input: str) -> None:
        """Motion drive i: a coordinate constraint between the rotation coordinates ``c_in`` and
        ``c_out`` whose offset is α(t) − α(0), set by :meth:`set_inputs` or by an offset user
        function; kept in ``constraints[i]`` (its force is minus the motor torque)."""
        mbs, ii, seg_start = self.mbs, self.ii, self.seg_start
        if drive_input == "pre-step":
            self.constraints[i] = mbs.AddObject(
                ii.ObjectConnectorCoordinate(markerNumbers=[c_in, c_out], offset=0.0)
            )
            self.inputs.append(("offset", self.constraints[i], drive.motion, 1.0, self.layout.alpha0[i]))
        else:

            def offset(mbs_, t, item, off, motion=drive.motion, a0=self.layout.alpha0[i]):
                return motion(t, t > seg_start[0])[0] - a0

            self.constraints[i] = mbs.AddObject(
                ii.ObjectConnectorCoordinate(markerNumbers=[c_in, c_out], offsetUserFunction=offset)
            )

    def set_inputs(self, t, left) -> None:
        """Set every drive input to its law's value at t (left or right limit)."""
        mbs = self.mbs
        for kind, item, law, sign, a0 in self.inputs:
            if kind == "load":
                mbs.SetLoadParameter(item, "loadVector", [0.0, 0.0, sign * law(t, left)])
            else:
                mbs.SetObjectParameter(item, "offset", law(t, left)[0] - a0)


class Run:
    """A dynamic run of an :class:`Arm`: the drive inputs' PreStepUserFunction and the closed
    loops' PostStepUserFunction, the sensors (position, rotation and angular velocity of the hub
    and tip nodes, the force of the motion constraints, the closed loops' own, and for the link
    shapes the total coordinates of the beam nodes), the segmented ``SolveDynamic`` run
    (:meth:`solve`), its meta (:meth:`meta`) and the conversion of what the sensors stored into a
    :class:`dttmm.Result`, or a SimulationError with a partial Result (:meth:`result`)."""

    def __init__(self, arm, method: str, shape_points: int):
        mbs, ii, closed = arm.mbs, arm.ii, arm.closed
        self.arm, self.method, self.shape_points = arm, method, shape_points
        if arm.inputs:
            set_pre_step(mbs, arm.set_inputs, arm.seg_start)
        if closed is not None:

            def post_step(mbs_, t):
                closed.post_step(mbs_, t)  # commit the integral states of the converged step
                return True

            mbs.SetPostStepUserFunction(post_step)
        OV = arm.exu.OutputVariableType
        frame = (OV.Position, OV.Rotation, OV.AngularVelocity)
        self.s_hub = node_sensors(mbs, ii, arm.hub_nodes, frame)
        self.s_tip = node_sensors(mbs, ii, arm.tip_nodes, frame)
        self.s_force = [
            None
            if c is None
            else mbs.AddSensor(
                ii.SensorObject(
                    objectNumber=c, outputVariableType=OV.Force, storeInternal=True, writeToFile=False
                )
            )
            for c in arm.constraints
        ]
        self.sensors = [x for tr in self.s_hub + self.s_tip for x in tr] + [
            x for x in self.s_force if x is not None
        ]
        if closed is not None:
            self.sensors += list(closed.sensors.values()) + list(closed.acc_sensors.values())
        self.s_shape = shape_sensors(mbs, ii, arm.elements, (OV.CoordinatesTotal,)) if shape_points else None
        if self.s_shape is not None:
            self.sensors += [x for link in self.s_shape for node in link for x in node]

    def solve(self, h, newton, jacobian_per_step) -> None:
        """Assemble, run the segments (:func:`reference_models._exudyn_common.solve`; ``newton``:
        rho_inf, relative and absolute tolerance, maximum iterations, modified Newton).
        Afterwards ``run`` is the run and :meth:`stored` reads a sensor's stored rows."""
        arm, closed = self.arm, self.arm.closed
        arm.mbs.Assemble()
        if closed is not None:
            closed.assembled(arm.mbs)
        self.h = h
        self.run, self.stored = solve(
            arm.mbs,
            arm.exu,
            arm.case.scenario,
            h,
            self.sensors,
            arm.set_inputs,
            arm.seg_start,
            newton,
            jacobian_per_step,
            closed,
        )

    def meta(self, k, n_steps, newton, jacobian_per_step, drive_input, axial, ratio, specific) -> dict:
        """The run's meta: its settings (``newton`` as for :meth:`solve`), the element's own
        (``specific``), the versions, the counts of the run and, with closed-loop laws, how
        they are evaluated."""
        arm, run, exu = self.arm, self.run, self.arm.exu
        rho_inf, rel_tol, abs_tol, max_iterations, modified_newton = newton
        meta = dict(
            method=self.method,
            elements_per_link=k,
            h=self.h,
            integrator="generalized-alpha",
            rho_inf=rho_inf,
            adaptive_step=False,
            linear_solver="EigenSparse",
            newton_rel_tol=rel_tol,
            newton_abs_tol=abs_tol,
            newton_max_iterations=max_iterations,
            modified_newton=bool(modified_newton),
            jacobian_per_step=bool(jacobian_per_step),
            drive_input=drive_input,
            ode2_size=int(arm.mbs.systemData.ODE2Size()),
            ae_size=int(arm.mbs.systemData.AEsize()),
            exudyn=exu.__version__,
            restarts=[float(b) for b in run.restarts],
            breakpoints_off_grid=[float(b) for b in run.off_grid],
            axial_stiffness=axial,
            inextensible_axial_ratio=float(ratio),
        )
        meta.update(specific)
        try:
            meta["versions"] = {**plumbing.versions(), "exudyn": exu.__version__}
        except Exception:  # versions() is informational only
            meta["versions"] = {"exudyn": exu.__version__}
        meta.update(
            steps=n_steps,
            steps_taken=run.steps,
            newton_iterations=run.newton,
            newton_iterations_per_step=(run.newton / run.steps if run.steps > 0 else float("nan")),
            jacobians=run.jacobians,
            t_reached=run.t_reached,
            wall_time_solve=run.wall,
            cpu_time_solve=run.cpu,
        )
        if arm.closed is not None:
            meta.update(
                closed_loop="implicit: coordinate spring-damper user function at every residual evaluation (t_{n+1})",
                root_moment="tau - J_hub * hub angular acceleration (Newton iterate)",
                integral_state="trapezoidal rule, committed after each step",
                initial_acceleration_solves=run.start_solves,
            )
        return meta

    def series(self):
        """The output times the sensors stored (at most the output grid's) and the Result's
        fields on them: joint angles, rates and torques, link roots, root angles and tips."""
        stored, closed, sc = self.stored, self.arm.closed, self.arm.case.scenario
        s_hub, s_tip, t_out, n = self.s_hub, self.s_tip, sc.output_times, self.arm.case.model.n_links
        ts = stored(s_hub[0][0])[:, 0]
        m = min(len(ts), len(t_out))
        root = np.empty((m, n, 2))
        tip = np.empty((m, n, 2))
        th_root = np.empty((m, n))
        th_tip = np.empty((m, n))
        w_root = np.empty((m, n))
        w_tip = np.empty((m, n))
        tq = np.empty((m, n))
        for i in range(n):
            root[:, i] = stored(s_hub[i][0])[:m, 1:3]
            th_root[:, i] = stored(s_hub[i][1])[:m, -1]
            w_root[:, i] = stored(s_hub[i][2])[:m, -1]
            tip[:, i] = stored(s_tip[i][0])[:m, 1:3]
            th_tip[:, i] = stored(s_tip[i][1])[:m, -1]
            w_tip[:, i] = stored(s_tip[i][2])[:m, -1]
            d = sc.drives[i]
            if d.closed_loop:  # the law's τ at the converged step (the connector force is −τ)
                acc = stored(closed.acc_sensors[i])[:m, -1] if i in closed.acc_sensors else None
                tq[:, i] = closed.torque(i, stored(closed.sensors[i])[:m, -1], acc)
            elif d.kind == "torque":
                # the value that acted on the step ending at the output time (left limit; right at t = 0)
                tq[:, i] = [d.torque(float(tt), tt > 0) for tt in t_out[:m]]
            else:
                tq[:, i] = -stored(self.s_force[i])[:m, -1]
        ja = th_root.copy()
        jr = w_root.copy()
        ja[:, 1:] -= th_tip[:, :-1]
        jr[:, 1:] -= w_tip[:, :-1]
        return ts[:m], dict(
            joint_angle=ja,
            joint_rate=jr,
            joint_torque=tq,
            link_root=root,
            link_root_angle=th_root,
            link_tip=tip,
        )

    def build(self, ts, fields, meta, success):
        """The Result on the output times ``ts`` (the link shapes from the beam nodes' sensors
        where recorded), its meta ``meta`` with ``success``."""
        shapes = None
        if self.s_shape is not None:
            stored = self.stored
            nodes = [
                [np.hstack([stored(x)[: len(ts), 1:] for x in node]) for node in link]
                for link in self.s_shape
            ]
            shapes = link_shapes(self.arm.case.model.links, nodes, self.shape_points)
        return make_result(
            t=self.arm.case.scenario.output_times[: len(ts)],
            **fields,
            wall_time=self.run.wall,
            n_steps=self.run.steps,
            meta={**meta, "success": success},
            link_shapes=shapes,
        )

    def fail(self, reason, t_fail, component, meta):
        """Raise the SimulationError of a failure at ``t_fail``, with the partial Result of what
        the sensors stored where it is finite and on the output grid."""
        run, sc = self.run, self.arm.case.scenario
        t_out = sc.output_times
        partial = None
        try:
            ts, fields = self.series()
            finite = all(np.isfinite(v).all() for v in fields.values())
            if len(ts) and finite and np.allclose(ts, t_out[: len(ts)], rtol=0, atol=1e-6 * sc.output_step):
                partial = self.build(ts, fields, meta, False)
        except Exception:  # the partial result is a courtesy; the error below is what matters
            partial = None
        # Exudyn's currentTime is the end of the step it attempted last
        step = max(int(round(t_fail / self.h)) - 1, 0) if math.isfinite(t_fail) else run.steps
        raise SimulationError(
            f"Exudyn {self.method}: {reason}", t=t_fail, step=step, component=component, partial=partial
        )

    def result(self, meta):
        """The Result of the run, or a SimulationError (:meth:`fail`) where Newton failed, the
        run ended short, the sensors missed the output grid or an output is not finite."""
        run, sc = self.run, self.arm.case.scenario
        t_out = sc.output_times
        if not run.ok:
            err = run.error
            reason = (
                f"SolveDynamic raised {type(err).__name__}: {err}"
                if err is not None
                else "SolveDynamic returned False (Newton did not converge)"
            )
            self.fail(reason, run.t_reached, "newton", meta)
        elif run.short is not None:
            self.fail(run.short, run.t_reached, "time integration", meta)
        ts, fields = self.series()
        if len(ts) != len(t_out) or np.max(np.abs(ts - t_out)) > 1e-6 * sc.output_step:
            self.fail(
                f"sensor rows ({len(ts)}) do not match the output grid ({len(t_out)} samples)",
                float(ts[-1]) if len(ts) else 0.0,
                "sensors",
                meta,
            )
        for name, arr in fields.items():
            bad = ~np.isfinite(arr)
            if bad.any():
                row, *rest = np.argwhere(bad)[0]
                self.fail(
                    f"non-finite {name}", float(t_out[row]), f"{name}[{', '.join(map(str, rest))}]", meta
                )
        return self.build(ts, fields, meta, True)


def simulate_exudyn(
    case,
    *,
    element,
    elements_per_link,
    h,
    rho_inf=0.8,
    newton_rel_tol=1e-8,
    newton_abs_tol=None,
    newton_max_iterations=25,
    modified_newton=True,
    jacobian_per_step=True,
    drive_input="pre-step",
    inextensible_axial_ratio=INEXTENSIBLE_AXIAL_RATIO,
    element_options=None,
    shape_points=0,
):
    """Build the Exudyn model of ``case`` with ``element`` meshing each link, solve, return a Result.

    ``element`` is an object with ``method`` (name), ``meta(case, k, axial)`` (dict),
    ``add_link(mbs, exu, ii, link, layout, i, k, axial_stiffness, **element_options)`` returning
    ``(hub_node, tip_node, elements, clamps)``: ``hub_node``/``tip_node`` are NodeRigidBody2D
    numbers at the link root and tip on which the hub and tip bodies are placed; ``elements`` are
    the beam objects (for gravity); ``clamps`` is None when those nodes are beam nodes, or the
    (root, tip) beam nodes to which the hub and tip bodies are clamped (:func:`clamp`).

    ``shape_points`` p ≥ 2 records ``Result.link_shapes`` from the beam nodes' total coordinates (see
    :func:`reference_models._exudyn_common.link_shapes`); 0 (default) records none.

    The passes: the options, the system (:class:`Arm`: links, joints and drives), the sensors and
    the run (:class:`Run`), its meta, the Result or the failure (:meth:`Run.result`).
    """
    k, h, n_steps, per_out = check_discretisation(case, elements_per_link, h)
    shape_points = _shape_points(shape_points)
    rho_inf = _check_options(
        rho_inf,
        newton_rel_tol,
        newton_abs_tol,
        newton_max_iterations,
        drive_input,
        jacobian_per_step,
        inextensible_axial_ratio,
    )
    arm = Arm(case, f"{element.method} needs")
    axial = [stiff_axial_stiffness(l.beam, inextensible_axial_ratio) for l in case.model.links]
    abs_tol = float(newton_abs_tol) if newton_abs_tol is not None else _default_abs_tol(case, k, axial)
    arm.add_links(element, k, axial, element_options)
    arm.add_drives(drive_input)
    run = Run(arm, element.method, shape_points)
    newton = (rho_inf, float(newton_rel_tol), abs_tol, int(newton_max_iterations), modified_newton)
    run.solve(h, newton, jacobian_per_step)
    specific = element.meta(case, k, axial, **(element_options or {}))
    meta = run.meta(
        k, n_steps, newton, jacobian_per_step, drive_input, axial, inextensible_axial_ratio, specific
    )
    return run.result(meta)
