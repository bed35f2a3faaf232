"""The planar chain of the Exudyn peers (the family's skeleton: :mod:`reference_models._exudyn_common`).

``exudyn_ancf`` (ObjectANCFCable2D) and ``exudyn_beam`` (ObjectBeamGeometricallyExact2D) differ
only in how one link's beam is meshed and how its ends are tied to the hub and tip bodies; the
hubs, tip bodies, joints, drives, gravity, the sensors' conversion to :class:`dttmm.Result` and
the failure with a partial Result live here.

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
    exu, ii = import_exudyn(f"{element.method} needs")

    model, sc = case.model, case.scenario
    n = model.n_links
    t_out = sc.output_times
    g = [float(model.gravity[0]), float(model.gravity[1]), 0.0]
    has_gravity = g[0] != 0.0 or g[1] != 0.0
    axial = [stiff_axial_stiffness(l.beam, inextensible_axial_ratio) for l in model.links]
    abs_tol = float(newton_abs_tol) if newton_abs_tol is not None else _default_abs_tol(case, k, axial)

    layout = _Layout(case)
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddObject(ii.ObjectGround())
    ground_node = mbs.AddNode(ii.NodePointGround())
    m_ground_pos = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    m_ground_coord = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))

    def add_body(node, mass, inertia):
        body = mbs.AddObject(ii.ObjectRigidBody2D(nodeNumber=node, mass=float(mass), inertia=float(inertia)))
        if has_gravity and mass > 0:
            gravity_loads(mbs, ii, [body], g)
        return body

    hub_nodes, tip_nodes, hub_bodies, tip_bodies = [], [], [], []
    link_elements = []
    for i, link in enumerate(model.links):
        hub_node, tip_node, elements, clamps = element.add_link(
            mbs, exu, ii, link, layout, i, k, axial[i], **(element_options or {})
        )
        link_elements.append(elements)
        hub_nodes.append(hub_node)
        tip_nodes.append(tip_node)
        hub_bodies.append(add_body(hub_node, link.hub_mass, link.hub_inertia))
        tip_bodies.append(add_body(tip_node, link.payload_mass, link.payload_inertia))
        if clamps is not None:
            for body, beam_node in zip((hub_bodies[-1], tip_bodies[-1]), clamps):
                clamp(mbs, ii, body, beam_node)
        if has_gravity:
            gravity_loads(mbs, ii, elements, g)

    seg_start = [0.0]  # start time of the running segment, read by the user functions

    # Drive inputs. "pre-step" (default): plain loads / constant offsets whose values a
    # PreStepUserFunction sets once per step at the step end time (Exudyn's recommended way to
    # prescribe forces and actuator values); "user-function": load and offset user functions
    # that Exudyn calls at every residual evaluation (~35 Python calls per step measured).
    constraints = [None] * n
    inputs = []  # (kind, item, law, sign, a0): what the pre-step function sets
    # closed-loop laws: a coordinate spring-damper whose user function is the law (implicit at
    # the step end; see reference_models._exudyn_control)
    closed = (
        ClosedLoop(case, layout.alpha0, hub_nodes, tip_nodes)
        if any(d.closed_loop for d in sc.drives)
        else None
    )
    for i, drive in enumerate(sc.drives):
        coordinates = joint_markers(
            mbs, ii, i, m_ground_pos, m_ground_coord, tip_bodies, hub_bodies, tip_nodes, hub_nodes
        )
        if drive.closed_loop:
            closed.add_joint(mbs, exu, ii, i, *coordinates())
        elif drive.kind == "torque":
            targets = [(hub_bodies[i], 1.0)] + ([(tip_bodies[i - 1], -1.0)] if i > 0 else [])
            for body, sign in targets:
                marker = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=body))
                if drive_input == "pre-step":
                    load = mbs.AddLoad(ii.LoadTorqueVector(markerNumber=marker, loadVector=[0, 0, 0]))
                    inputs.append(("load", load, drive.torque, sign, 0.0))
                else:
                    # right limit at the segment start, left limit everywhere after it (see module doc)
                    def tau_user(mbs_, t, load, tau=drive.torque, sign=sign):
                        return [0.0, 0.0, sign * tau(t, t > seg_start[0])]

                    mbs.AddLoad(
                        ii.LoadTorqueVector(
                            markerNumber=marker, loadVector=[0, 0, 0], loadVectorUserFunction=tau_user
                        )
                    )
        else:
            c_in, c_out = coordinates()
            if drive_input == "pre-step":
                constraints[i] = mbs.AddObject(
                    ii.ObjectConnectorCoordinate(markerNumbers=[c_in, c_out], offset=0.0)
                )
                inputs.append(("offset", constraints[i], drive.motion, 1.0, layout.alpha0[i]))
            else:

                def offset(mbs_, t, item, off, motion=drive.motion, a0=layout.alpha0[i]):
                    return motion(t, t > seg_start[0])[0] - a0

                constraints[i] = mbs.AddObject(
                    ii.ObjectConnectorCoordinate(markerNumbers=[c_in, c_out], offsetUserFunction=offset)
                )

    def set_inputs(t, left):
        """Set every drive input to its law's value at t (left or right limit)."""
        for kind, item, law, sign, a0 in inputs:
            if kind == "load":
                mbs.SetLoadParameter(item, "loadVector", [0.0, 0.0, sign * law(t, left)])
            else:
                mbs.SetObjectParameter(item, "offset", law(t, left)[0] - a0)

    if inputs:
        set_pre_step(mbs, set_inputs, seg_start)

    if closed is not None:

        def post_step(mbs_, t):
            closed.post_step(mbs_, t)  # commit the integral states of the converged step
            return True

        mbs.SetPostStepUserFunction(post_step)

    OV = exu.OutputVariableType
    frame = (OV.Position, OV.Rotation, OV.AngularVelocity)
    s_hub = node_sensors(mbs, ii, hub_nodes, frame)
    s_tip = node_sensors(mbs, ii, tip_nodes, frame)
    s_force = [
        None
        if c is None
        else mbs.AddSensor(
            ii.SensorObject(
                objectNumber=c, outputVariableType=OV.Force, storeInternal=True, writeToFile=False
            )
        )
        for c in constraints
    ]
    all_sensors = [x for tr in s_hub + s_tip for x in tr] + [x for x in s_force if x is not None]
    if closed is not None:
        all_sensors += list(closed.sensors.values()) + list(closed.acc_sensors.values())
    s_shape = shape_sensors(mbs, ii, link_elements, (OV.CoordinatesTotal,)) if shape_points else None
    if s_shape is not None:
        all_sensors += [x for link in s_shape for node in link for x in node]

    mbs.Assemble()
    if closed is not None:
        closed.assembled(mbs)

    newton = (rho_inf, float(newton_rel_tol), abs_tol, int(newton_max_iterations), modified_newton)
    run, stored = solve(
        mbs, exu, sc, h, all_sensors, set_inputs, seg_start, newton, jacobian_per_step, closed
    )
    meta = dict(
        method=element.method,
        elements_per_link=k,
        h=h,
        integrator="generalized-alpha",
        rho_inf=rho_inf,
        adaptive_step=False,
        linear_solver="EigenSparse",
        newton_rel_tol=float(newton_rel_tol),
        newton_abs_tol=abs_tol,
        newton_max_iterations=int(newton_max_iterations),
        modified_newton=bool(modified_newton),
        jacobian_per_step=bool(jacobian_per_step),
        drive_input=drive_input,
        ode2_size=int(mbs.systemData.ODE2Size()),
        ae_size=int(mbs.systemData.AEsize()),
        exudyn=exu.__version__,
        restarts=[float(b) for b in run.restarts],
        breakpoints_off_grid=[float(b) for b in run.off_grid],
        axial_stiffness=axial,
        inextensible_axial_ratio=float(inextensible_axial_ratio),
    )
    meta.update(element.meta(case, k, axial, **(element_options or {})))
    try:
        meta["versions"] = {**plumbing.versions(), "exudyn": exu.__version__}
    except Exception:  # versions() is informational only
        meta["versions"] = {"exudyn": exu.__version__}

    failure = None
    if not run.ok:
        err = run.error
        failure = (
            f"SolveDynamic raised {type(err).__name__}: {err}"
            if err is not None
            else "SolveDynamic returned False (Newton did not converge)",
            "newton",
        )
    elif run.short is not None:
        failure = (run.short, "time integration")
    wall, steps_done = run.wall, run.steps
    meta.update(
        steps=n_steps,
        steps_taken=steps_done,
        newton_iterations=run.newton,
        newton_iterations_per_step=(run.newton / steps_done if steps_done > 0 else float("nan")),
        jacobians=run.jacobians,
        t_reached=run.t_reached,
        wall_time_solve=wall,
        cpu_time_solve=run.cpu,
    )
    if closed is not None:
        meta.update(
            closed_loop="implicit: coordinate spring-damper user function at every residual evaluation (t_{n+1})",
            root_moment="tau - J_hub * hub angular acceleration (Newton iterate)",
            integral_state="trapezoidal rule, committed after each step",
            initial_acceleration_solves=run.start_solves,
        )

    # --- outputs ------------------------------------------------------------------------------

    def series():
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
                tq[:, i] = -stored(s_force[i])[:m, -1]
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

    def build(ts, fields, success):
        shapes = None
        if s_shape is not None:
            nodes = [
                [np.hstack([stored(x)[: len(ts), 1:] for x in node]) for node in link] for link in s_shape
            ]
            shapes = link_shapes(model.links, nodes, shape_points)
        return make_result(
            t=t_out[: len(ts)],
            **fields,
            wall_time=wall,
            n_steps=steps_done,
            meta={**meta, "success": success},
            link_shapes=shapes,
        )

    def fail(reason, t_fail, component):
        partial = None
        try:
            ts, fields = series()
            finite = all(np.isfinite(v).all() for v in fields.values())
            if len(ts) and finite and np.allclose(ts, t_out[: len(ts)], rtol=0, atol=1e-6 * sc.output_step):
                partial = build(ts, fields, False)
        except Exception:  # the partial result is a courtesy; the error below is what matters
            partial = None
        # Exudyn's currentTime is the end of the step it attempted last
        step = max(int(round(t_fail / h)) - 1, 0) if math.isfinite(t_fail) else steps_done
        raise SimulationError(
            f"Exudyn {element.method}: {reason}", t=t_fail, step=step, component=component, partial=partial
        )

    if failure is not None:
        fail(failure[0], run.t_reached, failure[1])

    ts, fields = series()
    if len(ts) != len(t_out) or np.max(np.abs(ts - t_out)) > 1e-6 * sc.output_step:
        fail(
            f"sensor rows ({len(ts)}) do not match the output grid ({len(t_out)} samples)",
            float(ts[-1]) if len(ts) else 0.0,
            "sensors",
        )
    for name, arr in fields.items():
        bad = ~np.isfinite(arr)
        if bad.any():
            row, *rest = np.argwhere(bad)[0]
            fail(f"non-finite {name}", float(t_out[row]), f"{name}[{', '.join(map(str, rest))}]")
    return build(ts, fields, True)
