"""Kelvin-Voigt damping on the rate of the second-order strain, in every DT-TMM engine.

With ``strain="second-order"`` the damping derives from R = ½ μ [EA l ε̇² + ẇᵀK_b ẇ],
ε̇ = u̇/l + wᵀGẇ, w = (v, φ), as in the global-equation solver
(:func:`reference_models.global_newmark.damping_forces`, written independently). Checked here:
the element damping matrix against the global solver's, DT-TMM (compiled, uncompiled, both
sweeps, the numpy one-step reference) against the global solver step by step, and the damped
heavy cantilever coming to rest at the static elastica (scipy's BVP solver).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import case, shortened, with_links

import dttmm
from dttmm import Case, Constant, Drive, Link, Manipulator, Scenario, Section, sweeps
from dttmm.element import damping_tangent
from dttmm.structure import build_structure, kinematics
from reference_models import global_newmark as gm

SO = "second-order"


def _damped_three_link(mu=1e-3, duration=0.1):
    """three_link (extensible links, EA = 7e6 N) with Kelvin-Voigt damping μ (s)."""
    return shortened(with_links(case("three_link"), damping=mu), duration, duration / 10)


def _drive_values(c, t):
    """(τ (n,), (α, α̇, α̈) (n, 3)) of the drives at t (the open-loop laws of the shipped cases)."""
    n = len(c.scenario.drives)
    tau, mot = np.zeros(n), np.zeros((n, 3))
    for i, d in enumerate(c.scenario.drives):
        if d.kind == "motion":
            mot[i] = d.motion(t)
        else:
            tau[i] = d.torque(t)
    return tau, mot


def test_element_damping_matrix_equals_global_solvers():
    """D(e) of :func:`dttmm.element.damping_tangent` is the global solver's rate tangent
    (block per element, k = 1 so the element coordinates are q without α), f_d = D(e) ė; μK
    for linear strain."""
    c = with_links(case("single_link"), damping=0.02)
    st = build_structure(c, 1, SO)
    et = st.links[0].et
    rng = np.random.default_rng(5)
    q, qd = rng.normal(size=4) * [0.3, 1e-4, 0.05, 0.1], rng.normal(size=4)
    fd, Dt = gm.damping_forces(c, 1, q, qd, strain=SO)
    D = damping_tangent(et, q[None, 1:])[0]
    assert np.allclose(D, Dt[1:, 1:], rtol=1e-12, atol=0.0)
    assert np.allclose(D @ qd[1:], fd[1:], rtol=1e-12, atol=1e-12 * np.abs(fd).max())
    lin = build_structure(c, 1, "linear").links[0].et
    assert np.array_equal(damping_tangent(lin, q[None, 1:])[0], 0.02 * lin.K)


def _physical_state(st, rng):
    """Random joint angles and rates, elastic coordinates of realistic size (axial 1e-6 l,
    transverse 1e-2 l, rotation 1e-2; rates ×10)."""
    q, qd = np.zeros(st.n_dof), np.zeros(st.n_dof)
    for lk in st.links:
        q[lk.i_alpha], qd[lk.i_alpha] = rng.uniform(-np.pi, np.pi), rng.normal()
        scale = np.array([1e-6 * lk.et.l, 1e-2 * lk.et.l, 1e-2])
        q[lk.e_slice] = (rng.normal(size=(lk.k, 3)) * scale).ravel()
        qd[lk.e_slice] = (rng.normal(size=(lk.k, 3)) * scale * 10).ravel()
    return q, qd


@pytest.mark.parametrize("k, sweep_names", [(1, ("riccati", "plain")), (4, ("riccati",))])
def test_one_step_reference_and_kernels_equal_global_accelerations(k, sweep_names):
    """q̈ at a random state with damping on the strain rate: the numpy reference and the
    kernel (compiled and uncompiled) equal the global dense solve. The damping matters at
    these states: μK ė instead changes q̈ by 2.1 % (k = 1) and 0.43 % (k = 4) of max|q̈| (measured),
    far above the tolerance. (The plain sweep is checked at k = 1 only: on three_link its
    final system is ill-conditioned from k = 4 on, see docs/kernel.md.)"""
    c = _damped_three_link()
    st = build_structure(c, k, SO)
    q, qd = _physical_state(st, np.random.default_rng(k))
    ref = gm.accelerations(c, k, q, qd, 0.3, strain=SO)
    scale = np.abs(ref).max()
    tau, mot = _drive_values(c, 0.3)
    for sw in sweep_names:
        a = sweeps.accelerations(st, q, qd, tau, mot, sw).qdd
        assert np.abs(a - ref).max() <= 1e-9 * scale, sw
        for engine in ("numba", "python"):
            b = dttmm.accelerations(c, k, q, qd, 0.3, sweep=sw, engine=engine, strain=SO)
            assert np.abs(b - ref).max() <= 1e-9 * scale, (sw, engine)


@pytest.mark.parametrize("k", [1, 3])
def test_one_step_reference_step_system_equals_global_iteration(k):
    """One frozen-coefficient solve with c_q, c_v ≠ 0 (Newmark, h = 1e-3): the numpy reference
    sweep at the iterate (q_i, q̇_i), predictors ẽ = e_i − c_q ë_i, ẽ' = ė_i − c_v ë_i, gives
    the q̈ of the global solver's iteration matrix M + c_q K_T(q_i) + c_v D_t(q_i) and
    right-hand side (assembled here from its private pieces, all torque-driven joints).
    With μK in place of D(e) the result differs by 24 % (k = 1) and 40 % (k = 3) of max|q̈|
    (measured)."""
    from reference_models import _global_numpy as gnp

    c = _damped_three_link()
    st = build_structure(c, k, SO)
    rng = np.random.default_rng(10 + k)
    q, qd = _physical_state(st, rng)
    qdd_i = rng.normal(size=st.n_dof) * 10.0
    h = 1e-3
    cq, cv = 0.25 * h * h, 0.5 * h
    lay = gnp._layout(c, k, SO)
    M, f = gnp._assemble(lay, q, qd)
    fi, KT = gnp._internal(lay, q)
    fd, Dt = gnp._damping(lay, q, qd)
    B = cq * KT + cv * Dt
    tau, mot = _drive_values(c, 0.3)
    assert not np.any([d.kind == "motion" for d in c.scenario.drives])
    ref = np.linalg.solve(M + B, f + gnp._torques(c, lay, 0.3, True) - fi - fd + B @ qdd_i)
    split = lambda x: [x[lk.e_slice].reshape(lk.k, lk.et.ne) for lk in st.links]
    for sw in ("riccati", "plain") if k == 1 else ("riccati",):
        out = sweeps.SWEEPS[sw](
            st, kinematics(st, q, qd), cq, cv, split(q - cq * qdd_i), split(qd - cv * qdd_i), tau, mot[:, 2]
        )
        assert np.abs(out.qdd - ref).max() <= 1e-9 * np.abs(ref).max(), sw


def _max_diff(a, b):
    return max(
        np.abs(a.end_effector - b.end_effector).max(),
        np.abs(a.tip_deflection - b.tip_deflection).max(),
        np.abs(a.joint_angle - b.joint_angle).max(),
    )


@pytest.mark.parametrize("k", [4, 8])
@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
@pytest.mark.parametrize("iterations", [None, 1])
def test_damped_second_order_trajectories_equal_global(k, integrator, iterations):
    """Same step, same frozen-coefficient iteration, the damping matrix D(e) in the iteration
    matrix as in the global solver: trajectories agree to ≤ 1e-9 m / rad, converged and with
    exactly two sweeps (identical iterates)."""
    c = _damped_three_link(duration=0.1)
    a = dttmm.simulate(
        c,
        elements_per_link=k,
        h=1e-3,
        integrator=integrator,
        iterations=iterations,
        strain=SO,
        cut_loads=False,
        energy=False,
    )
    b = gm.simulate(c, elements_per_link=k, h=1e-3, integrator=integrator, iterations=iterations, strain=SO)
    assert a.status == "ok" and b.status == "ok"
    assert _max_diff(a, b) <= 1e-9


def test_damped_second_order_plain_sweep_equals_global():
    c = _damped_three_link(duration=0.05)
    a = dttmm.simulate(
        c, elements_per_link=2, h=1e-3, sweep="plain", strain=SO, cut_loads=False, energy=False
    )
    b = gm.simulate(c, elements_per_link=2, h=1e-3, strain=SO)
    assert _max_diff(a, b) <= 1e-9


def test_damped_second_order_compiled_equals_python_engine():
    """The compiled and the uncompiled kernel agree over five generalized-α steps (the
    acceleration solver, c_q = c_v = 0, is compared at random states above)."""
    c = _damped_three_link(duration=0.005)
    kw = {"elements_per_link": 4, "h": 1e-3, "strain": SO, "integrator": "generalized-alpha"}
    a = dttmm.simulate(c, engine="numba", **kw)
    b = dttmm.simulate(c, engine="python", **kw)
    assert _max_diff(a, b) <= 1e-12
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-9 * np.abs(b.joint_torque).max()


# ----------------------------------------------------------------------------------------------
# The damped heavy cantilever comes to rest at the static elastica
# ----------------------------------------------------------------------------------------------

L, EI, RHOA = 2.0, 833.3333333333334, 78.0


def _elastica_tip(length, bending, w):
    """Tip of the inextensible cantilever elastica under its own weight w (N/m):
    EI θ'' = w (L − s) cos θ, θ(0) = 0, θ'(L) = 0 (scipy's collocation BVP solver)."""
    import scipy.integrate

    def f(s, y):
        return np.vstack([y[1], w * (length - s) * np.cos(y[0]) / bending, np.cos(y[0]), np.sin(y[0])])

    s = np.linspace(0.0, length, 201)
    y0 = np.zeros((4, s.size))
    y0[2] = s
    sol = scipy.integrate.solve_bvp(
        f, lambda a, b: np.array([a[0], b[1], a[2], a[3]]), s, y0, tol=1e-10, max_nodes=100000
    )
    assert sol.status == 0
    return np.array([sol.y[2, -1], sol.y[3, -1]])


def _cantilever(duration):
    """L = 2 m, ρA = 78 kg/m, EI = 833.3 N·m², EA = 1e9 N, μ = 0.35 s, held at angle 0 by a
    motion drive, dropped from straight under gravity."""
    beam = Section(L, EI, RHOA, 1.0e9, 0.35)
    return Case(
        Manipulator((Link(beam),), (0.0, -9.81)), Scenario(duration, 0.5, (Drive("motion", Constant(0.0)),))
    )


_CANTILEVER = {"h": 5e-3, "integrator": "generalized-alpha", "rho_inf": 0.8, "strain": SO}


@pytest.mark.parametrize("k, tol", [(8, 3e-3), (16, 4e-4)])
def test_damped_second_order_cantilever_settles_to_the_elastica(k, tol):
    """At rest from t = 9 s on, at the elastica (tip ≈ (1.498, −1.232) m) within the
    discretisation error (global solver: 2.1e-3 m at k = 8, 2.5e-4 m at k = 16), and at the
    global solver's final state to ≤ 1e-9 m. With μK ė (damping on u̇ rather than ε̇) the tip
    still creeps at t = 10 s (0.44 m off at k = 8)."""
    c = _cantilever(10.0)
    a = dttmm.simulate(c, elements_per_link=k, cut_loads=False, energy=False, **_CANTILEVER)
    b = gm.simulate(c, elements_per_link=k, **_CANTILEVER)
    tip = a.link_tip[:, 0]
    assert a.status == "ok"
    assert np.abs(tip[-1] - tip[-3]).max() < 1e-5
    assert np.abs(tip[-1] - _elastica_tip(L, EI, RHOA * 9.81)).max() < tol
    assert np.abs(tip[-1] - b.link_tip[-1, 0]).max() <= 1e-9
