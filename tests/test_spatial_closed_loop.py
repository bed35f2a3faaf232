"""Closed-loop drives (pd, pid, user laws) in the spatial DT-TMM kernel (dttmm.spatial) against
the spatial global-equation solver (reference_models.spatial_global), which assembles the same
discretisation and the same discrete law equations independently (the law at the step end with
the state there, the integral state by the trapezoidal rule, M_root = τ − a·(J_h ω̇ + ω × J_h ω)
as an exact row of q̈ in its iteration matrix), on the shipped yaw-pitch-pitch arm
(experiments/cases/spatial/three_joint_arm.toml) with pd/pid drives; and numba-jitted user laws
in the compiled kernel. The planar embedding of the shipped closed-loop case is in
tests/test_spatial_planar.py.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.drives import PD, PID, Constant, Drive, Sine, Table, UserLaw
from dttmm.errors import InputError
from dttmm.spatial import load_case, simulate
from reference_models import spatial_global as sg

ARM = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "three_joint_arm.toml"
#: the end-effector of DT-TMM and the global solver agree to this (m)
TOL_EE = 1e-9


def _arm(drives, duration, output_step=1e-3):
    case = load_case(ARM)
    sc = dc.replace(case.scenario, drives=tuple(drives), duration=duration, output_step=output_step)
    return dc.replace(case, scenario=sc)


def _pd_drives(end=0.1):
    """Rest-to-rest moves of the three joints: pd with moment feedback, pid with saturation and
    moment feedback, pd on a sine reference with a feedforward. The reference tables end at
    ``end`` (a breakpoint: both solvers restart there)."""
    return (
        Drive("torque", PD(20.0, 2.0, Table((0.0, end), (0.0, 0.5)), moment_gain=0.5)),
        Drive(
            "torque",
            PID(30.0, 2.0, Table((0.0, end), (0.0, -0.4)), ki=5.0, moment_gain=0.3, limit=8.0),
        ),
        Drive("torque", PD(5.0, 0.5, Sine(0.2, 2.0), feedforward=Constant(0.1))),
    )


def _diff(a, b):
    return {
        "end_effector": float(np.abs(a.end_effector - b.end_effector).max()),
        "joint_angle": float(np.abs(a.joint_angle - b.joint_angle).max()),
        "joint_rate": float(np.abs(a.joint_rate - b.joint_rate).max()),
        "joint_torque": float(np.abs(a.joint_torque - b.joint_torque).max()),
        "twist": float(np.abs(a.twist - b.twist).max()),
    }


def _assert_equal(a, b, ee=TOL_EE):
    d = _diff(a, b)
    assert d["end_effector"] <= ee, d
    assert d["joint_angle"] <= 1e-9, d
    assert d["joint_rate"] <= 1e-7 * max(1.0, np.abs(b.joint_rate).max()), d
    assert d["joint_torque"] <= 1e-8 * max(1.0, np.abs(b.joint_torque).max()), d
    assert d["twist"] <= 1e-9, d


@pytest.mark.parametrize(
    ("integrator", "duration"), [("newmark", 0.2), ("generalized-alpha", 0.2)], ids=["newmark", "galpha"]
)
def test_dttmm_equals_the_global_solver_on_the_closed_loop_arm(integrator, duration):
    case = _arm(_pd_drives(), duration)
    kw = {"elements_per_link": 2, "h": 1e-3, "integrator": integrator}
    ref = sg.simulate(case, **kw)
    res = simulate(case, **kw)
    assert res.status == ref.status == "ok"
    _assert_equal(res, ref)
    # the arm moves and the laws act: joint 2 saturates, the end-effector travels
    assert np.abs(res.joint_torque[:, 1]).max() == pytest.approx(8.0)
    assert np.linalg.norm(res.end_effector[-1] - res.end_effector[0]) > 5e-3


def test_cut_loads_of_a_closed_loop_run_equal_the_global_solver():
    case = _arm(_pd_drives(0.02), 0.03, 5e-3)
    kw = {"elements_per_link": 2, "h": 1e-3, "cut_loads": True}
    ref, res = sg.simulate(case, **kw), simulate(case, **kw)
    scale = np.abs(ref.cut_loads).max()
    assert np.abs(res.cut_loads - ref.cut_loads).max() <= 1e-9 * scale


def test_user_law_moment_feedback_equals_the_pd_law():
    """A user law that feeds back ``state.moment`` with gain g_M (the kernel's M_root = τ_sweep − H
    of the last sweep, resolved by repeating the sweeps) equals the pd law with moment_gain g_M
    (its moment loop solved in closed form through the measured sensitivity), and the global
    solver running the same user law."""
    gain = 0.5

    def law(t, s):
        kp, kd = (20.0, 30.0, 5.0)[s.joint], (2.0, 2.0, 0.5)[s.joint]
        return kp * (0.2 - s.angle) - kd * s.rate - gain * s.moment, -kp, -kd

    user = tuple(Drive("torque", UserLaw(law)) for _ in range(3))
    pd = tuple(
        Drive("torque", PD(kp, kd, Constant(0.2), moment_gain=gain))
        for kp, kd in ((20.0, 2.0), (30.0, 2.0), (5.0, 0.5))
    )
    kw = {"elements_per_link": 2, "h": 1e-3, "engine": "python"}
    a = simulate(_arm(user, 0.006), **kw)
    b = simulate(_arm(pd, 0.006), **kw)
    g = sg.simulate(_arm(user, 0.006), elements_per_link=2, h=1e-3)
    assert a.status == b.status == g.status == "ok"
    _assert_equal(a, b, 1e-12)
    _assert_equal(a, g, 1e-12)


def test_sensed_moment_is_the_root_cut_moment_along_the_axis():
    """What a law sees as M_root is the root cut load's moment (docs/spatial.md §4: the load the
    hub exerts on the beam) along the world joint axis R_link·a."""
    seen = {}

    def law(t, s):
        seen.setdefault(s.joint, {})[round(t, 9)] = s.moment  # the last call of a step: its final
        return 3.0 * (0.2 - s.angle) - 0.3 * s.rate, -3.0, -0.3

    case = _arm((Drive("torque", UserLaw(law)),) * 3, 0.005)
    k = 2
    res = simulate(case, elements_per_link=k, h=1e-3, engine="python", cut_loads=True)
    axes = np.array([lk.joint.axis for lk in case.model.links])
    for i in range(3):
        world = np.einsum("tij,j->ti", res.link_rotation[:, i], axes[i])
        cut = np.einsum("ti,ti->t", res.cut_loads[:, i * (k + 1), 3:], world)
        sensed = np.array([seen[i][round(t, 9)] for t in res.t[1:]])
        assert np.abs(cut).max() > 1e-3
        np.testing.assert_allclose(sensed, cut[1:], rtol=0, atol=1e-9 * np.abs(cut).max())


def test_rk4_closed_loop_converges_to_newmark():
    """RK4 (laws at every stage, z a fourth state) and Newmark (laws implicit at the step end)
    solve the same ODE: their difference shrinks with h (Newmark's O(h²) error dominates)."""
    case = _arm(_pd_drives(0.02), 0.02)
    rk = simulate(case, elements_per_link=1, h=2.5e-6, integrator="rk4", energy=False)
    err = []
    for h in (2e-4, 1e-4):
        nm = simulate(case, elements_per_link=1, h=h, energy=False)
        err.append(np.abs(nm.joint_angle - rk.joint_angle).max())
    assert rk.status == "ok"
    assert err[1] < 0.35 * err[0], err  # second order: 0.25


def test_refusals_name_the_drive():
    # computed_torque needs a reference on every joint (joint 3 here is an open-loop torque)
    pd = Drive("torque", PD(1.0, 0.1, Constant(0.0), feedforward={"law": "computed_torque"}))
    case = _arm((pd, _pd_drives()[1], Drive("torque", Constant(0.0))), 0.01)
    with pytest.raises(InputError, match=r"scenario\.drives\[2\]\.law.*reference motion on every joint"):
        simulate(case, elements_per_link=1, h=1e-3)
    with pytest.raises(InputError, match=r"scenario\.drives\[2\]\.law.*reference motion on every joint"):
        sg.simulate(case, elements_per_link=1, h=1e-3)
    plain = _arm((Drive("torque", UserLaw(lambda t, s: (0.0, 0.0, 0.0))), *_pd_drives()[1:]), 0.01)
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*numba-jitted"):
        simulate(plain, elements_per_link=1, h=1e-3, engine="numba")
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*closed-loop"):
        dttmm.spatial.accelerations(_arm(_pd_drives(), 0.01), 1, np.zeros(21), np.zeros(21))
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*'rk4'"):
        sg.simulate(_arm(_pd_drives(), 0.01), elements_per_link=1, h=1e-3, integrator="rk4")


def test_non_finite_user_torque_fails_the_step():
    def bad(t, s):
        return (np.nan if t > 0.0035 else 0.0), 0.0, 0.0

    drives = (Drive("torque", UserLaw(bad)), *_pd_drives()[1:])
    with pytest.raises(InputError, match=r"non-finite value at t = 0\.004 s \(joint 1\)"):
        simulate(_arm(drives, 0.01), elements_per_link=1, h=1e-3, engine="python")


# --- numba-jitted user laws ------------------------------------------------------------------

numba = pytest.importorskip("numba")

GAINS = np.array([[20.0, 2.0], [30.0, 2.0], [5.0, 0.5]])


def _jit_law():
    gains = GAINS.copy()

    @numba.njit
    def law(t, s):
        i = s.joint
        kp, kd = gains[i, 0], gains[i, 1]
        tau = kp * (0.2 - s.angle) - kd * s.rate - 0.5 * s.moment - 5.0 * s.tip_deflections[i]
        return tau, -kp, -kd

    return UserLaw(law, label="jit-tip-pd")


@pytest.mark.slow
def test_jitted_user_law_runs_compiled_as_uncompiled_and_as_the_global_solver():
    """One jitted law on the three joints (dispatching on ``state.joint``, reading the moment
    and the tip deflections): the compiled kernel (its user-law specialisation) = the
    uncompiled kernel = the spatial global solver (which calls the law from Python)."""
    case = _arm((Drive("torque", _jit_law()),) * 3, 0.01)
    kw = {"elements_per_link": 2, "h": 1e-3}
    a = simulate(case, engine="numba", **kw)
    b = simulate(case, engine="python", **kw)
    g = sg.simulate(case, **kw)
    assert a.status == b.status == g.status == "ok"
    _assert_equal(a, b, 1e-13)
    _assert_equal(a, g, 1e-12)
    assert np.abs(a.tip_deflection).max() > 0.0


@pytest.mark.slow
def test_non_finite_jitted_torque_stops_the_run_at_that_step():
    @numba.njit
    def bad(t, s):
        if t > 0.0045:
            return np.nan, -1.0, -1.0
        return -s.angle, -1.0, 0.0

    case = _arm((Drive("torque", UserLaw(bad)), *_pd_drives()[1:]), 0.02)
    with pytest.raises(dttmm.SimulationError, match=r"non-finite.*t = 0\.005 s") as info:
        simulate(case, elements_per_link=1, h=1e-3, engine="numba")
    partial = info.value.partial
    assert partial.status == "failed" and partial.t[-1] == pytest.approx(0.004)
