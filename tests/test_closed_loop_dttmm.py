"""Closed-loop (pd/pid) drives in the DT-TMM kernel against closed forms and the law itself.

A stiff uniform link (L = 1 m, ρA = 1 kg/m) on a hub of inertia J_h is, in the rigid limit, a
rotor of inertia J = J_h + ρA L³/3 about the joint: under τ = kp (α_ref − α) + kd (α̇_ref − α̇)
it obeys J α̈ + kd α̇ + kp α = kp α_ref + kd α̇_ref, whose responses are written out below (no
code under test involved). With moment feedback the root bending moment of a rigid link is
M_root = (J − J_h) α̈, so τ = L0 − g_M M_root gives the same equation with the inertia
J + g_M (J − J_h). The discretised link is flexible: EI is chosen so that its deviation from
the rigid rotor is below the tolerances (it scales as 1/EI, measured).
"""

from __future__ import annotations

import dataclasses as dc
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg

import dttmm
from dttmm.drives import PD, PID, BangBang, Constant, ControlState, Drive, Sine, Table, UserLaw
from dttmm.errors import InputError

L, RHOA, JH = 1.0, 1.0, 0.1
J = JH + RHOA * L**3 / 3
KP, KD = 20.0, 1.5
THREE_LINK = (
    Path(__file__).resolve().parents[1] / "experiments" / "cases" / "control" / "closed_loop_three_link.toml"
)


def rotor(law, duration=2.0, EI=1e8, step=0.01):
    link = dttmm.Link(dttmm.Section(L, EI, RHOA), dttmm.Hub(0.0, JH))
    drive = Drive("torque", law)
    return dttmm.Case(dttmm.Manipulator((link,), (0.0, 0.0)), dttmm.Scenario(duration, step, (drive,)))


def step_response(t, r, inertia=J):
    """α(t) of the PD rotor of the given inertia from rest at 0 for the constant reference r."""
    sig = KD / (2 * inertia)
    wd = math.sqrt(KP / inertia - sig**2)
    return r * (1 - np.exp(-sig * t) * (np.cos(wd * t) + sig / wd * np.sin(wd * t)))


def sine_response(t, A, f):
    """α(t) from rest at 0 for α_ref = A sin(Ωt): steady state plus the homogeneous solution."""
    sig = KD / (2 * J)
    wd = math.sqrt(KP / J - sig**2)
    w = 2 * math.pi * f
    G = (KP + 1j * KD * w) / (KP - J * w * w + 1j * KD * w)
    p0, pd0 = (G * A).imag, (1j * w * G * A).imag
    c1 = -p0
    c2 = (-pd0 + sig * c1) / wd
    return (G * A * np.exp(1j * w * t)).imag + np.exp(-sig * t) * (c1 * np.cos(wd * t) + c2 * np.sin(wd * t))


def linear_response(t, ki, r, pieces):
    """α(t) of J α̈ = d(t) + kp (r − α) − kd α̇ + ki z, ż = r − α from rest, z(0) = 0, for the
    piecewise-constant disturbance ``pieces`` = ((t_start, d), …): exact, by the matrix
    exponential of the augmented linear system on each piece."""
    A = np.array([[0.0, 1.0, 0.0], [-KP / J, -KD / J, ki / J], [-1.0, 0.0, 0.0]])
    x = np.zeros(3)
    out = np.empty(t.size)
    bounds = [p[0] for p in pieces] + [np.inf]
    for (t0, d), t1 in zip(pieces, bounds[1:]):
        b = np.array([0.0, (KP * r + d) / J, r])
        M = np.zeros((4, 4))
        M[:3, :3], M[:3, 3] = A, b
        sel = (t >= t0) & (t <= t1)
        for j in np.flatnonzero(sel):
            out[j] = (scipy.linalg.expm(M * (t[j] - t0)) @ np.append(x, 1.0))[0]
        if np.isfinite(t1):
            x = (scipy.linalg.expm(M * (t1 - t0)) @ np.append(x, 1.0))[:3]
    return out


def test_pd_step_rigid_limit_second_order_in_h():
    errs = []
    for h in (1e-3, 5e-4):
        res = dttmm.simulate(rotor(PD(KP, KD, Constant(0.3))), elements_per_link=2, h=h)
        assert res.status == "ok"
        errs.append(np.abs(res.joint_angle[:, 0] - step_response(res.t, 0.3)).max())
    assert errs[1] <= 1e-6  # measured 4.4e-7
    assert 3.5 < errs[0] / errs[1] < 4.5  # trapezoidal rule: order 2 (measured ratio 3.9)
    # the reported torque is the law at the reported state
    tau = KP * (0.3 - res.joint_angle[:, 0]) - KD * res.joint_rate[:, 0]
    np.testing.assert_allclose(res.joint_torque[:, 0], tau, rtol=0, atol=1e-10)


def test_pd_sine_reference_rigid_limit():
    res = dttmm.simulate(rotor(PD(KP, KD, Sine(0.5, 0.5))), elements_per_link=2, h=5e-4)
    assert np.abs(res.joint_angle[:, 0] - sine_response(res.t, 0.5, 0.5)).max() <= 1e-6


def test_pd_rk4_rigid_limit():
    # RK4 needs h below the stability limit of the link's bending modes: k = 1, EI = 1e7, h = 1e-5
    case = rotor(PD(KP, KD, Constant(0.3)), duration=1.0, EI=1e7)
    res = dttmm.simulate(case, elements_per_link=1, h=1e-5, integrator="rk4", cut_loads=False, energy=False)
    assert np.abs(res.joint_angle[:, 0] - step_response(res.t, 0.3)).max() <= 1e-6  # measured 1.1e-7


def test_moment_feedback_rotor_matches_the_larger_inertia():
    g = 1.0
    case = rotor(PD(KP, KD, Constant(0.3), moment_gain=g))
    for integrator in ("newmark", "generalized-alpha"):
        res = dttmm.simulate(case, elements_per_link=2, h=5e-4, integrator=integrator)
        exact = step_response(res.t, 0.3, J + g * (J - JH))
        assert np.abs(res.joint_angle[:, 0] - exact).max() <= 1e-6  # measured 3.3e-7


def test_pid_with_a_constant_disturbance():
    ki, d = 15.0, 2.0
    law = PID(KP, KD, Constant(0.3), feedforward=Constant(d), ki=ki)
    res = dttmm.simulate(rotor(law, duration=3.0), elements_per_link=2, h=5e-4)
    exact = linear_response(res.t, ki, 0.3, ((0.0, d),))
    assert np.abs(res.joint_angle[:, 0] - exact).max() <= 1e-6


def test_feedforward_jump_restarts_the_step():
    # a disturbance that switches at 0.505 s (not on the step grid): the step ends there, the
    # law restarts with the right limit; the response stays exact
    law = PID(KP, KD, Constant(0.3), feedforward=BangBang((1.0, -2.0), (0.505,)), ki=5.0)
    for integrator, h in (("newmark", 5e-4), ("rk4", 1e-5)):
        case = rotor(law, duration=1.0, EI=1e8 if integrator == "newmark" else 1e7)
        res = dttmm.simulate(
            case, elements_per_link=2 if integrator == "newmark" else 1, h=h, integrator=integrator
        )
        exact = linear_response(res.t, 5.0, 0.3, ((0.0, 1.0), (0.505, -2.0)))
        assert np.abs(res.joint_angle[:, 0] - exact).max() <= 1e-6


def test_saturation_accelerates_at_the_limit():
    limit = 1.0
    res = dttmm.simulate(
        rotor(PD(KP, KD, Constant(0.5), limit=limit), duration=1.0), elements_per_link=2, h=5e-4
    )
    tau = res.joint_torque[:, 0]
    assert np.abs(tau).max() <= limit * (1 + 1e-12)
    sat = np.flatnonzero(tau == limit)
    assert sat[0] == 0 and sat.size > 10
    # saturated from t = 0 (contiguous): α = ½ (limit/J) t²
    end = sat[np.flatnonzero(np.diff(sat) > 1)[0]] if np.any(np.diff(sat) > 1) else sat[-1]
    t = res.t[: end + 1]
    assert np.abs(res.joint_angle[: end + 1, 0] - 0.5 * limit / J * t**2).max() <= 1e-6


def three_link(duration=0.2, moment_gain=0.5, output_step=1e-3):
    case = dttmm.load_case(THREE_LINK)
    drives = tuple(Drive("torque", dc.replace(d.law, moment_gain=moment_gain)) for d in case.scenario.drives)
    scen = dc.replace(case.scenario, duration=duration, output_step=output_step, drives=drives)
    return dc.replace(case, scenario=scen)


@pytest.mark.parametrize(
    ("integrator", "h", "k"), [("newmark", 1e-3, 4), ("generalized-alpha", 1e-3, 4), ("rk4", 1e-5, 2)]
)
def test_converged_step_satisfies_the_law(integrator, h, k):
    """τ recomputed by drives.PD.evaluate from the recorded (α, α̇) and the recorded root moment
    (cut loads, first cut of each link) equals the recorded torque: with g_M ≠ 0 this also
    checks M_root = τ − J_hub ω̇ against the cut loads. (RK4 needs h below the stability limit
    of the links' axial modes: k = 2, h = 1e-5.)"""
    case = three_link(duration=0.02 if integrator == "rk4" else 0.2)
    res = dttmm.simulate(case, elements_per_link=k, h=h, integrator=integrator)
    worst = 0.0
    for j, t in enumerate(res.cut_load_t):
        jj = int(np.flatnonzero(res.t == t)[0])
        for i, d in enumerate(case.scenario.drives):
            state = ControlState(
                joint=i,
                angle=res.joint_angle[jj, i],
                rate=res.joint_rate[jj, i],
                moment=res.cut_loads[j, i * (k + 1), 0],
            )
            tau = d.evaluate(t, state, left=True)[0]
            worst = max(worst, abs(tau - res.joint_torque[jj, i]) / max(1.0, abs(tau)))
    assert res.status == "ok"
    assert worst <= 1e-9


def test_closed_loop_next_to_a_motion_drive():
    """Joint 2 prescribed (a sine), joints 1 and 3 under pd with moment feedback: the motion is
    followed exactly and the closed-loop joints satisfy their laws."""
    k = 4
    case = three_link()
    drives = list(case.scenario.drives)
    drives[1] = Drive("motion", Sine(0.2, 1.0))
    case = dc.replace(case, scenario=dc.replace(case.scenario, drives=tuple(drives)))
    res = dttmm.simulate(case, elements_per_link=k, h=1e-3)
    ref = np.array([Sine(0.2, 1.0).motion(t)[0] for t in res.t])
    assert np.abs(res.joint_angle[:, 1] - ref).max() <= 1e-14
    for j, t in enumerate(res.cut_load_t):
        jj = int(np.flatnonzero(res.t == t)[0])
        for i in (0, 2):
            state = ControlState(
                i, res.joint_angle[jj, i], res.joint_rate[jj, i], res.cut_loads[j, i * (k + 1), 0]
            )
            tau = case.scenario.drives[i].evaluate(t, state, left=True)[0]
            assert abs(tau - res.joint_torque[jj, i]) <= 1e-9 * max(1.0, abs(tau))


def test_chunked_run_keeps_the_integral_state():
    """A run split into chunks (progress bar) equals the run in one call: z is part of the
    state carried between calls of the kernel."""
    case = rotor(PID(KP, KD, Constant(0.3), ki=5.0))
    one = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=False)
    chunked = dttmm.simulate(case, elements_per_link=2, h=1e-3, progress=True)
    np.testing.assert_array_equal(one.joint_angle, chunked.joint_angle)
    np.testing.assert_array_equal(one.joint_torque, chunked.joint_torque)


def test_root_moment_is_the_beam_inertia_torque():
    """A smooth move of a stiff rotor: the root cut moment is the beam's inertia torque
    (J − J_h) α̈ (α̈ by finite differences of the recorded rate)."""
    law = PD(KP, KD, Table((0.0, 1.0), (0.0, 0.5)), moment_gain=0.5)
    case = rotor(law, duration=1.0, EI=1e6, step=1e-3)
    res = dttmm.simulate(case, elements_per_link=4, h=1e-4, integrator="generalized-alpha")
    acc = np.gradient(res.joint_rate[:, 0], res.t)
    M = res.cut_loads[:, 0, 0]
    inner = slice(5, -5)  # the reference's acceleration jumps at 0 and 1 s
    assert np.abs(M[inner] - (J - JH) * acc[inner]).max() <= 2e-3 * np.abs(M).max()


def test_numba_equals_python_on_the_three_link_arm():
    pytest.importorskip("numba")
    case = three_link(duration=0.01)
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3, engine="numba")
    b = dttmm.simulate(case, elements_per_link=2, h=1e-3, engine="python")
    for f in ("joint_angle", "joint_rate", "joint_torque", "link_tip"):
        np.testing.assert_allclose(getattr(a, f), getattr(b, f), rtol=0, atol=1e-12)
    # iteration counts are not compared: round-off decides a solve at the stop rule's bound
    assert a.status == b.status == "ok" and a.meta["unconverged_steps"] == b.meta["unconverged_steps"] == 0


def test_computed_torque_feedforward_tracks_the_references():
    """A stiff two-link arm under gravity: PD with the rigid model's computed torque tracks the
    sine references to the links' flexibility; the same PD alone lags (or sags) visibly."""

    def worst(feedforward):
        links = tuple(
            dttmm.Link(dttmm.Section(0.6, 1e8, 1.2), dttmm.Hub(0.5, 0.02), dttmm.Payload(0.3, 0.0))
            for _ in range(2)
        )
        refs = (Sine(0.6, 0.5), Sine(-0.8, 0.7, phase=0.3, offset=0.2))
        drives = tuple(Drive("torque", PD(30.0, 4.0, r, feedforward), *r.motion(0.0)[:2]) for r in refs)
        case = dttmm.Case(dttmm.Manipulator(links, (0.0, -9.81)), dttmm.Scenario(2.0, 0.01, drives))
        res = dttmm.simulate(case, elements_per_link=2, h=5e-4)
        ref = np.array([[r.motion(t)[0] for r in refs] for t in res.t])
        return np.abs(res.joint_angle - ref).max()

    assert worst({"law": "computed_torque"}) <= 1e-6  # measured 4.2e-7
    assert worst(None) > 1e-2


def _user_pd(gain):
    def law(t, s):
        return KP * (0.3 - s.angle) + KD * (0.0 - s.rate) - gain * s.moment, -KP, -KD

    return UserLaw(law, label="user-pd")


@pytest.mark.parametrize(
    ("integrator", "h", "gain"), [("newmark", 1e-3, 0.0), ("rk4", 2e-5, 0.0), ("newmark", 1e-3, 0.5)]
)
def test_user_law_equals_the_pd_law(integrator, h, gain):
    """engine="python": a user law re-implementing PD (with moment feedback through
    ``state.moment``, resolved by repeating the sweeps) runs as law="pd"."""
    runs = [
        dttmm.simulate(
            rotor(law, duration=0.02 if integrator == "rk4" else 0.05, EI=1e4),
            elements_per_link=2,
            h=h,
            integrator=integrator,
            engine="python",
        )
        for law in (_user_pd(gain), PD(KP, KD, Constant(0.3), moment_gain=gain))
    ]
    np.testing.assert_allclose(runs[0].joint_angle, runs[1].joint_angle, rtol=0, atol=1e-12)
    np.testing.assert_allclose(runs[0].joint_torque, runs[1].joint_torque, rtol=0, atol=1e-9)


def test_unconverged_moment_loop_is_reported():
    """RK4 with moment feedback solves the laws' loop in ω̇ by repeated sweeps: cut short by
    max_iterations = 1, the run says so."""
    case = three_link(duration=1e-3, output_step=1e-4)
    res = dttmm.simulate(case, elements_per_link=2, h=1e-5, integrator="rk4", max_iterations=1)
    assert res.status == "unconverged"
    assert res.meta["unconverged_solves"] > 0
    assert any("forward-dynamics solves" in w for w in res.warnings)
    ok = dttmm.simulate(case, elements_per_link=2, h=1e-5, integrator="rk4")
    assert ok.status == "ok" and "unconverged_solves" not in ok.meta


def test_refusals_name_the_drive():
    case = rotor(PD(KP, KD, Constant(0.3)))
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*sweep='riccati'"):
        dttmm.simulate(case, elements_per_link=2, h=1e-3, sweep="plain")
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law"):
        dttmm.accelerations(case, 2, np.zeros(7), np.zeros(7))
    user = rotor(UserLaw(lambda t, s: (0.0, 0.0, 0.0)))
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*engine='python'"):
        dttmm.simulate(user, elements_per_link=2, h=1e-3, engine="numba")


def test_restart_with_moment_feedback_converges_and_equals_the_global_solver():
    """The restart at the end of the move (t = 1 s, the references' breakpoint): its
    forward-dynamics solve stops at the round-off floor like a step's sweeps (it once ran into
    max_iterations there and flagged the run), and the run equals the global solver's."""
    gn = pytest.importorskip("reference_models.global_newmark")
    case = three_link(duration=1.2, output_step=1e-2)
    a = dttmm.simulate(case, elements_per_link=8, h=1e-3)
    assert a.status == "ok", a.warnings
    b = gn.simulate(case, elements_per_link=8, h=1e-3)
    assert np.abs(a.link_tip - b.link_tip).max() <= 1e-9
