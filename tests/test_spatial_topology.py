"""Trees and closed loops of spatial arms (docs/spatial.md "Trees and closed loops"): the
topology data (link names and parents, closures, the end-effector) in the model and the case
file, the engines that refuse them, the tree sweep of the spatial DT-TMM and its loop closure."""

from __future__ import annotations

import dataclasses
import itertools
import tomllib
from pathlib import Path

import numpy as np
import pytest

import dttmm
import dttmm.spatial as sp
from dttmm import InputError
from dttmm.spatial import SpatialClosure, SpatialLink, SpatialManipulator, SpatialSection
from dttmm.spatial.case import case_from_dict, case_to_dict, load_case
from experiments.handchecks import five_bar_tip, stiffened

TOPO = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"
FOUR_BAR = TOPO / "four_bar.toml"


def _beam(length=0.3):
    return SpatialSection(length=length, GJ=30.0, EIy=40.0, EIz=40.0, rhoA=0.8, rhoJ=4e-4, EA=2e6)


def _four_bar_dict() -> dict:
    return tomllib.loads(FOUR_BAR.read_text())


def _refused(data: dict) -> InputError:
    with pytest.raises(InputError) as info:
        case_from_dict(data)
    assert "\n" not in str(info.value)
    return info.value


# ------------------------------------------------------------------ the data layer ------------


def test_four_bar_topology():
    """The shipped four-bar: two branches from the base (AB → BC, CD), one revolute cut joint."""
    case = load_case(FOUR_BAR)
    m = case.model
    assert m.link_names == ("AB", "BC", "CD")
    assert m.parents == (-1, 0, -1)
    assert m.children(-1) == (0, 2) and m.children(0) == (1,) and m.children(1) == ()
    assert m.leaves == (1, 2)
    assert m.end_effector_index == 2 and not m.serial
    assert m.n_closure_equations == 5 and m.closure_names == ("C",)
    assert case.provenance["source"].startswith("O. A. Bauchau")


def test_default_names_and_parents():
    """Unnamed links are link1, link2, …; every parent defaults to the previous link; a chain
    written with explicit parents is the same arm as one without (serial)."""
    links = (SpatialLink(_beam()), SpatialLink(_beam()), SpatialLink(_beam()))
    m = SpatialManipulator(links)
    assert m.link_names == ("link1", "link2", "link3") and m.parents == (-1, 0, 1) and m.serial
    explicit = tuple(
        dataclasses.replace(lk, name=f"l{i}", parent="base" if i == 0 else f"l{i - 1}")
        for i, lk in enumerate(links)
    )
    m2 = SpatialManipulator(explicit, end_effector="l1")
    assert m2.parents == (-1, 0, 1) and m2.serial and m2.end_effector_index == 1
    tree = SpatialManipulator((links[0], links[1], dataclasses.replace(links[2], parent="link1")))
    assert tree.parents == (-1, 0, 0) and tree.leaves == (1, 2) and not tree.serial


def test_round_trip():
    """case_to_dict → case_from_dict rebuilds the four-bar and a tree with an end-effector; the
    existing (serial) cases write no topology keys."""
    case = load_case(FOUR_BAR)
    assert case_from_dict(case_to_dict(case)) == case
    data = _four_bar_dict()
    data["model"]["end_effector"] = "BC"
    data["model"]["closures"][0]["to_point"] = [0.0, 0.0, 0.0]
    data["model"]["closures"][0]["kind"] = "spherical"
    c2 = case_from_dict(data)
    assert c2.model.end_effector == "BC" and c2.model.closures[0].to_point == (0.0, 0.0, 0.0)
    assert case_from_dict(case_to_dict(c2)) == c2
    serial = load_case(TOPO.parent / "two_joint_arm.toml")
    d = case_to_dict(serial)
    assert "closures" not in d["model"] and "end_effector" not in d["model"]
    assert all("name" not in lk and "parent" not in lk for lk in d["model"]["links"])


@pytest.mark.parametrize(
    ("edit", "field", "words"),
    [
        (lambda d: d["model"]["links"][1].update(parnet="AB"), "parnet", "parent"),
        (lambda d: d["model"]["closures"][0].update(too="CD"), "too", "to"),
        (lambda d: d["model"].update(end_efector="BC"), "end_efector", "end_effector"),
        (lambda d: d["model"]["links"][1].update(parent="CD"), "model.links[1].parent", "listed before"),
        (lambda d: d["model"]["links"][1].update(parent="XY"), "model.links[1].parent", "names no link"),
        (lambda d: d["model"]["links"][2].update(name="AB"), "model.links[2].name", "unique"),
        (lambda d: d["model"]["links"][2].update(name="ground"), "model.links[2].name", "reserved"),
        (lambda d: d["model"]["closures"][0].update(link="XY"), "model.closures[0].link", "names no link"),
        (lambda d: d["model"]["closures"][0].update(to="XY"), "model.closures[0].to", "names no link"),
        (lambda d: d["model"]["closures"][0].update(to="BC"), "model.closures[0].to", "must differ"),
        (lambda d: d["model"]["closures"][0].update(axis=[1.0, 1.0, 0.0]), "model.closures[0].axis", "unit"),
        (lambda d: d["model"]["closures"][0].update(kind="prismatic"), "model.closures[0].kind", "revolute"),
        (lambda d: d["model"].update(end_effector="XY"), "model.end_effector", "must name a link"),
        (
            lambda d: d["model"]["closures"][0].update(to_point=[0.0, 1e-3, 0.0]),
            "model.closures[0].to_point",
            "open by 0.001 m",
        ),
    ],
)
def test_refusals(edit, field, words):
    """Each bad topology entry is a one-line InputError naming the field (an unknown key with
    the nearest valid one) and its reason."""
    data = _four_bar_dict()
    edit(data)
    msg = str(_refused(data))
    assert field in msg and words in msg, msg


def test_closure_record_refusals():
    """SpatialClosure checks its own fields; the manipulator checks the names it uses."""
    with pytest.raises(InputError, match="closure.point"):
        SpatialClosure("weld", "a", point=(0.0, 1.0))
    with pytest.raises(InputError, match="closure.link"):
        SpatialClosure("weld", "ground")
    with pytest.raises(InputError, match=r"model.closures\[0\]"):
        SpatialManipulator((SpatialLink(_beam()),), closures=("C",))


def test_serial_only_engines_refuse():
    """The engines that run chains only refuse a tree or a loop in one line, naming themselves;
    Pinocchio's rigid model refuses the four-bar's tilted revolute closure."""
    case = load_case(FOUR_BAR)
    from dttmm.spatial.inverse_dynamics import rigid_inverse_dynamics
    from dttmm.urdf import case_to_urdf

    with pytest.raises(InputError, match="trees and closed loops are not supported by the rigid inverse"):
        rigid_inverse_dynamics(case.model, np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="trees and closed loops are not supported by the URDF export"):
        case_to_urdf(case)
    pin = pytest.importorskip("pinocchio")  # noqa: F841
    from reference_models import pinocchio_spatial

    with pytest.raises(InputError, match="not supported by pinocchio-spatial"):
        pinocchio_spatial.check_case(case)  # the tilted revolute C (tests/test_topology_peers.py)


# ------------------------------------------------------------------ trees ---------------------

BRANCHED = TOPO / "branched_arm.toml"


def _short(case, duration, output_step=None):
    sc = dataclasses.replace(case.scenario, duration=duration)
    if output_step is not None:
        sc = dataclasses.replace(sc, output_step=output_step)
    return dataclasses.replace(case, scenario=sc)


def _rigid_tree(case):
    """The case with every link a SpatialRigidBody of its undeformed beam's mass, centre and
    inertia (rod + rotary inertia), hubs and payloads kept."""
    links = []
    for lk in case.model.links:
        b = lk.beam
        m, L = b.rhoA * b.length, b.length
        J = np.diag([b.rhoJ * L, b.rhoIy * L + m * L * L / 12, b.rhoIz * L + m * L * L / 12])
        body = sp.SpatialRigidBody(L, m, (L / 2, 0.0, 0.0), J)
        links.append(dataclasses.replace(lk, beam=body))
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=tuple(links)))


def _pin_tree(model):
    """Pinocchio's rigid model of a spatial tree, built joint by joint with the same parents
    (every joint unlocked, the base at the world origin)."""
    pin = pytest.importorskip("pinocchio")
    from dttmm.spatial.rotation import rpy_matrix
    from reference_models.pinocchio_spatial import link_inertia

    pm = pin.Model()
    tip = {-1: (0, pin.SE3(rpy_matrix(model.base_rpy), np.array(model.base_xyz, float)))}
    for i, link in enumerate(model.links):
        jpar, place = tip[model.parents[i]]
        origin = pin.SE3(rpy_matrix(link.joint.origin_rpy), np.array(link.joint.origin_xyz, float))
        jid = pm.addJoint(
            jpar, pin.JointModelRevoluteUnaligned(np.array(link.joint.axis)), place * origin, f"j{i}"
        )
        pm.appendBodyToJoint(jid, link_inertia(link), pin.SE3.Identity())
        tip[i] = (jid, pin.SE3(np.eye(3), np.array([link.beam.length, 0.0, 0.0])))
    pm.gravity.linear = np.array(model.gravity, float)
    return pm


def test_rigid_tree_accelerations_equal_pinocchio():
    """The branched arm with rigid links: the tree sweep's q̈ at random states = Pinocchio's ABA
    on a tree built by hand with the same parents (hubs, payloads with offsets, gravity)."""
    pin = pytest.importorskip("pinocchio")
    case = _rigid_tree(load_case(BRANCHED))
    pm = _pin_tree(case.model)
    pd = pm.createData()
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(4):
        q, v, tau = rng.normal(size=4), rng.normal(size=4), rng.normal(size=4)
        drives = tuple(dttmm.Drive("torque", dttmm.Constant(float(t))) for t in tau)
        c = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives))
        qdd = sp.accelerations(c, 1, q, v, engine="python")
        ref = pin.aba(pm, pd, q, v, tau)
        worst = max(worst, np.max(np.abs(qdd - ref)) / np.max(np.abs(ref)))
    assert worst < 1e-12, worst


def _tree_gap(f):
    """max |joint angle − Pinocchio's| (rad) of the branched arm with every stiffness × f (k = 2,
    Newmark, h = 5e-4, 0.2 s), and the largest joint angle."""
    pin = pytest.importorskip("pinocchio")
    from scipy.integrate import solve_ivp

    case = _short(_stiffened(load_case(BRANCHED), f), 0.2, 0.01)
    r = sp.simulate(case, elements_per_link=2, h=5e-4)
    pm = _pin_tree(case.model)
    pd = pm.createData()
    drives = case.scenario.drives

    def rhs(t, y):
        tau = np.array([d.torque(t) for d in drives])
        return np.concatenate([y[4:], pin.aba(pm, pd, y[:4], y[4:], tau)])

    bps = sorted({b for d in drives for b in d.law.breakpoints if b < 0.2} | {0.0, 0.2})
    y, ref = np.zeros(8), np.zeros((r.t.size, 4))
    for a, b in itertools.pairwise(bps):
        sol = solve_ivp(rhs, (a, b), y, method="DOP853", rtol=1e-12, atol=1e-13, dense_output=True)
        sel = (r.t >= a) & (r.t <= b)
        ref[sel] = sol.sol(r.t[sel])[:4].T
        y = sol.y[:, -1]
    return float(np.max(np.abs(r.joint_angle - ref))), float(np.max(np.abs(ref)))


def test_stiff_tree_approaches_pinocchio():
    """The branched arm with every stiffness × 1e3 and × 1e4 against Pinocchio's rigid tree
    (same parents; ABA integrated by SciPy's DOP853, rtol 1e-12): the joint angles (up to
    0.9 rad) differ by the links' compliance, which falls as 1/stiffness (measured 8.8e-5 and
    9.3e-6 rad; 8.6e-4 at × 1e2)."""
    soft, swing = _tree_gap(1e3)
    stiff, _ = _tree_gap(1e4)
    assert swing > 0.5
    assert soft < 1.5e-4 and stiff < 1.5e-5 and 7 < soft / stiff < 13, (soft, stiff)


def test_explicit_parents_change_nothing():
    """A chain written with explicit `parent` keys runs bit for bit as the same chain without."""
    case = _short(load_case(TOPO.parent / "three_joint_arm.toml"), 0.02, 0.005)
    links = tuple(
        dataclasses.replace(lk, name=f"l{i}", parent="base" if i == 0 else f"l{i - 1}")
        for i, lk in enumerate(case.model.links)
    )
    named = dataclasses.replace(case, model=dataclasses.replace(case.model, links=links))
    kw = dict(elements_per_link=2, h=1e-3, cut_loads=True, engine="python")
    a, b = sp.simulate(case, **kw), sp.simulate(named, **kw)
    for name in ("joint_angle", "joint_torque", "link_tip", "end_effector", "cut_loads", "energy", "twist"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name


# ------------------------------------------------------------------ closed loops --------------

FIVE_BAR = TOPO / "five_bar.toml"


def _stiffened(case, f):
    """Every link's stiffnesses (EA, GJ, EIy, EIz) × f."""
    return stiffened(case, f)


def _five_bar_tip(case, t):
    """The rigid five-bar's distal tip at time t (m): the closed-form loop-closure geometry."""
    return five_bar_tip(case, t)


def test_loop_refusals():
    """A closed loop runs with the Newmark family to the stop rule, open-loop drives and pd/pid
    laws; the rest is refused in one line (RK4, fixed or "auto" sweep counts, user laws, statics,
    linearisation, the one-state forward dynamics)."""
    case = _short(load_case(FOUR_BAR), 0.002, 0.001)
    for kw, field in (({"integrator": "rk4"}, "integrator"), ({"iterations": "auto"}, "iterations")):
        with pytest.raises(InputError, match=field) as info:
            sp.simulate(case, elements_per_link=1, h=1e-3, engine="python", **kw)
        assert "\n" not in str(info.value)
    from dttmm.drives import UserLaw

    user = dttmm.Drive("torque", UserLaw(lambda t, state: 0.0))
    drives = (case.scenario.drives[0], user, case.scenario.drives[2])
    c2 = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives))
    with pytest.raises(InputError, match=r"scenario.drives\[1\].law.*user law"):
        sp.simulate(c2, elements_per_link=1, h=1e-3, engine="python")
    with pytest.raises(InputError, match="closed loops are not supported by dttmm.spatial.accelerations"):
        sp.accelerations(case, 1, np.zeros(3 + 3 * 6), np.zeros(3 + 3 * 6), engine="python")
    with pytest.raises(InputError, match="not supported by the spatial statics"):
        sp.statics(case, elements_per_link=1, engine="python")


def test_four_bar_closure_holds():
    """Bauchau's four-bar (k = 2, h = 1e-3, 0.2 s: the crank spun up to −0.6 rad/s): the closure
    holds at position level to ≤ 1e-10 × the mechanism's size at every output time (step ends),
    its axis to ≤ 1e-10 rad; the crank follows its law; the tilted joint loads the loop."""
    case = load_case(FOUR_BAR)
    r = sp.simulate(case, elements_per_link=2, h=1e-3, cut_loads=True)
    assert r.status == "ok"
    size = case.model.size
    assert np.max(r.closure_residual) <= 1e-10 * size, np.max(r.closure_residual)
    assert np.max(r.closure_angle_residual) <= 1e-10, np.max(r.closure_angle_residual)
    law = case.scenario.drives[0]
    assert np.allclose(r.joint_angle[:, 0], [law.motion(t)[0] for t in r.t], rtol=0, atol=1e-14)
    assert np.max(np.abs(r.closure_loads)) > 1e-3  # the tilted axis: the links bend against it
    # the tip cut of BC (the load on its massless outboard side) balances the closure load
    k = 2
    tip_bc = 2 * (k + 1) - 1
    assert np.allclose(r.cut_loads[-1, tip_bc], -r.closure_loads[-1, 0], rtol=1e-6, atol=1e-9)


@pytest.mark.slow
def test_four_bar_closure_holds_over_two_seconds():
    """The four-bar over 2 s (the crank turns 1.17 rad at −0.6 rad/s): the closure holds at every
    step end to ≤ 1e-10 × the mechanism's size and its axis to ≤ 1e-10 rad."""
    case = _short(load_case(FOUR_BAR), 2.0, 0.01)
    r = sp.simulate(case, elements_per_link=2, h=1e-3)
    assert r.status == "ok" and abs(r.joint_angle[-1, 0] + 0.6 * (2.0 - 0.05)) < 1e-12
    assert np.max(r.closure_residual) <= 1e-10 * case.model.size, np.max(r.closure_residual)
    assert np.max(r.closure_angle_residual) <= 1e-10, np.max(r.closure_angle_residual)


def test_four_bar_closure_costs_few_sweeps():
    """The loop closure's quasi-Newton iteration on the closure loads (W measured anew every
    W_EVERY steps, extrapolated between; the gaps' round-off floor in the stop rule, against the
    change still to come from the iterates' contraction): the four-bar (k = 2, h = 1e-3,
    0.05 s) takes at most 3.8 sweeps per step (measured 3.48; 3.94 stopping on the change
    itself; 4.9 with W every 8th step, kept; 46 with W measured at every iteration), within
    1.25× its cut-open tree's (the same links with closures=(): 2.96), and a step at most
    m + 6."""
    case = _short(load_case(FOUR_BAR), 0.05, 0.01)
    loop = sp.simulate(case, elements_per_link=2, h=1e-3, energy=False)
    tree = sp.simulate(
        dataclasses.replace(case, model=dataclasses.replace(case.model, closures=())),
        elements_per_link=2,
        h=1e-3,
        energy=False,
    )
    assert loop.status == "ok" and loop.meta["unconverged_steps"] == 0
    assert loop.meta["sweeps_per_step"] <= 3.8, loop.meta["sweeps_per_step"]
    assert loop.meta["sweeps_per_step"] <= 1.25 * tree.meta["sweeps_per_step"]
    assert loop.meta["max_sweeps"] <= 5 + 6, loop.meta["max_sweeps"]


@pytest.mark.parametrize("name", ["topology/branched_arm.toml", "robots/ur5.toml"])
def test_tip_frames_are_the_kinematics_tip_frames(name):
    """tip_frames (the closures' gap at the sweep's q̈) gives the link tip frames and origins of
    kinematics bit for bit at a random configuration: a tree of extensible beams, and a URDF arm
    of rigid links, locked joints and beams without the axial coordinate."""
    from dttmm.spatial.build import build_model, make_work
    from dttmm.spatial.kernel_python import core

    case = dttmm.load_case(TOPO.parent / name)
    md = build_model(case.model, 3)
    q = np.random.default_rng(3).normal(scale=0.3, size=md.ndof)
    full, tips = make_work(md), make_work(md)
    core.kinematics(md, full, q, np.zeros(md.ndof))
    core.tip_frames(md, tips, q)
    assert np.array_equal(full.RT, tips.RT) and np.array_equal(full.pT, tips.pT)
    assert np.ptp(full.pT[1:], axis=0).max() > 0.1  # the tips are apart


def _closures_with(B, W, X, T):
    """A Closures record (uncompiled kernel) of one revolute closure (m = 5) holding B, W, X, T."""
    from dttmm.spatial.kernel_python import loop as kl

    n, nd = T.shape[1], X.shape[1]
    ei = np.zeros(1, np.int64)
    cl = kl.new_closures(n, nd, 15, 4, ei, ei, ei + 1, *(np.zeros((1, 3)),) * 4, np.zeros((1, 3, 3)), 5)
    cl.B[:] = B
    cl.W[:] = W
    cl.X[:] = X
    cl.T[:] = T
    return kl, cl


def _revolute_directions(angle):
    """Load directions of a revolute closure: the three forces, two moments ⊥ z turned by angle."""
    B = np.zeros((6, 5))
    B[:3, :3] = np.eye(3)
    c, s = np.cos(angle), np.sin(angle)
    B[3:, 3] = (c, s, 0.0)
    B[3:, 4] = (-s, c, 0.0)
    return B


def test_closure_compliance_extrapolated_between_measurements():
    """W, X, T kept in world components at two measured steps and extrapolated linearly to a
    later step (closure_predict), in that step's load directions: a compliance C(s) = C0 + s C1
    (world, symmetric) measured at steps 0 and 16 in directions turned by 0.3 and 0.7 rad is
    predicted at step 20, in directions turned by 1.1 rad, as B(1.1)ᵀ C(20) B(1.1) (exact: C is
    linear in s and the directions span the same loads); with one measurement kept, the last
    one turned into the new directions."""
    rng = np.random.default_rng(7)
    A0, A1 = rng.normal(size=(6, 6)), rng.normal(size=(6, 6))
    C0, C1 = A0 @ A0.T + 6 * np.eye(6), 0.01 * (A1 + A1.T)
    C0[5, :] = C0[:, 5] = 0.0  # no moment about the axis z: outside the directions' span
    C1[5, :] = C1[:, 5] = 0.0
    C0[5, 5] = 1.0
    XW0, XW1 = rng.normal(size=(6, 9)), 0.01 * rng.normal(size=(6, 9))
    TW0, TW1 = rng.normal(size=(6, 3)), 0.01 * rng.normal(size=(6, 3))
    XW0[5] = XW1[5] = TW0[5] = TW1[5] = 0.0

    def measured(s, angle):
        B = _revolute_directions(angle)
        return B, B.T @ (C0 + s * C1) @ B, B.T @ (XW0 + s * XW1), B.T @ (TW0 + s * TW1)

    kl, cl = _closures_with(*measured(0, 0.3))
    kl.closure_record(cl, 0)
    B, W, X, T = measured(16, 0.7)
    cl.B[:], cl.W[:], cl.X[:], cl.T[:] = B, W, X, T
    kl.closure_record(cl, 16)
    cl.B[:] = _revolute_directions(1.1)
    assert kl.closure_predict(cl, 20)
    _, W20, X20, T20 = measured(20, 1.1)
    np.testing.assert_allclose(cl.W, W20, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cl.X, X20, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cl.T, T20, rtol=0, atol=1e-12)
    np.testing.assert_allclose(cl.Wi @ W20, np.eye(5), rtol=0, atol=1e-12)
    # one measurement kept (after a restart): the last one, in the new directions
    kl2, one = _closures_with(*measured(16, 0.7))
    kl2.closure_record(one, 16)
    one.B[:] = _revolute_directions(1.1)
    assert kl2.closure_predict(one, 20)
    np.testing.assert_allclose(one.W, measured(16, 1.1)[1], rtol=0, atol=1e-12)


def _five_bar_gap(f):
    case = _short(_stiffened(load_case(FIVE_BAR), f), 0.1, 0.01)
    r = sp.simulate(case, elements_per_link=2, h=5e-4)
    ref = _five_bar_tip(case, r.t)
    assert np.max(r.closure_residual) <= 1e-10 * case.model.size
    return float(np.max(np.abs(r.end_effector - ref))), float(np.max(np.abs(ref - ref[0])))


def test_stiff_five_bar_follows_rigid_geometry():
    """The five-bar with every stiffness × 10 and × 100 (k = 2, h = 5e-4, 0.1 s): its distal
    tip follows the rigid mechanism's closed-form loop-closure geometry (where the circles about
    the driven proximal tips cross) to within the links' deflection, which falls as 1/stiffness
    (measured 3.1e-6 and 3.0e-7 m while the tip travels 0.04 m; 1.1e-4 m unstiffened)."""
    soft, travel = _five_bar_gap(10.0)
    stiff, _ = _five_bar_gap(100.0)
    assert travel > 0.03
    assert soft < 5e-6 and stiff < 5e-7 and 7 < soft / stiff < 14, (soft, stiff)


# ------------------------------------------------------------------ DT-TMM = global solver -----


@pytest.mark.parametrize("name", ["four_bar", "five_bar", "branched_arm"])
def test_dttmm_equals_global_solver(name):
    """The shipped tree and loop cases, k = 2, Newmark, h = 1e-3, 0.05 s: the spatial DT-TMM
    (tree sweep, cut-joint loads) = the spatial global solver (its own equations: the tree's
    frame recursion, Lagrange multipliers with its own closure equations), which solve the same
    discrete equations: link tips ≤ 1e-9 m (measured ≤ 6e-17 m over 0.1 s), joint torques,
    closure loads and cut loads to round-off relative to their largest values."""
    from reference_models import spatial_global as sg

    case = _short(load_case(TOPO / f"{name}.toml"), 0.05, 0.01)
    kw = dict(elements_per_link=2, h=1e-3, cut_loads=True)
    r, g = sp.simulate(case, **kw), sg.simulate(case, **kw)
    assert np.max(np.abs(r.link_tip - g.link_tip)) <= 1e-9
    assert np.max(np.abs(r.end_effector - g.end_effector)) <= 1e-9
    assert np.max(np.abs(r.link_tip - r.link_tip[0])) > 1e-4  # the mechanism moves

    def rel(a, b):
        return np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300)

    assert rel(r.joint_angle, g.joint_angle) < 1e-9
    assert rel(r.cut_loads, g.cut_loads) < 1e-7
    if case.model.closures:
        assert rel(r.closure_loads, g.closure_loads) < 1e-7
        assert np.max(r.closure_residual) <= 1e-10 * case.model.size


def test_tree_with_closed_loop_and_motion_drives_equals_global_solver():
    """The branched arm with a pd law (moment feedback) on one finger and a motion drive on the
    other (k = 2, h = 1e-3, 0.05 s): DT-TMM = the spatial global solver (measured 5.8e-16 m,
    torques 1.4e-12 N·m)."""
    from dttmm.drives import PD
    from reference_models import spatial_global as sg

    case = load_case(BRANCHED)
    d = list(case.scenario.drives)
    d[2] = dttmm.Drive("torque", PD(2.0, 0.05, dttmm.Sine(0.3, 4.0), moment_gain=0.5))
    d[3] = dttmm.Drive("motion", dttmm.SpinUp(-2.0, 0.05))
    case = _short(
        dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=tuple(d))), 0.05, 0.01
    )
    r = sp.simulate(case, elements_per_link=2, h=1e-3)
    g = sg.simulate(case, elements_per_link=2, h=1e-3)
    assert r.status == "ok"
    assert np.max(np.abs(r.link_tip - g.link_tip)) < 1e-12
    assert np.max(np.abs(r.joint_torque - g.joint_torque)) < 1e-9
    assert np.max(np.abs(r.joint_torque[:, 2])) > 0.1 and np.max(np.abs(r.joint_torque[:, 3])) > 0.05


def _five_bar_pd(**pd):
    """The five-bar with pd laws at its two base joints tracking the shipped motion laws."""
    from dttmm.drives import PD

    case = load_case(FIVE_BAR)
    d = list(case.scenario.drives)
    for j in (0, 2):
        d[j] = dttmm.Drive("torque", PD(200.0, 5.0, d[j].law, **pd))
    return dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=tuple(d)))


def test_five_bar_with_pd_laws_equals_global_solver():
    """pd laws on a mechanism with closures: the five-bar's base joints under pd laws tracking
    the pick-and-place motion (k = 2, h = 1e-3, 0.05 s, trapezoidal Newmark): DT-TMM = the
    spatial global solver (its own implicit laws and Lagrange multipliers), the loop closed at
    every output time, the laws at work (their torques, the tracking error)."""
    from reference_models import spatial_global as sg

    case = _short(_five_bar_pd(), 0.05, 0.01)
    r = sp.simulate(case, elements_per_link=2, h=1e-3)
    g = sg.simulate(case, elements_per_link=2, h=1e-3)
    assert r.status == "ok"
    assert np.max(np.abs(r.link_tip - g.link_tip)) <= 1e-9, np.max(np.abs(r.link_tip - g.link_tip))
    tq = np.max(np.abs(g.joint_torque))
    assert np.max(np.abs(r.joint_torque - g.joint_torque)) <= 1e-7 * tq
    assert np.max(np.abs(r.closure_loads - g.closure_loads)) <= 1e-7 * np.max(np.abs(g.closure_loads))
    assert np.max(r.closure_residual) <= 1e-10 * case.model.size
    assert tq > 0.05  # the laws drive the mechanism
    law = load_case(FIVE_BAR).scenario.drives[0]
    ref = np.array([law.motion(t)[0] for t in r.t])
    assert 1e-5 < np.max(np.abs(r.joint_angle[:, 0] - ref)) < 0.2 * np.max(np.abs(ref))  # it tracks


def test_closures_refuse_user_laws_and_moment_feedback():
    """On a mechanism with closures a pd law with moment feedback is refused in one line naming
    its gain (the laws' torques would depend on the sweep's closure loads)."""
    case = _short(_five_bar_pd(moment_gain=0.5), 0.01, 0.01)
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law\.moment_gain") as info:
        sp.simulate(case, elements_per_link=1, h=1e-3, engine="python")
    assert "\n" not in str(info.value)


def test_planar_five_bar_through_dttmm_simulate():
    """`dttmm.load_case` and `dttmm.simulate` take a loop case (a planar mechanism written as a
    spatial case, every axis z) and hand it to the spatial kernel: the same arrays as
    dttmm.spatial.simulate; the motion stays in the plane."""
    case = _short(dttmm.load_case(FIVE_BAR), 0.02, 0.01)
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3)
    b = sp.simulate(case, elements_per_link=2, h=1e-3)
    for name in ("link_tip", "joint_angle", "joint_torque", "closure_loads", "closure_residual"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert np.max(np.abs(a.link_tip[..., 2])) == 0.0


def _mid_span(res, k, link=1):
    """The mid-span deflection of a link (its centre line's midpoint minus its chord's, world z)
    and the magnitude of the moment at its mid-span cut (k even: a cut at an element root)."""
    s = res.link_shapes[:, link]
    deflection = (s[:, 1] - 0.5 * (s[:, 0] + s[:, 2]))[:, 2]
    moment = np.linalg.norm(res.cut_loads[:, (k + 1) * link + k // 2, 3:], axis=1)
    return deflection, moment


def test_four_bar_runs_past_its_change_point_under_the_default_integrator():
    """The shipped four-bar for 4.5 s (the crank passes the parallelogram's change point at
    2.6 s, where the closure load peaks at 1.6 kN, and the coupler swings over): trapezoidal
    Newmark, k = 2, the default stop rule. Every step converges (the closure iteration takes
    secant updates of W where a measured W stalls; before them the run stopped with a singular
    step at 3.97 s), the loop holds to 1e-10 of the size, and the largest mid-span moment of BC
    is within 1 % of Exudyn's GE beam (k = 15, element 8's centre at the mid-span, h = 1 ms,
    ρ∞ = 0.8: 43.487 N·m at 3.51 s, recorded once by this suite's Exudyn peer; DT-TMM k = 2:
    43.370 N·m)."""
    case = _short(load_case(TOPO / "four_bar.toml"), 4.5, 0.01)
    res = sp.simulate(case, elements_per_link=2, h=1e-3, shape_points=3, cut_loads=True)
    assert res.status == "ok" and res.meta["unconverged_steps"] == 0
    assert np.max(res.closure_residual) <= 1e-10 * case.model.size
    _, moment = _mid_span(res, 2)
    assert np.max(moment) == pytest.approx(43.487, rel=1e-2)


@pytest.mark.slow
def test_four_bar_mid_span_histories_against_exudyn_over_the_paper_s_duration():
    """The four-bar for the paper's 12 s (the crank turns by −7.17 rad through two change
    points), both engines generalized-α ρ∞ = 0.8, h = 1 ms: the DT-TMM at k = 8 against
    Exudyn's GE beam at k = 15 (odd, so that an element's centre, where its one-point section
    loads are, is BC's mid-span): the mid-span deflection and moment histories within 2 % of
    their peaks (measured 0.74 % and 0.42 %; Exudyn k = 7 against k = 15: 0.73 %, 1.26 %), the
    loop gap ≤ 1e-10 of the size. About 45 s."""
    pytest.importorskip("exudyn")
    from reference_models import exudyn_beam3d as eb

    case = _short(load_case(TOPO / "four_bar.toml"), 12.0, 0.01)
    ga = dict(integrator="generalized-alpha", rho_inf=0.8)
    res = sp.simulate(case, elements_per_link=8, h=1e-3, shape_points=3, cut_loads=True, **ga)
    ref = eb.simulate(case, elements_per_link=15, h=1e-3, rho_inf=0.8, shape_points=3, section_loads="middle")
    assert res.status == "ok" and np.max(res.closure_residual) <= 1e-10 * case.model.size
    deflection, moment = _mid_span(res, 8)
    s = ref.link_shapes[:, 1]
    ref_deflection = (s[:, 1] - 0.5 * (s[:, 0] + s[:, 2]))[:, 2]
    ref_moment = np.linalg.norm(ref.cut_loads[:, 1, 3:], axis=1)
    assert np.max(np.abs(deflection - ref_deflection)) <= 0.02 * np.max(np.abs(ref_deflection))
    assert np.max(np.abs(moment - ref_moment)) <= 0.02 * np.max(ref_moment)


def test_a_failed_loop_run_under_the_undamped_trapezoidal_rule_names_the_remedy():
    """A loop run that stops under Newmark β = ¼, γ = ½ (the four-bar's 12 s at k = 8 stops at
    6.42 s: its index-3 closure loads grow without numerical damping) says so and names
    generalized-α; other integrators and chains get no such hint."""
    from dttmm.integrators import newmark_family
    from dttmm.spatial import solver

    trapezoidal = newmark_family("newmark")
    assert "generalized-alpha" in solver._undamped_loop_hint(object(), trapezoidal)
    assert solver._undamped_loop_hint(object(), newmark_family("generalized-alpha", rho_inf=0.8)) == ""
    assert solver._undamped_loop_hint(object(), newmark_family("newmark", gamma=0.6)) == ""
    assert solver._undamped_loop_hint(None, trapezoidal) == ""


@pytest.mark.slow
def test_the_four_bar_under_the_undamped_trapezoidal_rule_stops_with_the_remedy():
    """The documented failure, run (k = 8, h = 1 ms, Newmark β = ¼, γ = ½): the run stops at
    6.42 s with the hint and the partial result up to there (generalized-α runs the 12 s,
    docs/spatial.md "Long loop runs"). If this run ever goes through, update those docs."""
    from dttmm.errors import SimulationError

    case = _short(load_case(FOUR_BAR), 7.0, 0.01)
    with pytest.raises(SimulationError, match="generalized-alpha") as err:
        sp.simulate(case, elements_per_link=8, h=1e-3, progress=False)
    assert 6.0 < err.value.t < 7.0 and err.value.partial.t[-1] > 6.0
