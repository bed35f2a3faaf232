"""Exudyn peer of the spatial cases: 3-D ANCF cable elements (ObjectANCFCable), a bending check.

Each link of a spatial case (docs/spatial.md §1) is meshed with k ``ObjectANCFCable`` elements
(Euler–Bernoulli ANCF cable: cubic Hermite centre line in absolute position and slope coordinates)
on k + 1 ``NodePointSlope1`` nodes (position r and slope r′, 6 coordinates). The element has one
bending stiffness EI (a round section), an axial stiffness EA, mass per length ρA, and **no
torsion and no rotary inertia**: its nodes carry no rotation about the centre line. Hence:

- a case with EIy ≠ EIz is refused (the cable has one bending stiffness);
- every link is **torsionally rigid** (zero twist strain): its twist is not modelled and GJ is
  ignored. Each cable node j carries a rigid frame F_j (``NodeRigidBodyEP``, R_link at t = 0):
  F_0 is the root frame (the hub's body), F_k the tip frame (the payload's body), the interior
  ones massless. F_j is clamped to node j: its origin by an ``ObjectJointSpherical``, its x axis
  along the slope r′ by an ``ObjectConnectorCoordinateVector`` with Python constraint and
  Jacobian user functions (r′·F_j e_y = r′·F_j e_z = 0; Exudyn has no built-in connector between
  a 3-D slope node and a rigid body, and the cable offers no rigid marker). Consecutive frames
  are twist-locked by a second such connector: the relative rotation F_jᵀ F_j+1 has no x
  component (the x component of the relative Euler parameters, bilinear, is zero), so F_j+1 is
  F_j carried by the minimal rotation from one slope to the next: discrete parallel transport,
  the frame of a rod without twist strain (as the DT-TMM element with GJ → ∞: φx = 0 per
  element). The reported ``twist`` (the log-twist between root and tip) is therefore the
  geometric twist of a bent rod, second order in the bending angles (7.1e-5 rad on
  ``two_joint_arm``, as the DT-TMM with GJ × 10⁴), not an elastic one. ``twist_lock="ends"``
  keeps only F_0 and F_k with one lock between them (zero log-twist: a different, cruder rigid
  rod, kept for comparison);
- a case whose twist is loaded at rest is refused: gravity (or a ``tip_loads`` load) with a
  moment about a link's axis at t = 0, or an unlocked joint whose axis has a component along
  its parent link's axis (its drive torque twists the parent). Twist excited by motion (the
  Coriolis and tangential loads of an outboard link) is allowed and neglected; docs/peers.md
  "Exudyn ANCF cable 3-D" states its measured size on ``two_joint_arm``;
- the link's polar and bending mass moments of inertia per length (ρJ, ρIy, ρIz) are lumped
  into the frames F_j (l/2 at the ends, l = L/k inside; all L/2 at the ends with
  ``twist_lock="ends"``): exact for the link's rigid motion, and the cable's rotary inertia as
  k grows (the cable element itself carries none).

Joints, hubs, payloads, gravity, torque drives (a body-fixed ``LoadTorqueVector`` pair set once
per step by a PreStepUserFunction), motion drives (the joint's ``offsetUserFunction``; torque =
the joint's reaction moment about its axis), the case's world-frame ``scenario.loads`` (follower
loads are refused) and ``tip_loads`` are built as in :mod:`reference_models.exudyn_beam3d`, on
the root and tip frames. Inextensible links get EA = 1e6·EI/L².

Time integration: Exudyn's generalized-α (``rho_inf``, default 0.8 as the planar ANCF peer) with
fixed step h, modified Newton with a Jacobian per step, EigenSparse, one thread, no files, no
graphics; drive breakpoints on the step grid restart the integrator. Output: a
:class:`dttmm.spatial.SpatialResult` on the case's output grid (h must divide the output step);
no cut loads or energy. :func:`statics` runs ``SolveStatic``; :func:`frequencies` the
constrained eigenvalues at t = 0.
"""

from __future__ import annotations

import math

import numpy as np

from dttmm import plumbing
from dttmm.errors import InputError
from dttmm.shapes import shape_points as check_shape_points
from dttmm.spatial import SpatialCase, SpatialResult
from dttmm.spatial.model import require_flexible, require_serial

from ._exudyn3d import Arm, Run, as_case, check_tip_loads, reference_frames, solve_static, static_frames
from ._exudyn_common import beam_elements, cable_properties, gravity_loads, output_grid
from ._spatial_mechanics import rot_axis

__all__ = ["METHOD", "TWIST_LOCKS", "check_case", "frequencies", "simulate", "statics"]

METHOD = "exudyn-ancf3d"
#: EA of an inextensible link: ratio·EI/L²
INEXTENSIBLE_AXIAL_RATIO = 1.0e6
#: where the twist-free frames sit: at every cable node (discrete parallel transport, zero twist
#: strain) or only at the link's ends (one lock: zero log-twist between root and tip)
TWIST_LOCKS = ("nodes", "ends")
#: relative tolerance of EIy = EIz and of the rest-twist tests
_REL = 1e-9


def _loads_at_rest(case, loads):
    """(point, force, torque) of every static load at t = 0 (world): gravity on the links' mass
    centres, hubs and payloads, and the ``tip_loads`` vectors (factor 1: a load whose direction
    twists a link is refused whatever its time factors)."""
    frames = reference_frames(case)
    g = np.array(case.model.gravity, float)
    out = []
    for i, link in enumerate(case.model.links):
        b, fr = link.beam, frames[i]
        out.append((fr["p_link"] + fr["R_link"] @ [0.5 * b.length, 0.0, 0.0], b.rhoA * b.length * g, None))
        if link.hub is not None:
            out.append((fr["p_link"], link.hub.mass * g, None))
        if link.payload is not None:
            out.append((fr["p_tip"] + fr["R_tip"] @ link.payload_offset, link.payload.mass * g, None))
    for i, F, T, _ in loads:
        out.append((frames[i]["p_tip"], F, T))
    return frames, out


def check_case(case, tip_loads=None):
    """Refuse (InputError) what the torsion-free cable cannot model: EIy ≠ EIz, closed-loop
    drives, and a twist loaded at rest (module notes). Returns the checked tip loads."""
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase or a path to one")
    for d in case.scenario.drives:
        if d.closed_loop:
            raise InputError(
                "scenario.drives", d.law.name, f"closed-loop drives are not supported by {METHOD}"
            )
    require_flexible(case.model, METHOD)
    require_serial(case.model, METHOD)
    for i, link in enumerate(case.model.links):
        b = link.beam
        if abs(b.EIy - b.EIz) > _REL * max(b.EIy, b.EIz):
            raise InputError(
                f"model.links[{i}].beam.EIy",
                b.EIy,
                f"must equal EIz = {b.EIz}: Exudyn's ObjectANCFCable has one bending stiffness ({METHOD})",
            )
    loads = check_tip_loads(case, tip_loads)
    frames, rest = _loads_at_rest(case, loads)
    # owner link of every load of ``rest`` (same order as _loads_at_rest), and its source
    owner, source = [], []
    for i, link in enumerate(case.model.links):
        n_ = 1 + (link.hub is not None) + (link.payload is not None)
        owner += [i] * n_
        source += ["model.gravity"] * n_
    owner += [i_ for i_, *_ in loads]
    source += [f"tip_loads[{j}]" for j in range(len(loads))]
    scale = sum(float(np.linalg.norm(F)) for _, F, _ in rest) * sum(l.beam.length for l in case.model.links)
    scale += sum(float(np.linalg.norm(T)) for _, _, T in rest if T is not None)
    for i in range(case.model.n_links):
        x, p0 = frames[i]["R_link"][:, 0], frames[i]["p_link"]
        by = {}
        for (p, F, T), j, src in zip(rest, owner, source):
            if j >= i:
                by[src] = by.get(src, 0.0) + x @ np.cross(p - p0, F) + (x @ T if T is not None else 0.0)
        for src, moment in by.items():
            if abs(moment) > _REL * max(scale, 1e-300):
                raise InputError(
                    src,
                    f"link {i}",
                    f"loads the twist of link {i} at rest ({moment:.3g} N·m about its axis at t = 0): "
                    f"{METHOD} has no torsion (ObjectANCFCable); use exudyn-beam3d",
                )
    for i in range(1, case.model.n_links):
        j = case.model.links[i].joint
        if j.locked:
            continue
        c = float(frames[i]["a_w"] @ frames[i - 1]["R_tip"][:, 0])
        if abs(c) > _REL:
            raise InputError(
                f"model.links[{i}].joint.axis",
                j.axis,
                f"has a component {c:.3g} along link {i - 1}'s axis: its drive would twist that link, "
                f"and {METHOD} has no torsion (ObjectANCFCable)",
            )
    return loads


def _slope_clamp_functions():
    """Constraint and Jacobian user functions of a slope clamp: q = [frame node (p, e0..e3),
    slope node (r, r′)] (reference values included); c = [r′·(R(e) e_y), r′·(R(e) e_z)] with the
    homogeneous quadratic form of R(e) (equal to Exudyn's at |e| = 1)."""

    def constraint(mbs, t, item, q, q_t, velocity_level):
        e0, e1, e2, e3 = q[3], q[4], q[5], q[6]
        sx, sy, sz = q[10], q[11], q[12]
        return [
            2.0 * (e1 * e2 - e0 * e3) * sx
            + (e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3) * sy
            + 2.0 * (e2 * e3 + e0 * e1) * sz,
            2.0 * (e1 * e3 + e0 * e2) * sx
            + 2.0 * (e2 * e3 - e0 * e1) * sy
            + (e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3) * sz,
        ]

    def jacobian(mbs, t, item, q, q_t, velocity_level):
        e0, e1, e2, e3 = q[3], q[4], q[5], q[6]
        sx, sy, sz = q[10], q[11], q[12]
        J = np.zeros((2, 13))
        J[0, 3:7] = (
            2.0 * (-e3 * sx + e0 * sy + e1 * sz),
            2.0 * (e2 * sx - e1 * sy + e0 * sz),
            2.0 * (e1 * sx + e2 * sy + e3 * sz),
            2.0 * (-e0 * sx - e3 * sy + e2 * sz),
        )
        J[0, 10:13] = (
            2.0 * (e1 * e2 - e0 * e3),
            e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3,
            2.0 * (e2 * e3 + e0 * e1),
        )
        J[1, 3:7] = (
            2.0 * (e2 * sx - e1 * sy + e0 * sz),
            2.0 * (e3 * sx - e0 * sy - e1 * sz),
            2.0 * (e0 * sx + e3 * sy - e2 * sz),
            2.0 * (e1 * sx + e2 * sy + e3 * sz),
        )
        J[1, 10:13] = (
            2.0 * (e1 * e3 + e0 * e2),
            2.0 * (e2 * e3 - e0 * e1),
            e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3,
        )
        return J

    return constraint, jacobian


def _twist_lock_functions():
    """Constraint and Jacobian user functions of the twist lock between a link's root and tip
    frames: q = [root (p, a0..a3), tip (p, b0..b3)]; c = the x component of the vector part of
    the relative Euler parameters a* ⊗ b (bilinear), zero exactly when the relative rotation
    R_rootᵀ R_tip has no x component (log-twist 0)."""

    def constraint(mbs, t, item, q, q_t, velocity_level):
        return [q[3] * q[11] - q[10] * q[4] - q[5] * q[13] + q[6] * q[12]]

    def jacobian(mbs, t, item, q, q_t, velocity_level):
        J = np.zeros((1, 14))
        J[0, 3:7] = (q[11], -q[10], -q[13], q[12])
        J[0, 10:14] = (-q[4], q[3], q[6], -q[5])
        return J

    return constraint, jacobian


def _build(case, k, loads, reduced_integration=False, twist_lock="nodes") -> Arm:
    """The Exudyn system of ``case`` (not assembled) with the handles the outputs need: per link
    its root and tip frame nodes, cable elements and end slope nodes."""
    arm = Arm(case, f"{METHOD} needs")
    ii, mbs, frames, model = arm.ii, arm.mbs, arm.frames, case.model
    clamp_c, clamp_j = _slope_clamp_functions()
    twist_c, twist_j = _twist_lock_functions()

    def frame_node(i, p, R, mass, com, J):
        nd = arm.ep_node(i, p, R)
        arm.add_body(nd, mass, com, J)
        return nd

    def connector(fa, fb, shape, constraint, jacobian):
        """A user-function constraint between the coordinates of the nodes fa and fb."""
        mbs.AddObject(
            ii.ObjectConnectorCoordinateVector(
                markerNumbers=[mbs.AddMarker(ii.MarkerNodeCoordinates(nodeNumber=nd)) for nd in (fa, fb)],
                scalingMarker0=np.zeros(shape),
                constraintUserFunction=constraint,
                jacobianUserFunction=jacobian,
            )
        )

    arm.cables, arm.slope_ends = [], []
    for i, link in enumerate(model.links):
        b, fr = link.beam, frames[i]
        L, l = b.length, b.length / k
        EI = b.EIz
        EA = b.EA if b.EA is not None else INEXTENSIBLE_AXIAL_RATIO * EI / L**2
        arm.kmax = max(arm.kmax, EA / l)
        Rr = rot_axis((1.0, 0.0, 0.0), b.roll)
        per_length = Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
        # rotary inertia lumped into the twist-free frames (trapezoidal: l/2 at the ends, l inside)
        lumped = 0.5 * (l if twist_lock == "nodes" else L) * per_length
        # root frame: hub (about the root point) + half the link's rotary inertia
        J = lumped + (link.hub.inertia_matrix if link.hub is not None else 0.0)
        root = frame_node(i, fr["p_link"], fr["R_link"], link.hub_mass, np.zeros(3), J)
        c = link.payload_offset
        m_p = link.payload_mass
        J = lumped + link.payload_inertia + m_p * (c @ c * np.eye(3) - np.outer(c, c))
        tip = frame_node(i, fr["p_tip"], fr["R_tip"], m_p, c, J)
        x = fr["R_link"][:, 0]
        om = fr["omega"]
        nodes = []
        for j in range(k + 1):
            p = fr["p_link"] + x * (j * l)
            nodes.append(
                mbs.AddNode(
                    ii.NodePointSlope1(
                        referenceCoordinates=list(p) + list(x),
                        initialVelocities=list(arm.velocity(i, p)) + list(np.cross(om, x)),
                    )
                )
            )
        els = beam_elements(
            mbs,
            ii.ObjectANCFCable,
            nodes,
            **cable_properties(b, l, EI, EA),
            useReducedOrderIntegration=int(bool(reduced_integration)),
        )
        if arm.has_g:
            gravity_loads(mbs, ii, els, list(arm.g))
        # the twist-free frames: root, (every interior node,) tip; each clamped to its cable node
        # (position: spherical joint; slope along the frame's x axis: user constraint), each
        # locked about x to the next (the relative rotation has no x component)
        chain = [(root, nodes[0])]
        if twist_lock == "nodes":
            for j in range(1, k):
                chain.append(
                    (
                        frame_node(
                            i, fr["p_link"] + x * (j * l), fr["R_link"], 0.0, np.zeros(3), l * per_length
                        ),
                        nodes[j],
                    )
                )
        chain.append((tip, nodes[-1]))
        for fnode, snode in chain:
            mbs.AddObject(
                ii.ObjectJointSpherical(
                    markerNumbers=[
                        mbs.AddMarker(ii.MarkerNodePosition(nodeNumber=nd)) for nd in (fnode, snode)
                    ]
                )
            )
            connector(fnode, snode, (2, 13), clamp_c, clamp_j)
        for (fa, _), (fb, _) in zip(chain, chain[1:]):
            connector(fa, fb, (1, 14), twist_c, twist_j)
        arm.root_nodes.append(root)
        arm.tip_nodes.append(tip)
        arm.cables.append(els)
        arm.slope_ends.append((nodes[0], nodes[-1]))

    arm.add_joints([fr["R_link"].T @ fr["R_J"] for fr in frames])
    # world loads only (followers are refused); the law at t (its right limit at a switch)
    arm.add_loads([(i, F, T, lambda t, left=False, f=law: f(t), False) for i, F, T, law in loads])
    return arm


def _abs_tol(case, arm, value):
    if value is not None:
        return plumbing.positive_number("newton_abs_tol", value)
    chain = sum(link.beam.length for link in case.model.links)
    return max(1e3 * np.finfo(float).eps * arm.kmax * chain, 1e-8)


def simulate(
    case,
    *,
    elements_per_link,
    h,
    rho_inf=0.8,
    reduced_integration=False,
    twist_lock="nodes",
    tip_loads=None,
    newton_rel_tol=1e-8,
    newton_abs_tol=None,
    newton_max_iterations=25,
    modified_newton=True,
    shape_points=0,
) -> SpatialResult:
    """Simulate a spatial case (a :class:`dttmm.spatial.SpatialCase` or a path to its TOML file)
    with k = ``elements_per_link`` Exudyn 3-D ANCF cable elements per link, step h.

    The links are torsionally rigid and EIy = EIz is required (module notes). Options:
    ``rho_inf`` (generalized-α spectral radius, 0.8), ``reduced_integration`` (the element's
    ``useReducedOrderIntegration``, False), ``tip_loads`` (as :mod:`exudyn_beam3d`: a list of
    dicts ``link``, ``force``, ``torque`` (world), ``times``, ``factors``), ``newton_rel_tol``
    (1e-8), ``newton_abs_tol`` (None: 10³·ε·max(EA k/L)·chain length, at least 1e-8),
    ``newton_max_iterations`` (25), ``modified_newton`` (True), ``shape_points`` (p ≥ 2 records
    ``link_shapes`` (nt, n, p, 3): cubic Hermite between the cable nodes from their positions and
    slopes, the element's own interpolation; 0, the default: none). Raises InputError on bad
    input or a case the cable cannot model, SimulationError on failure.
    """
    case = as_case(case)
    loads = check_case(case, tip_loads)
    k = plumbing.elements_per_link(elements_per_link)
    h = plumbing.step_size(h, case.scenario.duration)
    shape_points = check_shape_points(shape_points)
    if isinstance(rho_inf, bool) or not isinstance(rho_inf, (int, float)) or not (0.0 <= rho_inf <= 1.0):
        raise InputError("rho_inf", rho_inf, "must be a number in [0, 1]")
    newton_rel_tol = plumbing.positive_number("newton_rel_tol", newton_rel_tol)
    newton_max_iterations = plumbing.positive_integer("newton_max_iterations", newton_max_iterations)
    output_grid(case.scenario, h)
    plumbing.choice("twist_lock", twist_lock, TWIST_LOCKS)
    arm = _build(case, k, loads, reduced_integration, twist_lock)
    OV = arm.exu.OutputVariableType
    run = Run(arm, range(case.model.n_links), arm.cables if shape_points else None, (OV.CoordinatesTotal,))
    abs_tol = _abs_tol(case, arm, newton_abs_tol)
    # the clamp and twist user functions return new arrays at every call, which Exudyn's
    # allocation check reports as a warning after each solve: expected here, so not printed
    failure = run.solve(
        METHOD, h, rho_inf, newton_rel_tol, abs_tol, newton_max_iterations, modified_newton, quiet=True
    )
    if failure is not None:
        run.fail(METHOD, failure)
    meta = run.meta(
        METHOD,
        k,
        h,
        rho_inf,
        newton_rel_tol,
        abs_tol,
        modified_newton,
        element="ObjectANCFCable",
        node="NodePointSlope1",
        torsion="rigid: twist not modelled (GJ ignored)",
        twist_lock=twist_lock,
        rotary_inertia="(rhoJ, rhoIy, rhoIz) lumped into the twist-free frames (l/2 at the ends, l inside)"
        if twist_lock == "nodes"
        else "(rhoJ, rhoIy, rhoIz)·L lumped half at each end frame",
        reduced_integration=bool(reduced_integration),
    )
    steps = max(run.run.steps, 1)
    meta.update(jacobians_per_step=run.run.jacobians / steps, cpu_time_solve=run.run.cpu)
    return run.result(run.fields(-1, shape_points=shape_points), meta)


def statics(case, *, elements_per_link, tip_loads=None, load_steps=10, twist_lock="nodes"):
    """Static equilibrium of ``case`` by Exudyn's ``SolveStatic`` (gravity, the torque drives and
    ``tip_loads`` at t = duration, in ``load_steps`` load steps; Newton to 1e-12 relative).
    Returns a dict: ``link_root``, ``link_tip`` (n, 3), ``tip_deflection`` (n, 2) (tip − root
    along the root frame's y and z), ``twist`` (n,)."""
    case = as_case(case)
    loads = check_case(case, tip_loads)
    k = plumbing.elements_per_link(elements_per_link)
    steps = plumbing.positive_integer("load_steps", load_steps)
    plumbing.choice("twist_lock", twist_lock, TWIST_LOCKS)
    arm = _build(case, k, loads, twist_lock=twist_lock)
    arm.set_inputs(case.scenario.duration, True)
    arm.mbs.Assemble()
    solve_static(arm.mbs, arm.exu, arm.kmax, steps, METHOD)
    return static_frames(arm.mbs, arm.exu.OutputVariableType, arm.root_nodes, arm.tip_nodes)


def frequencies(case, *, elements_per_link, count=8, twist_lock="nodes"):
    """The ``count`` lowest natural frequencies (Hz) of ``case`` linearised at t = 0 (its initial
    configuration, joints as built: the torque-driven joints free), from Exudyn's
    ``ComputeODE2Eigenvalues`` with the constraints projected out (dense SVD null space)."""
    case = as_case(case)
    check_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    count = plumbing.positive_integer("count", count)
    plumbing.choice("twist_lock", twist_lock, TWIST_LOCKS)
    arm = _build(case, k, [], twist_lock=twist_lock)
    mbs, exu = arm.mbs, arm.exu
    mbs.Assemble()
    s = exu.SimulationSettings()
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    ev, _ = mbs.ComputeODE2Eigenvalues(
        simulationSettings=s,
        useSparseSolver=False,
        ignoreAlgebraicEquations=False,
        singularValuesTolerance=1e-10,
    )
    ev = np.sort(np.abs(np.asarray(ev, float)))
    f = np.sqrt(ev) / (2.0 * math.pi)
    return f[f > 1e-6 * max(f.max(), 1e-300)][:count]
