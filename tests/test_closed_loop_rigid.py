"""Closed-loop drives in the rigid (Pinocchio) and MuJoCo-chain peers against closed forms.

A rigid uniform link of length L and line density ρA on a hub of inertia J_h is a rotor of
inertia J = J_h + ρA·L³/3 about the joint. Under τ = kp (α_ref − α) + kd (α̇_ref − α̇) it obeys
J α̈ + kd α̇ + kp α = kp α_ref + kd α̇_ref: a linear second-order system whose step and sine
responses are written out below in closed form (no code under test involved).
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
import scipy.linalg
from scipy.optimize import brentq

import dttmm
from dttmm.drives import PD, PID, Constant, Drive, Sine, Table, UserLaw
from dttmm.errors import InputError

pin_rigid = pytest.importorskip("reference_models.pinocchio_rigid")

L, RHOA, JH = 1.0, 1.0, 0.1
J = JH + RHOA * L**3 / 3
KP, KD = 20.0, 1.5
SIG = KD / (2 * J)
WD = math.sqrt(KP / J - SIG**2)


def rotor(law, duration=2.0, EI=10.0, gravity=(0.0, 0.0), step=0.01, initial=(0.0, 0.0)):
    link = dttmm.Link(dttmm.Section(L, EI, RHOA), dttmm.Hub(0.0, JH))
    drive = Drive("torque", law, *initial)
    return dttmm.Case(dttmm.Manipulator((link,), gravity), dttmm.Scenario(duration, step, (drive,)))


def step_response(t, r):
    """α(t) of the PD rotor from rest at 0 for the constant reference r."""
    return r * (1 - np.exp(-SIG * t) * (np.cos(WD * t) + SIG / WD * np.sin(WD * t)))


def sine_response(t, A, f):
    """α(t) from rest at 0 for α_ref = A sin(Ωt): steady state Im(G A e^{iΩt}) plus the
    homogeneous solution that meets the initial conditions."""
    w = 2 * math.pi * f
    G = (KP + 1j * KD * w) / (KP - J * w * w + 1j * KD * w)
    p0, pd0 = (G * A).imag, (1j * w * G * A).imag  # particular solution and its rate at 0
    c1 = -p0
    c2 = (-pd0 + SIG * c1) / WD
    hom = np.exp(-SIG * t) * (c1 * np.cos(WD * t) + c2 * np.sin(WD * t))
    return (G * A * np.exp(1j * w * t)).imag + hom


def test_pd_step_matches_the_closed_form():
    res = pin_rigid.simulate(rotor(PD(KP, KD, Constant(0.3))), h=4e-3)
    assert np.abs(res.joint_angle[:, 0] - step_response(res.t, 0.3)).max() <= 1e-6
    # the reported torque is the law at the reported state
    tau = KP * (0.3 - res.joint_angle[:, 0]) - KD * res.joint_rate[:, 0]
    np.testing.assert_allclose(res.joint_torque[:, 0], tau, atol=1e-12)


def test_pd_sine_reference_matches_the_closed_form():
    res = pin_rigid.simulate(rotor(PD(KP, KD, Sine(0.5, 0.5))), h=4e-3)
    err = np.abs(res.joint_angle[:, 0] - sine_response(res.t, 0.5, 0.5)).max()
    assert err <= 1e-6


def test_user_law_equals_the_pd_law():
    def law(t, s):
        return 20.0 * (0.3 - s.angle) - 1.5 * s.rate, -20.0, -1.5

    a = pin_rigid.simulate(rotor(UserLaw(law)), h=4e-3)
    b = pin_rigid.simulate(rotor(PD(KP, KD, Constant(0.3))), h=4e-3)
    np.testing.assert_allclose(a.joint_angle, b.joint_angle, rtol=0, atol=1e-14)


def test_pid_against_the_closed_form_with_a_constant_disturbance():
    # a constant torque d (here fed in as the feedforward) is a constant disturbance:
    # x = (α, α̇, z), ẋ = A x + b, solved exactly by the matrix exponential
    ki, r, d = 10.0, 0.2, -1.0
    res = pin_rigid.simulate(rotor(PID(KP, KD, Constant(r), Constant(d), ki=ki), duration=8.0), h=4e-3)
    A = np.array([[0, 1, 0], [-KP / J, -KD / J, ki / J], [-1, 0, 0]])
    b = np.array([0, (KP * r + d) / J, r])
    xs = np.array([np.linalg.solve(A, (scipy.linalg.expm(A * t) - np.eye(3)) @ b) for t in res.t])
    assert np.abs(res.joint_angle[:, 0] - xs[:, 0]).max() <= 1e-6
    assert abs(res.joint_angle[-1, 0] - r) <= 1e-3  # the offset d/kp of a PD law is gone


def test_pid_removes_the_gravity_offset_pd_keeps():
    g = 9.81
    m, c = RHOA * L, L / 2
    kw = {"duration": 12.0, "gravity": (0.0, -g), "step": 0.05}
    pd = pin_rigid.simulate(rotor(PD(KP, KD, Constant(0.0)), **kw), h=0.01)
    # PD equilibrium: kp·α = −m g c cos α (closed form of the static balance, solved by brentq)
    a_ss = brentq(lambda a: KP * a + m * g * c * math.cos(a), -1.0, 0.0)
    assert abs(pd.joint_angle[-1, 0] - a_ss) <= 1e-6
    assert abs(a_ss) > 0.1
    # kd = 3, ki = 40: slowest pole of J s³ + kd s² + kp s + ki near −2.1 1/s, settled by 12 s
    pid = pin_rigid.simulate(rotor(PID(KP, 3.0, Constant(0.0), ki=40.0), **kw), h=0.01)
    assert abs(pid.joint_angle[-1, 0]) <= 1e-8
    assert pid.joint_torque[-1, 0] == pytest.approx(m * g * c, rel=1e-8)  # holds the weight


def test_saturation_holds_the_limit_and_the_saturated_closed_form():
    lim, r, kp = 1.0, 0.5, 200.0
    res = pin_rigid.simulate(rotor(PD(kp, KD, Constant(r), limit=lim), duration=1.5, step=0.005), h=2e-3)
    assert np.abs(res.joint_torque[:, 0]).max() <= lim
    # while saturated: α = ½ (lim/J) t²; it stays so until kp (r − α) − kd α̇ drops to lim
    t_sat = brentq(lambda t: kp * (r - 0.5 * lim / J * t * t) - KD * lim / J * t - lim, 0.0, 2.0)
    early = res.t < 0.95 * t_sat
    assert early.sum() > 50
    np.testing.assert_allclose(res.joint_angle[early, 0], 0.5 * lim / J * res.t[early] ** 2, atol=1e-9)
    assert np.all(res.joint_torque[early, 0] == lim)
    assert np.abs(res.joint_torque[:, 0]).min() < 0.5 * lim  # it leaves the limit again


def two_link(feedforward, h=2e-3):
    links = tuple(
        dttmm.Link(dttmm.Section(0.6, 10.0, 1.2), dttmm.Hub(0.5, 0.02), dttmm.Payload(0.3, 0.0))
        for _ in range(2)
    )
    refs = (Sine(0.6, 0.5), Sine(-0.8, 0.7, phase=0.3, offset=0.2))
    drives = tuple(Drive("torque", PD(30.0, 4.0, r, feedforward), *r.motion(0.0)[:2]) for r in refs)
    case = dttmm.Case(dttmm.Manipulator(links, (0.0, -9.81)), dttmm.Scenario(2.0, 0.01, drives))
    res = pin_rigid.simulate(case, h=h)
    ref = np.array([[r.motion(t)[0] for r in refs] for t in res.t])
    return np.abs(res.joint_angle - ref).max()


def test_computed_torque_feedforward_makes_the_tracking_error_vanish():
    assert two_link({"law": "computed_torque"}) <= 1e-8  # integration accuracy (RK4, h = 2 ms)
    assert two_link(None) > 1e-2  # the same PD without it lags visibly


def test_rigid_refusals():
    with pytest.raises(InputError, match="moment_gain.*rigid link"):
        pin_rigid.simulate(rotor(PD(KP, KD, Constant(0.0), moment_gain=0.1)), h=1e-2)
    with pytest.raises(InputError, match="integrator.*rk4"):
        pin_rigid.simulate(rotor(PD(KP, KD, Constant(0.0))), h=1e-2, integrator="dop853")
    link = rotor(Constant(0.0)).model.links[0]
    ct = PD(1.0, 1.0, Constant(0.0), {"law": "computed_torque"})
    case = dttmm.Case(
        dttmm.Manipulator((link, link)),
        dttmm.Scenario(1.0, 0.01, (Drive("torque", ct), Drive("torque", Constant(0.0)))),
    )
    with pytest.raises(InputError, match=r"drives\[1\].*reference motion on every joint"):
        pin_rigid.simulate(case, h=1e-2)


# --- MuJoCo chain: the law sampled once per step ------------------------------------------------
mc = pytest.importorskip("reference_models.mujoco_chain")


def test_mujoco_zero_order_hold_is_first_order_in_h():
    case = rotor(PD(KP, KD, Constant(0.3)), EI=1e5)  # stiff: the chain's own error is small
    hs = (5e-4, 2.5e-4, 1.25e-4)
    runs = [mc.simulate(case, elements_per_link=1, h=h) for h in hs]
    exact = step_response(runs[0].t, 0.3)
    errs = [np.abs(r.joint_angle[:, 0] - exact).max() for r in runs]
    orders = [math.log2(a / b) for a, b in itertools.pairwise(errs)]
    assert all(0.85 <= p <= 1.15 for p in orders), orders
    # Richardson on the first-order term leaves the chain's own (stiff-link) error, which
    # falls like 1/EI (measured: 9e-6 rad at EI = 1e5, 1e-6 at 1e6, against 6.5e-5 and 2.6e-5
    # of the first-order lag at h = 1.25e-4 s)
    rich = 2 * runs[2].joint_angle[:, 0] - runs[1].joint_angle[:, 0]
    assert np.abs(rich - exact).max() <= 0.2 * errs[2]


def test_mujoco_refuses_computed_torque():
    with pytest.raises(InputError, match="computed_torque.*mujoco-chain"):
        mc.simulate(rotor(PD(KP, KD, Constant(0.0), {"law": "computed_torque"})), elements_per_link=2, h=1e-3)


def test_mujoco_saturation_and_root_moment_sign():
    seen = []

    def law(t, s):
        seen.append((t, s.moment, s.tip_deflections[0]))
        return 1.0, 0.0, 0.0

    res = mc.simulate(rotor(UserLaw(law), duration=0.05, EI=100.0), elements_per_link=4, h=1e-4)
    assert res.status == "ok"
    t, m, w = np.array(seen).T
    # a constant torque accelerates the hub; the beam lags: the hub drags it forward (M > 0)
    # and the tip deflects backwards (w < 0) — the quasi-static share of the torque is
    # ρA L³/3 / J of it at the start
    assert m[5:200].min() > 0 and w[5:200].max() < 0
    # the tip deflection a law sees is the one the Result reports (same instants)
    at = {round(ti, 9): wi for ti, wi in zip(t, w)}
    out = [(at[round(ti, 9)], wi) for ti, wi in zip(res.t, res.tip_deflection[:, 0]) if round(ti, 9) in at]
    assert len(out) >= 4
    np.testing.assert_allclose(*np.array(out).T, rtol=1e-9, atol=1e-15)
    lim = mc.simulate(
        rotor(PD(200.0, KD, Constant(0.5), limit=1.0), duration=0.5, EI=1e4), elements_per_link=2, h=5e-4
    )
    assert np.abs(lim.joint_torque[:, 0]).max() <= 1.0


def mixed(second_law, EI=10.0):
    """Joint 1 prescribed (rest-to-rest table move), joint 2 closed-loop."""
    links = tuple(
        dttmm.Link(dttmm.Section(0.6, EI, 1.2), dttmm.Hub(0.5, 0.02), dttmm.Payload(0.3, 0.0))
        for _ in range(2)
    )
    move = Table((0.0, 0.8), (0.0, 0.7))
    drives = (Drive("motion", move), Drive("torque", second_law))
    return dttmm.Case(dttmm.Manipulator(links, (0.0, -9.81)), dttmm.Scenario(1.2, 0.01, drives))


def test_computed_torque_with_a_prescribed_joint():
    ref = Sine(0.3, 0.8, phase=0.5)
    law = PD(30.0, 4.0, ref, {"law": "computed_torque"})
    case = mixed(law)
    case = dttmm.Case(
        case.model,
        dttmm.Scenario(1.2, 0.01, (case.scenario.drives[0], Drive("torque", law, *ref.motion(0.0)[:2]))),
    )
    res = pin_rigid.simulate(case, h=2e-3)
    assert np.abs(res.joint_angle[:, 1] - [ref.motion(t)[0] for t in res.t]).max() <= 1e-8


def test_mujoco_mixed_motion_and_closed_loop_agrees_with_the_rigid_baseline():
    case = mixed(PD(30.0, 4.0, Constant(0.0)), EI=1e5)  # stiff links: the rigid limit
    rigid = pin_rigid.simulate(case, h=2e-3)
    chain = mc.simulate(case, elements_per_link=2, h=5e-5)  # h_stable = 1.1e-4 s
    np.testing.assert_allclose(chain.joint_angle[:, 0], rigid.joint_angle[:, 0], atol=1e-12)
    assert np.abs(rigid.joint_angle[:, 1]).max() > 0.05  # the move disturbs joint 2 visibly
    # measured 9e-5 rad, the same at h = 1e-4 and 2.5e-5 s: the links' residual flexibility
    assert np.abs(chain.joint_angle[:, 1] - rigid.joint_angle[:, 1]).max() <= 3e-4


@pytest.mark.parametrize("k", [4, 8])
def test_mujoco_root_moment_is_the_quasi_static_bending_moment(k):
    # a constant torque τ on the rotor: α̈ = τ/J; a straight link rotating with α̈ carries the
    # bending moment M(s) = α̈ ρA ∫_s^L x (x − s) dx at s (the rate only loads it axially).
    # The chain senses it at its first hinge, s = l/2; damped link, mean after 0.5 s.
    seen = []

    def law(t, s):
        seen.append((t, s.moment))
        return 1.0, 0.0, 0.0

    link = dttmm.Link(dttmm.Section(L, 100.0, RHOA, damping=0.01), dttmm.Hub(0.0, JH))
    case = dttmm.Case(dttmm.Manipulator((link,)), dttmm.Scenario(1.0, 0.01, (Drive("torque", UserLaw(law)),)))
    mc.simulate(case, elements_per_link=k, h=2e-4)
    t, m = np.array(seen).T
    s = L / k / 2
    exact = (1.0 / J) * RHOA * ((L**3 - s**3) / 3 - s * (L**2 - s**2) / 2)
    assert m[t > 0.5].mean() == pytest.approx(exact, rel=2e-3)  # measured 5e-4 (k = 4), 2e-4 (k = 8)
    assert m[t > 0.5].std() < 1e-3 * exact
