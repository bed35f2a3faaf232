"""The global-equation solver (reference_models.global_newmark) against independent references:
closed-form beam results, the rigid-body limit, Lagrange's equations, energy balance and an
adaptive high-order integrator."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
from _global_reference import adaptive_reference

import dttmm
from dttmm import Case, Constant, Drive, Link, Manipulator, Scenario, Section
from reference_models import _global_numpy as gnp
from reference_models import global_newmark as gn

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"

try:
    import numba  # noqa: F401

    _ENGINES = ["python", "numba"]
except ImportError:  # the compiled engine is optional (extra "fast")
    _ENGINES = ["python"]
needs_numba = pytest.mark.skipif("numba" not in _ENGINES, reason="numba not installed")


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------


def _load(name):
    return dttmm.load_case(CASES / f"{name}.toml")


def _with_beams(case, **changes):
    """Copy of ``case`` with every link's Section changed by ``changes`` (callables of the old)."""
    links = []
    for link in case.model.links:
        b = link.beam
        new = {key: (fn(getattr(b, key)) if callable(fn) else fn) for key, fn in changes.items()}
        links.append(dataclasses.replace(link, beam=dataclasses.replace(b, **new)))
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=tuple(links)))


def _shorten(case, duration, output_step):
    return dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=duration, output_step=output_step)
    )


def _single(beam, drive, *, gravity=(0.0, 0.0), duration=0.1, output_step=0.01, hub=None):
    return Case(Manipulator((Link(beam, hub),), gravity), Scenario(duration, output_step, (drive,)))


def _random_state(case, k, seed, scale=0.3):
    n = len(gn.coordinate_names(case, k))
    rng = np.random.default_rng(seed)
    return rng.normal(size=n) * scale, rng.normal(size=n)


def _hermite_mass(rhoA, l):
    """Consistent mass of the Hermite beam on (w1, θ1, w2, θ2) and of the linear bar on (u1, u2)."""
    Mb = (
        rhoA
        * l
        / 420.0
        * np.array(
            [
                [156, 22 * l, 54, -13 * l],
                [22 * l, 4 * l * l, 13 * l, -3 * l * l],
                [54, 13 * l, 156, -22 * l],
                [-13 * l, -3 * l * l, -22 * l, 4 * l * l],
            ]
        )
    )
    Mu = rhoA * l / 6.0 * np.array([[2.0, 1.0], [1.0, 2.0]])
    return Mb, Mu


def _slope(hs, errs):
    return np.polyfit(np.log(hs), np.log(errs), 1)[0]


# ----------------------------------------------------------------------------------------------
# (1) mass matrix
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [1, 3])
def test_mass_matrix_symmetric_positive_definite(k):
    case = _load("three_link")
    for seed in range(3):
        q, _ = _random_state(case, k, seed)
        M = gn.mass_matrix(case, k, q)
        assert np.allclose(M, M.T, rtol=0, atol=1e-14 * np.abs(M).max())
        assert np.linalg.eigvalsh(M).min() > 0


def test_element_mass_at_rest_is_consistent_hermite_mass():
    rhoA, l = 0.27, 0.4
    # p = (x_I, y_I, θ, u, v, φ) → (u1, u2) = (x_I, x_I + u),
    #                              (w1, θ1, w2, θ2) = (y_I, θ, y_I + lθ + v, θ + φ)
    Tu = np.array([[1, 0, 0, 0, 0, 0], [1, 0, 0, 1, 0, 0]], float)
    Tw = np.array([[0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 1, l, 0, 1, 0], [0, 0, 1, 0, 0, 1]], float)
    Mb, Mu = _hermite_mass(rhoA, l)
    expected = Tu.T @ Mu @ Tu + Tw.T @ Mb @ Tw
    assert np.allclose(gn.element_mass(rhoA, l), expected, rtol=1e-13, atol=1e-15)


def test_element_mass_rotates_with_the_frame():
    rhoA, l, th = 0.27, 0.4, 0.7
    e = (1e-3, 0.02, -0.05)
    R = np.eye(6)
    c, s = math.cos(th), math.sin(th)
    R[:2, :2] = [[c, -s], [s, c]]
    assert np.allclose(
        gn.element_mass(rhoA, l, th, e), R @ gn.element_mass(rhoA, l, 0.0, e) @ R.T, rtol=1e-13, atol=1e-15
    )


def test_single_link_mass_at_rest_maps_hermite_mass_to_minimal_coordinates():
    beam = Section(0.8, 2.0, 0.5, 1e6)
    case = _single(beam, Drive("torque", Constant(0.0)), hub=dttmm.Hub(0.0, 0.03))
    l = beam.length
    # q = (α, u, v, φ): (u1, u2) = (0, u), (w1, θ1, w2, θ2) = (0, α, lα + v, α + φ)
    Tu = np.array([[0, 0, 0, 0], [0, 1, 0, 0]], float)
    Tw = np.array([[0, 0, 0, 0], [1, 0, 0, 0], [l, 0, 1, 0], [1, 0, 0, 1]], float)
    Mb, Mu = _hermite_mass(beam.rhoA, l)
    expected = Tu.T @ Mu @ Tu + Tw.T @ Mb @ Tw
    expected[0, 0] += 0.03
    assert np.allclose(gn.mass_matrix(case, 1, np.zeros(4)), expected, rtol=1e-13, atol=1e-15)


def test_kinetic_energy_matches_point_velocities():
    """½q̇ᵀMq̇ equals the kinetic energy of hubs and payload computed from finite-difference
    velocities of the link frames, plus the beam part: checked on a chain of rigid-like links
    where the beam part is ∫½ρA|ṙ|² of straight links."""
    case = _with_beams(_load("three_link"), EA=None)
    k = 2
    q, qd = _random_state(case, k, 7)
    names = gn.coordinate_names(case, k)
    elastic = np.array([not n.startswith("alpha") for n in names])
    q[elastic], qd[elastic] = 0.0, 0.0  # straight links: every beam point lies on the root line
    eps = 1e-6
    f1, f0 = gn.kinematics(case, k, q + eps * qd), gn.kinematics(case, k, q - eps * qd)
    T = 0.0
    for i, link in enumerate(case.model.links):
        v_root = (f1["root"][i] - f0["root"][i]) / (2 * eps)
        w = (f1["root_angle"][i] - f0["root_angle"][i]) / (2 * eps)
        L, m = link.beam.length, link.beam.rhoA * link.beam.length
        th = gn.kinematics(case, k, q)["root_angle"][i]
        n_perp = np.array([-math.sin(th), math.cos(th)])
        T += 0.5 * m * v_root @ v_root + m * L / 2 * w * (v_root @ n_perp) + 0.5 * m * L * L / 3 * w * w
        T += 0.5 * link.hub_mass * v_root @ v_root + 0.5 * link.hub_inertia * w * w
        if link.payload is not None:
            v_tip = (f1["tip"][i] - f0["tip"][i]) / (2 * eps)
            T += 0.5 * link.payload_mass * v_tip @ v_tip + 0.5 * link.payload_inertia * w * w
    assert 0.5 * qd @ gn.mass_matrix(case, k, q) @ qd == pytest.approx(T, rel=1e-8)


# ----------------------------------------------------------------------------------------------
# Lagrange's equations: velocity terms and gravity from M(q) and the potential
# ----------------------------------------------------------------------------------------------


def test_velocity_and_gravity_terms_follow_from_lagrange_equations():
    """M q̈ = −h(q, q̇) − Kq + Q_g with h = Ṁq̇ − ½∂(q̇ᵀMq̇)/∂q and Q_g = −∂V/∂q,
    all derivatives by central differences of mass_matrix and energy."""
    case = _load("three_link")
    case = dataclasses.replace(
        case,
        scenario=dataclasses.replace(
            case.scenario, drives=tuple(Drive("torque", Constant(0.0)) for _ in range(3))
        ),
    )
    k = 2
    q, qd = _random_state(case, k, 3, scale=0.05)
    n, eps = q.size, 1e-6
    dM = np.array(
        [
            (gn.mass_matrix(case, k, q + eps * u) - gn.mass_matrix(case, k, q - eps * u)) / (2 * eps)
            for u in np.eye(n)
        ]
    )
    h = np.einsum("c,cij,j->i", qd, dM, qd) - 0.5 * np.einsum("icj,c,j->i", dM, qd, qd)
    V = lambda x: gn.energy(case, k, x, np.zeros(n))["gravity"]
    Qg = -np.array([(V(q + eps * u) - V(q - eps * u)) / (2 * eps) for u in np.eye(n)])
    K = gn.stiffness_matrix(case, k)
    expected = np.linalg.solve(gn.mass_matrix(case, k, q), Qg - h - K @ q)
    got = gn.accelerations(case, k, q, qd)
    assert np.allclose(got, expected, rtol=1e-6, atol=1e-6 * np.abs(expected).max())


# ----------------------------------------------------------------------------------------------
# (2) rigid limit
# ----------------------------------------------------------------------------------------------


def test_rigid_limit_matches_closed_form_rotor():
    """EI and EA × 1e6: the hub angle is the double integral of τ/J."""
    case = _with_beams(_load("single_link"), EI=lambda x: x * 1e6, EA=lambda x: x * 1e6)
    case = _shorten(case, case.scenario.duration, 1e-2)
    link = case.model.links[0]
    J = link.hub_inertia + link.beam.rhoA * link.beam.length**3 / 3
    law = case.scenario.drives[0].law
    t = case.scenario.output_times
    knots = np.concatenate([[0.0], law.switch_times])
    theta, rate, expected = 0.0, 0.0, np.zeros_like(t)
    for i, (a, level) in enumerate(zip(knots, law.levels)):
        b = knots[i + 1] if i + 1 < knots.size else np.inf
        on = (t >= a) & (t <= b)
        expected[on] = theta + rate * (t[on] - a) + 0.5 * level / J * (t[on] - a) ** 2
        if np.isfinite(b):
            theta, rate = theta + rate * (b - a) + 0.5 * level / J * (b - a) ** 2, rate + level / J * (b - a)
    res = gn.simulate(case, elements_per_link=2, h=5e-3)
    assert np.abs(res.joint_angle[:, 0] - expected).max() < 1e-6


# ----------------------------------------------------------------------------------------------
# (3) cantilever statics
# ----------------------------------------------------------------------------------------------


def _cantilever(damping=0.0, duration=0.1):
    beam = Section(1.0, 1.0e3, 1.0, 1.0e7, damping)
    return _single(
        beam, Drive("motion", Constant(0.0)), gravity=(0.0, -9.81), duration=duration, output_step=0.01
    )


def test_cantilever_static_deflection_under_gravity():
    case, k = _cantilever(), 8
    b = case.model.links[0].beam
    n = len(gn.coordinate_names(case, k))
    q0 = np.zeros(n)
    free = np.arange(1, n)
    # at rest and undeformed M q̈ = Q_gravity on the free rows; the static state solves K q = Q
    Q = gn.mass_matrix(case, k, q0)[np.ix_(free, free)] @ gn.accelerations(case, k, q0, q0)[free]
    q = np.zeros(n)
    q[free] = np.linalg.solve(gn.stiffness_matrix(case, k)[np.ix_(free, free)], Q)
    tip = gn.kinematics(case, k, q)["tip"][0]
    expected = b.rhoA * 9.81 * b.length**4 / (8 * b.EI)
    assert -tip[1] == pytest.approx(expected, rel=1e-3)


def test_damped_cantilever_settles_to_static_deflection_and_holding_torque():
    # generalized-α: the trapezoidal rule (plain Newmark) does not damp the stiff overdamped
    # Kelvin-Voigt roots, whose step-to-step alternation would linger in the joint torque
    case = _cantilever(damping=0.02, duration=0.3)
    b = case.model.links[0].beam
    res = gn.simulate(case, elements_per_link=8, h=1e-3, integrator="generalized-alpha", rho_inf=0.5)
    assert -res.tip_deflection[-1, 0] == pytest.approx(b.rhoA * 9.81 * b.length**4 / (8 * b.EI), rel=1e-3)
    # the held joint carries the weight moment ρA g L²/2 (counter-clockwise)
    assert res.joint_torque[-1, 0] == pytest.approx(b.rhoA * 9.81 * b.length**2 / 2, rel=1e-3)
    assert np.all(res.joint_angle == 0.0)


# ----------------------------------------------------------------------------------------------
# (4) clamped natural frequencies
# ----------------------------------------------------------------------------------------------


def test_clamped_natural_frequencies():
    beam = Section(1.2, 3.0, 0.6)
    case, k = _single(beam, Drive("motion", Constant(0.0))), 8
    n = len(gn.coordinate_names(case, k))
    free = np.arange(1, n)
    M = gn.mass_matrix(case, k, np.zeros(n))[np.ix_(free, free)]
    K = gn.stiffness_matrix(case, k)[np.ix_(free, free)]
    omega = np.sqrt(scipy.linalg.eigh(K, M, eigvals_only=True))
    scale = math.sqrt(beam.EI / (beam.rhoA * beam.length**4))
    expected = np.array([1.8751, 4.6941, 7.8548]) ** 2 * scale
    assert np.allclose(omega[:3], expected, rtol=5e-3)


# ----------------------------------------------------------------------------------------------
# (5) energy balance
# ----------------------------------------------------------------------------------------------


def _free_three_link():
    base = _with_beams(_load("three_link"), EA=None)
    drives = tuple(Drive("torque", Constant(0.0), initial_rate=w) for w in (2.0, -3.0, 4.0))
    return Case(Manipulator(base.model.links, (0.0, 0.0)), Scenario(0.2, 0.01, drives))


def test_energy_drift_is_second_order_in_h():
    case = _free_three_link()
    hs = [2e-3, 1e-3, 5e-4]
    drift = []
    for h in hs:
        res = gn.simulate(case, elements_per_link=2, h=h)
        assert res.energy[0] > 0.1
        drift.append(np.abs(res.energy - res.energy[0]).max())
    assert drift[-1] < 1e-6 * res.energy[0]
    assert 1.7 < _slope(hs, drift) < 2.3


# ----------------------------------------------------------------------------------------------
# (6) order of convergence against an adaptive 8th-order reference
# ----------------------------------------------------------------------------------------------


def _newmark_errors(case, k, hs, **options):
    ref_angle, ref_tip = adaptive_reference(case, k, method="DOP853", rtol=1e-9, atol=1e-11)
    errs = []
    for h in hs:
        res = gn.simulate(case, elements_per_link=k, h=h, **options)
        errs.append(
            max(np.abs(res.joint_angle - ref_angle).max(), np.abs(res.tip_deflection - ref_tip).max())
        )
    return np.array(errs)


@pytest.mark.slow
def test_newmark_second_order_single_link_through_torque_switch():
    # inextensible: the axial modes would make the explicit reference stiff;
    # 0.6 s spans the torque switch at 0.5 s (restart)
    case = _shorten(_with_beams(_load("single_link"), EA=None), 0.6, 0.01)
    hs = [2e-3, 1e-3, 5e-4]
    errs = _newmark_errors(case, 2, hs)
    assert errs[-1] < 1e-4
    assert abs(_slope(hs, errs) - 2.0) < 0.3


def test_newmark_second_order_three_link():
    case = _shorten(_with_beams(_load("three_link"), EA=None), 0.03, 0.01)
    hs = [2e-4, 1e-4, 5e-5]
    errs = _newmark_errors(case, 2, hs)
    assert abs(_slope(hs, errs) - 2.0) < 0.3


@pytest.mark.slow
def test_generalized_alpha_second_order_three_link():
    case = _shorten(_with_beams(_load("three_link"), EA=None), 0.03, 0.01)
    hs = [2e-4, 1e-4, 5e-5]
    errs = _newmark_errors(case, 2, hs, integrator="generalized-alpha", rho_inf=0.8)
    assert abs(_slope(hs, errs) - 2.0) < 0.3


@pytest.mark.slow
def test_adaptive_references_radau_and_dop853_agree():
    """The adaptive reference of the order tests does not depend on its integrator: Radau
    (implicit, order 5) and DOP853 (explicit, order 8) agree through the torque switch."""
    case = _shorten(_with_beams(_load("single_link"), EA=None), 0.6, 0.05)
    a = adaptive_reference(case, 1, method="Radau", rtol=1e-9, atol=1e-11)
    b = adaptive_reference(case, 1, method="DOP853")
    assert np.abs(a[0] - b[0]).max() < 1e-7
    assert np.abs(a[1] - b[1]).max() < 1e-7


# ----------------------------------------------------------------------------------------------
# stepping details: iteration counts, outputs between step ends, motion drives
# ----------------------------------------------------------------------------------------------


def test_fixed_iteration_count_and_tolerance_driven_iteration():
    case = _shorten(_load("three_link"), 0.02, 0.01)
    fixed = gn.simulate(case, elements_per_link=1, h=1e-3, iterations=2)
    assert fixed.meta["iterations_mean"] == 3 and fixed.meta["iterations_max"] == 3
    conv = gn.simulate(case, elements_per_link=1, h=1e-3)
    assert conv.meta["unconverged_steps"] == 0
    assert conv.meta["iterations_max"] <= 10
    assert conv.meta["method"] == "global" and conv.meta["n_dof"] == 12 and conv.meta["success"]
    # two corrections are close to the converged step
    assert np.abs(fixed.joint_angle - conv.joint_angle).max() < 1e-6


def test_outputs_between_step_ends_are_cubic_hermite_of_the_step_states():
    case = _shorten(_load("three_link"), 0.02, 2e-3)
    steps = gn.simulate(case, elements_per_link=2, h=2e-3)  # outputs = step ends
    fine = gn.simulate(_shorten(case, 0.02, 5e-4), elements_per_link=2, h=2e-3)  # 3 of 4 between
    assert np.array_equal(fine.joint_angle[::4], steps.joint_angle)
    assert np.array_equal(fine.joint_rate[::4], steps.joint_rate)
    H = 2e-3
    for j, s in ((1, 0.25), (2, 0.5), (3, 0.75)):
        y0, y1 = steps.joint_angle[:-1], steps.joint_angle[1:]
        v0, v1 = steps.joint_rate[:-1], steps.joint_rate[1:]
        y = (
            (2 * s**3 - 3 * s**2 + 1) * y0
            + (s**3 - 2 * s**2 + s) * H * v0
            + (-2 * s**3 + 3 * s**2) * y1
            + (s**3 - s**2) * H * v1
        )
        v = (
            (6 * s**2 - 6 * s) * y0 / H
            + (3 * s**2 - 4 * s + 1) * v0
            + (-6 * s**2 + 6 * s) * y1 / H
            + (3 * s**2 - 2 * s) * v1
        )
        assert np.allclose(fine.joint_angle[j::4], y, rtol=0, atol=1e-14)
        assert np.allclose(fine.joint_rate[j::4], v, rtol=0, atol=1e-11)


def test_motion_drive_follows_its_law_and_reports_torque():
    case = _shorten(_load("spin_up"), 1.0, 0.1)
    res = gn.simulate(case, elements_per_link=2, h=1e-2)
    law = case.scenario.drives[0].law
    expected = np.array([law.motion(t)[0] for t in res.t])
    assert np.allclose(res.joint_angle[:, 0], expected, rtol=0, atol=1e-14)
    # spinning up from rest needs a positive torque
    assert np.all(res.joint_torque[1:, 0] > 0)


def test_breakpoint_inside_a_step_is_hit_exactly():
    case = _shorten(_load("single_link"), 0.6, 0.05)
    res = gn.simulate(case, elements_per_link=1, h=0.03)  # 0.5 is not a multiple of 0.03
    assert res.n_steps == 21
    assert res.joint_torque[10, 0] == 1.0 and res.joint_torque[11, 0] == -1.0


def test_non_finite_state_raises_with_partial_result():
    class BrokenAfter(Constant):
        def __call__(self, t, left=False):
            return math.nan if t > 0.05 else self.value

    beam = Section(1.0, 2.0, 0.3)
    case = _single(beam, Drive("torque", BrokenAfter(1.0)), duration=0.1, output_step=0.01)
    with pytest.raises(dttmm.SimulationError) as info:
        gn.simulate(case, elements_per_link=1, h=0.01)
    err = info.value
    assert err.t == pytest.approx(0.06) and err.step == 5
    assert err.partial is not None and err.partial.t[-1] == pytest.approx(0.05)
    assert err.partial.meta["success"] is False


# ----------------------------------------------------------------------------------------------
# (7) bad input
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"elements_per_link": 0}, "elements_per_link"),
        ({"elements_per_link": 1.5}, "elements_per_link"),
        ({"elements_per_link": True}, "elements_per_link"),
        ({"h": 0.0}, "h"),
        ({"h": -1e-3}, "h"),
        ({"h": math.nan}, "h"),
        ({"h": 5.0}, "h"),
        ({"integrator": "euler"}, "integrator"),
        ({"iterations": -1}, "iterations"),
        ({"iterations": 1.5}, "iterations"),
        ({"tol": 0.0}, "tol"),
        ({"beta": -0.25}, "beta"),
        ({"linear_solver": "dense"}, "linear_solver"),
        ({"integrator": "generalized-alpha", "rho_inf": 1.5}, "rho_inf"),
        ({"integrator": "dop853"}, "integrator"),
        ({"integrator": "generalized-alpha", "beta": 0.3}, "beta"),
        ({"maxiter": 3}, "maxiter"),
        ({"max_iterations": 0}, "max_iterations"),
        ({"engine": "fortran"}, "engine"),
    ],
)
def test_bad_settings_are_refused_naming_the_field(kwargs, field):
    args = {"elements_per_link": 2, "h": 1e-3, **kwargs}
    with pytest.raises(dttmm.InputError) as info:
        gn.simulate(_load("single_link"), **args)
    assert info.value.field == field
    assert field in str(info.value)


def test_bad_state_and_case_are_refused():
    case = _load("single_link")
    with pytest.raises(dttmm.InputError, match="q"):
        gn.mass_matrix(case, 2, np.zeros(3))
    with pytest.raises(dttmm.InputError, match="qd"):
        gn.accelerations(case, 1, np.zeros(4), np.full(4, np.inf))
    with pytest.raises(dttmm.InputError, match="case"):
        gn.simulate("single_link.toml", elements_per_link=1, h=1e-3)


def test_coordinate_names_order():
    case = _load("three_link")
    names = gn.coordinate_names(case, 2)
    assert names[:7] == ["alpha_1", "u_1_1", "v_1_1", "phi_1_1", "u_1_2", "v_1_2", "phi_1_2"]
    assert names[7] == "alpha_2" and len(names) == 21
    inext = gn.coordinate_names(_with_beams(case, EA=None), 1)
    assert inext == [
        "alpha_1",
        "v_1_1",
        "phi_1_1",
        "alpha_2",
        "v_2_1",
        "phi_2_1",
        "alpha_3",
        "v_3_1",
        "phi_3_1",
    ]


# ----------------------------------------------------------------------------------------------
# (9) second-order axial strain (strain="second-order")
# ----------------------------------------------------------------------------------------------


def _mixed_case():
    """Two extensible links and one inextensible one (unchanged by the strain option)."""
    base = _load("three_link")
    links = list(base.model.links)
    links[1] = dataclasses.replace(links[1], beam=dataclasses.replace(links[1].beam, EA=None))
    return dataclasses.replace(base, model=dataclasses.replace(base.model, links=tuple(links)))


def _deformed_state(case, k, seed):
    """Random α and elastic coordinates large enough for the second-order terms to matter:
    u ~ 1e-4 l, v ~ 5e-2 l, φ ~ 5e-2."""
    names = gn.coordinate_names(case, k)
    rng = np.random.default_rng(seed)
    l = case.model.links[0].beam.length / k
    scale = {"a": 1.0, "u": 1e-4 * l, "v": 5e-2 * l, "p": 5e-2}
    return np.array([scale[n[0]] for n in names]) * rng.normal(size=len(names))


@pytest.mark.parametrize("k", [1, 3])
def test_second_order_force_is_energy_gradient_and_tangent_its_jacobian(k):
    case = _mixed_case()
    names = gn.coordinate_names(case, k)
    for seed in range(3):
        q = _deformed_state(case, k, seed)
        f, KT = gn.elastic_forces(case, k, q, strain="second-order")
        U = lambda x: gn.energy(case, k, x, np.zeros_like(x), strain="second-order")["elastic"]
        fd_f = np.zeros_like(f)
        fd_K = np.zeros_like(KT)
        for j in range(q.size):
            dq = np.zeros_like(q)
            dq[j] = 1e-4 * max(abs(q[j]), 1e-6)
            fd_f[j] = (U(q + dq) - U(q - dq)) / (2 * dq[j])
            fp = gn.elastic_forces(case, k, q + dq, strain="second-order")[0]
            fm = gn.elastic_forces(case, k, q - dq, strain="second-order")[0]
            fd_K[:, j] = (fp - fm) / (2 * dq[j])
        np.testing.assert_allclose(f, fd_f, rtol=1e-6, atol=1e-8 * np.abs(f).max())
        np.testing.assert_allclose(KT, fd_K, rtol=1e-6, atol=1e-8 * np.abs(KT).max())
        assert np.array_equal(KT, KT.T)
        # inextensible link and joint angles: exactly the linear element
        K = gn.stiffness_matrix(case, k)
        lin = np.array(
            [n.startswith("alpha") or n.endswith(tuple(f"_2_{j + 1}" for j in range(k))) for n in names]
        )
        np.testing.assert_allclose(KT[lin], K[lin], rtol=1e-14, atol=1e-14 * np.abs(K).max())
        np.testing.assert_allclose(f[lin], (K @ q)[lin], rtol=1e-14, atol=1e-14 * np.abs(f).max())
        # the second-order terms matter at this state
        assert np.abs(f - K @ q).max() > 1e-3 * np.abs(f).max()


def test_second_order_strain_is_the_mean_stretch_of_the_deflected_element():
    """ε = u/l + ½ mean((dv/dx)²) along the element, v(x) = N3 v + N4 φ (fine midpoint rule
    on finite differences of v, independent of the closed-form G)."""
    beam = Section(0.4, 2.0, 0.3, 5e6)
    case = _single(beam, Drive("torque", Constant(0.0)))
    l, EA = beam.length, beam.EA
    u, v, phi = 2e-5, 0.03, -0.08
    q = np.array([0.3, u, v, phi])
    xi = np.linspace(0.0, 1.0, 200001)
    y = (3 * xi**2 - 2 * xi**3) * v + l * (xi**3 - xi**2) * phi
    slope = np.diff(y) / (np.diff(xi) * l)
    eps = u / l + 0.5 * np.mean(slope**2)
    kb = beam.EI / l**3 * np.array([[12, -6 * l], [-6 * l, 4 * l * l]])
    w = np.array([v, phi])
    U = 0.5 * EA * l * eps**2 + 0.5 * w @ kb @ w
    f, _ = gn.elastic_forces(case, 1, q, strain="second-order")
    assert f[1] == pytest.approx(EA * eps, rel=1e-8)
    assert gn.energy(case, 1, q, np.zeros(4), strain="second-order")["elastic"] == pytest.approx(U, rel=1e-8)
    # linear strain: the familiar ½ qᵀKq
    f_lin, K_lin = gn.elastic_forces(case, 1, q)
    assert np.array_equal(K_lin, gn.stiffness_matrix(case, 1))
    assert np.array_equal(f_lin, K_lin @ q)


def _free_extensible_three_link():
    base = _with_beams(_load("three_link"), damping=0.0)
    drives = tuple(Drive("torque", Constant(0.0), initial_rate=w) for w in (2.0, -3.0, 4.0))
    return Case(Manipulator(base.model.links, (0.0, 0.0)), Scenario(0.2, 0.01, drives))


def test_second_order_energy_drift_is_second_order_in_h():
    """No damping, torque or gravity: the drift of T + U (U the second-order strain energy)
    shrinks at order 2 (h = 2e-3 is still pre-asymptotic for the axial modes)."""
    case = _free_extensible_three_link()
    hs = [1e-3, 5e-4, 2.5e-4]
    drift = []
    for h in hs:
        res = gn.simulate(case, elements_per_link=2, h=h, strain="second-order")
        assert res.meta["strain"] == "second-order" and res.meta["unconverged_steps"] == 0
        drift.append(np.abs(res.energy - res.energy[0]).max())
    assert drift[-1] < 1e-6 * res.energy[0]
    assert 1.8 < _slope(hs, drift) < 2.2, drift


@pytest.mark.slow
def test_second_order_energy_check_detects_an_inconsistent_energy(monkeypatch):
    """The drift test discriminates: reporting ½qᵀKq instead of U along the same second-order
    trajectory leaves a drift that does not shrink with h (≈ 20× the true drift at h = 2.5e-4)."""
    case = _free_extensible_three_link()
    good = gn.simulate(case, elements_per_link=2, h=2.5e-4, strain="second-order")
    monkeypatch.setattr(gnp, "_strain_energy", lambda lay, q: 0.5 * q @ lay.K @ q)  # the recorder's
    bad = gn.simulate(case, elements_per_link=2, h=2.5e-4, strain="second-order")
    d_good = np.abs(good.energy - good.energy[0]).max()
    d_bad = np.abs(bad.energy - bad.energy[0]).max()
    assert d_bad > 10 * d_good


def test_strain_option_is_validated_and_linear_is_the_default():
    case = _shorten(_load("single_link"), 0.01, 0.01)
    with pytest.raises(dttmm.InputError) as info:
        gn.simulate(case, elements_per_link=1, h=1e-3, strain="green")
    assert info.value.field == "strain"
    with pytest.raises(dttmm.InputError, match="strain"):
        gn.accelerations(case, 1, np.zeros(4), np.zeros(4), strain=None)
    a = gn.simulate(case, elements_per_link=2, h=1e-3)
    b = gn.simulate(case, elements_per_link=2, h=1e-3, strain="linear")
    assert a.meta["strain"] == "linear"
    assert np.array_equal(a.joint_angle, b.joint_angle) and np.array_equal(a.link_tip, b.link_tip)
    # inextensible links: the option changes nothing
    inext = _with_beams(case, EA=None)
    c = gn.simulate(inext, elements_per_link=2, h=1e-3)
    d = gn.simulate(inext, elements_per_link=2, h=1e-3, strain="second-order")
    assert np.array_equal(c.link_tip, d.link_tip)


# ----------------------------------------------------------------------------------------------
# (9) the two engines of the one time-loop source; one-step quantities against the numpy
# mechanics; stopping rule and status
# ----------------------------------------------------------------------------------------------


def _engine_module(engine):
    if engine == "numba":
        from reference_models import _global_numba as G
    else:
        from reference_models import _global_python as G
    return G


def _engines_case(name, damping=0.0):
    case = {
        "single_link": lambda: _shorten(_load("single_link"), 0.6, 0.02),
        "three_link": lambda: _shorten(_load("three_link"), 0.03, 0.01),
        "spin_up": lambda: _shorten(_load("spin_up"), 1.0, 0.1),
    }[name]()
    return _with_beams(case, damping=damping) if damping else case


_ENGINE_RUNS = [  # (case, damping μ, k, h): a restart (single_link), motion drive (spin_up)
    ("single_link", 0.0, 3, 2e-3),
    ("three_link", 0.0, 3, 1e-3),
    ("three_link", 2e-3, 2, 1e-3),
    ("spin_up", 0.0, 3, 1e-2),
]


def _rel(a, b):
    return np.abs(a - b).max() / max(1.0, np.abs(b).max())


@needs_numba
@pytest.mark.parametrize("strain", ["linear", "second-order"])
@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
@pytest.mark.parametrize("name, mu, k, h", _ENGINE_RUNS)
def test_uncompiled_engine_equals_compiled_engine(name, mu, k, h, integrator, strain):
    """engine="python" runs the compiled engine's source uncompiled: the same run to
    round-off. The iteration counts are not compared: where the last solve's change sits at the
    stop rule's bound, round-off decides whether one more solve is taken, and that differs
    between processors (both engines meet the stop rule at every step)."""
    case = _engines_case(name, mu)
    kw = {"elements_per_link": k, "h": h, "integrator": integrator, "strain": strain}
    a = gn.simulate(case, engine="python", **kw)
    b = gn.simulate(case, engine="numba", **kw)
    assert (a.meta["engine"], b.meta["engine"]) == ("python", "numba")
    assert a.status == b.status == "ok"
    for field in ("joint_angle", "joint_torque", "link_tip", "tip_deflection", "energy"):
        assert _rel(getattr(a, field), getattr(b, field)) <= 1e-12, field  # measured ≤ 2e-15
    # the rates carry the undamped elastic modes, where the iteration's tolerance (1e-10 on q̈)
    # lets the round-off through: measured ≤ 1.1e-12 (three_link, μ = 0), ≤ 4e-14 otherwise
    assert _rel(a.joint_rate, b.joint_rate) <= 1e-11
    assert a.meta["unconverged_steps"] == b.meta["unconverged_steps"] == 0


def test_numpy_is_an_alias_of_the_uncompiled_engine():
    case = _shorten(_load("three_link"), 0.005, 0.005)
    a = gn.simulate(case, elements_per_link=1, h=1e-3, engine="numpy")
    b = gn.simulate(case, elements_per_link=1, h=1e-3, engine="python")
    assert a.meta["engine"] == "python"
    assert np.array_equal(a.link_tip, b.link_tip) and np.array_equal(a.joint_torque, b.joint_torque)


@pytest.mark.parametrize("engine", _ENGINES)
def test_engine_assembly_equals_dense_jacobian_products(engine):
    """M(q) and the velocity/gravity forces of the engine's recursion equal Σ JᵀM_el J of the
    numpy mechanics at random states (extensible and inextensible links, hubs and a payload)."""
    G = _engine_module(engine)
    for case in (_load("three_link"), _with_beams(_load("three_link"), EA=None)):
        for k, seed in ((1, 0), (3, 1)):
            lay = gnp._layout(case, k)
            q, qd = _random_state(case, k, seed)
            M0, f0 = gnp._assemble(lay, q, qd)
            M, f = np.empty_like(M0), np.empty_like(f0)
            G.assemble(G.pack(lay, case), q, qd, M, f)
            assert np.abs(M - M0).max() <= 1e-13 * np.abs(M0).max()
            assert np.abs(f - f0).max() <= 1e-13 * np.abs(f0).max()


@pytest.mark.parametrize("engine", _ENGINES)
@pytest.mark.parametrize("strain", ["linear", "second-order"])
def test_engine_forward_dynamics_equal_the_numpy_accelerations(engine, strain):
    """The engine's one-step forward dynamics (recursive assembly, element forces, Cholesky)
    against :func:`accelerations` (dense Jacobians, scattered K_T and D_t, LU) at random
    states of a damped arm with a motion-driven joint; and its joint torque against the
    residual of the numpy equations."""
    base = _with_beams(_load("three_link"), damping=2e-3)
    drives = list(base.scenario.drives)
    drives[1] = Drive("motion", dttmm.Sine(0.4, 1.5, offset=0.2))
    case = dataclasses.replace(base, scenario=dataclasses.replace(base.scenario, drives=tuple(drives)))
    G = _engine_module(engine)
    k, t = 2, 0.3
    lay = gnp._layout(case, k, strain)
    P = G.pack(lay, case)
    for seed in range(3):
        q = _deformed_state(case, k, seed)  # elastic coordinates of a plausible size
        qd = _random_state(case, k, seed)[1] * 0.1
        pres = gnp._prescribed(case, lay, t, False)
        q[lay.presc], qd[lay.presc] = pres[:, 0], pres[:, 1]
        ref = gn.accelerations(case, k, q, qd, t, strain=strain)
        qdd, tau = G.forward(P, q, qd, gnp._torques(case, lay, t, False), pres[:, 2].copy())
        assert _rel(qdd, ref) <= 1e-11
        _, tau_ref = gnp._forward(case, lay, q, qd, t, False)
        # τ = M[p]·q̈ − rhs[p] is a residual of much larger terms: compare at their size
        terms = np.abs(gnp._assemble(lay, q, qd)[0][lay.presc]) @ np.abs(ref)
        assert np.all(np.abs(tau - tau_ref) <= 1e-13 * terms)


@pytest.mark.parametrize("engine", _ENGINES)
def test_exhausted_iterations_give_status_unconverged_with_the_time(engine):
    case = _shorten(_load("three_link"), 0.01, 0.005)
    res = gn.simulate(case, elements_per_link=2, h=1e-3, max_iterations=1, engine=engine)
    assert res.status == "unconverged" and not res.success
    assert res.meta["unconverged_steps"] == 10 and res.meta["iterations_max"] == 1
    assert len(res.warnings) == 1 and "t = 0.001 s" in res.warnings[0]
    ok = gn.simulate(case, elements_per_link=2, h=1e-3, engine=engine)
    assert ok.status == "ok" and ok.success and ok.warnings == ()


@pytest.mark.parametrize("engine", _ENGINES)
def test_stagnation_at_the_round_off_floor_counts_as_converged(engine):
    """A tolerance near round-off (1e-15) is met by chance only; the iteration stops on stagnation
    (as dttmm.simulate does) instead of running to max_iterations."""
    case = _shorten(_load("three_link"), 0.01, 0.005)
    res = gn.simulate(case, elements_per_link=2, h=1e-3, tol=1e-15, engine=engine)
    assert res.status == "ok" and res.meta["unconverged_steps"] == 0
    assert res.meta["iterations_max"] < 50


@pytest.mark.parametrize("engine", _ENGINES)
def test_non_finite_state_raises_with_partial_result_in_both_engines(engine):
    class BrokenAfter(Constant):
        def __call__(self, t, left=False):
            return math.nan if t > 0.05 else self.value

    case = _single(Section(1.0, 2.0, 0.3), Drive("torque", BrokenAfter(1.0)), duration=0.1, output_step=0.01)
    with pytest.raises(dttmm.SimulationError) as info:
        gn.simulate(case, elements_per_link=1, h=0.01, engine=engine)
    err = info.value
    assert err.t == pytest.approx(0.06) and err.step == 5 and err.component.startswith("alpha_1")
    assert err.partial is not None and err.partial.t[-1] == pytest.approx(0.05)
    assert err.partial.status == "failed"


# ----------------------------------------------------------------------------------------------
# (10) Kelvin-Voigt damping on the rate of the second-order strain
# ----------------------------------------------------------------------------------------------


def _one_element(EA, EI, l, mu):
    beam = Section(l, EI, 1.0, EA, mu)
    return _single(beam, Drive("torque", Constant(0.0)))


def test_second_order_damping_is_the_rate_derivative_of_its_dissipation_function():
    """f_d = ∂R/∂q̇ with R = ½μ[EA l ε̇² + ẇᵀK_b ẇ], ε̇ = u̇/l + wᵀGẇ (G, K_b in closed form
    here), checked by central differences; q̇ᵀf_d = 2R; and a rate that keeps the strain
    constant (u̇ = −l wᵀGẇ) leaves no axial damping force."""
    EA, EI, l, mu = 3.0e4, 2.0, 0.7, 0.05
    case = _one_element(EA, EI, l, mu)
    G = np.array([[6 / (5 * l * l), -1 / (10 * l)], [-1 / (10 * l), 2 / 15]])
    Kb = EI / l**3 * np.array([[12, -6 * l], [-6 * l, 4 * l * l]])
    rng = np.random.default_rng(3)
    q = np.concatenate([[0.3], rng.normal(size=3) * [1e-3, 0.05, 0.1]])
    qd = rng.normal(size=4)

    def R(v):
        w, wd = q[2:], v[2:]
        epsd = v[1] / l + w @ G @ wd
        return 0.5 * mu * (EA * l * epsd**2 + wd @ Kb @ wd)

    fd, Dt = gn.damping_forces(case, 1, q, qd, strain="second-order")
    step = 1e-6
    num = np.array([(R(qd + step * e) - R(qd - step * e)) / (2 * step) for e in np.eye(4)])
    assert np.allclose(fd, num, rtol=1e-7, atol=1e-9 * np.abs(fd).max())
    assert qd @ fd == pytest.approx(2 * R(qd), rel=1e-12)
    assert np.allclose(Dt @ qd, fd, rtol=1e-12)  # f_d is linear in q̇ at fixed q
    keep = qd.copy()
    keep[1] = -l * q[2:] @ G @ qd[2:]
    fk, _ = gn.damping_forces(case, 1, q, keep, strain="second-order")
    assert abs(fk[1]) <= 1e-12 * EA and np.allclose(fk[2:], mu * Kb @ keep[2:], rtol=1e-12)
    # the linear element keeps f_d = μK q̇
    fl, Dl = gn.damping_forces(case, 1, q, qd, strain="linear")
    assert np.allclose(Dl, mu * gn.stiffness_matrix(case, 1), rtol=1e-13)
    assert np.allclose(fl, mu * gn.stiffness_matrix(case, 1) @ qd, rtol=1e-13)


def _elastica_tip(L, EI, w):
    """Tip of the inextensible cantilever elastica under its own weight w (N/m):
    EI θ'' = w (L − s) cos θ, θ(0) = 0, θ'(L) = 0 (scipy's collocation BVP solver)."""
    import scipy.integrate

    def f(s, y):
        return np.vstack([y[1], w * (L - s) * np.cos(y[0]) / EI, np.cos(y[0]), np.sin(y[0])])

    s = np.linspace(0.0, L, 201)
    y0 = np.zeros((4, s.size))
    y0[2] = s
    sol = scipy.integrate.solve_bvp(
        f, lambda a, b: np.array([a[0], b[1], a[2], a[3]]), s, y0, tol=1e-10, max_nodes=100000
    )
    assert sol.status == 0
    return np.array([sol.y[2, -1], sol.y[3, -1]])


@pytest.mark.parametrize(
    "k, engine, tol",
    [
        pytest.param(8, "numba", 3e-3, marks=needs_numba),
        pytest.param(16, "numba", 4e-4, marks=needs_numba),
        pytest.param(8, "python", 3e-3, marks=pytest.mark.slow),
    ],
)
def test_damped_second_order_cantilever_settles_to_the_elastica(k, engine, tol):
    """Heavy cantilever (Exudyn's self-weight test: L = 2 m, ρA = 78 kg/m, EI = 833.3 N·m²)
    made nearly inextensible (EA = 1e9 N), μ = 0.35 s, dropped from straight: with the damping
    on the rate of the second-order strain it comes to rest within 10 s at the large-deflection
    elastica (tip ≈ (1.498, −1.232) m), up to the discretisation error (measured 2.1e-3 m at
    k = 8, 2.5e-4 m at k = 16). Damping μK ė (on u̇ instead of ε̇) resists the chord
    shortening of bending, which is not a strain rate: with it the tip is still creeping,
    0.44 m (k = 8) and 0.085 m (k = 16) above the elastica at t = 10 s (measured)."""
    L, EI, rhoA = 2.0, 833.3333333333334, 78.0
    beam = Section(L, EI, rhoA, 1.0e9, 0.35)
    case = Case(
        Manipulator((Link(beam),), (0.0, -9.81)), Scenario(10.0, 0.5, (Drive("motion", Constant(0.0)),))
    )
    res = gn.simulate(
        case,
        elements_per_link=k,
        h=5e-3,
        integrator="generalized-alpha",
        rho_inf=0.8,
        strain="second-order",
        engine=engine,
    )
    tip = res.link_tip[:, 0]
    assert res.status == "ok"
    assert np.abs(tip[-1] - tip[-3]).max() < 1e-5  # at rest from t = 9 s on
    assert np.abs(tip[-1] - _elastica_tip(L, EI, rhoA * 9.81)).max() < tol
