"""MuJoCo's hinge chain and Pinocchio's rigid model on trees and closed loops (docs/spatial.md
§11 "Peers on trees and loops"): the MuJoCo body tree follows the links' parents and its
closures are equality constraints whose forces are the closure loads; Pinocchio's rigid tree
and its point-contact loop closure. Every golden value comes from an independent source: the
spatial global solver, the spatial DT-TMM (= the global solver to round-off,
tests/test_spatial_topology.py), the closed-form geometry of the rigid five-bar, MuJoCo's own
constraint forces."""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import numpy as np
import pytest

from dttmm import InputError
from dttmm.spatial.case import load_case

mujoco = pytest.importorskip("mujoco")
pin = pytest.importorskip("pinocchio")

from reference_models import mujoco_spatial as ms  # noqa: E402
from reference_models import pinocchio_spatial as ps  # noqa: E402

TOPO = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"
sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_spatial_topology import _five_bar_tip, _rigid_tree, _short  # noqa: E402


def _case(name, duration=0.05, output_step=0.005):
    return _short(load_case(TOPO / f"{name}.toml"), duration, output_step)


def _with_kind(case, kind):
    cl = dataclasses.replace(case.model.closures[0], kind=kind)
    return dataclasses.replace(case, model=dataclasses.replace(case.model, closures=(cl,)))


# ------------------------------------------------------------------ MuJoCo --------------------


def test_mujoco_body_tree_follows_the_link_parents():
    """Each link's root piece hangs from its parent link's tip piece (the base body for a link
    on the base); a loop adds no body, only equality constraints (two connects for a revolute)."""
    for name in ("branched_arm", "four_bar", "five_bar"):
        case = load_case(TOPO / f"{name}.toml")
        m, _, lay = ms.build(case.model, 2)
        base = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "base")
        for i, par in enumerate(case.model.parents):
            want = base if par < 0 else lay.tip_body[par]
            assert m.body_parentid[lay.hub_body[i]] == want, (name, i)
        revolute = sum(cl.kind == "revolute" for cl in case.model.closures)
        assert m.neq == len(case.model.closures) + revolute
        assert m.nbody == 1 + 1 + 3 * case.model.n_links  # world, base, k + 1 pieces per link


@pytest.mark.parametrize(
    ("name", "kind"), [("four_bar", "revolute"), ("five_bar", "spherical"), ("five_bar", "weld")]
)
def test_mujoco_closure_loads_are_its_constraint_forces(name, kind):
    """The four-bar (its tilted revolute C) and the five-bar closed by a spherical joint and a
    weld, k = 2, 400 steps under random motor torques: the closure load λ on `link` (−λ on `to`,
    at the closure point) reproduces MuJoCo's generalised constraint force ``qfrc_constraint``
    (to 1e-6 of its largest: the gap moves the points), and the revolute closure carries no
    moment about its axis (≤ 1e-6 of the moment's magnitude; measured 8.5e-17)."""
    case = _with_kind(_case(name, 0.02, 0.002), kind)
    st = ms._Stepper(case, 2, 1e-5, "implicitfast", "hinges")
    m, d = st.m, st.d
    st.initial_state()
    rng = np.random.default_rng(3)
    d.ctrl[:] = rng.normal(size=m.nu)
    for _ in range(400):
        mujoco.mj_step(m, d)
    mujoco.mj_forward(m, d)
    lam = ms.closure_loads(m, d, case.model)[0]
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cl0_a0")
    point = d.site_xpos[site].copy()
    if kind == "revolute":
        other = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cl0_a1")
        point = 0.5 * (point + d.site_xpos[other])
    body_a = m.site_bodyid[site]
    body_b = m.site_bodyid[mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "cl0_b0")]
    qa, qb = np.zeros(m.nv), np.zeros(m.nv)
    mujoco.mj_applyFT(m, d, lam[:3], lam[3:], point, body_a, qa)
    mujoco.mj_applyFT(m, d, -lam[:3], -lam[3:], point, body_b, qb)
    scale = np.max(np.abs(d.qfrc_constraint))
    assert scale > 1e-3  # the loop carries load
    assert np.max(np.abs(qa + qb - d.qfrc_constraint)) <= 1e-6 * scale
    if kind == "revolute":
        axis = d.site_xpos[site] - d.site_xpos[other]
        axis /= np.linalg.norm(axis)
        assert abs(lam[3:] @ axis) <= 1e-6 * max(np.linalg.norm(lam[3:]), 1e-300)


@pytest.mark.parametrize(
    ("name", "k", "gap", "angle"),
    [("five_bar", 2, 1e-8, 1e-12), ("four_bar", 2, 1e-10, 1e-9)],
)
def test_mujoco_loop_gap_is_small(name, k, gap, angle):
    """The equality constraints (time constant 2 steps, impedance 0.9999, solver tolerance 1e-12)
    hold the loops to a small gap over 0.05 s at the stable step: measured five-bar 2.7e-9 m and
    1.2e-14 rad (h = 7.8e-5 s), four-bar 1.1e-12 m and 5.6e-11 rad (h = 9.8e-6 s); the result's
    residuals are the gaps of its own tip frames."""
    case = _case(name)
    h = 7.8125e-05 if name == "five_bar" else 9.765625e-06
    r = ms.simulate(case, elements_per_link=k, h=h)
    assert r.closure_loads.shape == (r.t.size, 1, 6)
    assert np.max(r.closure_residual) <= gap
    assert np.max(r.closure_angle_residual) <= angle
    assert np.max(np.abs(r.link_tip - r.link_tip[0])) > 4e-4  # the mechanism moves (four-bar: 0.53 mm)


def _inextensible(case):
    """Every link's EA × 1e3: MuJoCo's chain has no axial compliance (its pieces keep their
    lengths), which a closed loop's axial loads bring out (the five-bar's tips stall at 3.8e-6 m
    from the DT-TMM's with the case's EA, from k = 8 on)."""
    links = tuple(
        dataclasses.replace(lk, beam=dataclasses.replace(lk.beam, EA=lk.beam.EA * 1e3))
        for lk in case.model.links
    )
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=links))


#: MuJoCo's step at k = 2, 4 stations per link: 5 ms halved until below half the explicit
#: stability limit of its joint springs (stability_limit; the four-bar's steel links need ~1e-5 s)
_MJ_STEPS = {
    "branched_arm": (1.5625e-4, 3.90625e-5),
    "five_bar": (7.8125e-5, 3.90625e-5),
    "four_bar": (9.765625e-6, 4.8828125e-6),
}


@pytest.mark.parametrize(
    ("name", "bound"), [("branched_arm", 1.4e-4), ("five_bar", 1.2e-5), ("four_bar", 1.5e-7)]
)
def test_mujoco_converges_to_the_global_solver(name, bound):
    """MuJoCo's hinge chain (k = 2, 4 stations per link) against the spatial global solver (k = 2,
    Newmark, h = 0.25 ms; its tips within 3e-5 m (branched arm), 2.9e-7 m (five-bar), 4e-10 m
    (four-bar) of its k = 32 values), 0.05 s: the two discretisations differ, and MuJoCo's tips
    approach the reference as O(1/k²) (the error falls ×4.2, ×3.6, ×4.2 from k = 2 to 4; measured
    4.7e-4 → 1.1e-4 m, 3.5e-5 → 9.6e-6 m, 4.9e-7 → 1.2e-7 m while the tips travel 9, 12 and
    0.53 mm). The five-bar is made inextensible (EA × 1e3, :func:`_inextensible`). The four-bar's
    closure load converges alike (5.5e-2 → 1.3e-2 of its largest; its crank torque, 2.3e-3 →
    1.2e-3, meets the reference's own step error at h = 0.25 ms: 6.0e-4 at k = 4 against the
    DT-TMM at h = 62.5 µs)."""
    from reference_models import spatial_global as sg

    case = _case(name)
    if name == "five_bar":
        case = _inextensible(case)
    g = sg.simulate(case, elements_per_link=2, h=2.5e-4)
    err, load = [], []
    for k, h in zip((2, 4), _MJ_STEPS[name]):
        r = ms.simulate(case, elements_per_link=k, h=h)
        assert np.array_equal(r.end_effector, r.link_tip[:, case.model.end_effector_index])
        err.append(np.max(np.abs(r.link_tip - g.link_tip)))
        if case.model.closures:
            load.append(np.max(np.abs(r.closure_loads - g.closure_loads)) / np.max(np.abs(g.closure_loads)))
    assert err[1] <= bound, err
    assert 3.0 < err[0] / err[1] < 5.5, err
    if name == "four_bar":
        assert load[1] < 2e-2 and 3.0 < load[0] / load[1] < 5.5, load


def test_mujoco_statics_refuse_a_tree():
    case = load_case(TOPO / "branched_arm.toml")
    with pytest.raises(InputError, match="not supported by mujoco-spatial statics") as info:
        ms.statics(case, 2)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", ["branched_arm", "five_bar"])
def test_peers_fill_the_fields_the_dttmm_fills(name):
    """Field by field, the arrays the spatial DT-TMM returns on a tree and a loop (k = 2, 0.02 s)
    come back from MuJoCo and Pinocchio with the same shapes (cut loads: none asked for);
    ``end_effector`` is the named link's tip in each."""
    import dttmm.spatial as sp

    case = _case(name, 0.02, 0.005)
    ref = sp.simulate(case, elements_per_link=2, h=5e-4)
    peers = {
        "mujoco": ms.simulate(case, elements_per_link=2, h=3.90625e-5),
        "pinocchio": ps.simulate(case, h=5e-4),
    }
    filled = {f.name for f in dataclasses.fields(ref) if isinstance(getattr(ref, f.name), np.ndarray)}
    assert {"link_tip", "joint_angle", "end_effector"} <= filled
    assert ("closure_loads" in filled) == bool(case.model.closures)
    for who, r in peers.items():
        for f in filled:
            assert getattr(r, f) is not None and getattr(r, f).shape == getattr(ref, f).shape, (who, f)
        assert np.array_equal(r.end_effector, r.link_tip[:, case.model.end_effector_index]), who


# ------------------------------------------------------------------ Pinocchio -----------------


def test_pinocchio_tree_equals_the_global_solver_with_rigid_links():
    """The branched arm in Pinocchio (ABA on its tree, RK4, h = 1 ms, 0.2 s) = the spatial global
    solver on the same arm with every link a rigid body of the beam's mass and inertia (its own
    tree recursion and mass matrix, RK4 on the same schedule): the arm swings by 0.9 rad, the
    link tips agree to round-off (measured 2.2e-16 m); the flexible case's rigid model is that
    rigid arm (same arrays bit for bit)."""
    from reference_models import spatial_global as sg

    rigid = _short(_rigid_tree(load_case(TOPO / "branched_arm.toml")), 0.2, 0.01)
    p = ps.simulate(rigid, h=1e-3)
    g = sg.simulate(rigid, elements_per_link=1, h=1e-3, integrator="rk4")
    assert np.max(np.abs(g.joint_angle)) > 0.5
    assert np.max(np.abs(p.link_tip - g.link_tip)) <= 1e-12
    assert np.max(np.abs(p.end_effector - g.end_effector)) <= 1e-12
    assert np.array_equal(p.end_effector, p.link_tip[:, rigid.model.end_effector_index])
    flexible = ps.simulate(_short(load_case(TOPO / "branched_arm.toml"), 0.2, 0.01), h=1e-3)
    assert np.array_equal(flexible.link_tip, p.link_tip)


def test_pinocchio_five_bar_follows_the_closed_form_geometry_and_balances_energy():
    """The rigid five-bar by Pinocchio's constraintDynamics (a 3-D point contact at the distal
    tips, RK4, h = 0.5 ms, 0.2 s, outputs every 0.5 ms): its distal tip = the closed-form loop
    geometry (where the circles about the driven proximal tips cross) to the Baumgarte-held gap
    (measured 1.3e-9 m, gap 1.8e-9 m; the tip travels 0.04 m); the work of the drive torques,
    ∫ τ·q̇ dt by the trapezoidal rule on the output grid, = the kinetic energy gained (the
    constraint does no work): 1.5e-6 J of 0.12 J (9.1e-6 J on a 1 ms grid: the rule's O(dt²));
    the closure loads lie in the plane."""
    case = _case("five_bar", 0.2, 5e-4)
    r = ps.simulate(case, h=5e-4)
    ref = _five_bar_tip(case, r.t)
    assert np.max(np.abs(ref - ref[0])) > 0.03
    assert np.max(np.abs(r.end_effector - ref)) <= 1e-8
    assert np.max(r.closure_residual) <= 1e-8
    assert np.max(np.abs(r.closure_loads[..., 2:])) <= 1e-9 * np.max(np.abs(r.closure_loads))
    power = np.sum(r.joint_torque * r.joint_rate, axis=1)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(r.t))])
    gained = r.energy - r.energy[0]
    assert np.max(np.abs(gained)) > 0.1
    assert np.max(np.abs(work - gained)) <= 5e-6


def test_pinocchio_closure_loads_are_its_constraint_forces():
    """At output states of the five-bar run (RK4, h = 0.5 ms): the closure load F on `link` (−F on
    `to`, world components, at the closure point) reproduces Pinocchio's generalised constraint
    force M q̈ + b − τ, with the point's Jacobians of the two links (to 1e-8 of its largest,
    measured 4.7e-9: the gap, ~1e-9 m, moves `to`'s point by that much times the 1.5 N load), and
    the loads and torques at those states are the result's."""
    case = _case("five_bar", 0.05, 0.01)
    r = ps.simulate(case, h=5e-4)
    arm = ps._Arm(case)
    model, data = arm.model, arm.data
    cm = arm.cms[0]
    for s in (2, 5):
        q, v = r.joint_angle[s].copy(), r.joint_rate[s].copy()
        a, tau = arm.forward(float(r.t[s]), False, q, v)
        F = arm.loads[0, :3]
        assert np.allclose(arm.loads, r.closure_loads[s], rtol=0, atol=1e-12)
        assert np.allclose(tau, r.joint_torque[s], rtol=0, atol=1e-12)
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        Q = M @ a + pin.rnea(model, data, q, v, np.zeros(q.size)) - tau
        pin.forwardKinematics(model, data, q)
        point = data.oMi[cm.joint1_id].act(cm.joint1_placement).translation

        def jac(joint, q=q, point=point):
            J = pin.computeJointJacobian(model, data, q, joint)  # LOCAL
            J = data.oMi[joint].toActionMatrix() @ J  # WORLD: the velocity at the world origin
            return J[:3] + np.cross(J[3:].T, point).T

        G = jac(cm.joint1_id) - jac(cm.joint2_id)
        assert np.max(np.abs(Q)) > 0.1
        assert np.max(np.abs(G.T @ F - Q)) <= 1e-8 * np.max(np.abs(Q))


def test_pinocchio_four_bar_sits_out_with_its_reason():
    """The four-bar's tilted joint C locks the rigid mechanism; Pinocchio's rigid constraints (3-D
    point, 6-D weld) have no 5-equation revolute: one line naming the closure's axis."""
    case = load_case(TOPO / "four_bar.toml")
    with pytest.raises(InputError, match=r"model.closures\[0\].axis") as info:
        ps.check_case(case)
    assert "\n" not in str(info.value)
    with pytest.raises(InputError, match="rk4 only"):
        ps.simulate(_case("five_bar"), h=1e-3, integrator="newmark")


def test_pinocchio_refuses_motion_drives_a_loop_locks():
    """The five-bar's left distal tip pinned to the ground: its driven base joint cannot turn, so
    the motion law cannot be imposed — one line naming the drives, not a singular solve."""
    case = _case("five_bar")
    cl = dataclasses.replace(case.model.closures[0], kind="spherical", to="ground", to_point=None)
    case = dataclasses.replace(case, model=dataclasses.replace(case.model, closures=(cl,)))
    with pytest.raises(InputError, match="scenario.drives") as info:
        ps.simulate(case, h=1e-3)
    assert "\n" not in str(info.value)
