"""Closed-loop drives in the Exudyn reference models (ANCF cable, geometrically exact beam).

The law is a coordinate spring-damper user function that Exudyn evaluates implicitly at the
step end, so the generalized-α step keeps its second order. Checks against closed forms on a
stiff rotor: a uniform link (L = 1 m, ρA = 1 kg/m) on a hub (J_h = 0.1 kg·m²) is a rigid rotor
of inertia J = J_h + ρA L³/3 obeying J α̈ + kd α̇ + kp α = kp α_ref + kd α̇_ref under PD; moment
feedback, PID, saturation and user laws have closed forms too (written out below, no code under
test involved). Slow tier: the three-link arm of experiments/cases/control against DT-TMM and
the MuJoCo chain.
"""

from __future__ import annotations

import dataclasses
import itertools
import math
import os

import numpy as np
import pytest
import scipy.linalg

pytest.importorskip("exudyn")

import dttmm  # noqa: E402
from dttmm.drives import PD, PID, Constant, Drive, Sine, Table, UserLaw  # noqa: E402
from dttmm.errors import InputError  # noqa: E402
from reference_models import exudyn_ancf, exudyn_beam  # noqa: E402

METHODS = [pytest.param(exudyn_ancf, id="ancf"), pytest.param(exudyn_beam, id="beam")]
CASE = os.path.join(
    os.path.dirname(__file__), "..", "experiments", "cases", "control", "closed_loop_three_link.toml"
)

L, RHOA, JH = 1.0, 1.0, 0.1
JROD = RHOA * L**3 / 3
KP, KD = 20.0, 1.5
# EI = 1e6 N·m² is stiff enough that the link's flexibility moves the hub by < 5e-7 rad here;
# EA is given (1e7 N) because the inextensible default 1e6·EI/L² would make the residual's
# round-off floor, and with it Newton's absolute tolerance, too coarse for this check.
EI_STIFF, EA_STIFF = 1.0e6, 1.0e7


def rotor(law, duration=2.0, EI=EI_STIFF, EA=EA_STIFF, step=0.01, damping=0.0):
    link = dttmm.Link(dttmm.Section(L, EI, RHOA, EA, damping), dttmm.Hub(0.0, JH))
    return dttmm.Case(dttmm.Manipulator((link,)), dttmm.Scenario(duration, step, (Drive("torque", law),)))


def inertia(res):
    """J of the rotor in this model: the GE beam adds its rotary inertia ρI·L."""
    return JH + JROD + res.meta.get("cross_section_inertia", [0.0])[0] * L


def second_order_response(t, J, kp, kd, r):
    """α(t) from rest at 0 of J α̈ + kd α̇ + kp α = kp r (underdamped)."""
    sig = kd / (2 * J)
    wd = math.sqrt(kp / J - sig**2)
    return r * (1 - np.exp(-sig * t) * (np.cos(wd * t) + sig / wd * np.sin(wd * t)))


# --------------------------------------------------------------------------------------------
# rigid-limit rotor against closed forms
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mod", METHODS)
def test_pd_step_is_second_order_in_h(mod):
    """No lag: the error against the closed form falls like h² (generalized-α's order).
    Measured (ANCF): 1.9e-4, 4.8e-5, 1.25e-5 rad at h = 1e-2, 5e-3, 2.5e-3 s."""
    errs = []
    for h in (1e-2, 5e-3, 2.5e-3):
        res = mod.simulate(rotor(PD(KP, KD, Constant(0.3))), elements_per_link=1, h=h)
        exact = second_order_response(res.t, inertia(res), KP, KD, 0.3)
        errs.append(np.abs(res.joint_angle[:, 0] - exact).max())
        # the reported torque is the law at the reported state
        tau = KP * (0.3 - res.joint_angle[:, 0]) - KD * res.joint_rate[:, 0]
        np.testing.assert_allclose(res.joint_torque[:, 0], tau, rtol=0, atol=1e-9)
    orders = [math.log2(a / b) for a, b in itertools.pairwise(errs)]
    assert all(1.8 <= p <= 2.2 for p in orders), (errs, orders)
    assert errs[-1] < 2e-5


@pytest.mark.parametrize("mod", METHODS)
def test_sine_reference_tracks_the_closed_form(mod):
    """α_ref = A sin(Ωt): steady state Im(G A e^{iΩt}) plus the homogeneous solution from rest."""
    A, f = 0.5, 0.5
    res = mod.simulate(rotor(PD(KP, KD, Sine(A, f))), elements_per_link=1, h=2.5e-3)
    J, w = inertia(res), 2 * math.pi * f
    sig, t = KD / (2 * J), res.t
    wd = math.sqrt(KP / J - sig**2)
    G = (KP + 1j * KD * w) / (KP - J * w * w + 1j * KD * w)
    p0, pd0 = (G * A).imag, (1j * w * G * A).imag
    c2 = (-pd0 - sig * p0) / wd
    exact = (G * A * np.exp(1j * w * t)).imag + np.exp(-sig * t) * (
        -p0 * np.cos(wd * t) + c2 * np.sin(wd * t)
    )
    assert np.abs(res.joint_angle[:, 0] - exact).max() < 3e-5  # of 0.5 rad


def test_moment_feedback_rotor_closed_form():
    """A rigid link carries M_root = J_rod ω̇ at its root; τ = L0 − g M_root with J ω̇ = τ gives
    τ = L0 / (1 + g J_rod/J): the PD gains scaled by 1/(1 + g J_rod/J). The torque step at t = 0
    also excites the link's (stiff) bending, which generalized-α damps within ~0.2 s; after it
    the reported torque is the rigid law's."""
    g = 2.0
    res = exudyn_ancf.simulate(rotor(PD(KP, KD, Constant(0.3), moment_gain=g)), elements_per_link=1, h=2.5e-3)
    J = JH + JROD
    s = 1 + g * JROD / J
    exact = second_order_response(res.t, J, KP / s, KD / s, 0.3)
    plain = second_order_response(res.t, J, KP, KD, 0.3)
    assert np.abs(exact - plain).max() > 0.05  # the feedback changes the response visibly
    assert np.abs(res.joint_angle[:, 0] - exact).max() < 2e-5  # measured 8e-6 (3e-5, 2.6e-6 at 2h, h/2)
    tau = (KP * (0.3 - res.joint_angle[:, 0]) - KD * res.joint_rate[:, 0]) / s
    late = res.t > 0.5
    assert np.abs(res.joint_torque[late, 0] - tau[late]).max() < 1e-5


@pytest.mark.parametrize("mod", METHODS)
def test_moment_feedback_equals_a_lighter_hub_with_scaled_gains(mod):
    """At joint 1 (reaction on the ground) the loop τ = clip((L0 + g J_h ω̇)/(1 + g)) is, while
    unsaturated, the same dynamics as a hub of inertia J_h/(1 + g) driven by L0/(1 + g): the hub's
    balance J_h ω̇ = τ − M_root becomes J_h/(1+g) ω̇ = L0/(1+g) − M_root. The second model has no
    ω̇ loop (Exudyn's own linear solves), so the two runs agree only if the loop is solved at
    every step and at the start (a feedforward step at t = 0 and a restart at its switch)."""
    g, d = 1.5, 0.5

    def run(law, jh):
        link = dttmm.Link(dttmm.Section(L, 50.0, RHOA, 1e5, 1e-3), dttmm.Hub(0.0, jh))
        case = dttmm.Case(dttmm.Manipulator((link,)), dttmm.Scenario(0.6, 0.01, (Drive("torque", law),)))
        return mod.simulate(case, elements_per_link=4, h=2.5e-3)

    ff = dttmm.BangBang((d, -d), (0.3,))
    a = run(PD(KP, KD, Sine(0.2, 1.0), ff, moment_gain=g), JH)
    ff_s = dttmm.BangBang((d / (1 + g), -d / (1 + g)), (0.3,))
    b = run(PD(KP / (1 + g), KD / (1 + g), Sine(0.2, 1.0), ff_s), JH / (1 + g))
    assert a.meta["restarts"] == [0.3]
    assert np.abs(a.tip_deflection).max() > 1e-3  # a flexible link (4 mm peak)
    np.testing.assert_allclose(a.joint_angle, b.joint_angle, rtol=0, atol=1e-9)
    np.testing.assert_allclose(a.tip_deflection, b.tip_deflection, rtol=0, atol=1e-9)


def test_pid_with_a_constant_disturbance_matches_the_matrix_exponential():
    """x = (α, α̇, z), ẋ = A x + b (constant torque d fed as the feedforward), solved exactly."""
    ki, r, d = 10.0, 0.2, -1.0
    res = exudyn_ancf.simulate(
        rotor(PID(KP, KD, Constant(r), Constant(d), ki=ki), duration=8.0), elements_per_link=1, h=2.5e-3
    )
    J = JH + JROD
    A = np.array([[0, 1, 0], [-KP / J, -KD / J, ki / J], [-1, 0, 0]])
    b = np.array([0, (KP * r + d) / J, r])
    xs = np.array([np.linalg.solve(A, (scipy.linalg.expm(A * t) - np.eye(3)) @ b) for t in res.t])
    assert np.abs(res.joint_angle[:, 0] - xs[:, 0]).max() < 2e-5
    assert abs(res.joint_angle[-1, 0] - r) < 1e-3  # the offset d/kp of a PD law is gone
    tau = d + KP * (r - xs[:, 0]) - KD * xs[:, 1] + ki * xs[:, 2]
    late = res.t > 0.5  # after the bending transient of the torque step at t = 0
    assert np.abs(res.joint_torque[late, 0] - tau[late]).max() < 3e-4  # of 1.4 N·m (measured 1.4e-4)


def test_saturation_holds_the_limit_and_the_saturated_closed_form():
    from scipy.optimize import brentq

    lim, r, kp = 1.0, 0.5, 200.0
    res = exudyn_ancf.simulate(
        rotor(PD(kp, KD, Constant(r), limit=lim), duration=1.5, step=0.005), elements_per_link=1, h=2.5e-3
    )
    J = JH + JROD
    assert np.abs(res.joint_torque[:, 0]).max() <= lim
    t_sat = brentq(lambda t: kp * (r - 0.5 * lim / J * t * t) - KD * lim / J * t - lim, 0.0, 2.0)
    early = res.t < 0.95 * t_sat
    assert early.sum() > 50
    np.testing.assert_allclose(res.joint_angle[early, 0], 0.5 * lim / J * res.t[early] ** 2, atol=1e-6)
    assert np.all(res.joint_torque[early, 0] == lim)
    assert np.abs(res.joint_torque[:, 0]).min() < 0.5 * lim  # it leaves the limit again


def test_saturated_moment_feedback():
    """Moment feedback with a limit: while saturated τ = limit and α = ½ (limit/J) t² (the
    feedback only acts through the unsaturated value); it leaves the limit when the unsaturated
    torque of the rigid rotor, (kp (r − α) − kd α̇)/(1 + g J_rod/J), drops to it."""
    from scipy.optimize import brentq

    lim, r, kp, g = 1.0, 0.5, 200.0, 1.0
    res = exudyn_ancf.simulate(
        rotor(PD(kp, KD, Constant(r), moment_gain=g, limit=lim), duration=1.0, step=0.005),
        elements_per_link=1,
        h=2.5e-3,
    )
    J = JH + JROD
    s = 1 + g * JROD / J
    t_sat = brentq(lambda t: (kp * (r - 0.5 * lim / J * t * t) - KD * lim / J * t) / s - lim, 0.0, 2.0)
    early = res.t < 0.95 * t_sat
    assert early.sum() > 50 and res.meta["initial_acceleration_solves"] >= 1
    assert np.abs(res.joint_torque[:, 0]).max() <= lim
    np.testing.assert_allclose(res.joint_angle[early, 0], 0.5 * lim / J * res.t[early] ** 2, atol=1e-6)
    np.testing.assert_allclose(res.joint_torque[early, 0], lim, rtol=0, atol=1e-12)
    t_off = res.t[np.argmax(res.joint_torque[:, 0] < lim)]  # first output below the limit
    assert t_sat <= t_off <= t_sat + 0.01  # output step 5 ms


@pytest.mark.parametrize("mod", METHODS)
def test_user_law_equals_the_pd_law(mod):
    """The same PD law with a ramp feedforward (a kink at 0.25 s, a breakpoint: a restart,
    where the user law's start is solved as a fixed point), as a user law and as ``pd``."""
    ff = Table((0.0, 0.25), (0.0, 0.5))

    def law(t, s):
        return ff(t) + KP * (0.3 - s.angle) - KD * s.rate, -KP, -KD

    a = mod.simulate(rotor(UserLaw(law, breakpoints=(0.25,)), duration=0.5), elements_per_link=2, h=2.5e-3)
    b = mod.simulate(rotor(PD(KP, KD, Constant(0.3), ff), duration=0.5), elements_per_link=2, h=2.5e-3)
    assert a.meta["restarts"] == [0.25] and a.meta["initial_acceleration_solves"] >= 2
    np.testing.assert_allclose(a.joint_angle, b.joint_angle, rtol=0, atol=1e-11)
    np.testing.assert_allclose(a.joint_torque, b.joint_torque, rtol=0, atol=1e-9)


def test_user_law_sees_the_root_moment_and_the_reported_tip_deflection():
    """Constant torque τ on a damped, moderately soft rotor: after the transient the root moment
    is the quasi-static one of a link rotating with α̈ = τ/J, M_root = J_rod α̈ (> 0: the hub
    drags the beam), and the tip deflects backwards; the tip deflection the law sees at an
    output time is the one the Result reports."""
    seen = []

    def law(t, s):
        seen.append((t, s.moment, s.tip_deflections[0], s.angles[0], s.rates[0]))
        return 1.0, 0.0, 0.0

    case = rotor(UserLaw(law), duration=1.0, EI=100.0, EA=1e6, damping=0.01)
    res = exudyn_ancf.simulate(case, elements_per_link=8, h=2e-3)
    last = {}  # the last call at a time is the sensor's, at the converged state (the calls
    for row in seen:  # inside the Newton iteration see its iterates)
        last[round(row[0], 9)] = row
    rows = np.array([last[round(ti, 9)] for ti in res.t[1:]])
    t, m, w = rows[:, 0], rows[:, 1], rows[:, 2]
    exact = JROD / (JH + JROD)
    late = t > 0.5
    assert m[late].mean() == pytest.approx(exact, rel=2e-3)
    assert m[late].std() < 2e-3 * exact
    assert w[t > 0.02].max() < 0
    np.testing.assert_allclose(rows[:, 2], res.tip_deflection[1:, 0], rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(rows[:, 3], res.joint_angle[1:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(rows[:, 4], res.joint_rate[1:, 0], rtol=0, atol=1e-12)


def test_bad_user_law_is_an_input_error_naming_the_time():
    def law(t, s):
        return (1.0, 0.0, 0.0) if t < 0.1 else "no"

    with pytest.raises(InputError, match="at t = 0.1"):
        exudyn_ancf.simulate(rotor(UserLaw(law), duration=0.5), elements_per_link=1, h=1e-2)


# --------------------------------------------------------------------------------------------
# computed-torque feedforward (rigid inverse dynamics through dttmm.control)
# --------------------------------------------------------------------------------------------
def test_computed_torque_feedforward_tracks_the_references():
    pytest.importorskip("dttmm.control")
    links = tuple(
        dttmm.Link(dttmm.Section(0.6, EI_STIFF, 1.2, EA_STIFF), dttmm.Hub(0.5, 0.02), dttmm.Payload(0.3, 0.0))
        for _ in range(2)
    )
    refs = (Sine(0.6, 0.5), Sine(-0.8, 0.7, phase=0.3, offset=0.2))

    def run(ff):
        drives = tuple(Drive("torque", PD(30.0, 4.0, r, ff), *r.motion(0.0)[:2]) for r in refs)
        case = dttmm.Case(dttmm.Manipulator(links, (0.0, -9.81)), dttmm.Scenario(1.0, 0.01, drives))
        res = exudyn_ancf.simulate(case, elements_per_link=1, h=2.5e-3)
        ref = np.array([[r.motion(t)[0] for r in refs] for t in res.t])
        return np.abs(res.joint_angle - ref).max()

    assert run({"law": "computed_torque"}) < 1e-4  # generalized-α and the stiff links' flexibility
    assert run(None) > 1e-2  # the same PD without it lags visibly


# --------------------------------------------------------------------------------------------
# the three-link arm (slow)
# --------------------------------------------------------------------------------------------
def _three_link(duration):
    case = dttmm.case.load_case(CASE)
    return dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, duration=duration))


@pytest.mark.slow
def test_three_link_ancf_converges_in_h():
    """ANCF k = 8 at h = 1e-3 and 5e-4 s over the move: tip positions agree to < 1e-5 m
    (measured at k = 32 over 3 s against h = 2.5e-4: 2.4e-6 and 3.4e-7 m)."""
    case = _three_link(1.2)
    a = exudyn_ancf.simulate(case, elements_per_link=8, h=1e-3)
    b = exudyn_ancf.simulate(case, elements_per_link=8, h=5e-4)
    assert np.abs(a.link_tip - b.link_tip).max() < 1e-5


@pytest.mark.slow
def test_three_link_ge_beam_agrees_with_ancf():
    """Two element families, the same closed loop: measured 5.9e-6 m over the move (k = 32)."""
    case = _three_link(1.2)
    a = exudyn_ancf.simulate(case, elements_per_link=32, h=5e-4)
    b = exudyn_beam.simulate(case, elements_per_link=32, h=5e-4)
    assert np.abs(a.link_tip - b.link_tip).max() < 2e-5


@pytest.mark.slow
def test_three_link_mujoco_chain_converges_to_ancf():
    """The MuJoCo chain samples the law once per step (first order in h) on a hinge chain; with k
    and 1/h doubled together its tip error against ANCF halves (measured over 3 s: 5.9e-3,
    2.9e-3, 1.5e-3 m for k = 8, 16, 32 at h = 1e-4, 5e-5, 2.5e-5 s)."""
    mc = pytest.importorskip("reference_models.mujoco_chain")
    case = _three_link(1.2)
    ref = exudyn_ancf.simulate(case, elements_per_link=16, h=5e-4)
    d8 = np.abs(mc.simulate(case, elements_per_link=8, h=1e-4).link_tip - ref.link_tip).max()
    d16 = np.abs(mc.simulate(case, elements_per_link=16, h=5e-5).link_tip - ref.link_tip).max()
    assert d16 < 2.5e-3 and 0.4 < d16 / d8 < 0.6, (d8, d16)


@pytest.mark.slow
def test_three_link_ancf_agrees_with_dttmm():
    """Two discretisations and integrators solving the same closed loop: tip positions within
    1.0e-6 m over the move (measured; 1.2e-6 m over 3 s). For scale, the same arm in open loop
    (ANCF's closed-loop torques fed to both as tables) differs by 9.3e-6 m (k = 32, h = 1e-3)."""
    case = _three_link(1.2)
    a = exudyn_ancf.simulate(case, elements_per_link=32, h=1e-3)
    b = dttmm.simulate(case, elements_per_link=32, h=1e-3, cut_loads=False, energy=False)
    assert np.abs(a.link_tip - b.link_tip).max() < 5e-6
    assert np.abs(a.joint_torque - b.joint_torque).max() < 2e-3  # of 4.5 N·m (measured 4.9e-4)
