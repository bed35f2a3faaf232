"""Closed-loop drive laws (pd, pid, user laws) in the global-equation solver.

The law is solved implicitly at every step end. Checks: the two engines of the one time-loop
source (uncompiled and compiled) agree to round-off; a stiff rotor follows the closed-form response of the rigid rotor (with and
without moment feedback, PID, saturation); the converged steps satisfy the law, with the
accelerations recomputed by the open-loop forward dynamics from the recorded torques; the
moment-feedback study of the three-link example against the MuJoCo-chain numbers of
docs/control.md; DT-TMM solves the same discrete equations.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import scipy.linalg

import dttmm
from dttmm.case import load_case
from dttmm.drives import PD, PID, Constant, ControlState, Drive, Table, UserLaw
from dttmm.errors import InputError
from reference_models import _global_driver as gd
from reference_models import global_newmark as gn
from tests.golden import value as golden

pytest.importorskip("numba")

THREE_LINK = "experiments/cases/control/closed_loop_three_link.toml"

# stiff rotor: L = 1 m, ρA = 1 kg/m, hub J_h = 0.1 kg·m²; rigid inertia J = J_h + ρA L³/3
L, RHOA, JH, EI = 1.0, 1.0, 0.1, 1e8
JB = RHOA * L**3 / 3
KP, KD = 20.0, 1.5


def rotor(law, duration=1.0, step=0.01):
    link = dttmm.Link(dttmm.Section(L, EI, RHOA), dttmm.Hub(0.0, JH))
    drive = Drive("torque", law)
    return dttmm.Case(dttmm.Manipulator((link,), (0.0, 0.0)), dttmm.Scenario(duration, step, (drive,)))


def step_response(t, r, J):
    """α(t) from rest of J α̈ + kd α̇ + kp α = kp r (r constant)."""
    sig = KD / (2 * J)
    wd = math.sqrt(KP / J - sig**2)
    return r * (1 - np.exp(-sig * t) * (np.cos(wd * t) + sig / wd * np.sin(wd * t)))


def three_link(duration=0.3, k_ref_end=0.2):
    """The three-link example, shortened; references end at k_ref_end (a restart), joint 1
    saturates, joint 2 is a PID, joint 3 has a large moment gain."""
    case = load_case(THREE_LINK)
    d1, d2, d3 = case.scenario.drives
    end = (0.0, k_ref_end)
    laws = (
        dataclasses.replace(d1.law, reference=Table(end, (0.0, 0.8)), limit=10.0),
        PID(34.0, 5.0, Table(end, (0.0, -0.6)), moment_gain=0.5, ki=40.0),
        dataclasses.replace(d3.law, reference=Table(end, (0.0, 0.4)), moment_gain=2.0),
    )
    drives = tuple(dataclasses.replace(d, law=law) for d, law in zip((d1, d2, d3), laws))
    sc = dataclasses.replace(case.scenario, drives=drives, duration=duration, output_step=1e-3)
    return dataclasses.replace(case, scenario=sc)


# --------------------------------------------------------------------------------------------
# the two engines
# --------------------------------------------------------------------------------------------


def test_uncompiled_engine_equals_compiled_engine_in_closed_loop():
    case = three_link()
    a = gn.simulate(case, elements_per_link=2, h=1e-3, engine="python")
    b = gn.simulate(case, elements_per_link=2, h=1e-3, engine="numba")
    assert a.status == b.status == "ok"
    assert np.isclose(np.abs(a.joint_torque[:, 0]), 10.0, rtol=0, atol=1e-15).sum() > 50  # saturated
    assert np.abs(a.end_effector - b.end_effector).max() <= 1e-12
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-9
    # generalized-α too
    a = gn.simulate(case, elements_per_link=1, h=2e-3, integrator="generalized-alpha", engine="python")
    b = gn.simulate(case, elements_per_link=1, h=2e-3, integrator="generalized-alpha", engine="numba")
    assert np.abs(a.end_effector - b.end_effector).max() <= 1e-12


def test_engines_agree_with_a_prescribed_joint_inboard():
    # joint 1 follows its reference exactly (motion drive): ω̇ of links 2, 3 has a prescribed part
    case = three_link(duration=0.25)
    d1 = case.scenario.drives[0]
    drives = (Drive("motion", d1.law.reference),) + case.scenario.drives[1:]
    case = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives))
    a = gn.simulate(case, elements_per_link=2, h=1e-3, engine="python")
    b = gn.simulate(case, elements_per_link=2, h=1e-3, engine="numba")
    assert a.status == b.status == "ok"
    assert np.abs(a.end_effector - b.end_effector).max() <= 1e-12
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-9


# --------------------------------------------------------------------------------------------
# rigid limit: closed forms of the rotor
# --------------------------------------------------------------------------------------------


def test_stiff_rotor_under_pd_follows_the_rigid_closed_form():
    res = gn.simulate(rotor(PD(KP, KD, Constant(0.3))), elements_per_link=2, h=5e-4)
    assert np.abs(res.joint_angle[:, 0] - step_response(res.t, 0.3, JH + JB)).max() <= 1e-6
    tau = KP * (0.3 - res.joint_angle[:, 0]) - KD * res.joint_rate[:, 0]
    np.testing.assert_allclose(res.joint_torque[:, 0], tau, rtol=0, atol=1e-9)


def test_moment_feedback_on_a_stiff_rotor_adds_beam_inertia():
    # rigid beam: M_root = J_b α̈, so τ = L0 − g_M J_b α̈ and (J_h + (1 + g_M) J_b) α̈ = L0
    gm = 1.5
    res = gn.simulate(rotor(PD(KP, KD, Constant(0.3), moment_gain=gm)), elements_per_link=2, h=5e-4)
    assert np.abs(res.joint_angle[:, 0] - step_response(res.t, 0.3, JH + (1 + gm) * JB)).max() <= 1e-6


def test_stiff_rotor_under_pid_with_a_disturbance_matches_the_matrix_exponential():
    ki, d, r = 30.0, -2.0, 0.3  # the feedforward d acts as a constant disturbance
    res = gn.simulate(
        rotor(PID(KP, KD, Constant(r), feedforward=Constant(d), ki=ki)), elements_per_link=2, h=5e-4
    )
    J = JH + JB
    A = np.array([[0, 1, 0], [-KP / J, -KD / J, ki / J], [-1, 0, 0]], float)
    b = np.array([0.0, (KP * r + d) / J, r])
    # x' = A x + b from x = 0: x(t) = A⁻¹ (e^{At} − I) b
    x = np.array([np.linalg.solve(A, (scipy.linalg.expm(A * t) - np.eye(3)) @ b) for t in res.t])
    assert np.abs(res.joint_angle[:, 0] - x[:, 0]).max() <= 1e-6


def test_saturated_rotor_accelerates_uniformly():
    limit = 0.5
    res = gn.simulate(
        rotor(PD(KP, KD, Constant(2.0), limit=limit), duration=0.3), elements_per_link=2, h=5e-4
    )
    np.testing.assert_allclose(res.joint_torque[:, 0], limit, rtol=0, atol=1e-12)
    alpha = 0.5 * limit / (JH + JB) * res.t**2
    assert np.abs(res.joint_angle[:, 0] - alpha).max() <= 1e-7


def _two_link_under_gravity(feedforward, duration=1.5):
    """Two stiff links (EI = 1e8 N·m²) with hubs under gravity, rest-to-rest references."""
    links = tuple(dttmm.Link(dttmm.Section(0.5, EI, 1.0), dttmm.Hub(0.2, 0.01)) for _ in range(2))
    refs = (Table((0.0, 1.0), (0.0, 0.8)), Table((0.0, 1.0), (0.0, -0.6)))
    drives = tuple(Drive("torque", PD(20.0, 2.0, r, feedforward=feedforward)) for r in refs)
    case = dttmm.Case(dttmm.Manipulator(links, (0.0, -9.81)), dttmm.Scenario(duration, 0.01, drives))
    return case, refs


def test_computed_torque_feedforward_tracks_the_references():
    # the rigid inverse dynamics of the references is the stiff arm's torque to O(1/EI)
    errors = []
    for ff in ({"law": "computed_torque"}, None):
        case, refs = _two_link_under_gravity(ff)
        res = gn.simulate(case, elements_per_link=2, h=5e-4)
        ref = np.array([[r.motion(t)[0] for r in refs] for t in res.t])
        errors.append(np.abs(res.joint_angle - ref).max())
    assert errors[0] <= 1e-6  # measured 4.8e-8 rad
    assert errors[1] >= 1e-2  # the PD law alone lags (0.43 rad)
    case, _ = _two_link_under_gravity({"law": "computed_torque"}, duration=0.3)
    a = gn.simulate(case, elements_per_link=1, h=1e-3, engine="python")
    b = gn.simulate(case, elements_per_link=1, h=1e-3, engine="numba")
    assert np.abs(a.end_effector - b.end_effector).max() <= 1e-12


# --------------------------------------------------------------------------------------------
# the converged step satisfies the law
# --------------------------------------------------------------------------------------------


def _recorded_states(monkeypatch, case, **kw):
    """Run and keep the full recorded coordinates (q, q̇) of the outputs."""
    kept = []
    result = gd._Recorder.result

    def keep(self, *a, **k):
        kept.append(self)
        return result(self, *a, **k)

    monkeypatch.setattr(gd._Recorder, "result", keep)
    res = gn.simulate(case, **kw)
    return res, kept[-1].q[: res.t.size], kept[-1].qd[: res.t.size]


def _root_accelerations(case, k, q, qd, tau):
    """ω̇ (n,) of every link root from the open-loop forward dynamics with the torques τ:
    the joint accelerations up to the link plus the element rotations φ̈ of inboard links."""
    drives = tuple(Drive("torque", Constant(float(x))) for x in tau)
    twin = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives))
    qdd = gn.accelerations(twin, k, q, qd)
    names = gn.coordinate_names(case, k)
    n = len(tau)
    out = np.zeros(n)
    for i in range(n):
        for name, a in zip(names, qdd):
            parts = name.split("_")
            if parts[0] == "alpha" and int(parts[1]) <= i + 1:
                out[i] += a
            elif parts[0] == "phi" and int(parts[1]) < i + 1:
                out[i] += a
    return out


@pytest.mark.parametrize("engine", ["python", "numba"])
def test_converged_steps_satisfy_the_law(monkeypatch, engine):
    # M_root is not an output: it is τ − J_hub ω̇ (the hub's moment balance) with ω̇ from the
    # forward dynamics of the recorded state under the recorded torques
    case = three_link(duration=0.25)
    k = 2
    res, q, qd = _recorded_states(monkeypatch, case, elements_per_link=k, h=1e-3, engine=engine)
    hubs = [link.hub_inertia for link in case.model.links]
    worst = 0.0
    for row in range(1, res.t.size, 10):
        tau = res.joint_torque[row]
        wdot = _root_accelerations(case, k, q[row], qd[row], tau)
        for i, d in enumerate(case.scenario.drives):
            if isinstance(d.law, PID):
                continue  # its integral state is not an output
            st = ControlState(i, res.joint_angle[row, i], res.joint_rate[row, i], tau[i] - hubs[i] * wdot[i])
            law = d.evaluate(res.t[row], st, left=True)[0]
            worst = max(worst, abs(law - tau[i]) / max(1.0, abs(tau[i])))
    assert worst <= 1e-9


# --------------------------------------------------------------------------------------------
# user laws
# --------------------------------------------------------------------------------------------


def test_user_law_with_moment_feedback_equals_the_pd_law():
    # the user law sees M_root of the latest iterate: the fixed point is the pd law's step
    gm, ref = 0.5, Table((0.0, 0.2), (0.0, 0.3))

    def law(t, s):
        a, r, _ = ref.motion(t, True)
        return KP * (a - s.angle) + KD * (r - s.rate) - gm * s.moment, -KP, -KD

    case_u = rotor(UserLaw(law, breakpoints=(0.2,)), duration=0.3)
    case_pd = rotor(PD(KP, KD, ref, moment_gain=gm), duration=0.3)
    a = gn.simulate(case_u, elements_per_link=2, h=1e-3, engine="python")
    b = gn.simulate(case_pd, elements_per_link=2, h=1e-3, engine="python")
    assert a.status == "ok"
    assert np.abs(a.joint_angle - b.joint_angle).max() <= 1e-10
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-7


def test_user_law_sees_the_tip_deflection():
    seen = []

    def law(t, s):
        seen.append((t, s.tip_deflections[0]))
        return 1.0, 0.0, 0.0

    link = dttmm.Link(dttmm.Section(L, 50.0, RHOA), dttmm.Hub(0.0, JH))
    case = dttmm.Case(
        dttmm.Manipulator((link,), (0.0, 0.0)), dttmm.Scenario(0.1, 0.01, (Drive("torque", UserLaw(law)),))
    )
    res = gn.simulate(case, elements_per_link=2, h=1e-3, engine="python")
    ts, ws = np.array(seen).T
    # the last call at a step end is at its converged state
    w = np.array([ws[np.flatnonzero(np.abs(ts - t) <= 1e-12)[-1]] for t in res.t[1:]])
    np.testing.assert_allclose(w, res.tip_deflection[1:, 0], rtol=1e-8, atol=1e-14)
    assert np.abs(w).max() > 1e-4


# --------------------------------------------------------------------------------------------
# refusals
# --------------------------------------------------------------------------------------------


def test_compiled_engine_refuses_a_python_user_law():
    case = rotor(UserLaw(lambda t, s: (0.0, 0.0, 0.0), label="mine"))
    with pytest.raises(InputError, match="engine='python'"):
        gn.simulate(case, elements_per_link=1, h=1e-2, engine="numba")


def test_forward_dynamics_helper_refuses_closed_loop():
    case = rotor(PD(KP, KD, Constant(0.3)))
    n = len(gn.coordinate_names(case, 1))
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law"):
        gn.accelerations(case, 1, np.zeros(n), np.zeros(n))


# --------------------------------------------------------------------------------------------
# moment feedback on the three-link example
# --------------------------------------------------------------------------------------------


def _with_moment_gain(case, gm, duration):
    drives = tuple(
        dataclasses.replace(d, law=dataclasses.replace(d.law, moment_gain=gm)) for d in case.scenario.drives
    )
    sc = dataclasses.replace(case.scenario, drives=drives, duration=duration, output_step=5e-3)
    return dataclasses.replace(case, scenario=sc)


def test_moment_feedback_lowers_the_deflection_as_in_the_mujoco_chain():
    # peak |w₁| and decay rate of the residual vibration of the MuJoCo chain (tests/golden.py)
    base = load_case(THREE_LINK)
    out = {}
    for gm in (0.0, 4.0):
        res = gn.simulate(_with_moment_gain(base, gm, 4.0), elements_per_link=4, h=1e-3)
        t, w = res.t, res.tip_deflection[:, 0]
        decay = math.log(np.abs(w[(t >= 1) & (t <= 2)]).max() / np.abs(w[(t >= 3) & (t <= 4)]).max()) / 2
        out[gm] = (np.abs(w).max(), decay)
    assert out[0.0][0] == pytest.approx(golden("closed_loop.peak_w1_gain0"), rel=0.05)
    assert out[4.0][0] == pytest.approx(golden("closed_loop.peak_w1_gain4"), rel=0.05)
    assert out[0.0][1] == pytest.approx(golden("closed_loop.decay_gain0"), rel=0.1)
    assert out[4.0][1] == pytest.approx(golden("closed_loop.decay_gain4"), rel=0.2)


# --------------------------------------------------------------------------------------------
# DT-TMM solves the same discrete equations
# --------------------------------------------------------------------------------------------


def test_dttmm_equals_global_solver_in_closed_loop():
    case = three_link(duration=0.3)
    a = dttmm.simulate(case, elements_per_link=2, h=1e-3)
    b = gn.simulate(case, elements_per_link=2, h=1e-3)
    assert a.status == b.status == "ok"
    assert np.abs(a.link_tip - b.link_tip).max() <= 1e-9
