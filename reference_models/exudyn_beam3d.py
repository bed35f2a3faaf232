"""Exudyn peer of the spatial cases: 3-D geometrically exact beams (ObjectBeamGeometricallyExact).

Each link of a spatial case (docs/spatial.md §1) is meshed with k ``ObjectBeamGeometricallyExact``
elements (linear interpolation on SE(3), one-point integration: a shear-deformable Reissner beam)
on k + 1 ``NodeRigidBodyEP`` nodes (Euler parameters, as Exudyn recommends for its implicit
solvers; :func:`statics` also takes ``node="RotVecLG"``, ``NodeRigidBodyRotVecLG``, whose
Lie-group update Exudyn's generalized-α does not run: Newton fails in the first step).
The node frames are the element frames R_link·Rx(roll) (local x along
the beam, y and z the section's principal axes). Section: ``exu.BeamSection()`` with
``stiffnessMatrix = diag(EA, GA, GA, GJ, EIy, EIz)``, ``inertia = diag(ρJ, ρIy, ρIz)``,
``massPerLength = ρA``. Damped links (``damping`` μ > 0) are refused: the element ignores the
section's ``dampingMatrix`` (Exudyn 1.13: a three-link arm with μ = 0.05 s moves to every digit
as with μ = 0, where the DT-TMM's end-effector moves by 1e-3 m, measured). The suite's links
are Euler–Bernoulli; they are approached with the shear stiffness GA = ``shear_ratio``·EA
(default 1e3: the shear part of a cantilever's tip deflection, 3EI/(GA L²) relative, is below
1e-6 on the shipped cases; see docs/spatial.md "Exudyn 3-D beam"). Inextensible links get
EA = 1e6·max(EIy, EIz)/L² (as the planar peers).

Rigid links (``SpatialRigidBody``, docs/spatial.md §1): one ``NodeRigidBodyEP`` at the link
frame carrying an ``ObjectRigidBody`` (the body's mass, its centre of mass, its inertia moved to
the node by the parallel-axis rule); the link's tip is the point L·x of that node's frame
(joints, payloads and tip loads beyond it are markers there), its shape the straight segment,
its tip deflections and twist zero; it has no beam element, so no section loads (``statics``
gives NaN for it; ``simulate`` refuses ``section_loads`` on an arm with rigid links).

Joints: an unlocked joint is an ``ObjectJointGeneric`` with the rotation about its axis free,
between the parent marker (ground, or the tip node of link i−1, at the origin o with the joint
frame R_J·A, A a rotation taking z to the axis a) and the root node of link i; a locked joint
constrains all six axes at the origin's angle. Hubs and payloads are ``ObjectRigidBody`` on the
root and tip nodes (mass, inertia about the node, centre of mass offset). Gravity:
``LoadMassProportional`` on every element and body. Torque drives: a ``LoadTorqueVector`` pair
(body-fixed, ±τ·a) whose values a PreStepUserFunction sets once per step at the step end (as the
planar peers); motion drives: all six axes constrained with the angle prescribed by the joint's
``offsetUserFunction`` (a Python call per residual evaluation); their torque is the joint's
reaction moment about the axis. External loads at link tips: the case's ``scenario.loads``
(:class:`dttmm.spatial.SpatialLoad`: world components as a ``LoadForceVector``/``LoadTorqueVector``
on the tip node, follower loads as body-fixed ones in the node frame R_tip·Rx(roll)) and the
option ``tip_loads`` (world components, piecewise-linear in time), their values set by the same
pre-step function.

Time integration: Exudyn's generalized-α (``rho_inf``, default 1: no numerical damping, as
Exudyn's right-angle cantilever test model) with fixed step h, modified Newton with a Jacobian
per step, EigenSparse, one thread, no files, no graphics; drive breakpoints on the step grid
restart the integrator (as the planar peers). Newton's default absolute tolerance, 1e-16 of the
largest element stiffness GA/l, lies at the round-off floor of the residual (ε·GA/l·|x|): where
Newton stalls just above it (the five-bar at k ≥ 8: residual 7e-5 against 6.4e-5, its first step)
the run is repeated once with 10× the tolerance. Output: a :class:`dttmm.spatial.SpatialResult`
on the case's output grid (h must divide the output step) with the DT-TMM's fields (§4);
``section_loads`` (nt, n, 6) adds Exudyn's ``ForceLocal``/``TorqueLocal`` of the first element of
every link (constant over the element: one-point integration; the load the outboard part
exerts on the inboard part, in the deformed section frame at x = l/2).
"""

from __future__ import annotations

import math

import numpy as np

from dttmm import plumbing
from dttmm.errors import InputError
from dttmm.shapes import shape_points as check_shape_points
from dttmm.spatial import SpatialCase, SpatialResult
from dttmm.spatial.topology import closure_gaps, initial_angles, resolve_closures, rigid_tip_frames

from ._exudyn3d import Arm, Run, all_loads, as_case, axis_frame, reference_frames, solve_static, static_frames
from ._exudyn_common import beam_elements, beam_nodes, body_sensor, gravity_loads, node_sensors, output_grid
from ._spatial_mechanics import rot_axis

__all__ = ["METHOD", "SHEAR_RATIO", "NODES", "check_case", "simulate", "reference_frames"]

METHOD = "exudyn-beam3d"
#: GA / EA of the Euler–Bernoulli limit
SHEAR_RATIO = 1.0e3
NODES = ("EP", "RotVecLG")
#: EA of an inextensible link: ratio·max(EIy, EIz)/L²
INEXTENSIBLE_AXIAL_RATIO = 1.0e6


def _closure_frames(case, frames) -> list:
    """Per closure of the case (docs/spatial.md "Trees and closed loops"): the joint frame at the
    initial state in ``link``'s and ``to``'s tip frames (rotation with z along a revolute's axis,
    origin the closure point; world components for the ground) and the constrained axes of its
    ``ObjectJointGeneric`` (revolute: all but the rotation about z; spherical: the translations;
    weld: all six)."""
    model = case.model
    out = []
    for cl in model.closures:
        a = model.link_index(cl.link)
        b = -1 if cl.to == "ground" else model.link_index(cl.to)
        Ra, xa0 = frames[a]["R_tip"], frames[a]["p_tip"]
        Rb, xb0 = (frames[b]["R_tip"], frames[b]["p_tip"]) if b >= 0 else (np.eye(3), np.zeros(3))
        pa = np.array(cl.point, float)
        x = xa0 + Ra @ pa
        pb = Rb.T @ (x - xb0) if cl.to_point is None else np.array(cl.to_point, float)
        A = axis_frame(np.array(cl.axis, float) / np.linalg.norm(cl.axis))
        axes = {"revolute": [1, 1, 1, 1, 1, 0], "spherical": [1, 1, 1, 0, 0, 0], "weld": [1] * 6}[cl.kind]
        out.append(dict(a=a, b=b, pa=pa, pb=pb, Ra=A, Rb=Rb.T @ Ra @ A, axes=axes))
    return out


def _build(case, k, shear_ratio, node, loads) -> Arm:
    """The Exudyn system of ``case`` (not assembled) with the handles the outputs need: per link
    its root and tip nodes, elements, first element (None for a rigid link), section roll and
    tip reach (beyond its node, for a rigid link), the closing joints."""
    arm = Arm(case, f"{METHOD} needs")
    exu, ii, mbs, frames, model = arm.exu, arm.ii, arm.mbs, arm.frames, case.model
    arm.first_el, arm.elements, rolls, reach = [], [], [], []

    def add_body(nd, mass, c, J):
        """A rigid body on node ``nd``: mass, centre c and inertia J about it (node frame)."""
        arm.add_body(nd, mass, c, J + mass * (c @ c * np.eye(3) - np.outer(c, c)))

    def rigid_node(i, p, R):
        if node == "EP":
            return arm.ep_node(i, p, R)
        from exudyn.rigidBodyUtilities import RotationMatrix2RotationVector

        v = list(arm.velocity(i, p)) + list(R.T @ frames[i]["omega"])
        rv = RotationMatrix2RotationVector(R)
        return mbs.AddNode(
            ii.NodeRigidBodyRotVecLG(referenceCoordinates=list(p) + list(rv), initialVelocities=v)
        )

    for i, link in enumerate(model.links):
        b, fr = link.beam, frames[i]
        if link.rigid:  # one node at the link frame, the body on it; the tip at L·x
            nd = rigid_node(i, fr["p_link"], fr["R_link"])
            rolls.append(np.eye(3))
            reach.append(np.array([b.length, 0.0, 0.0]))
            arm.root_nodes.append(nd)
            arm.tip_nodes.append(nd)
            arm.first_el.append(None)
            arm.elements.append([])
            add_body(nd, b.mass, b.com_vector, b.inertia_matrix)
            if link.hub is not None:
                add_body(nd, link.hub.mass, np.zeros(3), link.hub_inertia)
            if link.payload is not None:
                add_body(nd, link.payload.mass, reach[-1] + link.payload_offset, link.payload_inertia)
            continue
        reach.append(np.zeros(3))
        L, l = b.length, b.length / k
        EA = b.EA if b.EA is not None else INEXTENSIBLE_AXIAL_RATIO * max(b.EIy, b.EIz) / L**2
        GA = shear_ratio * EA
        C = np.diag([EA, GA, GA, b.GJ, b.EIy, b.EIz])
        arm.kmax = max(arm.kmax, GA / l)
        sec = exu.BeamSection()
        sec.stiffnessMatrix = C
        sec.inertia = np.diag([b.rhoJ, b.rhoIy, b.rhoIz])
        sec.massPerLength = b.rhoA
        Rx = rot_axis((1.0, 0.0, 0.0), b.roll)
        rolls.append(Rx)
        Rn = fr["R_link"] @ Rx
        nodes = [
            rigid_node(i, p, Rn)
            for p in (fr["p_link"] + fr["R_link"] @ np.array([j * l, 0.0, 0.0]) for j in range(k + 1))
        ]
        els = beam_elements(
            mbs,
            ii.ObjectBeamGeometricallyExact,
            nodes,
            length=l,
            sectionData=sec,
        )
        if arm.has_g:
            gravity_loads(mbs, ii, els, list(arm.g))
        arm.root_nodes.append(nodes[0])
        arm.tip_nodes.append(nodes[-1])
        arm.first_el.append(els[0])
        arm.elements.append(els)
        # hub: inertia about the root point in the link frame -> node frame
        for rb in (link.hub, link.payload):
            if rb is None or (rb.mass == 0.0 and not np.any(rb.inertia_matrix)):
                continue
            if rb is link.hub:
                add_body(nodes[0], rb.mass, np.zeros(3), Rx.T @ rb.inertia_matrix @ Rx)
            else:
                add_body(nodes[-1], rb.mass, Rx.T @ np.array(rb.offset, float), Rx.T @ rb.inertia_matrix @ Rx)

    arm.add_joints([r.T for r in rolls], rolls, reach)
    arm.closures = []
    for cl in _closure_frames(case, frames):  # the loops, each closed by a joint
        a, b = cl["a"], cl["b"]
        # (on a rigid link the tip is at L·x from its node: ``reach``)
        ma = arm.rigid_marker(arm.tip_nodes[a], rolls[a].T @ cl["Ra"], rolls[a].T @ cl["pa"] + reach[a])
        if b < 0:
            mb = arm.rigid_marker(arm.ground, cl["Rb"], cl["pb"])
        else:
            mb = arm.rigid_marker(arm.tip_nodes[b], rolls[b].T @ cl["Rb"], rolls[b].T @ cl["pb"] + reach[b])
        arm.closures.append(
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[mb, ma], constrainedAxes=cl["axes"]))
        )
    arm.add_loads(loads, rolls, reach)
    arm.rolls, arm.reach = rolls, reach
    return arm


def check_case(case):
    """Refuse (InputError) what this peer cannot model: closed-loop drives, and damped links
    (module notes: the element ignores the section's damping matrix)."""
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase or a path to one")
    for d in case.scenario.drives:
        if d.closed_loop:
            raise InputError(
                "scenario.drives", d.law.name, f"closed-loop drives are not supported by {METHOD}"
            )
    for i, link in enumerate(case.model.links):
        if not link.rigid and link.beam.damping:
            raise InputError(
                f"model.links[{i}].beam.damping",
                link.beam.damping,
                f"must be 0 for {METHOD}: Exudyn's ObjectBeamGeometricallyExact ignores the section's damping matrix",
            )


def simulate(
    case,
    *,
    elements_per_link,
    h,
    rho_inf=1.0,
    shear_ratio=SHEAR_RATIO,
    node="EP",
    tip_loads=None,
    section_loads=False,
    energy=False,
    newton_rel_tol=1e-8,
    newton_abs_tol=None,
    newton_max_iterations=25,
    modified_newton=True,
    shape_points=0,
) -> SpatialResult:
    """Simulate a spatial case (a :class:`dttmm.spatial.SpatialCase` or a path to its TOML file)
    with k = ``elements_per_link`` Exudyn 3-D geometrically exact beam elements per link, step h.
    ``shape_points`` p ≥ 2 records ``link_shapes`` (nt, n, p, 3) from a sensor per beam node
    (:func:`reference_models._exudyn_common.link_shapes`); 0 (default): none.

    Options: ``rho_inf`` (generalized-α spectral radius, 1), ``shear_ratio`` (GA/EA, 1e3),
    ``node`` ("EP" only here; see the module notes), ``tip_loads`` (list of dicts ``link``,
    ``force``, ``torque`` (world, N and N·m), ``times``, ``factors``: the load times a
    piecewise-linear factor, at the link's tip node; in addition to the case's own
    ``scenario.loads``), ``section_loads`` (True or "first", or "middle": record as
    ``cut_loads`` (nt, n, 6) Exudyn's section force and moment in the first element of each link,
    or in element k // 2 + 1, whose centre is the link's mid-span for odd k), ``energy`` (beam kinetic +
    strain energy, rigid bodies' kinetic energy and the gravity potential at the nodes),
    ``newton_rel_tol`` (1e-8), ``newton_abs_tol`` (None: 1e-16·max stiffness/l, the residual's
    round-off floor; where Newton fails there, the run is repeated once with 1e-15·max stiffness/l
    and ``meta["newton_abs_tol_raised"]`` says so), ``newton_max_iterations``
    (25), ``modified_newton`` (True). Raises InputError on bad input, SimulationError on failure.
    """
    case = as_case(case)
    check_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    h = plumbing.step_size(h, case.scenario.duration)
    plumbing.choice("node", node, NODES)
    if node != "EP":
        raise InputError(
            "node",
            node,
            "simulate needs 'EP': Exudyn's implicit generalized-alpha does not take its Lie-group nodes "
            "(Newton fails in the first step; they are for its explicit Lie-group integrators); statics takes both",
        )
    for name, val, lo in (("shear_ratio", shear_ratio, 0.0), ("rho_inf", rho_inf, -1e-300)):
        if (
            isinstance(val, bool)
            or not isinstance(val, (int, float))
            or not (math.isfinite(val) and val > lo)
        ):
            raise InputError(name, val, "must be a positive number")
    if rho_inf > 1:
        raise InputError("rho_inf", rho_inf, "must lie in [0, 1]")
    loads = all_loads(case, tip_loads)
    shape_points = check_shape_points(shape_points)
    if section_loads and case.model.rigid_links:
        i = case.model.rigid_links[0]
        raise InputError(
            "section_loads", True, f"model.links[{i}] is rigid: it has no beam element to take them from"
        )
    output_grid(case.scenario, h)

    arm = _build(case, k, shear_ratio, node, loads)
    mbs, ii, elements, bodies, model, g = arm.mbs, arm.ii, arm.elements, arm.bodies, case.model, arm.g
    OV = arm.exu.OutputVariableType
    flexible = [i for i, els in enumerate(elements) if els]
    beams = [elements[i] for i in flexible] if shape_points else None
    run = Run(arm, flexible, beams, (OV.Position, OV.RotationMatrix))
    s_sec = []
    if section_loads:
        sel = (
            "first"
            if section_loads is True
            else plumbing.choice("section_loads", section_loads, ("first", "middle"))
        )
        # "middle": the element at the middle of each link, whose centre is the mid-span for odd k
        chosen = arm.first_el if sel == "first" else [els[k // 2] for els in elements]
        for e in chosen:
            s_sec.append(
                [body_sensor(mbs, ii, e, v, (0.0, 0.0, 0.0)) for v in (OV.ForceLocal, OV.TorqueLocal)]
            )
    s_en, s_pos_all, s_body_pos = [], [], []
    if energy:
        for els in elements:
            for e in els:
                s_en += [
                    body_sensor(mbs, ii, e, v, (0.0, 0.0, 0.0))
                    for v in (OV.KineticEnergy, OV.PotentialEnergy)
                ]
        s_en += [body_sensor(mbs, ii, body, OV.KineticEnergy) for body, *_ in bodies]
        if arm.has_g:
            for els in elements:
                if els:
                    s_pos_all += [x for (x,) in node_sensors(mbs, ii, beam_nodes(mbs, els), (OV.Position,))]
            s_body_pos = [body_sensor(mbs, ii, b_, OV.Position, c) for b_, _, c, _ in bodies]
    run.sensors += [x for p in s_sec for x in p] + s_en + s_pos_all + s_body_pos

    abs_tol = float(newton_abs_tol) if newton_abs_tol is not None else max(1e-10 * arm.kmax * 1e-6, 1e-10)
    rel_tol = float(newton_rel_tol)
    failure = run.solve(METHOD, h, rho_inf, rel_tol, abs_tol, int(newton_max_iterations), modified_newton)
    if failure is not None and newton_abs_tol is None:
        # the default absolute tolerance, 1e-16·kmax, is at the round-off floor of the residual
        # (ε·kmax·|x|): at fine k, or on a loop, Newton can stall just above it (module notes);
        # the run is repeated once with the tolerance 10× that floor
        res = simulate(
            case,
            elements_per_link=k,
            h=h,
            rho_inf=rho_inf,
            shear_ratio=shear_ratio,
            node=node,
            tip_loads=tip_loads,
            section_loads=section_loads,
            energy=energy,
            newton_rel_tol=newton_rel_tol,
            newton_abs_tol=max(1e-10 * arm.kmax * 1e-5, 1e-10),
            newton_max_iterations=newton_max_iterations,
            modified_newton=modified_newton,
            shape_points=shape_points,
        )
        res.meta["newton_abs_tol_raised"] = f"the default {abs_tol:.3g} failed: {failure}"
        return res
    if failure is not None:
        run.fail(METHOD, failure)

    stored = run.stored
    fields = run.fields(model.end_effector_index, arm.rolls, arm.reach, shape_points)
    en = None
    if energy:
        en = np.zeros(len(fields["t"]))
        for sn in s_en:
            en += stored(sn)[:, 0]
        if arm.has_g:
            ptr = 0
            for i in flexible:
                b = model.links[i].beam
                l = b.length / k
                pos = np.stack([stored(s_pos_all[ptr + j]) for j in range(k + 1)], axis=1)
                ptr += k + 1
                mid = 0.5 * (pos[:, 1:] + pos[:, :-1])
                en -= b.rhoA * l * np.einsum("tjx,x->t", mid, g)
            for sn, (_, _, _, mass) in zip(s_body_pos, bodies):
                en -= mass * stored(sn) @ g
    cut = None
    if section_loads:
        cut = np.stack([np.concatenate([stored(f), stored(m_)], axis=1) for f, m_ in s_sec], axis=1)
    meta = run.meta(
        METHOD,
        k,
        h,
        rho_inf,
        rel_tol,
        abs_tol,
        modified_newton,
        element="ObjectBeamGeometricallyExact",
        node=f"NodeRigidBody{node}",
        shear_ratio=float(shear_ratio),
    )
    meta.update(
        section_loads=(
            "ForceLocal/TorqueLocal of the "
            + ("first element" if section_loads in (True, "first") else f"element {k // 2 + 1} of {k}")
            + " of each link (section frame, at the element's centre)"
        )
        if section_loads
        else None,
        energy="beam kinetic + strain (Exudyn), rigid-body kinetic, gravity potential at element midpoints"
        if energy
        else None,
    )
    if model.closures:  # the loops' gaps at the tip frames (what the closing joints hold)
        rc = resolve_closures(model, *rigid_tip_frames(model, initial_angles(case)))
        Rt, tip = fields["tip_rotation"], fields["link_tip"]
        gaps = [closure_gaps(rc, Rt[t_], tip[t_]) for t_ in range(len(tip))]
        meta["closure_residual"] = np.array([g_[0] for g_ in gaps])
        meta["closure_angle_residual"] = np.array([g_[1] for g_ in gaps])
    return run.result(
        fields, meta, cut_loads=cut, cut_load_t=fields["t"] if section_loads else None, energy=en
    )


def statics(case, *, elements_per_link, shear_ratio=SHEAR_RATIO, node="EP", tip_loads=None, load_steps=10):
    """Static equilibrium of ``case`` by Exudyn's ``SolveStatic`` (gravity, the torque drives, the
    case's ``scenario.loads`` and ``tip_loads`` at t = duration, applied in ``load_steps`` load steps; Newton to 1e-12
    relative). Returns a dict: ``link_root``, ``link_tip`` (n, 3), ``tip_deflection`` (n, 2),
    ``twist`` (n,), ``section_loads`` (n, 6) (ForceLocal, TorqueLocal of each link's first
    element, at x = l/2, section frame), ``section_rotation`` (n, 3, 3) (that section frame); NaN for a rigid link (no beam element)."""
    case = as_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("node", node, NODES)
    steps = plumbing.positive_integer("load_steps", load_steps)
    arm = _build(case, k, shear_ratio, node, all_loads(case, tip_loads))
    mbs, exu = arm.mbs, arm.exu
    arm.set_inputs(case.scenario.duration, True)
    mbs.Assemble()
    solve_static(mbs, exu, arm.kmax, steps, METHOD)
    OV = exu.OutputVariableType
    out = static_frames(mbs, OV, arm.root_nodes, arm.tip_nodes, arm.rolls, arm.reach)
    nan = np.full(3, np.nan)
    sec = np.array(
        [
            np.concatenate(
                [
                    mbs.GetObjectOutputBody(e, v, localPosition=[0.0, 0.0, 0.0]) if e is not None else nan
                    for v in (OV.ForceLocal, OV.TorqueLocal)
                ]
            )
            for e in arm.first_el
        ]
    )
    return dict(
        **out,
        section_loads=sec,
        section_rotation=np.array(
            [
                np.reshape(
                    mbs.GetObjectOutputBody(e, OV.RotationMatrix, localPosition=[0.0, 0.0, 0.0])
                    if e is not None
                    else np.full(9, np.nan),
                    (3, 3),
                )
                for e in arm.first_el
            ]
        ),
    )
