"""Exudyn flexible reference models (ANCF cable, geometrically exact beam).

Fast tier: rigid limits against closed forms, cantilever statics, input and failure handling,
consistency of a short 3-link run. Slow tier (-m slow): ANCF vs GE on the 3-link case, k-convergence,
the Kane-Ryan-Banerjee spin-up.
"""

import dataclasses
import math
import os

import numpy as np
import pytest

pytest.importorskip("exudyn")

import dttmm  # noqa: E402
from dttmm import (
    BangBang,
    Case,
    Constant,
    Drive,
    Hub,
    InputError,
    Link,
    Manipulator,  # noqa: E402
    Payload,
    Scenario,
    Section,
    SimulationError,
    Sine,
    SpinUp,
)
from reference_models import exudyn_ancf, exudyn_beam  # noqa: E402
from tests.golden import value as golden  # noqa: E402

CASES = os.path.join(os.path.dirname(__file__), "..", "experiments", "cases")
METHODS = [pytest.param(exudyn_ancf, id="ancf"), pytest.param(exudyn_beam, id="beam")]

# aluminium strip 50 mm x 2 mm
EI_AL, RHOA_AL, EA_AL = 2.3333333333333335, 0.27, 7.0e6


def _extra_rotary_inertia(res, length, link=0):
    """Rotary inertia the element adds about the joint beyond ρA·L³/3 (GE beam: ρI·L)."""
    return res.meta.get("cross_section_inertia", [0.0] * (link + 1))[link] * length


def _single(
    EI,
    *,
    EA=EA_AL,
    hub=Hub(0.0, 0.01),  # noqa: B008 (a frozen dataclass: an immutable default)
    payload=None,
    drive,
    duration,
    output_step=1e-3,
    gravity=(0.0, 0.0),
    damping=0.0,
    L=1.0,
):
    link = Link(Section(L, EI, RHOA_AL, EA, damping), hub, payload)
    return Case(Manipulator((link,), gravity), Scenario(duration, output_step, (drive,)))


# --------------------------------------------------------------------------------------------
# rigid limits and statics (closed forms)
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mod", METHODS)
def test_rigid_limit_bang_bang_hub_angle(mod):
    """EI x 1e5: the hub follows the rigid rotor J = J_hub + ρA L³/3 under ±1 N·m bang-bang."""
    case = _single(EI_AL * 1e5, drive=Drive("torque", BangBang((1.0, -1.0), (0.5,))), duration=1.0)
    res = mod.simulate(case, elements_per_link=2, h=1e-3)
    J = 0.01 + RHOA_AL / 3.0 + _extra_rotary_inertia(res, 1.0)
    t = res.t
    angle = np.where(t <= 0.5, 0.5 * t**2 / J, 0.125 / J + 0.5 * (t - 0.5) / J - 0.5 * (t - 0.5) ** 2 / J)
    rate = np.where(t <= 0.5, t / J, (0.5 - (t - 0.5)) / J)
    assert res.meta["success"] and res.meta["restarts"] == [0.5]
    assert res.n_steps == 1000 and np.allclose(res.t, case.scenario.output_times)
    assert np.max(np.abs(res.joint_angle[:, 0] - angle)) < 1e-4  # of 2.5 rad swept
    late = t >= 0.9  # after the switch transient
    assert np.max(np.abs(res.joint_rate[late, 0] - rate[late])) < 1e-3  # of 5 rad/s peak
    assert np.max(np.abs(res.tip_deflection)) < 1e-4


@pytest.mark.parametrize("mod", METHODS)
def test_inextensible_link_uses_the_documented_stiff_axial_value(mod):
    """EA None: EA = 1e6·EI/L² (2.3e6 N for the strip), recorded in meta, and the run equals one
    with that EA given; the physical strip (EA = 7e6 N) moves alike (differences: axial strain
    and, for ANCF, membrane locking, both small at k = 8)."""
    drive = Drive("torque", Sine(0.2, 2.0))
    runs = [
        mod.simulate(_single(EI_AL, EA=ea, drive=drive, duration=0.2), elements_per_link=8, h=1e-3)
        for ea in (None, 1e6 * EI_AL, EA_AL)
    ]
    assert runs[0].meta["axial_stiffness"] == [pytest.approx(1e6 * EI_AL)]
    assert runs[0].meta["inextensible_axial_ratio"] == 1e6
    assert np.array_equal(runs[0].link_tip, runs[1].link_tip)
    scale = np.max(np.abs(runs[2].tip_deflection))  # 0.035 m
    assert np.max(np.abs(runs[0].tip_deflection - runs[2].tip_deflection)) < 1e-2 * scale


@pytest.mark.parametrize("mod", METHODS)
def test_motion_joint_torque_is_rigid_inverse_dynamics(mod):
    """Prescribed smooth spin-up of a stiff link with payload: τ = J_total·α̈ (sign and size)."""
    law = SpinUp(3.0, 0.5)
    case = _single(EI_AL * 1e5, payload=Payload(0.1, 0.001), drive=Drive("motion", law), duration=0.5)
    res = mod.simulate(case, elements_per_link=2, h=1e-3)
    J = 0.01 + RHOA_AL / 3.0 + 0.1 * 1.0**2 + 0.001 + _extra_rotary_inertia(res, 1.0)
    ang, rate, acc = np.array([law.motion(t) for t in res.t]).T
    tau = J * acc  # peak 2.41 N·m at t = 0.25 s
    assert np.max(np.abs(res.joint_torque[:, 0] - tau)) < 1e-3 * np.max(np.abs(tau))
    assert np.max(np.abs(res.joint_angle[:, 0] - ang)) < 1e-9
    assert np.max(np.abs(res.joint_rate[:, 0] - rate)) < 1e-4


@pytest.mark.parametrize("mod", METHODS)
def test_two_link_motor_reaction_and_held_joint_torque(mod):
    """Stiff 2-link arm, joint 1 held by a motion drive, joint 2 driven by τ2 = 0.2 sin(4πt):
    link 2 turns as a rigid rotor about joint 2, and joint 1 must supply the rate of change of
    the angular momentum about the origin, τ1 = J2 α̈ + m2 (L2/2) L1 (α̈ cos α − α̇² sin α)
    (this holds only if the motor's reaction −τ2 acts on the tip of link 1)."""
    L1 = L2 = 0.5
    links = (
        Link(Section(L1, EI_AL * 1e5, RHOA_AL, EA_AL), Hub(0.0, 0.01)),
        Link(Section(L2, EI_AL * 1e5, RHOA_AL, EA_AL), Hub(0.0, 0.005)),
    )
    drives = (Drive("motion", Constant(0.0)), Drive("torque", Sine(0.2, 2.0)))
    case = Case(Manipulator(links), Scenario(0.5, 1e-3, drives))
    res = mod.simulate(case, elements_per_link=2, h=1e-3)
    m2 = RHOA_AL * L2
    J2 = 0.005 + m2 * L2**2 / 3 + _extra_rotary_inertia(res, L2, 1)
    w = 4 * np.pi
    angle = 0.2 / J2 * (res.t / w - np.sin(w * res.t) / w**2)  # peak 0.49 rad
    assert np.max(np.abs(res.joint_angle[:, 1] - angle)) < 1e-4
    assert np.max(np.abs(res.joint_angle[:, 0])) < 1e-12
    acc = 0.2 * np.sin(w * res.t) / J2
    a, ad = res.joint_angle[:, 1], res.joint_rate[:, 1]
    tau1 = J2 * acc + m2 * (L2 / 2) * L1 * (acc * np.cos(a) - ad**2 * np.sin(a))  # peak 0.41 N·m
    assert np.max(np.abs(res.joint_torque[:, 0] - tau1)) < 5e-3 * np.max(np.abs(tau1))


@pytest.mark.parametrize(
    "mod,k", [pytest.param(exudyn_ancf, 4, id="ancf"), pytest.param(exudyn_beam, 16, id="beam")]
)
def test_held_cantilever_under_gravity(mod, k):
    """Joint held at 0 by a motion drive, gravity, damping: static tip deflection ρA g L⁴/(8EI)
    and holding torque ρA g L²/2 once the vibration has decayed."""
    EI, g = EI_AL * 100.0, 9.81
    case = _single(
        EI,
        hub=None,
        drive=Drive("motion", Constant(0.0)),
        duration=0.4,
        output_step=1e-2,
        gravity=(0.0, -g),
        damping=0.01,
    )
    res = mod.simulate(case, elements_per_link=k, h=1e-3)
    w_static = RHOA_AL * g / (8 * EI)  # 1.42e-3 m, small: linear theory holds
    assert res.tip_deflection[-1, 0] == pytest.approx(-w_static, rel=1e-2)
    assert res.joint_torque[-1, 0] == pytest.approx(RHOA_AL * g / 2, rel=1e-3)


@pytest.mark.parametrize(
    "mod,k", [pytest.param(exudyn_ancf, 4, id="ancf"), pytest.param(exudyn_beam, 8, id="beam")]
)
def test_kelvin_voigt_damping_ratio(mod, k):
    """Cantilever released under gravity vibrates in its first mode with the Kelvin-Voigt damping
    ratio ζ = μω/2 (D = μK), measured by the logarithmic decrement of successive peaks."""
    EI, mu = EI_AL * 100.0, 1e-3  # ω1 ≈ 103 rad/s, ζ1 ≈ 0.05
    case = _single(
        EI, hub=None, drive=Drive("motion", Constant(0.0)), duration=0.3, gravity=(0.0, -9.81), damping=mu
    )
    res = mod.simulate(case, elements_per_link=k, h=1e-3)
    u = res.tip_deflection[:, 0] + RHOA_AL * 9.81 / (8 * EI)  # about the static sag
    i = np.flatnonzero((u[1:-1] < u[:-2]) & (u[1:-1] <= u[2:])) + 1  # minima (release goes down)
    assert len(i) >= 4
    period = np.mean(np.diff(res.t[i]))
    delta = np.mean(np.log(u[i[:-1]] / u[i[1:]]))
    zeta = delta / np.sqrt(4 * np.pi**2 + delta**2)
    omega = 2 * np.pi / period / np.sqrt(1 - zeta**2)
    assert omega == pytest.approx(1.8751**2 * np.sqrt(EI / RHOA_AL), rel=5e-3)
    assert zeta == pytest.approx(mu * omega / 2, rel=1e-2)


# --------------------------------------------------------------------------------------------
# multi-link consistency, initial state, output grid
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mod", METHODS)
def test_three_link_short_run_is_consistent(mod, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = dttmm.load_case(os.path.join(CASES, "three_link.toml"))
    case = dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, duration=0.1))
    res = mod.simulate(case, elements_per_link=2, h=1e-3)
    assert list(tmp_path.iterdir()) == []  # nothing written
    assert res.t.shape == (101,) and np.allclose(res.t, case.scenario.output_times)
    for name in ("joint_angle", "joint_rate", "joint_torque", "tip_deflection"):
        arr = getattr(res, name)
        assert arr.shape == (101, 3) and np.isfinite(arr).all(), name
    assert np.max(np.abs(res.link_root[:, 0])) < 1e-12  # joint 1 at the origin
    assert np.max(np.abs(res.link_root[:, 1:] - res.link_tip[:, :-1])) < 1e-9
    assert np.array_equal(res.end_effector, res.link_tip[:, -1])
    law_tau = np.array([[d.torque(t, t > 0) for d in case.scenario.drives] for t in res.t])
    assert np.array_equal(res.joint_torque, law_tau)
    # straight, horizontal reference configuration at rest
    assert np.allclose(res.link_tip[0], [[0.5, 0.0], [1.0, 0.0], [1.5, 0.0]], atol=1e-12)
    assert np.allclose(res.joint_angle[0], 0.0, atol=1e-12) and np.allclose(
        res.joint_rate[0], 0.0, atol=1e-12
    )
    # gravity pulls the arm down
    assert res.end_effector[-1, 1] < 0.0
    m = res.meta
    assert m["method"] == mod.METHOD and m["success"] and m["steps"] == m["steps_taken"] == 100
    assert m["elements_per_link"] == 2 and m["h"] == 1e-3 and m["rho_inf"] == 0.8
    assert m["newton_iterations"] > 0 and m["ode2_size"] > 0 and m["exudyn"]


@pytest.mark.parametrize("mod", METHODS)
def test_initial_angles_and_rates_are_a_rigid_motion(mod):
    """Initial joint angles set the straight reference configuration; initial joint rates give
    every node the velocity of the rigidly rotating chain (else the stiff links would ring)."""
    links = (
        Link(Section(0.5, EI_AL * 1e4, RHOA_AL, EA_AL), Hub(0.0, 0.01)),
        Link(Section(0.5, EI_AL * 1e4, RHOA_AL, EA_AL), Hub(0.1, 0.005), Payload(0.1, 0.0)),
    )
    drives = (
        Drive("torque", Constant(0.0), initial_angle=0.3, initial_rate=1.0),
        Drive("torque", Constant(0.0), initial_angle=-0.5, initial_rate=2.0),
    )
    case = Case(Manipulator(links), Scenario(0.05, 1e-3, drives))
    res = mod.simulate(case, elements_per_link=2, h=1e-3)
    p1 = 0.5 * np.array([math.cos(0.3), math.sin(0.3)])
    p2 = p1 + 0.5 * np.array([math.cos(-0.2), math.sin(-0.2)])
    assert np.allclose(res.link_tip[0], [p1, p2], atol=1e-12)
    assert np.allclose(res.joint_angle[0], [0.3, -0.5], atol=1e-12)
    assert np.allclose(res.joint_rate[0], [1.0, 2.0], atol=1e-9)
    assert np.max(np.abs(res.tip_deflection)) < 1e-5  # a non-rigid start would ring at ~mm


@pytest.mark.parametrize("mod", METHODS)
def test_switch_off_the_output_grid_restarts_there(mod):
    """A switch at 10.5 ms (on the 0.5 ms step grid, off the 1 ms output grid): the integrator
    restarts there and the output rows are the same whatever the output step."""
    drive = Drive("torque", BangBang((1.0, -1.0), (0.0105,)))
    coarse = _single(EI_AL, drive=drive, duration=0.02, output_step=1e-3)
    fine = _single(EI_AL, drive=drive, duration=0.02, output_step=5e-4)
    a = mod.simulate(coarse, elements_per_link=2, h=5e-4)
    b = mod.simulate(fine, elements_per_link=2, h=5e-4)
    assert a.meta["restarts"] == [0.0105] and a.n_steps == 40
    assert np.allclose(a.t, coarse.scenario.output_times)
    assert np.array_equal(a.joint_angle, b.joint_angle[::2])
    assert np.array_equal(a.tip_deflection, b.tip_deflection[::2])


# --------------------------------------------------------------------------------------------
# bad input and failures
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "kw,field",
    [
        (dict(elements_per_link=0, h=1e-3), "elements_per_link"),
        (dict(elements_per_link=1.5, h=1e-3), "elements_per_link"),
        (dict(elements_per_link=True, h=1e-3), "elements_per_link"),
        (dict(elements_per_link=2, h=0.0), "h"),
        (dict(elements_per_link=2, h=-1e-3), "h"),
        (dict(elements_per_link=2, h=float("nan")), "h"),
        (dict(elements_per_link=2, h=0.5), "h"),  # longer than the duration
        (dict(elements_per_link=2, h=3e-4), "h"),  # does not divide the output step
        (dict(elements_per_link=2, h=1e-3, rho_inf=1.5), "rho_inf"),
        (dict(elements_per_link=2, h=1e-3, newton_abs_tol=-1.0), "newton_abs_tol"),
        (dict(elements_per_link=2, h=1e-3, newton_max_iterations=0), "newton_max_iterations"),
    ],
)
@pytest.mark.parametrize("mod", METHODS)
def test_bad_input_is_refused(mod, kw, field):
    case = _single(EI_AL, drive=Drive("torque", Constant(1.0)), duration=0.1)
    with pytest.raises(InputError) as exc:
        mod.simulate(case, **kw)
    assert exc.value.field == field and field in str(exc.value)


def test_beam_options_are_checked():
    case = _single(EI_AL, drive=Drive("torque", Constant(1.0)), duration=0.1)
    for name in ("shear_ratio", "cross_section_inertia"):
        with pytest.raises(InputError, match=name):
            exudyn_beam.simulate(case, elements_per_link=2, h=1e-3, **{name: 0.0})


@pytest.mark.parametrize(
    "kw",
    [dict(newton_max_iterations=1), dict(newton_abs_tol=1e-16, newton_rel_tol=1e-16)],
    ids=["max_iterations", "tolerance"],
)
@pytest.mark.parametrize("mod", METHODS)
def test_newton_failure_raises(mod, kw):
    case = _single(EI_AL, drive=Drive("torque", Sine(1.0, 1.0)), duration=0.05)
    with pytest.raises(SimulationError) as exc:
        mod.simulate(case, elements_per_link=4, h=1e-3, **kw)
    err = exc.value
    assert err.component == "newton" and 0.0 < err.t <= 0.05 and err.step >= 0
    assert "Exudyn" in str(err)
    if err.partial is not None:
        assert err.partial.meta["success"] is False and err.partial.t[-1] < err.t


# --------------------------------------------------------------------------------------------
# slow tier: cross-checks on the suite's cases
# --------------------------------------------------------------------------------------------
def _rms(a, b):
    return np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2, axis=0))


@pytest.fixture(scope="module")
def three_link_runs():
    case = dttmm.load_case(os.path.join(CASES, "three_link.toml"))
    runs = {}
    for mod in (exudyn_ancf, exudyn_beam):
        for k in (8, 16, 32, 64):
            runs[mod.METHOD, k] = mod.simulate(case, elements_per_link=k, h=1e-3)
    return runs


@pytest.mark.slow
def test_three_link_ancf_and_beam_agree(three_link_runs):
    a = three_link_runs["exudyn-ancf", 32]
    b = three_link_runs["exudyn-beam", 32]
    assert np.all(_rms(a.tip_deflection, b.tip_deflection) <= 1e-4)  # measured 2.5e-5 m
    # joint angles: the GE beam's extra rotary inertia ρI·L (5e-6 kg·m² per 0.5 m link, ~5e-4 of the
    # hub inertias) shifts them by ~1e-3 rad over the 2 s run
    assert np.max(np.abs(a.joint_angle - b.joint_angle)) < 5e-3


@pytest.mark.slow
@pytest.mark.parametrize("method", ["exudyn-ancf", "exudyn-beam"])
def test_three_link_converges_in_k(three_link_runs, method):
    ref = three_link_runs[method, 64]
    err = [np.max(_rms(three_link_runs[method, k].tip_deflection, ref.tip_deflection)) for k in (8, 16, 32)]
    assert err[0] > err[1] > err[2]
    assert err[2] < 1e-4


@pytest.mark.slow
def test_spin_up_ancf_is_bounded_with_the_known_peak():
    """Kane-Ryan-Banerjee spin-up at k = 8: the peak |v| of ANCF k = 64 (tests/golden.py), small
    and bounded after."""
    case = dttmm.load_case(os.path.join(CASES, "spin_up.toml"))
    res = exudyn_ancf.simulate(case, elements_per_link=8, h=5e-3)
    v = res.tip_deflection[:, 0]
    assert np.max(np.abs(v)) == pytest.approx(golden("spin_up.peak_tip_deflection"), abs=2e-3)
    assert np.max(np.abs(v[res.t > 15.0])) < 1e-2


# --------------------------------------------------------------------------------------------
# tuning options: drive inputs once per step, Jacobian per step, physical rotary inertia
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mod", METHODS)
def test_pre_step_inputs_equal_user_functions(mod):
    """Torques and prescribed angles set once per step (PreStepUserFunction, at the step end) give
    the results of load/offset user functions evaluated at every residual evaluation."""
    links = (
        Link(Section(0.5, EI_AL, RHOA_AL, EA_AL), Hub(0.0, 0.01)),
        Link(Section(0.5, EI_AL, RHOA_AL, EA_AL), Hub(0.1, 0.005), Payload(0.1, 0.0)),
    )
    drives = (Drive("motion", SpinUp(2.0, 0.1)), Drive("torque", BangBang((0.2, -0.2), (0.03,))))
    case = Case(Manipulator(links, (0.0, -9.81)), Scenario(0.06, 1e-3, drives))
    a = mod.simulate(case, elements_per_link=2, h=1e-3, drive_input="user-function")
    b = mod.simulate(case, elements_per_link=2, h=1e-3, drive_input="pre-step")
    assert a.meta["drive_input"] == "user-function" and b.meta["drive_input"] == "pre-step"
    assert np.max(np.abs(a.link_tip - b.link_tip)) < 1e-11  # of ~0.1 m of motion
    assert np.max(np.abs(a.joint_torque - b.joint_torque)) < 1e-6 * np.max(np.abs(a.joint_torque))


@pytest.mark.parametrize("mod", METHODS)
def test_jacobian_per_step_changes_only_the_iteration(mod):
    case = _single(EI_AL, drive=Drive("torque", Sine(1.0, 2.0)), duration=0.1, output_step=2e-3)
    a = mod.simulate(case, elements_per_link=4, h=2e-3, jacobian_per_step=True)
    b = mod.simulate(case, elements_per_link=4, h=2e-3, jacobian_per_step=False)
    assert a.meta["jacobian_per_step"] and not b.meta["jacobian_per_step"]
    assert a.meta["jacobians"] >= a.meta["steps_taken"]  # at least one per step
    assert np.max(np.abs(a.tip_deflection - b.tip_deflection)) < 1e-6  # Newton tolerance level
    with pytest.raises(InputError, match="jacobian_per_step"):
        mod.simulate(case, elements_per_link=4, h=2e-3, jacobian_per_step="yes")
    with pytest.raises(InputError, match="drive_input"):
        mod.simulate(case, elements_per_link=4, h=2e-3, drive_input="python")


def test_beam_physical_rotary_inertia():
    """ "physical": ρI = ρA·EI/EA (I/A = EI/EA for a homogeneous section), 9e-8 kg·m for the
    50 × 2 mm strip, the value 2700 kg/m³ · 0.05 · 0.002³ / 12 m⁴ from the geometry; default 1e-5."""
    case = _single(EI_AL, drive=Drive("torque", Constant(0.1)), duration=0.01)
    res = exudyn_beam.simulate(case, elements_per_link=2, h=1e-3, cross_section_inertia="physical")
    assert res.meta["cross_section_inertia_rule"] == "physical"
    assert res.meta["cross_section_inertia"] == [pytest.approx(2700 * 0.05 * 0.002**3 / 12, rel=1e-12)]
    assert exudyn_beam.simulate(case, elements_per_link=2, h=1e-3).meta["cross_section_inertia"] == [1e-5]
    with pytest.raises(InputError, match="cross_section_inertia"):
        exudyn_beam.simulate(case, elements_per_link=2, h=1e-3, cross_section_inertia="exact")
