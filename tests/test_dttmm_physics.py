"""DT-TMM against closed forms: statics, clamped frequencies, rigid limit, energy, spin-up."""

import dataclasses as dc

import numpy as np
import pytest
from conftest import case, shortened, with_links

import dttmm
from dttmm import Case, Constant, Drive, Link, Manipulator, Scenario, Section
from tests.golden import value as golden


def clamped(sec, gravity=(0.0, 0.0), duration=0.5, out=0.01):
    return Case(
        Manipulator((Link(sec),), gravity), Scenario(duration, out, (Drive("motion", Constant(0.0)),))
    )


@pytest.mark.parametrize("k", [8, 16])
def test_cantilever_under_gravity(k):
    """Tip deflection ρA g L⁴/(8 EI) of a stiff clamped beam (damped to rest)."""
    sec = Section(1.0, 100.0, 0.27, 7e6, damping=0.02)
    res = dttmm.simulate(clamped(sec, (0.0, -9.81)), elements_per_link=k, h=1e-3)
    exact = -0.27 * 9.81 / (8 * 100.0)
    assert res.tip_deflection[-1, 0] == pytest.approx(exact, rel=1e-3)


@pytest.mark.parametrize("extensible", [True, False])
def test_clamped_natural_frequencies(extensible):
    """First two clamped-free frequencies (1.8751², 4.6941²)·√(EI/ρAL⁴) within 0.5 % at k = 8,
    from the free-vibration equations q̈ = −M⁻¹K q of the acceleration solver linearised at rest."""
    L, EI, rhoA = 1.0, 2.3333, 0.27
    sec = Section(L, EI, rhoA, 7e6 if extensible else None)
    c = clamped(sec)
    k = 8
    st = dttmm.structure.build_structure(c, k)
    n = st.n_dof
    eps = 1e-7
    A = np.empty((n - 1, n - 1))
    for j in range(1, n):
        dq = np.zeros(n)
        dq[j] = eps
        ap = dttmm.accelerations(c, k, dq, np.zeros(n))
        am = dttmm.accelerations(c, k, -dq, np.zeros(n))
        A[:, j - 1] = (ap - am)[1:] / (2 * eps)
    w = np.sort(np.sqrt(np.abs(np.linalg.eigvals(-A).real)))
    exact = np.array([1.87510407, 4.69409113]) ** 2 * np.sqrt(EI / (rhoA * L**4))
    np.testing.assert_allclose(w[:2], exact, rtol=5e-3)


def test_free_vibration_frequency_from_time_response():
    """The same first frequency from a simulated free vibration (zero crossings of the tip)."""
    L, EI, rhoA = 1.0, 2.3333, 0.27
    sec = Section(L, EI, rhoA)
    # excite by gravity switched on at t = 0 around the unloaded rest state: the tip oscillates
    # about the static deflection with the first mode dominating
    c = clamped(sec, (0.0, -0.5), duration=3.0, out=1e-3)
    res = dttmm.simulate(c, elements_per_link=8, h=1e-3, cut_loads=False, energy=False)
    v = res.tip_deflection[:, 0] - (-rhoA * 0.5 * L**4 / (8 * EI))
    s = np.sign(v)
    idx = np.flatnonzero(s[1:] != s[:-1])
    tz = res.t[idx] - v[idx] * (res.t[idx + 1] - res.t[idx]) / (v[idx + 1] - v[idx])
    period = 2 * np.mean(np.diff(tz))
    exact = 1.87510407**2 * np.sqrt(EI / (rhoA * L**4))
    assert 2 * np.pi / period == pytest.approx(exact, rel=5e-3)


def test_rigid_limit_single_link(single_link):
    """EI × 1e6: hub angle equals the closed-form rotor J = J_hub + ρA L³/3 within 1e-6 rad."""
    c = with_links(shortened(single_link, 1.5), EI=lambda b: b.EI * 1e6, EA=lambda b: b.EA * 1e6)
    res = dttmm.simulate(c, elements_per_link=2, h=1e-3)
    J = 0.01 + 0.27 * 1.0**3 / 3
    t = res.t
    # τ = +1 on [0, 0.5), −1 on [0.5, 1), 0 afterwards
    theta = (
        np.where(t < 0.5, 0.5 * t**2, np.where(t < 1.0, 0.125 + 0.5 * (t - 0.5) - 0.5 * (t - 0.5) ** 2, 0.25))
        / J
    )
    assert np.max(np.abs(res.joint_angle[:, 0] - theta)) < 1e-6


def _energy_case(extensible=True):
    c = case("three_link")
    if not extensible:  # explicit RK4 cannot afford the axial modes' step limit
        c = with_links(c, EA=None)
    drives = tuple(
        Drive("torque", Constant(0.0), initial_angle=a, initial_rate=r)
        for a, r in zip((0.3, -0.5, 0.4), (2.0, -1.0, 3.0))
    )
    c = dc.replace(c, model=dc.replace(c.model, gravity=(0.0, 0.0)), scenario=Scenario(0.3, 1e-3, drives))
    return c


@pytest.mark.parametrize("integrator, order", [("newmark", 2), ("rk4", 4)])
def test_energy_drift_shrinks_at_integrator_order(integrator, order):
    c = _energy_case(extensible=integrator != "rk4")
    drift = []
    hs = (2e-3, 1e-3) if integrator == "newmark" else (4e-4, 2e-4)
    for h in hs:
        res = dttmm.simulate(c, elements_per_link=2, h=h, integrator=integrator, cut_loads=False)
        E = res.energy
        drift.append(np.max(np.abs(E - E[0])) / abs(E[0]))
    assert max(drift) < 1e-2
    slope = np.log2(drift[0] / drift[1])
    assert abs(slope - order) < 0.5, (drift, slope)


def test_generalized_alpha_rho1_is_newmark():
    c = shortened(case("three_link"), 0.1)
    a = dttmm.simulate(c, elements_per_link=2, h=1e-3)
    b = dttmm.simulate(c, elements_per_link=2, h=1e-3, integrator="generalized-alpha", rho_inf=1.0)
    np.testing.assert_allclose(b.joint_angle, a.joint_angle, atol=1e-12)


def test_bang_bang_switch_keeps_second_order(single_link):
    """Restarting at the torque jumps keeps Newmark second order on the bang-bang case."""
    c = shortened(single_link, 0.75)
    ref = dttmm.simulate(c, elements_per_link=2, h=1.25e-4, cut_loads=False, energy=False)
    errs = []
    for h in (4e-3, 2e-3, 1e-3):
        r = dttmm.simulate(
            dc.replace(c, scenario=dc.replace(c.scenario, output_step=4e-3)),
            elements_per_link=2,
            h=h,
            cut_loads=False,
            energy=False,
        )
        errs.append(np.max(np.abs(r.joint_angle[:, 0] - ref.joint_angle[::4, 0])))
    slopes = np.diff(np.log(errs)) / np.log(0.5)
    assert np.all(np.abs(slopes - 2) < 0.3), (errs, slopes)


def test_spin_up_stays_bounded(spin_up):
    """Geometric stiffening from the corotated chain: |v| < 1 m over 20 s at k = 8 (the
    classic single floating-frame element diverges here); peak and the residual after the spin-up
    as Exudyn ANCF's (tests/golden.py)."""
    res = dttmm.simulate(spin_up, elements_per_link=8, h=1e-2, cut_loads=False, energy=False)
    v = res.tip_deflection[:, 0]
    assert np.all(np.isfinite(v)) and np.max(np.abs(v)) < 1.0
    assert np.max(np.abs(v)) == pytest.approx(golden("spin_up.peak_tip_deflection"), rel=0.02)
    assert np.max(np.abs(v[res.t > 16])) < 5 * golden("spin_up.tip_deflection_after_16s")


def test_divergence_is_reported_with_partial_result():
    """A one-shot linearisation run at an absurd step blows up: the error names time, step and
    component, and keeps what was computed."""
    c = case("spin_up")
    with pytest.raises(dttmm.SimulationError) as exc:
        dttmm.simulate(c, elements_per_link=8, h=0.2, iterations=0, cut_loads=False)
    e = exc.value
    assert e.partial is not None and e.partial.t.size >= 1
    assert e.t > 0 and e.step >= 1
    assert "link 1" in e.component or "joint" in e.component


def test_cut_loads_of_a_cantilever_under_gravity():
    """Loads at the cuts (M, Qx, Qy): at rest under gravity the section at x carries the weight
    of the beam outboard of it, Qy = ρA g (L − x), M = ρA g (L − x)²/2; the free tip carries 0."""
    L, rhoA, g = 1.0, 0.27, 9.81
    sec = Section(L, 100.0, rhoA, 7e6, damping=0.02)
    k = 8
    # generalised-α damps the overdamped Kelvin-Voigt roots that the trapezoidal rule keeps ringing
    res = dttmm.simulate(
        clamped(sec, (0.0, -g), duration=1.0),
        elements_per_link=k,
        h=1e-3,
        integrator="generalized-alpha",
        rho_inf=0.5,
    )
    loads = res.cut_loads[-1]  # (k + 1, 3): element roots, then the tip
    x = np.arange(k + 1) * L / k
    np.testing.assert_allclose(loads[:, 2], rhoA * g * (L - x), atol=1e-4)
    np.testing.assert_allclose(loads[:, 0], rhoA * g * (L - x) ** 2 / 2, atol=1e-4)
    np.testing.assert_allclose(loads[:, 1], 0.0, atol=1e-4)
    assert res.joint_torque[-1, 0] == pytest.approx(rhoA * g * L**2 / 2, rel=1e-4)
    assert res.cut_load_t[-1] == res.t[-1]
