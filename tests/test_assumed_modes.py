"""The assumed modes method (reference_models.assumed_modes) against independent values.

Independent sources: De Luca & Siciliano's published frequencies (1991), the clamped–free beam's
characteristic equation, Southwell's coefficient of the rotating cantilever, the spin-up
benchmark values (experiments/cases/benchmarks), Pinocchio's rigid arm, DT-TMM (a different
discretisation, elements instead of modes) and Exudyn's ANCF cable (slow tier). Nothing here
compares the module with numbers it produced itself, except the observed order in h (a
self-convergence rate) and the energy balance (a property of Lagrange's equations).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.drives import BangBang, Constant, Drive, UserLaw
from experiments.fit import slope
from experiments.studies import problems as B
from reference_models import assumed_modes as am
from reference_models._amm_shapes import link_modes, outboard_inertia

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"


def _case(name, duration=None):
    case = dttmm.load_case(CASES / f"{name}.toml")
    return case if duration is None else _dur(case, duration)


def _dur(case, duration):
    return replace(case, scenario=replace(case.scenario, duration=float(duration)))


def _problem(name):
    return B.problems([name])[name]


# ----------------------------------------------------------------------------- mode shapes
def test_deluca_link_frequencies_published():
    """Two clamped–mass modes per link of De Luca & Siciliano's arm reproduce the paper's
    0.48, 1.80 (link 1) and 2.18, 15.91 Hz (link 2) within ±0.005 Hz."""
    case, prov = _problem("deluca_bang_bang")
    # link 1's tip carries m_h2 + m_2 + m_p and J_h2 + ρ l³/3 + J_p + m_p l² (from the paper's data)
    mo, jo = outboard_inertia(case.model, 0)
    assert mo == pytest.approx(1.0 + 0.2 * 0.5 + 0.1) and jo == pytest.approx(
        0.1 + 0.2 * 0.5**3 / 3 + 5e-4 + 0.1 * 0.25
    )
    f = am.link_frequencies(case, 2).ravel()
    published = np.array(prov["mode_frequencies"])
    assert np.all(np.abs(f - published) <= prov["mode_frequencies_tolerance"]), f


def test_clamped_free_frequencies_closed_form():
    """Clamped–free shapes: frequencies from the roots of 1 + cos βL cosh βL = 0."""
    beam = _case("single_link").model.links[0].beam
    lm = link_modes(beam, 4)
    bl = np.array([1.875104068711961, 4.694091132974175, 7.854757438237613, 10.995540734875467])
    exact = bl**2 * np.sqrt(beam.EI / (beam.rhoA * beam.length**4)) / (2 * np.pi)
    assert np.allclose(lm.freq, exact, rtol=2e-6)
    # modal mass normalised to the link mass; modal stiffness ω² × (modal mass)
    assert np.allclose(np.diag(lm.M), beam.mass) and np.allclose(
        np.diag(lm.K), (2 * np.pi * exact) ** 2 * beam.mass
    )


def test_southwell_coefficient_of_the_geometric_stiffness():
    """The centrifugal geometric stiffness of the first clamped–free mode, ∫ρA (L² − x²)/2 φ'² dx
    over ∫ρA φ² dx, is Southwell's coefficient 1.1933 of the rotating cantilever."""
    lm = link_modes(_case("single_link").model.links[0].beam, 1)
    assert lm.P[0, 0] / lm.M[0, 0] == pytest.approx(1.1933, abs=2e-4)


@pytest.mark.parametrize("name", ["deluca_link1_clamped", "deluca_link2_clamped"])
def test_linearised_arm_frequencies(name):
    """modes(): the AMM arm linearised at rest (joint held) gives the quoted values and agrees
    with DT-TMM's linearisation (k = 16) to 1e-6."""
    case, prov = _problem(name)
    f = am.modes(case, 2)
    assert np.all(np.abs(f - prov["values"]) <= prov["tolerance"]), f
    assert np.allclose(f, dttmm.modes(case, 16, n=2).frequencies, rtol=1e-6)


def test_modes_of_a_free_joint_has_a_rigid_mode():
    case = _case("single_link")
    f = am.modes(case, 3)
    assert f[0] == 0.0 and np.all(f[1:] > 0)
    assert np.allclose(f[1:3], dttmm.modes(case, 16, n=3).frequencies[1:3], rtol=1e-3)


# ----------------------------------------------------------------------------- spin-up
@pytest.mark.parametrize("name", ["spin_up_w4", "spin_up_w6"])
def test_spin_up_consistent_within_benchmark_tolerance(name):
    case, prov = _problem(name)
    res = am.simulate(case, elements_per_link=2, h=2e-3)
    peak = B.peak_tip_deflection(res)
    assert abs(peak / prov["value"] - 1) <= prov["tolerance"], peak
    assert res.success and res.meta["variant"] == "consistent"


def test_spin_up_premature_diverges_and_ruthless_misses():
    """Without the stiffening the spin-up above the first clamped frequency (3.80 rad/s)
    diverges; with neither term the peak is off by several percent."""
    case, prov = _problem("spin_up_w4")
    pre = am.simulate(case, elements_per_link=2, h=2e-3, variant="premature")
    assert np.abs(pre.tip_deflection[-1, 0]) > 10.0  # m, on a 10 m beam
    ruth = am.simulate(case, elements_per_link=2, h=2e-3, variant="ruthless")
    assert abs(B.peak_tip_deflection(ruth) / prov["value"] - 1) > 10 * prov["tolerance"]


def test_motion_drive_torque_matches_dttmm():
    """The torque of a motion-driven joint (an output) against DT-TMM second-order strain."""
    case = _case("spin_up", 6.0)
    d = dttmm.simulate(case, elements_per_link=8, h=2e-3, strain="second-order")
    r = am.simulate(case, elements_per_link=3, h=2e-3)
    assert np.abs(r.joint_torque - d.joint_torque).max() <= 1e-4 * np.abs(d.joint_torque).max()
    assert np.abs(r.tip_deflection - d.tip_deflection).max() <= 1e-3 * np.abs(d.tip_deflection).max()


# ----------------------------------------------------------------------------- rigid limit
def test_rigid_limit_against_pinocchio():
    """EI × 1e6: the joint angles of three_link (gravity, hubs, payload) within 1e-6 rad of
    Pinocchio's rigid arm at the same step."""
    pytest.importorskip("pinocchio")
    import _pinocchio_newmark as newmark  # the rigid arm by the same Newmark step

    case = _case("three_link")
    links = tuple(replace(lk, beam=replace(lk.beam, EI=lk.beam.EI * 1e6)) for lk in case.model.links)
    case = replace(case, model=replace(case.model, links=links))
    r = am.simulate(case, elements_per_link=2, h=1e-3)
    p = newmark.simulate(case, 1e-3)
    assert np.abs(r.joint_angle - p.joint_angle).max() <= 1e-6
    assert np.abs(r.end_effector - p.end_effector).max() <= 1e-6


# ----------------------------------------------------------------------------- single_link
def _scaled_single_link(level=0.1):
    case = _case("single_link")
    drv = Drive("torque", BangBang((level, -level, 0.0), (0.5, 1.0)))
    return replace(case, scenario=replace(case.scenario, drives=(drv,)))


@pytest.mark.parametrize("variant", am.VARIANTS)
def test_single_link_small_torque_matches_dttmm(variant):
    """At 0.1 N·m (tip deflection ≈ 2 % of the length) every variant with 3 modes is within
    1 mm of DT-TMM (k = 16)."""
    case = _scaled_single_link()
    d = dttmm.simulate(case, elements_per_link=16, h=5e-4)
    r = am.simulate(case, elements_per_link=3, h=5e-4, variant=variant)
    assert np.abs(r.tip_deflection - d.tip_deflection).max() <= 1e-3


def test_single_link_nominal_torque_is_beyond_every_variant():
    """At the nominal ±1 N·m (deflections 12–23 % of the length) every truncated variant drifts
    by more than 20 mm from the stored reference (Exudyn ANCF, k = 32): the method's limit."""
    import pandas as pd

    path = (
        Path(__file__).resolve().parents[1]
        / "data"
        / "references"
        / "quick"
        / "single_link_T2_dt0.004.parquet"
    )
    if not path.exists():
        pytest.skip("no stored single_link reference")
    ref = dttmm.Result.from_frame(pd.read_parquet(path))
    for variant in am.VARIANTS:
        r = am.simulate(_case("single_link"), elements_per_link=3, h=1e-3, variant=variant)
        err = np.abs(np.interp(ref.t, r.t, r.tip_deflection[:, 0]) - ref.tip_deflection[:, 0]).max()
        assert err > 0.02, (variant, err)


# ----------------------------------------------------------------------------- closed loop, energy, order
def test_closed_loop_against_dttmm():
    """pd laws with moment feedback on closed_loop_three_link: joint angles within 1e-4 rad and
    torques within 1e-2 N·m of DT-TMM (k = 8)."""
    case = _dur(dttmm.load_case(CASES / "control" / "closed_loop_three_link.toml"), 1.0)
    d = dttmm.simulate(case, elements_per_link=8, h=1e-3)
    for integrator in am.INTEGRATORS:
        r = am.simulate(case, elements_per_link=3, h=1e-3, integrator=integrator)
        assert np.abs(r.joint_angle - d.joint_angle).max() <= 1e-4
        assert np.abs(r.joint_torque - d.joint_torque).max() <= 1e-2


def _free_three_link(gravity=(0.0, 0.0), damping=0.0):
    case = _case("three_link", 1.0)
    drv = tuple(Drive("torque", Constant(0.0), initial_rate=w) for w in (1.0, -2.0, 3.0))
    links = tuple(replace(lk, beam=replace(lk.beam, damping=damping)) for lk in case.model.links)
    return replace(
        case,
        model=replace(case.model, links=links, gravity=gravity),
        scenario=replace(case.scenario, drives=drv),
    )


@pytest.mark.parametrize("variant", am.VARIANTS)
def test_energy_is_conserved_without_damping(variant):
    """Lagrange's equations conserve kinetic + elastic + gravitational energy; the trapezoidal
    rule keeps it up to O(h²): the swing is < 1e-3 of the initial energy at h = 1e-3 and falls
    about fourfold when h is halved (a modelling error in the forces would not)."""
    case = _free_three_link(gravity=(0.0, -9.81))
    swing = [
        np.ptp(am.simulate(case, elements_per_link=3, h=h, variant=variant).energy) for h in (1e-3, 5e-4)
    ]
    e0 = am.simulate(case, elements_per_link=3, h=1e-3, variant=variant).energy[0]
    assert swing[0] <= 1e-3 * e0 and 3.5 <= swing[0] / swing[1] <= 4.5, swing


def test_damping_dissipates():
    """Kelvin–Voigt damping removes energy: far more than the undamped run's O(h²) swing."""
    free = am.simulate(_free_three_link(), elements_per_link=3, h=1e-3)
    damped = am.simulate(_free_three_link(damping=1e-2), elements_per_link=3, h=1e-3)
    assert damped.energy[-1] < free.energy[-1] - 10 * np.ptp(free.energy)


@pytest.mark.parametrize("integrator", list(am.INTEGRATORS))
def test_observed_order_two_in_h(integrator):
    case = _case("three_link", 0.5)
    ref = am.simulate(case, elements_per_link=2, h=1.25e-4, integrator=integrator)
    hs = [2e-3, 1e-3, 5e-4]
    errs = [
        np.abs(
            am.simulate(case, elements_per_link=2, h=h, integrator=integrator).end_effector - ref.end_effector
        ).max()
        for h in hs
    ]
    assert slope(hs, errs)[0] == pytest.approx(2.0, abs=0.25), errs


# ----------------------------------------------------------------------------- Result and errors
def test_result_fields():
    case = _case("three_link", 0.2)
    r = am.simulate(case, elements_per_link=2, h=1e-3)
    nt = case.scenario.output_times.size
    assert r.t.shape == (nt,) and r.joint_angle.shape == (nt, 3) and r.link_tip.shape == (nt, 3, 2)
    assert r.meta["method"] == "assumed-modes" and r.meta["elements_per_link"] == 2 and r.meta["h"] == 1e-3
    assert "numpy" in r.meta["versions"] and r.wall_time > 0 and r.n_steps == 200
    # the root of link i + 1 is the tip of link i
    assert np.allclose(r.link_root[:, 1:], r.link_tip[:, :-1])


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"elements_per_link": 0}, "elements_per_link"),
        ({"elements_per_link": 31}, "elements_per_link"),
        ({"elements_per_link": 2.5}, "elements_per_link"),
        ({"variant": "exact"}, "variant"),
        ({"boundary": "pinned"}, "boundary"),
        ({"integrator": "rk4"}, "integrator"),
        ({"rho_inf": 0.5}, "rho_inf"),
        ({"h": -1e-3}, "h"),
        ({"h": 5.0}, "h"),
    ],
)
def test_bad_input_names_the_field(kwargs, field):
    args = {"elements_per_link": 2, "h": 1e-3, **kwargs}
    with pytest.raises(dttmm.InputError) as err:
        am.simulate(_case("single_link"), **args)
    assert str(err.value).startswith(field) and "\n" not in str(err.value)


def test_user_law_refused():
    case = _case("single_link")
    drv = Drive("torque", UserLaw(lambda t, s: (0.0, 0.0, 0.0)))
    case = replace(case, scenario=replace(case.scenario, drives=(drv,)))
    with pytest.raises(dttmm.InputError, match=r"scenario.drives\[0\].law"):
        am.simulate(case, elements_per_link=2, h=1e-3)


def test_failure_raises_with_partial_result():
    """Premature softening at 60 rad/s overflows: SimulationError with the samples so far."""
    case, _ = _problem("spin_up_w4")
    law = replace(case.scenario.drives[0].law, rate=60.0)
    case = replace(case, scenario=replace(case.scenario, drives=(replace(case.scenario.drives[0], law=law),)))
    with pytest.raises(dttmm.SimulationError) as err:
        am.simulate(case, elements_per_link=2, h=2e-3, variant="premature")
    part = err.value.partial
    assert part is not None and part.status == "failed" and 0 < part.t[-1] < 15.0
    assert np.all(np.isfinite(part.tip_deflection))


# ----------------------------------------------------------------------------- slow tier
@pytest.mark.slow
def test_single_link_small_torque_matches_exudyn_ancf():
    """At 0.1 N·m: within 1 mm of Exudyn's ANCF cable (k = 32, h = 2.5e-4), the engine behind
    the stored references."""
    ancf = pytest.importorskip("reference_models.exudyn_ancf")
    case = _scaled_single_link()
    ref = ancf.simulate(case, elements_per_link=32, h=2.5e-4)
    for variant in am.VARIANTS:
        r = am.simulate(case, elements_per_link=3, h=2.5e-4, variant=variant)
        assert np.abs(r.tip_deflection - ref.tip_deflection).max() <= 1e-3, variant


@pytest.mark.slow
def test_three_link_converges_in_modes_to_dttmm():
    """three_link (gravity, hubs, payload): the end-effector error against DT-TMM (k = 16)
    falls with the modes per link and is below 1 mm at N = 4."""
    case = _case("three_link")
    d = dttmm.simulate(case, elements_per_link=16, h=5e-4)
    errs = [
        np.abs(am.simulate(case, elements_per_link=n, h=5e-4).end_effector - d.end_effector).max()
        for n in (1, 2, 4)
    ]
    assert errs[2] < errs[0] and errs[2] <= 1e-3, errs


@pytest.mark.slow
def test_deluca_bang_bang_within_benchmark_tolerance():
    """De Luca & Siciliano's arm, open loop: the link-2 tip deflection's relative RMS difference
    to the benchmark's reference run (Exudyn ANCF, k = 32, h = 2.5e-4) within its tolerance."""
    ancf = pytest.importorskip("reference_models.exudyn_ancf")
    case, prov = _problem("deluca_bang_bang")
    r = prov["reference"]
    ref = ancf.simulate(case, elements_per_link=r["k"], h=r["h"])
    res = am.simulate(case, elements_per_link=2, h=1e-3)
    assert B.tip_deflection_rms(res, ref) <= prov["tolerance"]
