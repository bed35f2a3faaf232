"""Rigid links and offset payloads on planar arms (docs/cases.md "Rigid links and offset
payloads"): the planar DT-TMM against the global solver and the spatial kernel on the same arm,
an all-rigid arm against Pinocchio and a closed form, the refusals, and the outputs."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import dttmm
from dttmm import Drive, Hub, InputError, Link, Manipulator, Payload, RigidBody, Scenario, Section
from dttmm.case import case_from_dict, case_to_dict
from dttmm.drives import Constant, Sine

global_newmark = pytest.importorskip("reference_models.global_newmark")


def mixed_case(motion: bool = False, duration: float = 0.3) -> dttmm.Case:
    """Three links: rigid (hub, centre of mass off both axes), flexible extensible (offset
    payload), rigid (offset payload); gravity, torque drives (joint 2 motion-driven if asked)."""
    links = (
        Link(RigidBody(0.4, 2.0, (0.15, 0.03), 0.03), hub=Hub(0.3, 1e-3)),
        Link(Section(0.6, 30.0, 1.2, EA=2e5), payload=Payload(0.5, 2e-3, offset=(0.05, -0.03))),
        Link(RigidBody(0.3, 0.8, (0.12, -0.02), 0.01), payload=Payload(0.4, 1e-3, offset=(0.04, 0.02))),
    )
    d2 = Drive("motion", Sine(0.3, 2.0)) if motion else Drive("torque", Sine(-1.5, 2.0))
    drives = (Drive("torque", Sine(4.0, 1.5)), d2, Drive("torque", Constant(0.2)))
    return dttmm.Case(Manipulator(links, (0.0, -9.81)), Scenario(duration, 0.01, drives), "mixed")


def _diff(a, b, field):
    return float(np.max(np.abs(getattr(a, field) - getattr(b, field))))


# --- physics: the same arm by independent assemblies ------------------------------------------
@pytest.mark.parametrize("motion", [False, True])
@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
def test_dttmm_equals_global_solver(motion, integrator):
    """The Riccati sweep (rigid segments, offset bodies as articulated inertias) and the global
    solver (the rigid body as element moments, the offset payload's 3×3 mass) step the same
    equations: equal to round-off (bound 1e-9 m / rad)."""
    case = mixed_case(motion)
    opts = {"elements_per_link": 3, "h": 1e-3, "integrator": integrator}
    a = dttmm.simulate(case, **opts, progress=False)
    b = global_newmark.simulate(case, **opts)
    assert a.status == b.status == "ok"
    for f in ("joint_angle", "joint_rate", "link_tip", "tip_deflection", "end_effector"):
        assert _diff(a, b, f) <= 1e-9, f
    assert _diff(a, b, "joint_torque") <= 1e-8
    assert _diff(a, b, "energy") <= 1e-9
    assert np.ptp(a.joint_angle[:, 0]) > 0.05  # the arm moves


@pytest.mark.parametrize("moment_gain", [0.0, 0.5])
def test_closed_loop_dttmm_equals_global_solver(moment_gain):
    """pd laws on the rigid links (with root-moment feedback: the hub's moment balance holds at
    a rigid link's root as at a beam's): the same iterates in both solvers."""
    from dttmm.drives import PD

    case = mixed_case(duration=0.1)
    d = list(case.scenario.drives)
    d[0] = Drive("torque", PD(kp=50.0, kd=5.0, reference=Sine(0.3, 1.0), moment_gain=moment_gain))
    d[2] = Drive("torque", PD(kp=20.0, kd=2.0, reference=Sine(-0.2, 1.5), moment_gain=moment_gain))
    case = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=tuple(d)))
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False)
    b = global_newmark.simulate(case, elements_per_link=2, h=1e-3)
    assert _diff(a, b, "joint_angle") <= 1e-9 and _diff(a, b, "joint_torque") <= 1e-8


def test_dttmm_equals_spatial_kernel():
    """The planar case and its spatial embedding (dttmm.spatial.embed_planar: SpatialRigidBody,
    payload offsets (x, y, 0)) are the same arm: equal to round-off."""
    case = mixed_case()
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False)
    b = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False, kernel="spatial")
    assert np.max(np.abs(a.joint_angle - b.joint_angle)) <= 1e-11
    assert np.max(np.abs(a.joint_torque - b.joint_torque)) <= 1e-10
    assert np.max(np.abs(a.link_tip - b.link_tip[..., :2])) <= 1e-11
    assert np.max(np.abs(b.link_tip[..., 2])) == 0.0
    assert np.max(np.abs(a.tip_deflection - b.tip_deflection[..., 0])) <= 1e-11
    assert np.max(np.abs(a.energy - b.energy)) <= 1e-10


def test_python_engine_equals_compiled():
    case = mixed_case(duration=0.05)
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False)
    b = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False, engine="python")
    assert _diff(a, b, "joint_angle") <= 1e-12 and _diff(a, b, "link_tip") <= 1e-12


def _all_rigid(gravity=(0.0, -9.81)) -> dttmm.Case:
    links = (
        Link(RigidBody(0.5, 1.5, (0.2, 0.04), 0.02), hub=Hub(0.2, 2e-3)),
        Link(RigidBody(0.4, 1.0, (0.25, -0.05), 0.015), payload=Payload(0.3, 1e-3, offset=(0.03, 0.02))),
    )
    drives = (Drive("torque", Sine(2.0, 1.0), initial_angle=0.3), Drive("torque", Constant(-0.4)))
    return dttmm.Case(Manipulator(links, gravity), Scenario(1.0, 0.01, drives), "rigid2")


def test_all_rigid_arm_equals_pinocchio():
    """An arm of rigid links has q = joint angles only: RK4 on the same step schedule in the
    DT-TMM kernel and in Pinocchio's ABA (the model built from the same bodies) agree to round-off
    (bound 1e-8 rad)."""
    pinocchio_rigid = pytest.importorskip("reference_models.pinocchio_rigid")
    case = _all_rigid()
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3, integrator="rk4", progress=False)
    b = pinocchio_rigid.simulate(case, elements_per_link=None, h=1e-3, integrator="rk4")
    assert a.meta["n_dof"] == 2
    assert np.max(np.abs(a.joint_angle - b.joint_angle)) <= 1e-8
    assert np.max(np.abs(a.link_tip - b.link_tip)) <= 1e-8
    assert np.ptp(a.joint_angle[:, 1]) > 0.1


def test_rigid_inverse_dynamics_equals_pinocchio_rnea():
    """The computed-torque feedforward's rigid inverse dynamics (dttmm.control) takes the rigid
    links' bodies and the payload offsets: equal to Pinocchio's RNEA of the same bodies."""
    pin_rigid = pytest.importorskip("reference_models.pinocchio_rigid")
    from dttmm import control

    case = mixed_case()
    model = pin_rigid.build_model(case.model)
    data = model.createData()
    q, qd, qdd = np.random.default_rng(3).normal(size=(3, 20, 3))
    ours = control.rigid_inverse_dynamics(case, q, qd, qdd)
    theirs = np.array([pin_rigid.pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)


def test_compound_pendulum_period():
    """One rigid link, centre of mass at d = (x, y) off the axis, hub: small oscillations about
    the hanging equilibrium (θ* + atan2(y, x) = −π/2) have T = 2π √(I_O / (m g |d|)),
    I_O = J + m|d|² + J_hub (the hub's mass at the pin does not swing)."""
    m, d, J, Jh, g = 2.0, (0.3, 0.08), 0.05, 0.01, 9.81
    theta_eq = -math.pi / 2 - math.atan2(d[1], d[0])
    amp = 1e-3
    link = Link(RigidBody(0.5, m, d, J), hub=Hub(0.7, Jh))
    scen = Scenario(4.0, 1e-3, (Drive("torque", Constant(0.0), initial_angle=theta_eq + amp),))
    case = dttmm.Case(Manipulator((link,), (0.0, -g)), scen)
    r = dttmm.simulate(case, elements_per_link=1, h=2e-4, progress=False)
    x = r.joint_angle[:, 0] - theta_eq
    # upward zero crossings, linearly interpolated
    i = np.flatnonzero((x[:-1] < 0) & (x[1:] >= 0))
    tc = r.t[i] - x[i] * (r.t[i + 1] - r.t[i]) / (x[i + 1] - x[i])
    period = float(np.mean(np.diff(tc)))
    I_O = J + m * (d[0] ** 2 + d[1] ** 2) + Jh
    expected = 2 * math.pi * math.sqrt(I_O / (m * g * math.hypot(*d)))
    assert len(tc) >= 3
    assert abs(period / expected - 1) <= 2e-5
    assert np.max(np.abs(x)) <= 1.0001 * amp


def test_energy_conserved_without_drive():
    """Undamped, no torque: the total energy of the mixed arm stays (trapezoidal rule, converged)."""
    case = mixed_case(duration=0.5)
    drives = tuple(Drive("torque", Constant(0.0), initial_angle=a) for a in (0.4, -0.3, 0.5))
    case = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives))
    r = dttmm.simulate(case, elements_per_link=3, h=5e-4, progress=False)
    scale = 5.0 * 9.81 * 1.3
    assert np.ptp(r.energy) / scale <= 1e-4


# --- outputs ------------------------------------------------------------------------------
def test_rigid_link_outputs():
    """No elastic coordinates; zero tip deflection; straight shape ending at the link tip."""
    case = mixed_case(duration=0.05)
    r = dttmm.simulate(case, elements_per_link=3, h=1e-3, progress=False, shape_points=4)
    st = dttmm.structure.build_structure(case, 3)
    assert st.n_dof == 1 + (1 + 3 * 3) + 1
    names = st.coordinate_names()
    assert names[0] == "joint 1 angle" and names[1] == "joint 2 angle" and names[-1] == "joint 3 angle"
    assert np.max(np.abs(r.tip_deflection[:, [0, 2]])) <= 1e-15
    assert np.max(np.abs(r.tip_deflection[:, 1])) > 1e-6
    sh = r.link_shapes
    assert np.max(np.abs(sh[:, :, -1] - r.link_tip)) <= 1e-14
    assert np.max(np.abs(sh[:, :, 0] - r.link_root)) <= 1e-14
    for i in (0, 2):  # collinear points
        v = sh[:, i] - sh[:, i, :1]
        assert np.max(np.abs(v[..., 0] * v[:, -1:, 1] - v[..., 1] * v[:, -1:, 0])) <= 1e-14
    length = np.hypot(*(r.link_tip[:, 0] - r.link_root[:, 0]).T)
    assert np.max(np.abs(length - 0.4)) <= 1e-14
    g = global_newmark.simulate(case, elements_per_link=3, h=1e-3, shape_points=4)
    assert np.max(np.abs(g.link_shapes - sh)) <= 1e-9


def test_case_file_round_trip(tmp_path):
    case = mixed_case()
    d = case_to_dict(case)
    assert d["model"]["links"][0]["rigid"] == {"mass": 2.0, "com": [0.15, 0.03], "inertia": 0.03}
    assert "EI" not in d["model"]["links"][0]
    assert d["model"]["links"][1]["payload"]["offset"] == [0.05, -0.03]
    assert case_from_dict(d) == case
    p = dttmm.case.save_case(case, tmp_path / "mixed.toml")
    assert dttmm.load_case(p) == case
    # a payload on the axis writes no offset (files of flexible arms are unchanged)
    flat = case_to_dict(dttmm.load_case("experiments/cases/three_link.toml"))
    assert all("offset" not in lk.get("payload", {}) for lk in flat["model"]["links"])


def test_defaults_unchanged():
    p = Payload(1.0, 0.1)
    assert p.offset == (0.0, 0.0) and not p.offset_set
    assert dttmm.load_case("experiments/cases/three_link.toml").model.flexible_only


# --- refusals: one line naming field and value -------------------------------------------
def _doc(**link):
    base = {"length": 0.4, "rigid": {"mass": 1.0, "com": [0.1, 0.0], "inertia": 0.01}}
    base.update(link)
    return {
        "model": {"links": [base]},
        "scenario": {
            "duration": 1.0,
            "output_step": 0.1,
            "drives": [{"kind": "torque", "law": "constant", "value": 0.0}],
        },
    }


@pytest.mark.parametrize(
    ("link", "field", "value"),
    [
        ({"rigid": {"mass": -1.0}}, "model.links[0].rigid.mass", "-1.0"),
        ({"rigid": {"inertia": -0.1}}, "model.links[0].rigid.inertia", "-0.1"),
        ({"rigid": {"com": [0.1]}}, "model.links[0].rigid.com", "[0.1]"),
        ({"rigid": {"com": [0.1, 0.0, 0.0]}}, "model.links[0].rigid.com", "[0.1, 0.0, 0.0]"),
        ({"rigid": {"com": [0.1, "a"]}}, "model.links[0].rigid.com", "'a'"),
        ({"rigid": {"com": [0.1, math.inf]}}, "model.links[0].rigid.com", "inf"),
        ({"rigid": {"mass": 1.0, "density": 2.0}}, "model.links[0].rigid.density", "2.0"),
        ({"rigid": True}, "model.links[0].rigid", "True"),
        ({"length": 0.0}, "model.links[0].length", "0.0"),
        ({"EI": 3.0}, "model.links[0].EI", "3.0"),
        ({"rhoA": 1.0}, "model.links[0].rhoA", "1.0"),
        ({"damping": 0.1}, "model.links[0].damping", "0.1"),
        ({"payload": {"mass": 1.0, "offset": [0.1]}}, "model.links[0].payload.offset", "[0.1]"),
        ({"payload": {"mass": 1.0, "offset": [0.1, math.nan]}}, "model.links[0].payload.offset", "nan"),
    ],
)
def test_refusals_case_file(link, field, value):
    with pytest.raises(InputError) as ei:
        case_from_dict(_doc(**link))
    msg = str(ei.value)
    assert "\n" not in msg
    assert field in msg and value in msg, msg


@pytest.mark.parametrize(
    ("make", "field"),
    [
        (lambda: RigidBody(-0.4, 1.0), "rigid.length"),
        (lambda: RigidBody(0.4, -1.0), "rigid.mass"),
        (lambda: RigidBody(0.4, 1.0, (0.1,)), "rigid.com"),
        (lambda: RigidBody(0.4, 1.0, (0.1, 0.0), math.nan), "rigid.inertia"),
        (lambda: Payload(1.0, 0.1, offset=(1.0, 2.0, 3.0)), "payload.offset"),
        (lambda: Link(RigidBody(0.4), payload=Hub(1.0)), "link.payload"),
        (lambda: Link("rigid"), "link.beam"),
    ],
)
def test_refusals_objects(make, field):
    with pytest.raises(InputError) as ei:
        make()
    assert "\n" not in str(ei.value) and field in str(ei.value)


def test_refusals_methods():
    """The plain sweep, the numpy reference sweeps and the methods that model flexible links
    only refuse a rigid arm in one line naming the field."""
    case = mixed_case(duration=0.05)
    with pytest.raises(InputError, match=r"^sweep = 'plain': .*rigid link at link 1") as ei:
        dttmm.simulate(case, elements_per_link=2, h=1e-3, sweep="plain")
    assert "\n" not in str(ei.value)
    with pytest.raises(InputError, match=r"model\.links\[0\]\.rigid"):
        dttmm.linear.frequencies(case, 2)
    offset_only = dataclasses.replace(
        case, model=Manipulator((case.model.links[1],), case.model.gravity),
        scenario=dataclasses.replace(case.scenario, drives=case.scenario.drives[:1]),
    )  # fmt: skip
    with pytest.raises(InputError, match=r"^sweep = 'plain': .*offset payload at link 1"):
        dttmm.simulate(offset_only, elements_per_link=2, h=1e-3, sweep="plain")
    from reference_models import assumed_modes, mujoco_chain

    for mod in (assumed_modes, mujoco_chain):
        with pytest.raises(InputError, match=r"model\.links\[0\]\.rigid") as ei:
            mod.simulate(case, elements_per_link=2, h=1e-3)
        assert "\n" not in str(ei.value)
    with pytest.raises(InputError, match=r"model\.links\[0\]\.payload\.offset"):
        mujoco_chain.simulate(offset_only, elements_per_link=2, h=1e-3)


def test_registry_sits_rigid_arms_out():
    from experiments import methods

    case = mixed_case()
    takes = {name for name, m in methods.METHODS.items() if m.module and m.runs_on(case)}
    assert {"dttmm", "dttmm-rk4", "dttmm-2nd", "global", "global-2nd", "pinocchio-rigid"} <= takes
    for name in ("exudyn-ancf", "exudyn-beam", "mujoco-chain"):
        why = methods.get(name).why_not_case(case)
        assert why and "\n" not in why and "rigid" in why
    flexible = dttmm.load_case("experiments/cases/three_link.toml")
    assert all(m.why_not_case(flexible) == "" for m in methods.METHODS.values())
