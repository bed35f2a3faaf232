"""dttmm.control: the tables the engines read, the pd/pid torque with its moment loop solved,
and the rigid inverse dynamics of the computed-torque feedforward (against Pinocchio's RNEA and
closed forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest

import dttmm
from dttmm import control
from dttmm.drives import PD, PID, Constant, ControlState, Drive, Sine, Table, UserLaw
from dttmm.errors import InputError
from dttmm.model import Hub, Link, Manipulator, Payload, Section
from experiments.plan import CASE_DIR


def arm(gravity=(0.0, -9.81), drives=None):
    links = (
        Link(Section(0.6, 3.0, 0.4, 1e6), hub=Hub(0.3, 0.02)),
        Link(Section(0.5, 2.0, 0.3), hub=Hub(0.2, 0.01)),
        Link(Section(0.4, 1.0, 0.2), payload=Payload(0.15, 0.003)),
    )
    drives = drives or (
        Drive("torque", PD(10.0, 2.0, Sine(0.4, 0.7), moment_gain=0.5, limit=3.0)),
        Drive("motion", Sine(0.3, 1.1)),
        Drive("torque", PID(5.0, 1.0, Table((0.0, 1.0), (0.0, 0.5)), Constant(0.2), ki=2.0)),
    )
    return dttmm.Case(Manipulator(links, gravity), dttmm.Scenario(1.0, 0.01, drives))


def test_rigid_inverse_dynamics_equals_pinocchio_rnea():
    pin_rigid = pytest.importorskip("reference_models.pinocchio_rigid")
    pin = pin_rigid.pin
    case = arm()
    model = pin_rigid.build_model(case.model)
    data = model.createData()
    rng = np.random.default_rng(7)
    q, qd, qdd = rng.normal(size=(3, 20, 3))
    ours = control.rigid_inverse_dynamics(case, q, qd, qdd)
    theirs = np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd)])
    np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)


def test_rigid_inverse_dynamics_of_one_link_by_hand():
    """τ = I α̈ + s g cos α for a rigid link under gravity −g ŷ (I, s about the joint)."""
    L, rhoA, mh, Jh, mp, Jp = 0.8, 0.5, 0.3, 0.01, 0.2, 0.004
    link = Link(Section(L, 1.0, rhoA), hub=Hub(mh, Jh), payload=Payload(mp, Jp))
    case = dttmm.Case(
        Manipulator((link,), (0.0, -9.81)), dttmm.Scenario(1.0, 0.1, (Drive("motion", Constant(0.0)),))
    )
    m = rhoA * L
    inertia = Jh + m * L**2 / 3 + mp * L**2 + Jp
    s = m * L / 2 + mp * L
    a, ad, add = 0.7, 3.0, -2.0
    tau = control.rigid_inverse_dynamics(case, [a], [ad], [add])
    assert tau[0] == pytest.approx(inertia * add + s * 9.81 * math.cos(a), rel=1e-13)


@pytest.mark.parametrize("omega_dot", [0.0, 2.5, -40.0])
@pytest.mark.parametrize("angle", [0.1, 2.0, -3.0])  # unsaturated, saturated high and low
def test_pd_torque_solves_the_moment_loop_of_the_law(angle, omega_dot):
    """pd_torque's τ satisfies the law itself, τ = PD.evaluate with M_root = τ − J_hub ω̇."""
    law = PID(10.0, 2.0, Sine(0.4, 0.7), Constant(0.3), moment_gain=0.8, limit=12.0, ki=3.0)
    j_hub, t, rate, z = 0.05, 0.3, -0.4, 0.2
    a_ref, r_ref, _ = law.reference.motion(t)

    def torque(z=z, angle=angle, rate=rate, w=omega_dot):
        args = (law.kp, law.kd, law.ki, law.moment_gain, law.limit, j_hub, 0.3, a_ref, r_ref)
        return control.pd_torque(*args, z, angle, rate, w)

    tau, da, dr, dz, dw = torque()
    state = ControlState(joint=0, angle=angle, rate=rate, moment=tau - j_hub * omega_dot, integral=z)
    assert law.evaluate(t, state)[0] == pytest.approx(tau, rel=1e-14, abs=1e-14)
    # the slopes against central differences of the closed form
    f = lambda **kw: torque(**kw)[0]
    eps = 1e-6
    for name, slope, x in (("angle", da, angle), ("rate", dr, rate), ("z", dz, z), ("w", dw, omega_dot)):
        num = (f(**{name: x + eps}) - f(**{name: x - eps})) / (2 * eps)
        assert slope == pytest.approx(num, abs=1e-7), name
    if abs(tau) == law.limit:
        assert (da, dr, dz, dw) == (0.0, 0.0, 0.0, 0.0)


def test_gains_and_tables():
    case = arm()
    g = control.gains(case)
    assert list(g.code) == [control.CODE_PD, control.CODE_OPEN, control.CODE_PD]
    assert (g.kp[0], g.kd[0], g.ki[0], g.moment_gain[0], g.limit[0]) == (10.0, 2.0, 0.0, 0.5, 3.0)
    assert (g.ki[2], g.limit[2]) == (2.0, math.inf)
    np.testing.assert_array_equal(g.j_hub, [0.02, 0.01, 0.0])
    t = np.array([0.0, 0.25, 1.0])
    ff, ref = control.time_tables(case, t)
    np.testing.assert_array_equal(ff[:, 0], 0.0)
    np.testing.assert_array_equal(ff[:, 2], 0.2)
    np.testing.assert_array_equal(ff[:, 1], 0.0)
    np.testing.assert_allclose(ref[1, 0], Sine(0.4, 0.7).motion(0.25)[:2])
    np.testing.assert_array_equal(ref[:, 1], 0.0)


def test_open_loop_and_user_joints_in_the_tables():
    drives = (
        Drive("torque", Sine(0.4, 0.7)),
        Drive("torque", UserLaw(lambda t, s: (0.0, 0.0, 0.0))),
        Drive("motion", Constant(0.0)),
    )
    case = arm(drives=drives)
    ff, ref = control.time_tables(case, [0.3], left=True)
    assert ff[0, 0] == Sine(0.4, 0.7)(0.3, True)
    assert ff[0, 1] == 0.0 and not ref.any()
    assert list(control.gains(case).code) == [control.CODE_OPEN, control.CODE_USER, control.CODE_OPEN]


def test_computed_torque_feedforward_in_the_tables():
    case = arm(
        drives=(
            Drive("torque", PD(10.0, 2.0, Sine(0.4, 0.7), feedforward={"law": "computed_torque"})),
            Drive("motion", Sine(0.3, 1.1)),
            Drive("torque", PD(5.0, 1.0, Sine(-0.2, 0.5), feedforward={"law": "computed_torque"})),
        )
    )
    t = np.linspace(0.0, 1.0, 5)
    ff, _ = control.time_tables(case, t)
    refs = [Sine(0.4, 0.7), Sine(0.3, 1.1), Sine(-0.2, 0.5)]
    for j, tt in enumerate(t):
        m = np.array([r.motion(tt) for r in refs])
        tau = control.rigid_inverse_dynamics(case, m[:, 0], m[:, 1], m[:, 2])
        np.testing.assert_allclose(ff[j, [0, 2]], tau[[0, 2]], rtol=1e-14)
    np.testing.assert_allclose(control.computed_torque(case, 0.5), control.computed_torque(case, [0.5])[0])


def test_computed_torque_needs_a_reference_on_every_joint():
    drives = (
        Drive("torque", PD(10.0, 2.0, Sine(0.4, 0.7), feedforward={"law": "computed_torque"})),
        Drive("torque", Constant(0.0)),
        Drive("motion", Constant(0.0)),
    )
    with pytest.raises(InputError, match=r"scenario.drives\[1\].law.*reference motion on every joint"):
        control.time_tables(arm(drives=drives), [0.1])


@pytest.mark.parametrize("gain", [-1.0, -2.5])
def test_moment_gain_at_or_below_minus_one_is_refused(gain):
    with pytest.raises(InputError, match=r"moment_gain.*-1"):
        PD(10.0, 2.0, Sine(0.4, 0.7), moment_gain=gain)


def test_shipped_closed_loop_case_gains():
    case = dttmm.load_case(CASE_DIR / "control" / "closed_loop_three_link.toml")
    g = control.gains(case)
    assert list(g.code) == [control.CODE_PD] * 3
    np.testing.assert_array_equal(g.moment_gain, 0.5)
