"""Numba-jitted user laws inside the compiled DT-TMM kernel.

A jitted law re-implementing PD must run as law="pd" (an independent implementation of the
same discrete equations: the pd law's closed-form moment loop against the user law's moment
resolved by repeated sweeps), and the compiled kernel must run it as the uncompiled kernel
(engine "python") does. The first user-law run compiles a second specialisation of the kernel
(~80 s CPU, then cached on disk): those runs are in the slow tier.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest

import dttmm
from dttmm.control_state import make_state
from dttmm.drives import PD, Constant, Drive, UserLaw
from dttmm.errors import InputError

numba = pytest.importorskip("numba")

from tests.test_closed_loop_dttmm import KD, KP, rotor, three_link  # noqa: E402


def test_a_law_can_be_tried_by_hand():
    law = _jit_pd(0.5).fn
    state = make_state(0, 0.1, -0.2, moment=0.4, tips=[1e-3])
    assert isinstance(state.angles, np.ndarray) and state.tip_deflections[0] == 1e-3
    assert law(0.0, state) == law.py_func(0.0, state) == (KP * 0.2 + KD * 0.2 - 0.2, -KP, -KD)


def test_jitted_law_in_the_uncompiled_kernel():
    """engine="python" passes a jitted law the compiled kernel's JitState (no kernel compile)."""
    run = lambda law: dttmm.simulate(
        rotor(law, duration=0.02, EI=1e4), elements_per_link=2, h=1e-3, engine="python"
    )
    _close(run(_jit_pd(0.5)), run(PD(KP, KD, Constant(0.3), moment_gain=0.5)), 1e-12, 1e-9)


def test_law_that_does_not_fit_the_signature_names_the_drive():
    @numba.njit
    def bad(t, s):
        return s.no_such_field, 0.0, 0.0

    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*numba-jitted user law"):
        dttmm.simulate(rotor(UserLaw(bad)), elements_per_link=2, h=1e-3, engine="numba")


def test_plain_python_law_is_still_refused_by_the_compiled_kernel():
    with pytest.raises(InputError, match=r"scenario\.drives\[0\]\.law.*numba-jitted"):
        dttmm.simulate(
            rotor(UserLaw(lambda t, s: (0.0, 0.0, 0.0))), elements_per_link=2, h=1e-3, engine="numba"
        )


def _jit_pd(gain):
    if gain is None:  # no moment term at all (the rigid baseline's moment is nan)

        @numba.njit
        def pd(t, s):
            return KP * (0.3 - s.angle) + KD * (0.0 - s.rate), -KP, -KD

        return UserLaw(pd, label="jit-pd")

    @numba.njit
    def law(t, s):
        return KP * (0.3 - s.angle) + KD * (0.0 - s.rate) - gain * s.moment, -KP, -KD

    return UserLaw(law, label="jit-pd")


def _close(a, b, angle_tol, load_tol):
    """Angles to ``angle_tol`` (rad); rates and torques to ``load_tol`` relative to their
    largest magnitude (the compiled kernel contracts a·b + c to FMA: rounding differs at ~1e-14
    relative; the pd law and the user law resolve the moment loop to the iteration tolerance)."""
    np.testing.assert_allclose(a.joint_angle, b.joint_angle, rtol=0, atol=angle_tol, err_msg="joint_angle")
    for f in ("joint_rate", "joint_torque"):
        ref = getattr(b, f)
        tol = load_tol * max(1.0, np.abs(ref).max())
        np.testing.assert_allclose(getattr(a, f), ref, rtol=0, atol=tol, err_msg=f)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("integrator", "h", "gain"), [("newmark", 1e-3, 0.0), ("newmark", 1e-3, 0.5), ("rk4", 2e-5, 0.5)]
)
def test_jitted_pd_law_on_the_rotor(integrator, h, gain):
    """As law="pd" (the moment feedback through ``state.moment``) and as engine "python"."""
    run = lambda law, engine: dttmm.simulate(
        rotor(law, duration=0.02 if integrator == "rk4" else 0.05, EI=1e4),
        elements_per_link=2,
        h=h,
        integrator=integrator,
        engine=engine,
    )
    jit = run(_jit_pd(gain), "numba")
    assert jit.status == "ok"
    _close(jit, run(PD(KP, KD, Constant(0.3), moment_gain=gain), "numba"), 1e-12, 1e-9)
    _close(jit, run(_jit_pd(gain), "python"), 1e-12, 1e-12)


# the three-link arm's pd gains (experiments/cases/control/closed_loop_three_link.toml), here
# with constant references
GAINS = np.array([[111.0, 16.5], [34.0, 5.0], [4.9, 0.73]])
TARGETS = np.array([0.8, -0.6, 0.4])


def _three_link_pd():
    gains, targets = GAINS.copy(), TARGETS.copy()

    @numba.njit
    def law(t, s):
        i = s.joint
        kp, kd = gains[i, 0], gains[i, 1]
        return kp * (targets[i] - s.angle) - kd * s.rate, -kp, -kd

    return UserLaw(law, label="jit-three-link")


def _three_link(duration):
    case = three_link(duration=duration, moment_gain=0.0)
    laws = tuple(dc.replace(d.law, reference=Constant(v)) for d, v in zip(case.scenario.drives, TARGETS))
    assert all((law.kp, law.kd) == tuple(g) for law, g in zip(laws, GAINS))
    return _with_laws(case, laws)


def _with_laws(case, laws):
    drives = tuple(Drive("torque", law) for law in laws)
    return dc.replace(case, scenario=dc.replace(case.scenario, drives=drives))


@pytest.mark.slow
def test_jitted_pd_law_on_the_three_link_arm():
    """One jitted law on three joints (dispatching on ``state.joint``) as the case's pd laws."""
    case = _three_link(0.02)
    law = _three_link_pd()
    kw = {"elements_per_link": 2, "h": 1e-3}
    pd = dttmm.simulate(case, **kw)
    jit = dttmm.simulate(_with_laws(case, (law,) * 3), **kw)
    assert jit.status == "ok"
    _close(jit, pd, 1e-12, 1e-9)


@pytest.mark.slow
def test_law_reading_tips_and_moment_runs_as_in_python():
    """Distinct laws on the joints, reading every link's tip deflection and the root moment:
    the compiled kernel sees the same state as the uncompiled one."""
    case = _three_link(0.01)
    base = _three_link_pd().fn

    @numba.njit
    def tips(t, s):
        tau, da, dr = base(t, s)
        return tau - 50.0 * (s.tip_deflections[0] + s.tip_deflections[2]) - 0.05 * s.moment, da, dr

    laws = (UserLaw(tips), UserLaw(base), UserLaw(tips))
    kw = {"elements_per_link": 2, "h": 1e-3}
    a = dttmm.simulate(_with_laws(case, laws), engine="numba", **kw)
    b = dttmm.simulate(_with_laws(case, laws), engine="python", **kw)
    assert a.status == "ok"
    _close(a, b, 1e-12, 1e-12)
    assert np.abs(a.tip_deflection).max() > 0.0


@pytest.mark.slow
def test_non_finite_torque_stops_the_run_at_that_step():
    @numba.njit
    def bad(t, s):
        if t > 0.0105:
            return np.nan, -1.0, -1.0
        return -s.angle, -1.0, 0.0

    with pytest.raises(dttmm.SimulationError, match=r"non-finite.*t = 0\.011 s"):
        dttmm.simulate(rotor(UserLaw(bad), duration=0.05, step=1e-3), elements_per_link=2, h=1e-3)


@pytest.mark.parametrize("engine", ["global-python", "exudyn-ancf", "pinocchio-rigid"])
def test_a_jitted_law_runs_in_the_other_engines(engine):
    """Engines that call a law from Python give a jitted one a JitState (UserLaw.evaluate): the
    same run as law="pd" (without the moment term: the rigid baseline's moment is nan)."""
    if engine == "global-python":
        gn = pytest.importorskip("reference_models.global_newmark")
        run = lambda law: gn.simulate(
            rotor(law, duration=0.05, EI=1e4), elements_per_link=2, h=1e-3, engine="python"
        )
    elif engine == "exudyn-ancf":
        ex = pytest.importorskip("reference_models.exudyn_ancf")
        run = lambda law: ex.simulate(rotor(law, duration=0.05, EI=1e4), elements_per_link=2, h=1e-3)
    else:
        pr = pytest.importorskip("reference_models.pinocchio_rigid")
        run = lambda law: pr.simulate(rotor(law, duration=0.05, EI=1e4), h=1e-3, integrator="rk4")
    a, b = run(_jit_pd(None)), run(PD(KP, KD, Constant(0.3)))
    _close(a, b, 1e-10, 1e-8)
