"""The spatial rigid inverse dynamics (dttmm.spatial.inverse_dynamics, recursive Newton–Euler)
against Pinocchio's RNEA, and the ``computed_torque`` feedforward of pd drives on spatial arms.

* RNEA = ``pinocchio.rnea`` on the model of reference_models.pinocchio_spatial at random
  states of every shipped spatial arm with joints, and of an arm with a locked joint between
  two unlocked ones, a tilted and offset base and off-axis payloads: to round-off (≤ 1e-12 of
  the largest torque; measured ≤ 7e-15 N·m).
* With the links made 1e4 times stiffer, pd + computed torque tracks a rest-to-rest move of
  all three joints of three_joint_arm to the links' residual flexibility (measured 7e-6 rad
  RMS, 5e-5 rad at most) where pd alone lags by 0.08 rad RMS: the feedforward is the inverse
  dynamics of the kernel's rigid limit.
* On the flexible arm itself pd + computed torque halves the RMS joint error of pd alone
  (measured 0.043 against 0.085 rad; asserted < 0.6×).
* The spatial DT-TMM and the spatial global solver run the feedforward alike (to round-off).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest

from dttmm import control
from dttmm.drives import PD, Drive, Sine, Table
from dttmm.spatial import SpatialJoint, load_case, simulate
from dttmm.spatial.inverse_dynamics import rigid_inverse_dynamics

SPATIAL = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial"
ARM = SPATIAL / "three_joint_arm.toml"
CT = {"law": "computed_torque"}
#: rest-to-rest moves of the three joints of three_joint_arm (rad, over 0.8 s)
REFS = (Table((0.0, 0.8), (0.0, 0.8)), Table((0.0, 0.8), (0.0, -0.5)), Table((0.0, 0.8), (0.0, 0.6)))


def _locked_middle():
    """three_joint_arm with a fourth link: a locked joint with an origin offset and rpy between
    joints 2 and 3, a tilted offset base."""
    case = load_case(ARM)
    m = case.model
    extra = dc.replace(
        m.links[1],
        joint=SpatialJoint(locked=True, origin_xyz=(0.02, 0.01, -0.03), origin_rpy=(0.3, 0.2, -0.4)),
    )
    links = (m.links[0], m.links[1], extra, m.links[2])
    return dc.replace(m, links=links, base_rpy=(0.2, -0.1, 0.5), base_xyz=(0.1, 0.2, 0.3))


def _arms():
    arms = [
        load_case(SPATIAL / f).model
        for f in ("three_joint_arm.toml", "two_joint_arm.toml", "bang_bang_arm.toml")
    ]
    return [*arms, _locked_middle()]


@pytest.mark.parametrize("i", range(4), ids=["three_joint", "two_joint", "bang_bang", "locked_middle"])
def test_rnea_equals_pinocchio(i):
    pin = pytest.importorskip("pinocchio")
    from reference_models.pinocchio_spatial import build_model

    arm = _arms()[i]
    model = build_model(arm)
    data = model.createData()
    rng = np.random.default_rng(7 + i)
    m = len(arm.unlocked)
    for _ in range(10):
        q, v, a = rng.normal(scale=2.0, size=(3, m))
        ref = pin.rnea(model, data, q, v, a)
        tau = rigid_inverse_dynamics(arm, q, v, a)
        assert np.abs(tau - ref).max() <= 1e-12 * max(1.0, np.abs(ref).max())


def test_rnea_broadcasts_over_time():
    arm = _locked_middle()
    rng = np.random.default_rng(3)
    q, v, a = rng.normal(size=(3, 5, 3))
    tau = rigid_inverse_dynamics(arm, q, v, a)
    for j in range(5):
        np.testing.assert_allclose(tau[j], rigid_inverse_dynamics(arm, q[j], v[j], a[j]), rtol=0, atol=1e-14)


def test_feedforward_is_the_rnea_along_the_references():
    case = load_case(ARM)
    drives = tuple(Drive("torque", PD(10.0, 1.0, r, feedforward=CT)) for r in REFS)
    case = dc.replace(case, scenario=dc.replace(case.scenario, drives=drives))
    t = np.array([0.0, 0.3, 0.55])
    m = np.array([[r.motion(tt) for r in REFS] for tt in t])
    expected = rigid_inverse_dynamics(case.model, m[..., 0], m[..., 1], m[..., 2])
    np.testing.assert_allclose(control.computed_torque(case, t), expected, rtol=1e-15, atol=1e-14)
    ff, _ = control.time_tables(case, t)
    np.testing.assert_allclose(ff, expected, rtol=1e-15, atol=1e-14)


def _tracking(ff, stiffness=1.0, kp=100.0, kd=10.0):
    """RMS and max joint error (rad) of pd (+ ff) drives tracking REFS on three_joint_arm."""
    case = load_case(ARM)
    drives = tuple(Drive("torque", PD(kp, kd, r, feedforward=ff)) for r in REFS)
    links = tuple(
        dc.replace(
            lk,
            beam=dc.replace(
                lk.beam, EIy=lk.beam.EIy * stiffness, EIz=lk.beam.EIz * stiffness, GJ=lk.beam.GJ * stiffness
            ),
        )
        for lk in case.model.links
    )
    case = dc.replace(
        case,
        model=dc.replace(case.model, links=links),
        scenario=dc.replace(case.scenario, drives=drives, duration=1.2),
    )
    res = simulate(case, elements_per_link=4, h=1e-3, energy=False)
    assert res.status == "ok"
    ref = np.array([[r.motion(t)[0] for r in REFS] for t in res.t])
    err = res.joint_angle - ref
    return float(np.sqrt(np.mean(err**2))), float(np.abs(err).max())


def test_stiff_arm_with_computed_torque_tracks_to_its_flexibility():
    rms_pd, _ = _tracking(None, stiffness=1e4)
    rms_ct, max_ct = _tracking(CT, stiffness=1e4)
    assert rms_pd > 0.05
    assert rms_ct < 3e-5 and max_ct < 2e-4, (rms_ct, max_ct)


def test_flexible_arm_tracks_better_with_computed_torque():
    rms_pd, max_pd = _tracking(None)
    rms_ct, max_ct = _tracking(CT)
    assert rms_ct < 0.6 * rms_pd, (rms_ct, rms_pd)
    assert max_ct < max_pd


def test_dttmm_equals_the_global_solver_with_computed_torque():
    sg = pytest.importorskip("reference_models.spatial_global")
    case = load_case(ARM)
    refs = (*REFS[:2], Sine(0.2, 2.0))
    drives = tuple(Drive("torque", PD(30.0, 3.0, r, feedforward=CT, moment_gain=0.2)) for r in refs)
    case = dc.replace(case, scenario=dc.replace(case.scenario, drives=drives, duration=0.05))
    kw = {"elements_per_link": 1, "h": 1e-3}
    a, b = simulate(case, **kw), sg.simulate(case, **kw)
    assert a.status == b.status == "ok"
    assert np.abs(a.end_effector - b.end_effector).max() <= 1e-12
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-9 * np.abs(b.joint_torque).max()
