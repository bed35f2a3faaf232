"""The spatial global solver (reference_models.spatial_global) on trees and closed loops against
independent references: the same arm written as a chain, Pinocchio's rigid tree (kinematics,
mass matrix, velocity and gravity terms, joint forces; the stiff limit of a flexible tree),
central differences of the closure equations, the energy of a passive loop, the rigid four-bar's
closed-form loop closure and its statics by hand."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import dttmm
from dttmm import Constant, Drive, Scenario, Sine, SpinUp
from dttmm.spatial import (
    SpatialCase,
    SpatialClosure,
    SpatialHub,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialRigidBody,
    SpatialSection,
)
from reference_models import spatial_global as sg
from reference_models._spatial_mechanics import rpy_matrix
from tests.test_spatial_global import CASES, _torque_drives, arm

# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------


def _bar(L, stiff=1.0, w=0.008, damping=0.0):
    """An aluminium bar of square section w × w (E = 70 GPa, ρ = 2700 kg/m³), inextensible,
    its stiffnesses times ``stiff``."""
    E, rho, I = 70e9, 2700.0, w**4 / 12
    return SpatialSection(
        length=L,
        GJ=0.38 * E * 2 * I * stiff,
        EIy=E * I * stiff,
        EIz=E * I * stiff,
        rhoA=rho * w * w,
        rhoJ=rho * 2 * I,
        rhoIy=rho * I,
        rhoIz=rho * I,
        damping=damping,
    )


def _case(model, drives, duration, output_step):
    return SpatialCase(model, Scenario(duration, output_step, tuple(drives)))


# A planar crank-rocker (Grashof: 0.08 + 0.26 < 0.24 + 0.18): ground AD along x, crank AB,
# coupler BC, rocker DC; every joint about z; the loop is closed at C by a revolute joint.
_A, _B, _C, _D = 0.08, 0.26, 0.18, 0.24


def _coupler_point(th2):
    """The rigid four-bar's C at crank angle θ2 (the assembly with C above the line BD)."""
    B = np.array([_A * math.cos(th2), _A * math.sin(th2)])
    e = np.array([_D, 0.0]) - B
    L = float(np.linalg.norm(e))
    x = (_B**2 - _C**2 + L * L) / (2 * L)
    return B + x * e / L + math.sqrt(_B**2 - x * x) * np.array([-e[1], e[0]]) / L


def four_bar(th2=math.pi / 3, *, stiff=1.0, kind="revolute", damping=0.0, gravity=(0.0, -9.81, 0.0)):
    """The crank-rocker at crank angle θ2, every joint angle zero there (the initial geometry in
    the joint origins); returns (model, (θ2, θ3, θ4)) with θ3, θ4 the coupler's and rocker's
    world angles."""
    B = np.array([_A * math.cos(th2), _A * math.sin(th2)])
    C = _coupler_point(th2)
    th3 = math.atan2(*(C - B)[::-1])
    th4 = math.atan2(*(C - np.array([_D, 0.0]))[::-1])
    links = (
        SpatialLink(_bar(_A, stiff, damping=damping), SpatialJoint(origin_rpy=(0, 0, th2)), name="AB"),
        SpatialLink(_bar(_B, stiff, damping=damping), SpatialJoint(origin_rpy=(0, 0, th3 - th2)), name="BC"),
        SpatialLink(
            _bar(_C, stiff, damping=damping),
            SpatialJoint(origin_xyz=(_D, 0, 0), origin_rpy=(0, 0, th4)),
            name="DC",
            parent="base",
        ),
    )
    closure = SpatialClosure(kind, link="BC", to="DC", name="C")
    return SpatialManipulator(links, gravity, closures=(closure,), end_effector="BC"), (th2, th3, th4)


def _rocker_angle(th2):
    C = _coupler_point(th2)
    return math.atan2(C[1], C[0] - _D)


# A tree: a trunk on a yaw joint carrying two branches at its tip (one with a further link), and
# a second link on the base; full inertia tensors, payloads off the axis, a rotated base.
_TREE = (  # name, parent, axis, origin xyz, origin rpy, length
    ("trunk", "base", (0, 0, 1), (0.0, 0.0, 0.1), (0.0, 0.0, 0.0), 0.4),
    ("left", "trunk", (0, 1, 0), (0.0, 0.02, 0.0), (0.0, 0.0, 0.5), 0.3),
    ("right", "trunk", (0, 1, 0), (0.0, -0.02, 0.0), (0.3, 0.0, -0.5), 0.25),
    ("left2", "left", (0, 0, 1), (0.0, 0.0, 0.0), (0.0, 0.4, 0.0), 0.2),
    ("side", "base", (0, 1, 0), (-0.1, 0.2, 0.0), (0.0, 0.0, 1.0), 0.2),
)


def tree(rigid=False, stiff=1.0):
    links = []
    for i, (name, parent, axis, xyz, rpy, L) in enumerate(_TREE):
        if rigid:
            inertia = ((2e-3, 1e-4, 0.0), (1e-4, 3e-3, 2e-4), (0.0, 2e-4, 2.5e-3))
            body = SpatialRigidBody(L, 0.3 + 0.1 * i, (L / 2, 0.01, -0.01), inertia)
        else:
            body = _bar(L, stiff, w=0.012)
        hub = SpatialHub(0.1, ((1e-4, 0, 0), (0, 2e-4, 0), (0, 0, 1.5e-4)))
        pay = (
            SpatialPayload(0.05, (0.01, 0.0, 0.02), ((1e-5, 0, 0), (0, 1e-5, 0), (0, 0, 1e-5)))
            if i in (2, 3)
            else None
        )
        joint = SpatialJoint(axis=axis, origin_xyz=xyz, origin_rpy=rpy)
        links.append(SpatialLink(body, joint, hub, pay, name=name, parent=parent))
    return SpatialManipulator(
        tuple(links), (0.0, -3.0, -9.81), (0.05, 0.0, 0.1), (0.1, 0.0, 0.2), end_effector="left2"
    )


def _pinocchio_tree(model):
    """Pinocchio's rigid model of :func:`tree`: a flexible link as its undeformed bar (mass ρA L
    at L/2, inertia about the centre diag(ρJ L, ρIy L + ρA L³/12, ρIz L + ρA L³/12))."""
    pin = pytest.importorskip("pinocchio")
    pm = pin.Model()
    pm.gravity = pin.Motion(np.array(model.gravity), np.zeros(3))
    ids = {}
    for name, parent, axis, xyz, rpy, L in _TREE:
        if parent == "base":
            place = pin.SE3(rpy_matrix(model.base_rpy), np.array(model.base_xyz, float))
        else:
            place = pin.SE3(np.eye(3), np.array([dict((t[0], t[5]) for t in _TREE)[parent], 0.0, 0.0]))
        place = place * pin.SE3(rpy_matrix(rpy), np.array(xyz, float))
        j = pm.addJoint(
            ids.get(parent, 0), pin.JointModelRevoluteUnaligned(np.array(axis, float)), place, name
        )
        ids[name] = j
        lk = model.links[model.link_names.index(name)]
        b = lk.beam
        if lk.rigid:
            inertia = pin.Inertia(b.mass, np.array(b.com), b.inertia_matrix)
        else:
            m = b.rhoA * L
            rot = np.diag([b.rhoJ * L, b.rhoIy * L + m * L * L / 12, b.rhoIz * L + m * L * L / 12])
            inertia = pin.Inertia(m, np.array([L / 2, 0.0, 0.0]), rot)
        inertia = inertia + pin.Inertia(lk.hub_mass, np.zeros(3), np.array(lk.hub_inertia))
        if lk.payload_mass:
            c = np.array([L, 0.0, 0.0]) + np.array(lk.payload_offset)
            inertia = inertia + pin.Inertia(lk.payload_mass, c, np.array(lk.payload_inertia))
        pm.appendBodyToJoint(j, inertia, pin.SE3.Identity())
    return pin, pm


def _pinocchio_run(pin, pm, drives, duration, h, output_step):
    """Pinocchio's rigid tree from rest under the torque drives: classical RK4 on its
    articulated-body forward dynamics, sampled every ``output_step``."""
    data = pm.createData()
    q, v = np.zeros(pm.nq), np.zeros(pm.nv)

    def acc(t, q, v):
        return pin.aba(pm, data, q, v, np.array([d.torque(t) for d in drives]))

    out, every = [q.copy()], int(round(output_step / h))
    for s in range(int(round(duration / h))):
        t = s * h
        k1q, k1v = v, acc(t, q, v)
        k2q, k2v = v + h / 2 * k1v, acc(t + h / 2, q + h / 2 * k1q, v + h / 2 * k1v)
        k3q, k3v = v + h / 2 * k2v, acc(t + h / 2, q + h / 2 * k2q, v + h / 2 * k2v)
        k4q, k4v = v + h * k3v, acc(t + h, q + h * k3q, v + h * k3v)
        q = q + h / 6 * (k1q + 2 * k2q + 2 * k3q + k4q)
        v = v + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        if (s + 1) % every == 0:
            out.append(q.copy())
    return np.array(out)


def _out(res, name):
    """A closure output of a run: its field of the result, or its entry of ``meta``."""
    value = getattr(res, name, None)
    return res.meta[name] if value is None else value


def _arrays(res):
    out = {k: v for k, v in vars(res).items() if isinstance(v, np.ndarray)}
    out.update({f"meta.{k}": res.meta[k] for k in ("q", "qd")})
    return out


# ----------------------------------------------------------------------------------------------
# trees
# ----------------------------------------------------------------------------------------------


def test_chain_with_explicit_parents_is_the_chain_bit_for_bit():
    """The yaw + pitch + pitch arm written with names, explicit parents ("base", then the
    previous link) and its last link as the end effector gives every output array of the plain
    chain bit for bit (Newmark with cut loads and link shapes; the mass matrix and forces)."""
    chain = arm()
    names = ("shoulder", "upper", "fore")
    links = tuple(
        dataclasses.replace(lk, name=n, parent="base" if i == 0 else names[i - 1])
        for i, (lk, n) in enumerate(zip(chain.links, names))
    )
    named = dataclasses.replace(chain, links=links, end_effector="fore")
    assert named.parents == (-1, 0, 1)
    runs = []
    for model in (chain, named):
        case = _case(model, _torque_drives(3), 0.02, 0.01)
        runs.append(sg.simulate(case, elements_per_link=2, h=2e-3, cut_loads=True, shape_points=3))
    a, b = (_arrays(r) for r in runs)
    assert a.keys() == b.keys()
    for key in a:
        assert np.array_equal(a[key], b[key]), key
    q = runs[0].meta["q"][-1]
    cases = [_case(m, _torque_drives(3), 0.02, 0.01) for m in (chain, named)]
    assert np.array_equal(*(sg.mass_matrix(c, 2, q) for c in cases))
    assert np.array_equal(*(sg.generalized_forces(c, 2, q, runs[0].meta["qd"][-1]) for c in cases))


def test_rigid_tree_equals_pinocchio():
    """A tree of rigid links (a branch at the trunk's tip, a second link on the base, a rotated
    base, gravity, payloads): at a random state the frames, the mass matrix (from Pinocchio's
    RNEA, column by column) and the velocity and gravity terms (Pinocchio's ``nle``) equal the
    global solver's to round-off (measured: 1e-15 relative), and the end effector is the
    named link's tip."""
    model = tree(rigid=True)
    pin, pm = _pinocchio_tree(model)
    data = pm.createData()
    case = _case(model, [Drive("torque", Constant(0.0))] * 5, 0.02, 0.01)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, qd = rng.uniform(-2, 2, 5), rng.uniform(-2, 2, 5)
        pin.forwardKinematics(pm, data, q)
        kin = sg.kinematics(case, 1, q)
        for i, (_, _, _, _, _, L) in enumerate(_TREE):
            frame = data.oMi[i + 1]
            np.testing.assert_allclose(kin["root"][i], frame.translation, rtol=0, atol=1e-15)
            np.testing.assert_allclose(kin["tip"][i], frame.act(np.array([L, 0.0, 0.0])), rtol=0, atol=1e-15)
            np.testing.assert_allclose(kin["root_rotation"][i], frame.rotation, rtol=0, atol=1e-15)
        zero = np.zeros(5)
        M = np.column_stack(
            [pin.rnea(pm, data, q, zero, e) - pin.rnea(pm, data, q, zero, zero) for e in np.eye(5)]
        )
        np.testing.assert_allclose(sg.mass_matrix(case, 1, q), M, rtol=0, atol=1e-14 * np.abs(M).max())
        nle = pin.nle(pm, data, q, qd)
        np.testing.assert_allclose(
            -sg.generalized_forces(case, 1, q, qd), nle, rtol=0, atol=1e-14 * np.abs(nle).max()
        )
    res = sg.simulate(case, elements_per_link=1, h=1e-2)
    assert np.array_equal(res.end_effector, res.link_tip[:, model.end_effector_index])
    assert model.end_effector_index == 3


def test_rigid_tree_cut_loads_equal_pinocchio_joint_forces():
    """At a random state of the rigid tree, from rest under joint torques: the load at the
    trunk's tip cut (everything outboard of it: both branches) equals the sum of the spatial
    forces Pinocchio's RNEA passes through the two branch joints, moved to the trunk's tip
    point; the left branch's tip cut equals the force through the joint of the link it carries."""
    model = tree(rigid=True)
    pin, pm = _pinocchio_tree(model)
    data = pm.createData()
    drives = [Drive("torque", Constant(v)) for v in (0.5, -0.3, 0.2, 0.1, -0.4)]
    case = _case(model, drives, 0.02, 0.01)
    rng = np.random.default_rng(5)
    q, qd = rng.uniform(-2, 2, 5), rng.uniform(-2, 2, 5)
    loads = sg.cut_loads(case, 1, q, qd)  # per link: root, tip (k = 1)
    tau = np.array([d.torque(0.0) for d in drives])
    qdd = pin.aba(pm, data, q, qd, tau).copy()
    np.testing.assert_allclose(sg.accelerations(case, 1, q, qd), qdd, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pin.rnea(pm, data, q, qd, qdd), tau, rtol=0, atol=1e-12)
    pin.forwardKinematics(pm, data, q)  # the joints' placements (data.oMi) at q
    kin = sg.kinematics(case, 1, q)

    def through(children, point):
        F, M = np.zeros(3), np.zeros(3)
        for j in children:
            R, o = data.oMi[j + 1].rotation, data.oMi[j + 1].translation
            f = data.f[j + 1]
            F += R @ f.linear
            M += R @ f.angular + np.cross(o - point, R @ f.linear)
        return np.concatenate([F, M])

    for link, children in ((0, (1, 2)), (1, (3,))):
        ref = through(children, kin["tip"][link])
        np.testing.assert_allclose(loads[2 * link + 1], ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def _tree_gaps(stiffs, duration, h):
    drives = [Drive("torque", Sine(a, 3.0)) for a in (0.5, 0.3, -0.3, 0.1, 0.2)]
    gaps = []
    for stiff in stiffs:
        model = tree(stiff=stiff)
        pin, pm = _pinocchio_tree(model)
        res = sg.simulate(_case(model, drives, duration, 0.02), elements_per_link=1, h=h)
        ref = _pinocchio_run(pin, pm, drives, duration, 1e-4, 0.02)
        gaps.append(float(np.max(np.abs(res.joint_angle - ref))))
    return gaps


def test_flexible_tree_tends_to_the_rigid_tree():
    """The tree with flexible links (k = 1) under smooth joint torques for 0.1 s tends to
    Pinocchio's rigid tree as the links' stiffnesses grow: the joint angles' largest gap falls
    tenfold when the stiffnesses grow tenfold (the static deflections' O(1/EI); measured
    1.01e-2 and 1.02e-3 rad)."""
    gaps = _tree_gaps((1.0, 10.0), 0.1, 5e-4)
    assert gaps[0] < 2e-2 and 7.0 < gaps[0] / gaps[1] < 13.0, gaps


@pytest.mark.slow
def test_flexible_tree_tends_to_the_rigid_tree_longer():
    """As above over 0.2 s and three stiffnesses; measured gaps 1.07e-2, 1.01e-3, 1.05e-4 rad
    (the time error at h = 0.5 ms, 2e-5 rad, is below them)."""
    gaps = _tree_gaps((1.0, 10.0, 100.0), 0.2, 5e-4)
    assert gaps[0] < 2e-2 and all(7.0 < a / b < 13.0 for a, b in zip(gaps, gaps[1:])), gaps


# ----------------------------------------------------------------------------------------------
# closed loops
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("kind", ["revolute", "spherical", "weld"])
@pytest.mark.parametrize("to", ["DC", "ground"])
def test_closure_jacobian_is_the_derivative_of_the_closure_equations(kind, to):
    """J = ∂g/∂q (analytic, from the frames' Jacobians) equals the central differences of g at
    random states (steps 1e-6; measured 5e-11 of |J| = 1), for every kind, to a link and to
    ground; g vanishes at the initial state; the closure has the spec's number of equations."""
    model, _ = four_bar(stiff=1.0, kind=kind)
    if to == "ground":
        model = dataclasses.replace(model, closures=(SpatialClosure(kind, link="BC", name="C"),))
    drives = [Drive("torque", Constant(0.0))] * 3
    case = _case(model, drives, 0.02, 0.01)
    lay = sg._layout(case, 2)
    g0 = sg._constraints(lay, np.zeros(lay.n_dof))[0]
    assert g0.size == {"revolute": 5, "spherical": 3, "weld": 6}[kind] == model.n_closure_equations
    assert np.max(np.abs(g0)) < 1e-16
    rng = np.random.default_rng(7)
    for _ in range(2):
        q = 0.05 * rng.standard_normal(lay.n_dof)
        J = sg._constraints(lay, q)[1]
        fd = np.column_stack(
            [
                (sg._constraints(lay, q + 1e-6 * e)[0] - sg._constraints(lay, q - 1e-6 * e)[0]) / 2e-6
                for e in np.eye(lay.n_dof)
            ]
        )
        np.testing.assert_allclose(J, fd, rtol=0, atol=2e-9)


def _passive_run(h, duration=0.2):
    model, _ = four_bar()
    case = _case(model, [Drive("torque", Constant(0.0))] * 3, duration, 0.01)
    return model, sg.simulate(case, elements_per_link=1, h=h)


def test_passive_loop_holds_and_conserves_energy():
    """The crank-rocker released from rest in gravity (k = 1, no damping, no drive: one
    degree of freedom of the rigid mechanism, the crank swings through about 3 rad in 0.2 s).
    The loop holds at every output (position gap ≤ 1e-10 × the mechanism's size, axis gap
    ≤ 1e-10 rad; measured 2e-16 m, 0); the closure does no work: the total energy stays
    constant to the trapezoidal rule's O(h²) (its spread falls by ≈ 4 when h halves; measured
    3.3e-5 J and 8.0e-6 J at h = 2 and 1 ms, of a kinetic energy up to 0.029 J)."""
    spreads = []
    for h in (2e-3, 1e-3):
        model, res = _passive_run(h)
        assert res.status == "ok"
        assert np.max(_out(res, "closure_residual")) <= 1e-10 * model.size
        assert np.max(_out(res, "closure_angle_residual")) <= 1e-10
        spreads.append(float(np.ptp(res.energy)))
        swing = float(np.ptp(res.joint_angle[:, 0]))
    kinetic = max(
        sg.energy(_case(model, [Drive("torque", Constant(0.0))] * 3, 0.2, 0.01), 1, q, qd)["kinetic"]
        for q, qd in zip(res.meta["q"], res.meta["qd"])
    )
    assert swing > 1.0 and kinetic > 0.01, (swing, kinetic)
    assert spreads[0] < 3e-3 * kinetic, spreads
    assert 3.0 < spreads[0] / spreads[1] < 5.5, spreads


def _rocker_gap(stiff, duration=0.15):
    model, (th2, _, th4) = four_bar(stiff=stiff)
    drives = [
        Drive("motion", SpinUp(10.0, 0.1)),
        Drive("torque", Constant(0.0)),
        Drive("torque", Constant(0.0)),
    ]
    res = sg.simulate(_case(model, drives, duration, 0.01), elements_per_link=1, h=1e-3)
    closed = np.array([_rocker_angle(th2 + a) for a in res.joint_angle[:, 0]])
    return float(np.max(np.abs(th4 + res.joint_angle[:, 2] - closed))), float(np.ptp(res.joint_angle[:, 2]))


def test_nearly_rigid_four_bar_follows_the_closed_form_loop_closure():
    """The crank driven through a spin-up to 10 rad/s (0.1 s ramp, 0.15 s: the crank turns
    0.99 rad): the rocker's angle follows the rigid mechanism's loop closure (C where the
    circles about B and D of radii BC and DC cross) to the links' deflection, which falls a
    hundredfold when the stiffnesses grow a hundredfold."""
    soft, swing = _rocker_gap(1e2)
    stiff, _ = _rocker_gap(1e4)
    assert swing > 0.3
    assert soft < 1e-4 and stiff < 1e-6 * 10 and 50 < soft / stiff < 200, (soft, stiff)


def test_loop_held_by_its_crank_carries_the_statics_by_hand():
    """The crank-rocker held at rest by its crank (motion drive at 0) in gravity, links 1e3
    times stiffer and damped, generalized-α (ρ∞ = 0.3) until the vibrations have died out
    (0.05 s): the closure force on BC from DC, the crank's torque and the cut loads at the
    closure equal the hand statics of the two pinned bars (moment balance of BC about B and DC
    about D under their weights), to the links' residual sag (measured 1e-8 relative)."""
    model, (th2, th3, th4) = four_bar(stiff=1e3, damping=2e-5)
    drives = [Drive("motion", Constant(0.0)), Drive("torque", Constant(0.0)), Drive("torque", Constant(0.0))]
    case = _case(model, drives, 0.05, 0.01)
    res = sg.simulate(
        case, elements_per_link=1, h=1e-3, cut_loads=True, integrator="generalized-alpha", rho_inf=0.3
    )
    B = _A * np.array([math.cos(th2), math.sin(th2)])
    C = B + _B * np.array([math.cos(th3), math.sin(th3)])
    D = np.array([_D, 0.0])
    rhoA = model.links[0].beam.rhoA
    g = np.array(model.gravity[:2])

    def cross(u, v):
        return u[0] * v[1] - u[1] * v[0]

    # F on BC at C: (C − B) × F + (C − B)/2 × W_BC = 0 and (C − D) × (−F) + (C − D)/2 × W_DC = 0
    A = np.array([[-(C - B)[1], (C - B)[0]], [-(C - D)[1], (C - D)[0]]])
    F = np.linalg.solve(A, [-cross((C - B) / 2, rhoA * _B * g), cross((C - D) / 2, rhoA * _C * g)])
    tau = -cross(B, F + rhoA * _B * g) - cross(B / 2, rhoA * _A * g)
    load = _out(res, "closure_loads")[-1, 0]
    np.testing.assert_allclose(load[:2], F, rtol=1e-6)
    assert np.max(np.abs(load[2:])) < 1e-9 * np.abs(F).max()
    assert res.joint_torque[-1, 0] == pytest.approx(tau, rel=1e-6)
    # the closure load acts on the outboard side of BC's and DC's tip cuts (k = 1: cuts 1 and 5)
    np.testing.assert_allclose(res.cut_loads[-1, 3], -load, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.cut_loads[-1, 5], load, rtol=0, atol=1e-9)


def test_closed_loop_refusals():
    """RK4 with a closed loop, and an explicit ``to_point`` that leaves the loop open at the
    initial state, are refused in one line naming the field and value."""
    model, _ = four_bar()
    drives = [Drive("torque", Constant(0.0))] * 3
    with pytest.raises(dttmm.InputError, match=r"integrator.*rk4.*closed loops"):
        sg.simulate(_case(model, drives, 0.02, 0.01), elements_per_link=1, h=1e-3, integrator="rk4")
    C = _coupler_point(math.pi / 3)
    far = SpatialClosure("revolute", link="BC", to="ground", to_point=(C[0] + 1e-6, C[1], 0.0), name="C")
    with pytest.raises(dttmm.InputError, match=r"model\.closures\[0\]\.to_point.*'C'.*open"):
        sg.simulate(
            _case(dataclasses.replace(model, closures=(far,)), drives, 0.02, 0.01),
            elements_per_link=1,
            h=1e-3,
        )
    near = dataclasses.replace(far, to_point=(C[0], C[1], 0.0))
    res = sg.simulate(
        _case(dataclasses.replace(model, closures=(near,)), drives, 0.02, 0.01), elements_per_link=1, h=1e-3
    )
    assert np.max(_out(res, "closure_residual")) < 1e-10 * model.size


def test_bauchau_four_bar_holds_its_tilted_revolute():
    """The shipped flexible four-bar (the revolute at C about (sin 5°, 0, cos 5°)), k = 1, its
    first 0.02 s: the loop holds (gaps ≤ 1e-10 of the size, axis gap ≤ 1e-12 rad; measured
    5e-23 m, 3e-17 rad), the closure's moment has no component along the joint's axis (the
    joint turns freely about it) while the other components carry the bending the tilt causes."""
    case = dttmm.load_case(CASES / "spatial" / "topology" / "four_bar.toml")
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.02, output_step=0.002)
    )
    res = sg.simulate(case, elements_per_link=1, h=1e-3)
    assert res.status == "ok"
    assert np.max(_out(res, "closure_residual")) <= 1e-10 * case.model.size
    assert np.max(_out(res, "closure_angle_residual")) <= 1e-12
    loads = _out(res, "closure_loads")[-5:, 0]  # 1e-3 … 8e-3 N·m
    axis = np.array(case.model.closures[0].axis)  # BC's tip frame turns with the crank: ≤ 1e-4 rad
    moment = np.linalg.norm(loads[:, 3:], axis=1)
    assert np.min(moment) > 5e-4
    assert np.max(np.abs(loads[:, 3:] @ axis) / moment) < 1e-3
