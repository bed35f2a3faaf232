"""DT-TMM is exact: it reproduces the global-equation ("traditional") solver of the same
discretisation (reference_models/global_newmark.py, written independently of the kernel, from the mechanics in docs/method.md)."""

import numpy as np
import pytest
from _global_reference import adaptive_reference
from conftest import case, shortened, with_links

import dttmm
from dttmm.structure import build_structure
from reference_models import _global_numpy as gnp
from reference_models import global_newmark as gm


def physical_state(st, rng):
    """Random joint angles and rates, elastic coordinates of realistic size."""
    q, qd = np.zeros(st.n_dof), np.zeros(st.n_dof)
    for i, lk in enumerate(st.links):
        q[lk.i_alpha] = rng.uniform(-np.pi, np.pi)
        qd[lk.i_alpha] = rng.normal()
        ne = lk.et.ne
        scale = np.array([1e-6 * lk.et.l, 1e-2 * lk.et.l, 1e-2])[-ne:]
        q[lk.e_slice] = (rng.normal(size=(lk.k, ne)) * scale).ravel()
        qd[lk.e_slice] = (rng.normal(size=(lk.k, ne)) * scale * 10).ravel()
        d = st.case.scenario.drives[i]
        if d.kind == "motion":
            q[lk.i_alpha], qd[lk.i_alpha], _ = d.motion(0.3)
    return q, qd


@pytest.mark.parametrize("name", ["single_link", "three_link", "spin_up"])
@pytest.mark.parametrize("k", [1, 4, 16])
def test_acceleration_solver_equals_global_Minv_f(name, k):
    """DT-TMM's q̈ solves the global equations M q̈ = f to round-off (backward error ≤ 1e-13)
    and equals the global dense solve to 1e-9 relative — or, where M itself is too ill
    conditioned for that (axial coordinates at k = 16: cond(M) ~ 1e9, so any float64 solver
    carries ~cond·ε), to within 20·cond(M)·ε."""
    c = case(name)
    st = build_structure(c, k)
    lay = gnp._layout(c, k)
    rng = np.random.default_rng(k)
    free = lay.free
    for _ in range(3):
        q, qd = physical_state(st, rng)
        a = dttmm.accelerations(c, k, q, qd, 0.3)
        b = gm.accelerations(c, k, q, qd, 0.3)
        M, f = gnp._assemble(lay, q, qd)
        rhs = (f + gnp._torques(c, lay, 0.3, False) - lay.K @ q - lay.D @ qd)[free]
        Mf = M[np.ix_(free, free)]
        rhs = rhs - M[np.ix_(free, lay.presc)] @ a[lay.presc]
        backward = np.linalg.norm(Mf @ a[free] - rhs) / (
            np.linalg.norm(Mf, 2) * np.linalg.norm(a[free]) + np.linalg.norm(rhs)
        )
        assert backward <= 1e-13
        bound = max(1e-9, 20 * np.linalg.cond(Mf) * np.finfo(float).eps)
        assert np.linalg.norm(a - b) <= bound * np.linalg.norm(b)


def _compare(a, b):
    return (np.max(np.abs(a.end_effector - b.end_effector)), np.max(np.abs(a.joint_angle - b.joint_angle)))


@pytest.mark.parametrize(
    "name, k, duration",
    [
        ("single_link", 1, None),
        ("three_link", 1, None),
        ("single_link", 8, 0.6),
        ("three_link", 8, 0.3),
        pytest.param("single_link", 8, None, marks=pytest.mark.slow),
        pytest.param("three_link", 8, None, marks=pytest.mark.slow),
        pytest.param("single_link", 32, None, marks=pytest.mark.slow),
        pytest.param("three_link", 32, None, marks=pytest.mark.slow),
    ],
)
@pytest.mark.parametrize("iterations", [None, 1])
def test_newmark_trajectories_equal_global(name, k, duration, iterations):
    """Same Newmark step, same frozen-coefficient iteration: identical iterates, so the
    trajectories agree to round-off (≤ 1e-9 m, 1e-9 rad), converged or with 2 sweeps."""
    c = case(name) if duration is None else shortened(case(name), duration)
    a = dttmm.simulate(c, elements_per_link=k, h=1e-3, iterations=iterations, cut_loads=False, energy=False)
    b = gm.simulate(c, elements_per_link=k, h=1e-3, iterations=iterations)
    d_ee, d_ang = _compare(a, b)
    assert d_ee <= 1e-9 and d_ang <= 1e-9, (d_ee, d_ang)
    np.testing.assert_allclose(a.joint_torque, b.joint_torque, atol=1e-8)


def test_motion_joint_torque_equals_global():
    c = shortened(case("spin_up"), 2.0)
    a = dttmm.simulate(c, elements_per_link=4, h=1e-2, iterations=2, cut_loads=False, energy=False)
    b = gm.simulate(c, elements_per_link=4, h=1e-2, iterations=2)
    np.testing.assert_allclose(a.joint_torque, b.joint_torque, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.tip_deflection, b.tip_deflection, atol=1e-10)


def test_generalized_alpha_equals_global():
    c = shortened(case("three_link"), 0.2)
    kw = dict(elements_per_link=4, h=1e-3, integrator="generalized-alpha", rho_inf=0.7, iterations=2)
    a = dttmm.simulate(c, cut_loads=False, energy=False, **kw)
    b = gm.simulate(c, **kw)
    assert max(_compare(a, b)) <= 1e-9


def test_one_shot_and_one_correction_converge_to_the_implicit_step(single_link):
    """iterations=0 (the paper's one-shot linearisation) and 1 vs converged: the difference
    shrinks at second order in h where the one-shot scheme is stable."""
    c = shortened(single_link, 0.4)
    diffs = {0: [], 1: []}
    hs = (2e-3, 1e-3, 5e-4)
    for h in hs:
        ref = dttmm.simulate(c, elements_per_link=2, h=h, cut_loads=False, energy=False)
        for m in (0, 1):
            r = dttmm.simulate(c, elements_per_link=2, h=h, iterations=m, cut_loads=False, energy=False)
            diffs[m].append(np.max(np.abs(r.joint_angle - ref.joint_angle)))
    for m in (0, 1):
        slopes = np.diff(np.log(diffs[m])) / np.log(0.5)
        assert np.all(slopes > 1.7), (m, diffs[m], slopes)
    assert all(d1 < d0 for d0, d1 in zip(diffs[0], diffs[1]))


def test_converges_to_solve_ivp_reference_at_second_order():
    """DT-TMM Newmark and the global Newmark both converge to a DOP853 solution of the global
    solver's forward dynamics (integrator-independent; tests/_global_reference.py) with order
    2 ± 0.3 (inextensible: DOP853 affordable)."""
    c = with_links(shortened(case("three_link"), 0.03, 1e-3), EA=None)
    ref_tip = adaptive_reference(c, 2, method="DOP853", rtol=1e-12, atol=1e-14)[1]
    errs_d, errs_g = [], []
    for h in (2e-4, 1e-4, 5e-5):
        a = dttmm.simulate(c, elements_per_link=2, h=h, cut_loads=False, energy=False)
        b = gm.simulate(c, elements_per_link=2, h=h)
        errs_d.append(np.max(np.abs(a.tip_deflection - ref_tip)))
        errs_g.append(np.max(np.abs(b.tip_deflection - ref_tip)))
    for errs in (errs_d, errs_g):
        slope = np.polyfit(np.log([2e-4, 1e-4, 5e-5]), np.log(errs), 1)[0]
        assert abs(slope - 2) <= 0.3, (errs, slope)


# ----------------------------------------------------------------------------------------------
# Second-order axial strain (strain="second-order"): DT-TMM numpy engine vs the global solver
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("name", ["single_link", "three_link", "spin_up"])
@pytest.mark.parametrize("k", [1, 4, 16])
def test_second_order_acceleration_solver_equals_global(name, k):
    """Same q̈ from (q, q̇) with the second-order elastic forces, to 1e-9 relative or
    20·cond(M)·ε; the second-order terms change q̈ substantially at these states."""
    c = case(name)
    st = build_structure(c, k, "second-order")
    lay = gnp._layout(c, k, "second-order")
    rng = np.random.default_rng(100 + k)
    free = lay.free
    for _ in range(3):
        q, qd = physical_state(st, rng)
        a = dttmm.accelerations(c, k, q, qd, 0.3, strain="second-order")
        b = gm.accelerations(c, k, q, qd, 0.3, strain="second-order")
        M, _ = gnp._assemble(lay, q, qd)
        bound = max(1e-9, 20 * np.linalg.cond(M[np.ix_(free, free)]) * np.finfo(float).eps)
        assert np.linalg.norm(a - b) <= bound * np.linalg.norm(b)
        lin = gm.accelerations(c, k, q, qd, 0.3)
        assert np.linalg.norm(lin - b) > 1e-3 * np.linalg.norm(b)


@pytest.mark.parametrize(
    "name, k",
    [
        ("single_link", 1),
        ("single_link", 4),
        ("single_link", 8),
        ("three_link", 1),
        ("three_link", 4),
        pytest.param("three_link", 8, marks=pytest.mark.slow),
    ],
)
@pytest.mark.parametrize("iterations", [None, 1])
def test_second_order_newmark_trajectories_equal_global(name, k, iterations):
    """Newton-linearised elastic forces in the frozen-coefficient iteration: identical
    iterates in both solvers, trajectories equal to round-off (≤ 1e-9 m, 1e-9 rad)."""
    c = shortened(case(name), 0.3)
    kw = dict(elements_per_link=k, h=1e-3, iterations=iterations, strain="second-order")
    a = dttmm.simulate(c, cut_loads=False, energy=False, **kw)
    b = gm.simulate(c, **kw)
    d_ee, d_ang = _compare(a, b)
    assert d_ee <= 1e-9 and d_ang <= 1e-9, (d_ee, d_ang)
    np.testing.assert_allclose(a.joint_torque, b.joint_torque, atol=1e-8)
    lin = gm.simulate(c, elements_per_link=k, h=1e-3, iterations=iterations)
    assert np.max(np.abs(lin.end_effector - b.end_effector)) > 1e-6


def test_second_order_motion_joint_torque_and_generalized_alpha_equal_global():
    c = shortened(case("spin_up"), 1.0)
    kw = dict(elements_per_link=4, h=1e-2, iterations=2, strain="second-order")
    a = dttmm.simulate(c, cut_loads=False, energy=False, **kw)
    b = gm.simulate(c, **kw)
    np.testing.assert_allclose(a.joint_torque, b.joint_torque, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(a.tip_deflection, b.tip_deflection, atol=1e-10)
    c = shortened(case("three_link"), 0.1)
    kw = dict(
        elements_per_link=4,
        h=1e-3,
        integrator="generalized-alpha",
        rho_inf=0.7,
        iterations=2,
        strain="second-order",
    )
    a = dttmm.simulate(c, cut_loads=False, energy=False, **kw)
    b = gm.simulate(c, **kw)
    assert max(_compare(a, b)) <= 1e-9
