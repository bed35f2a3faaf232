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
from types import SimpleNamespace

import numpy as np

from dttmm import plumbing
from dttmm.errors import InputError, SimulationError
from dttmm.shapes import shape_points as check_shape_points
from dttmm.shapes import straight_shapes
from dttmm.spatial import SpatialCase, SpatialResult
from dttmm.spatial.topology import closure_gaps, initial_angles, resolve_closures, rigid_tip_frames

from ._exudyn3d import (
    as_case,
    axis_frame,
    dynamic_settings,
    frame_outputs,
    frame_sensors,
    initial_joint_states,
    joint_outputs,
    motion_sensors,
    reference_frames,
    run_segments,
    segments,
    solve_static,
    static_frames,
    stored_reader,
)
from ._exudyn_common import spatial_link_shapes, spatial_shape_sensors
from ._spatial_mechanics import rot_axis

__all__ = ["METHOD", "SHEAR_RATIO", "NODES", "check_case", "simulate", "reference_frames"]

METHOD = "exudyn-beam3d"
#: GA / EA of the Euler–Bernoulli limit
SHEAR_RATIO = 1.0e3
NODES = ("EP", "RotVecLG")
#: EA of an inextensible link: ratio·max(EIy, EIz)/L²
INEXTENSIBLE_AXIAL_RATIO = 1.0e6


def _ancestors(model, i) -> list:
    """Link i and the links it hangs from, base first."""
    out = [i]
    while model.parents[out[-1]] >= 0:
        out.append(model.parents[out[-1]])
    return out[::-1]


def _piecewise(times, values):
    times = np.asarray(times, float)
    values = np.asarray(values, float)
    return lambda t: float(np.interp(t, times, values))


def _case_load(ld, n: int):
    """(link, F, T, law(t, left=False)) of a SpatialLoad of the case's scenario."""
    law = lambda t, left=False, f=ld.factor: float(f(t, left))  # noqa: E731
    return ld.link_index(n), np.array(ld.force, float), np.array(ld.moment, float), law


def _check_tip_loads(case, tip_loads, followers=False):
    """The world loads at link tips: the case's ``scenario.loads`` in the world frame, then the
    option ``tip_loads``, as (link, F, T, law(t, left=False)) per load. A follower load of the
    case (frame "tip") is refused unless ``followers`` (then it is left to
    :func:`_follower_loads`)."""
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


def _follower_loads(case):
    """The case's follower loads (frame "tip"), as (link, F, T, law(t, left=False)) with F, T in
    the tip frame."""
    n = case.model.n_links
    return [_case_load(ld, n) for ld in getattr(case.scenario, "loads", ()) if ld.follower]


def _all_loads(case, tip_loads):
    """(link, F, T, law, follower) of every tip load of a run."""
    world = [(*x, False) for x in _check_tip_loads(case, tip_loads, followers=True)]
    return world + [(*x, True) for x in _follower_loads(case)]


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


def _build(case, k, shear_ratio, node, loads):
    """The Exudyn system of ``case`` (not assembled) and the handles the outputs need."""
    import exudyn as exu
    import exudyn.itemInterface as ii
    from exudyn.rigidBodyUtilities import (
        AngularVelocity2EulerParameters_t,
        RotationMatrix2EulerParameters,
        RotationMatrix2RotationVector,
    )

    model, sc = case.model, case.scenario
    frames = reference_frames(case)
    g = np.array(model.gravity, float)
    has_g = bool(np.any(g != 0.0))
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    ground = mbs.AddNode(ii.NodePointGround())

    ground_body = mbs.AddObject(ii.ObjectGround())
    carrier = {}  # node -> rigid body on it (for markers away from the node)

    def rigid_marker(nd, R=None, p=None):
        R = np.eye(3) if R is None else R
        p = np.zeros(3) if p is None else p
        if not np.any(p):
            return mbs.AddMarker(ii.MarkerNodeRigid(nodeNumber=nd, localHT=exu.HT(rotation=R)))
        if nd == ground:
            body = ground_body
        elif nd in carrier:
            body = carrier[nd]
        else:  # a massless body on the node carries the offset marker
            body = carrier[nd] = mbs.AddObject(ii.ObjectRigidBody(nodeNumber=nd, mass=0.0))
        return mbs.AddMarker(
            ii.MarkerBodyRigid(bodyNumber=body, localHT=exu.HT(rotation=R, translation=list(p)))
        )

    root_nodes, tip_nodes, first_el, elements, bodies, rolls, reach = [], [], [], [], [], [], []
    kmax = 0.0
    alpha_rates = initial_joint_states(case)[1]

    def add_body(nd, mass, c, J):
        """A rigid body on node ``nd``: mass, centre c and inertia J about it (node frame)."""
        Jn = J + mass * (c @ c * np.eye(3) - np.outer(c, c))
        body = mbs.AddObject(
            ii.ObjectRigidBody(
                nodeNumber=nd,
                mass=float(mass),
                inertia=[Jn[0, 0], Jn[1, 1], Jn[2, 2], Jn[1, 2], Jn[0, 2], Jn[0, 1]],
                centerOfMass=list(c),
            )
        )
        bodies.append((body, nd, c, float(mass)))
        carrier.setdefault(nd, body)
        if has_g and mass > 0:
            mbs.AddLoad(
                ii.LoadMassProportional(
                    markerNumber=mbs.AddMarker(ii.MarkerBodyMass(bodyNumber=body)), loadVector=list(g)
                )
            )

    def rigid_node(p, R, v):
        if node == "EP":
            ep = np.array(RotationMatrix2EulerParameters(R))
            ep_t = AngularVelocity2EulerParameters_t(fr["omega"], ep)
            return mbs.AddNode(
                ii.NodeRigidBodyEP(
                    referenceCoordinates=list(p) + list(ep), initialVelocities=list(v) + list(ep_t)
                )
            )
        rv = RotationMatrix2RotationVector(R)
        return mbs.AddNode(
            ii.NodeRigidBodyRotVecLG(
                referenceCoordinates=list(p) + list(rv), initialVelocities=list(v) + list(R.T @ fr["omega"])
            )
        )

    def velocity(i, p):
        return sum(
            (np.cross(frames[m_]["a_w"], p - frames[m_]["p_J"]) * alpha_rates[m_])
            for m_ in _ancestors(model, i)
        ) + np.zeros(3)

    for i, link in enumerate(model.links):
        b, fr = link.beam, frames[i]
        if link.rigid:  # one node at the link frame, the body on it; the tip at L·x
            nd = rigid_node(fr["p_link"], fr["R_link"], velocity(i, fr["p_link"]))
            rolls.append(np.eye(3))
            reach.append(np.array([b.length, 0.0, 0.0]))
            root_nodes.append(nd)
            tip_nodes.append(nd)
            first_el.append(None)
            elements.append([])
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
        kmax = max(kmax, GA / l)
        sec = exu.BeamSection()
        sec.stiffnessMatrix = C
        sec.inertia = np.diag([b.rhoJ, b.rhoIy, b.rhoIz])
        sec.massPerLength = b.rhoA
        Rx = rot_axis((1.0, 0.0, 0.0), b.roll)
        rolls.append(Rx)
        Rn = fr["R_link"] @ Rx
        nodes = []
        for j in range(k + 1):
            p = fr["p_link"] + fr["R_link"] @ np.array([j * l, 0.0, 0.0])
            nodes.append(rigid_node(p, Rn, velocity(i, p)))
        els = [
            mbs.AddObject(
                ii.ObjectBeamGeometricallyExact(
                    nodeNumbers=[nodes[j], nodes[j + 1]], length=l, sectionData=sec
                )
            )
            for j in range(k)
        ]
        if has_g:
            for e in els:
                mbs.AddLoad(
                    ii.LoadMassProportional(
                        markerNumber=mbs.AddMarker(ii.MarkerBodyMass(bodyNumber=e)), loadVector=list(g)
                    )
                )
        root_nodes.append(nodes[0])
        tip_nodes.append(nodes[-1])
        first_el.append(els[0])
        elements.append(els)
        # hub: inertia about the root point in the link frame -> node frame
        for rb in (link.hub, link.payload):
            if rb is None or (rb.mass == 0.0 and not np.any(rb.inertia_matrix)):
                continue
            if rb is link.hub:
                add_body(nodes[0], rb.mass, np.zeros(3), Rx.T @ rb.inertia_matrix @ Rx)
            else:
                add_body(nodes[-1], rb.mass, Rx.T @ np.array(rb.offset, float), Rx.T @ rb.inertia_matrix @ Rx)

    # joints and drives
    inputs = []  # (load, law, sign-vector) set by the pre-step function
    motion_joints = {}
    drives = iter(sc.drives)
    for i, link in enumerate(model.links):
        fr, j = frames[i], link.joint
        par = model.parents[i]
        if par < 0:
            parent, R_pn, p_pn = ground, np.eye(3), np.zeros(3)
        else:
            parent = tip_nodes[par]
            R_pn = frames[par]["R_tip"] @ rolls[par]
            p_pn = frames[par]["p_tip"] - frames[par]["R_tip"] @ reach[par]  # the node's position
        A = np.eye(3) if j.locked else axis_frame(j.axis)
        # marker 0: the joint frame R_J·A at p_J in the parent's node frame
        m0 = rigid_marker(parent, R_pn.T @ fr["R_J"] @ A, R_pn.T @ (fr["p_J"] - p_pn))
        m1 = rigid_marker(root_nodes[i], rolls[i].T @ A)
        if j.locked:
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1] * 6))
            continue
        d = next(drives)
        if d.kind == "motion":

            def offset(mbs_, t, item, par, law=d.motion, seg=None):
                return [0.0, 0.0, 0.0, 0.0, 0.0, law(t, True)[0]]

            motion_joints[i] = mbs.AddObject(
                ii.ObjectJointGeneric(
                    markerNumbers=[m0, m1], constrainedAxes=[1] * 6, offsetUserFunction=offset
                )
            )
        else:
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1, 1, 1, 1, 1, 0]))
            a = np.array(j.axis, float)
            targets = [(root_nodes[i], rolls[i].T @ a)]
            if par >= 0:
                targets.append((parent, -(R_pn.T @ fr["R_J"] @ a)))
            for nd, vec in targets:
                ld = mbs.AddLoad(
                    ii.LoadTorqueVector(
                        markerNumber=rigid_marker(nd), loadVector=[0.0, 0.0, 0.0], bodyFixed=True
                    )
                )
                inputs.append((ld, d.torque, vec))
    closures = []
    for cl in _closure_frames(case, frames):  # the loops, each closed by a joint
        a, b = cl["a"], cl["b"]
        # (on a rigid link the tip is at L·x from its node: ``reach``)
        ma = rigid_marker(tip_nodes[a], rolls[a].T @ cl["Ra"], rolls[a].T @ cl["pa"] + reach[a])
        if b < 0:
            mb = rigid_marker(ground, cl["Rb"], cl["pb"])
        else:
            mb = rigid_marker(tip_nodes[b], rolls[b].T @ cl["Rb"], rolls[b].T @ cl["pb"] + reach[b])
        closures.append(
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[mb, ma], constrainedAxes=cl["axes"]))
        )
    for i, F, T, law, follower in loads:
        mk = rigid_marker(tip_nodes[i], None, reach[i])
        if follower:  # tip-frame components -> the node frame R_tip Rx(roll)
            F, T = rolls[i].T @ F, rolls[i].T @ T
        for vec, Load in ((F, ii.LoadForceVector), (T, ii.LoadTorqueVector)):
            if np.any(vec):
                ld = mbs.AddLoad(Load(markerNumber=mk, loadVector=[0.0] * 3, bodyFixed=bool(follower)))
                inputs.append((ld, law, vec))

    def set_inputs(t, left):
        for ld, law, vec in inputs:
            mbs.SetLoadParameter(ld, "loadVector", list(law(t, left) * vec))

    return dict(
        mbs=mbs,
        exu=exu,
        ii=ii,
        frames=frames,
        g=g,
        has_g=has_g,
        root_nodes=root_nodes,
        tip_nodes=tip_nodes,
        first_el=first_el,
        elements=elements,
        bodies=bodies,
        rolls=rolls,
        reach=reach,
        motion_joints=motion_joints,
        closures=closures,
        inputs=inputs,
        set_inputs=set_inputs,
        kmax=kmax,
    )


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
    (:func:`reference_models._exudyn_common.spatial_link_shapes`); 0 (default): none.

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
    loads = _all_loads(case, tip_loads)
    shape_points = check_shape_points(shape_points)
    if section_loads and case.model.rigid_links:
        i = case.model.rigid_links[0]
        raise InputError(
            "section_loads", True, f"model.links[{i}] is rigid: it has no beam element to take them from"
        )
    sc = case.scenario
    ratio = sc.output_step / h
    per_out = int(round(ratio))
    if per_out < 1 or abs(ratio - per_out) > 1e-9 * ratio:
        raise InputError("h", h, f"must divide the output step {sc.output_step}")
    t_out = sc.output_times
    n_steps = (len(t_out) - 1) * per_out

    B = _build(case, k, shear_ratio, node, loads)
    mbs, exu, ii, g, has_g = B["mbs"], B["exu"], B["ii"], B["g"], B["has_g"]
    root_nodes, tip_nodes, first_el, elements = B["root_nodes"], B["tip_nodes"], B["first_el"], B["elements"]
    bodies, rolls, motion_joints, inputs, set_inputs = (
        B["bodies"],
        B["rolls"],
        B["motion_joints"],
        B["inputs"],
        B["set_inputs"],
    )
    kmax, model = B["kmax"], case.model
    seg_start = [0.0]
    if inputs:

        def pre_step(mbs_, t):
            set_inputs(t, t > seg_start[0])
            return True

        mbs.SetPreStepUserFunction(pre_step)

    OV = exu.OutputVariableType

    def sens(nd, var):
        return mbs.AddSensor(
            ii.SensorNode(nodeNumber=nd, outputVariableType=var, storeInternal=True, writeToFile=False)
        )

    s_root = frame_sensors(mbs, ii, OV, root_nodes)
    s_tip = frame_sensors(mbs, ii, OV, tip_nodes)
    s_mot = motion_sensors(mbs, ii, OV, motion_joints)
    flexible = [i for i, els in enumerate(elements) if els]
    s_shape = (
        spatial_shape_sensors(mbs, ii, OV, [elements[i] for i in flexible], "beam") if shape_points else []
    )
    s_sec = []
    if section_loads:
        sel = (
            "first"
            if section_loads is True
            else plumbing.choice("section_loads", section_loads, ("first", "middle"))
        )
        # "middle": the element at the middle of each link, whose centre is the mid-span for odd k
        chosen = first_el if sel == "first" else [els[k // 2] for els in elements]
        for e in chosen:
            s_sec.append(
                [
                    mbs.AddSensor(
                        ii.SensorBody(
                            bodyNumber=e,
                            localPosition=[0.0, 0.0, 0.0],
                            outputVariableType=v,
                            storeInternal=True,
                            writeToFile=False,
                        )
                    )
                    for v in (OV.ForceLocal, OV.TorqueLocal)
                ]
            )
    s_en = []
    if energy:
        for els in elements:
            for e in els:
                for v in (OV.KineticEnergy, OV.PotentialEnergy):
                    s_en.append(
                        mbs.AddSensor(
                            ii.SensorBody(
                                bodyNumber=e,
                                localPosition=[0.0, 0.0, 0.0],
                                outputVariableType=v,
                                storeInternal=True,
                                writeToFile=False,
                            )
                        )
                    )
        for body, *_ in bodies:
            s_en.append(
                mbs.AddSensor(
                    ii.SensorBody(
                        bodyNumber=body,
                        outputVariableType=OV.KineticEnergy,
                        storeInternal=True,
                        writeToFile=False,
                    )
                )
            )
        s_pos_all = (
            [
                sens(nd, OV.Position)
                for els in elements
                if els
                for nd in [mbs.GetObject(e)["nodeNumbers"][0] for e in els]
                + [mbs.GetObject(els[-1])["nodeNumbers"][1]]
            ]
            if has_g
            else []
        )
        s_body_pos = (
            [
                mbs.AddSensor(
                    ii.SensorBody(
                        bodyNumber=b_,
                        localPosition=list(c),
                        outputVariableType=OV.Position,
                        storeInternal=True,
                        writeToFile=False,
                    )
                )
                for b_, _, c, _ in bodies
            ]
            if has_g
            else []
        )
    mbs.Assemble()

    abs_tol = float(newton_abs_tol) if newton_abs_tol is not None else max(1e-10 * kmax * 1e-6, 1e-10)
    s, ti = dynamic_settings(
        exu, rho_inf, float(newton_rel_tol), abs_tol, int(newton_max_iterations), modified_newton
    )
    t_end = n_steps * h
    bps, segs, on_grid = segments(sc, h, n_steps, per_out)
    s.solution.sensors.writePeriod = sc.output_step if on_grid else h
    all_sensors = (
        [x for tr in s_root + s_tip for x in tr] + list(s_mot.values()) + [x for p in s_sec for x in p] + s_en
    )
    if energy and has_g:
        all_sensors += s_pos_all + s_body_pos
    all_sensors += [x for link in s_shape for node_ in link for x in node_]
    rows = {sn: [] for sn in all_sensors}
    wall, cpu, newton, steps, _, failure, it = run_segments(
        mbs, exu, s, ti, segs, h, seg_start, set_inputs, all_sensors, rows
    )
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
            newton_abs_tol=max(1e-10 * kmax * 1e-5, 1e-10),
            newton_max_iterations=newton_max_iterations,
            modified_newton=modified_newton,
            shape_points=shape_points,
        )
        res.meta["newton_abs_tol_raised"] = f"the default {abs_tol:.3g} failed: {failure}"
        return res
    if failure is not None:
        raise SimulationError(
            f"Exudyn {METHOD}: {failure}", t=float(it.currentTime), step=steps, component="newton"
        )

    stored = stored_reader(rows, sc, t_out, per_out, t_end, steps, METHOD)
    nt = len(t_out)
    root, tip, Rl, Rt, w_root, w_tip, defl, twist = frame_outputs(
        stored, s_root, s_tip, nt, rolls, B["reach"]
    )
    ja, jr, jt = joint_outputs(case, Rl, Rt, w_root, w_tip, stored, s_mot, t_out)
    en = None
    if energy:
        en = np.zeros(nt)
        for sn in s_en:
            en += stored(sn)[:, 0]
        if has_g:
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
    meta = dict(
        method=METHOD,
        elements_per_link=k,
        h=h,
        element="ObjectBeamGeometricallyExact",
        node=f"NodeRigidBody{node}",
        shear_ratio=float(shear_ratio),
        integrator="generalized-alpha",
        rho_inf=float(rho_inf),
        newton_rel_tol=float(newton_rel_tol),
        newton_abs_tol=abs_tol,
        modified_newton=bool(modified_newton),
        jacobian_per_step=True,
        linear_solver="EigenSparse",
        newton_iterations_per_step=newton / max(steps, 1),
        ode2_size=int(mbs.systemData.ODE2Size()),
        ae_size=int(mbs.systemData.AEsize()),
        restarts=[float(x) for x in bps],
        wall_time_solve=wall,
        cpu_time=cpu,
        exudyn=exu.__version__,
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
    shapes = None
    if shape_points:
        nodes = [[np.hstack([stored(x) for x in node_]) for node_ in link] for link in s_shape]
        shapes = straight_shapes(root, tip, shape_points)  # the rigid links'
        if flexible:
            beams = SimpleNamespace(model=SimpleNamespace(links=[model.links[i] for i in flexible]))
            shapes[:, flexible] = spatial_link_shapes(beams, nodes, shape_points)
    if model.closures:  # the loops' gaps at the tip frames (what the closing joints hold)
        rc = resolve_closures(model, *rigid_tip_frames(model, initial_angles(case)))
        gaps = [closure_gaps(rc, Rt[t_], tip[t_]) for t_ in range(nt)]
        meta["closure_residual"] = np.array([g_[0] for g_ in gaps])
        meta["closure_angle_residual"] = np.array([g_[1] for g_ in gaps])
    return SpatialResult(
        t=t_out,
        link_shapes=shapes,
        joint_angle=ja,
        joint_rate=jr,
        joint_torque=jt,
        link_root=root,
        link_tip=tip,
        tip_deflection=defl,
        end_effector=tip[:, model.end_effector_index].copy(),
        wall_time=wall,
        n_steps=steps,
        meta=meta,
        cut_loads=cut,
        cut_load_t=t_out if section_loads else None,
        energy=en,
        twist=twist,
        link_rotation=Rl,
        tip_rotation=Rt,
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
    B = _build(case, k, shear_ratio, node, _all_loads(case, tip_loads))
    mbs, exu = B["mbs"], B["exu"]
    B["set_inputs"](case.scenario.duration, True)
    mbs.Assemble()
    solve_static(mbs, exu, B["kmax"], steps, METHOD)
    OV = exu.OutputVariableType
    out = static_frames(mbs, OV, B["root_nodes"], B["tip_nodes"], B["rolls"], B["reach"])
    nan = np.full(3, np.nan)
    sec = np.array(
        [
            np.concatenate(
                [
                    mbs.GetObjectOutputBody(e, v, localPosition=[0.0, 0.0, 0.0]) if e is not None else nan
                    for v in (OV.ForceLocal, OV.TorqueLocal)
                ]
            )
            for e in B["first_el"]
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
                for e in B["first_el"]
            ]
        ),
    )
