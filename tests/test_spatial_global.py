"""The spatial global-equation solver (reference_models.spatial_global) against independent
references: SciPy's rotations, finite differences, closed-form beam and rigid-body results, the
planar global solver on embedded planar cases and energy conservation; and the spatial DT-TMM
(dttmm.spatial) against it."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import dttmm
from dttmm import Constant, Drive, Scenario, Sine
from dttmm.drives import PD
from dttmm.spatial import (
    SpatialCase,
    SpatialHub,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialSection,
    embed_planar,
)
from reference_models import _spatial_mechanics as mech
from reference_models import global_newmark as gn
from reference_models import spatial_global as sg

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"


# ----------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------


def _section(L=0.5, *, EA=None, GJ=1.5, EIy=3.0, EIz=2.0, rhoA=0.3, roll=0.0, damping=0.0, **kw):
    data = dict(rhoJ=2e-4, rhoIy=8e-5, rhoIz=1.2e-4)
    data.update(kw)
    return SpatialSection(
        length=L, GJ=GJ, EIy=EIy, EIz=EIz, rhoA=rhoA, EA=EA, roll=roll, damping=damping, **data
    )


_FULL_INERTIA = ((2e-3, 2e-4, -1e-4), (2e-4, 3e-3, 3e-4), (-1e-4, 3e-4, 2.5e-3))


def arm(n=3, *, gravity=(0.0, 0.0, -9.81), EA=None, roll=(0.0, 0.3, -0.2), stiff=1.0, damping=0.0):
    """A yaw + pitch + pitch arm (n = 2: yaw + pitch) along x, with hubs, a payload with an
    offset and a full inertia tensor, EIy ≠ EIz, rolled sections and a base frame that is
    not the world's."""
    axes = [(0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (0.0, 1.0, 0.0)]
    links = []
    for i in range(n):
        beam = _section(
            0.5 - 0.1 * i,
            EA=None if EA is None else EA * stiff,
            GJ=1.5 * stiff,
            EIy=3.0 * stiff,
            EIz=2.0 * stiff,
            roll=roll[i],
            damping=damping,
        )
        joint = SpatialJoint(axis=axes[i], origin_xyz=(0.0, 0.0, 0.02 * i), origin_rpy=(0.05 * i, 0.0, 0.0))
        hub = SpatialHub(0.2, ((1e-3, 0.0, 1e-4), (0.0, 2e-3, 0.0), (1e-4, 0.0, 1.5e-3)))
        pay = SpatialPayload(0.15, (0.03, 0.02, -0.01), _FULL_INERTIA) if i == n - 1 else None
        links.append(SpatialLink(beam, joint, hub, pay))
    return SpatialManipulator(tuple(links), gravity, (0.1, -0.05, 0.2), (0.1, -0.2, 0.3))


def _case(model, drives, duration=0.1, output_step=0.01):
    return SpatialCase(model, Scenario(duration, output_step, tuple(drives)))


def _torque_drives(n, amp=(1.0, 0.6, 0.2)):
    return [Drive("torque", Sine(amp[i], 2.0, phase=0.3 * i)) for i in range(n)]


def _random_state(case, k, seed, scale=0.05):
    rng = np.random.default_rng(seed)
    names = sg.coordinate_names(case, k)
    q = np.where([n.startswith("alpha") for n in names], 1.0, scale) * rng.normal(size=len(names))
    qd = np.where([n.startswith("alpha") for n in names], 1.0, 10 * scale) * rng.normal(size=len(names))
    return q, qd


# ----------------------------------------------------------------------------------------------
# SO(3) and the element kinematics
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("scale", [1e-9, 1e-4, 0.3, 2.5])
def test_exp_and_log_against_scipy(scale):
    rng = np.random.default_rng(1)
    psi = scale * rng.normal(size=(20, 3))
    R = mech.exp_so3(psi)
    ref = Rotation.from_rotvec(psi).as_matrix()
    assert np.max(np.abs(R - ref)) < 1e-15 * 10
    back = mech.log_so3(R)
    assert np.max(np.abs(mech.exp_so3(back) - R)) < 1e-14
    inside = np.linalg.norm(psi, axis=1) < math.pi  # the logarithm's range: |ψ| ≤ π
    assert np.max(np.abs(back[inside] - psi[inside])) < 1e-14 * max(1.0, scale) + 1e-15
    axis = psi[0] / np.linalg.norm(psi[0])
    assert np.max(np.abs(mech.rot_axis(axis, 0.7) - Rotation.from_rotvec(0.7 * axis).as_matrix())) < 1e-15


def test_rpy_is_urdf_convention():
    rpy = (0.3, -0.4, 1.1)
    ref = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()  # intrinsic z-y'-x'' = Rz Ry Rx
    assert np.max(np.abs(mech.rpy_matrix(rpy) - ref)) < 1e-15


@pytest.mark.parametrize("scale", [1e-5, 0.2, 1.7])
def test_left_jacobian_gives_the_spatial_angular_velocity(scale):
    """[J_L(ψ) ψ̇]× = (d/dt exp[ψ]×) exp[ψ]×ᵀ, by central differences of SciPy's exponential."""
    rng = np.random.default_rng(2)
    psi, dpsi = scale * rng.normal(size=3), rng.normal(size=3)
    d = 1e-6
    dR = (
        Rotation.from_rotvec(psi + d * dpsi).as_matrix() - Rotation.from_rotvec(psi - d * dpsi).as_matrix()
    ) / (2 * d)
    W = dR @ Rotation.from_rotvec(psi).as_matrix().T
    w = np.array([W[2, 1], W[0, 2], W[1, 0]])
    assert np.max(np.abs(mech.left_jacobian(psi) @ dpsi - w)) < 1e-8


def test_complex_step_of_the_maps_is_their_derivative():
    """Im f(ψ + iε ψ̇)/ε equals the central difference of f for exp and J_L, also at ψ = 0."""
    rng = np.random.default_rng(3)
    dpsi = rng.normal(size=3)
    for psi in (np.zeros(3), 1e-5 * rng.normal(size=3), 0.8 * rng.normal(size=3)):
        for f in (mech.exp_so3, mech.left_jacobian):
            cs = f(psi + 1e-30j * dpsi).imag / 1e-30
            d = 1e-6
            fd = (f(psi + d * dpsi) - f(psi - d * dpsi)) / (2 * d)
            assert np.max(np.abs(cs - fd)) < 1e-8


def test_element_shape_functions():
    """s(1) = (l + u, v, w), ψ(1) = φ, and ψ(ξ) = (ξφx, −∂s_z/∂x, ∂s_y/∂x) by differences."""
    l = 0.3
    e = np.array([1e-3, 0.02, -0.01, 0.05, 0.03, -0.04])
    s0, S, P = mech.shape_matrices(l, np.array([0.0, 0.37, 1.0]))
    s = s0 + S @ e
    psi = P @ e
    assert np.allclose(s[0], 0.0) and np.allclose(psi[0], [0.0, 0.0, 0.0])
    assert np.max(np.abs(s[2] - [l + e[0], e[1], e[2]])) < 1e-16
    assert np.max(np.abs(psi[2] - e[3:])) < 1e-16
    d = 1e-6
    sp, _, _ = mech.shape_matrices(l, np.array([0.37 + d]))
    sm, Sp, _ = mech.shape_matrices(l, np.array([0.37 - d]))
    Sp1 = mech.shape_matrices(l, np.array([0.37 + d]))[1]
    slope = ((sp + Sp1 @ e) - (sm + Sp @ e))[0] / (2 * d * l)
    assert abs(psi[1, 1] + slope[2]) < 1e-8 and abs(psi[1, 2] - slope[1]) < 1e-8
    assert abs(psi[1, 0] - 0.37 * e[3]) < 1e-16


# ----------------------------------------------------------------------------------------------
# Mass matrix, velocity terms, elastic forces
# ----------------------------------------------------------------------------------------------


@pytest.mark.parametrize("k", [1, 2])
def test_mass_matrix_symmetric_positive_definite(k):
    case = _case(arm(EA=7e5), _torque_drives(3))
    for seed in range(3):
        q, _ = _random_state(case, k, seed)
        M = sg.mass_matrix(case, k, q)
        assert np.array_equal(M, M.T)
        ev = np.linalg.eigvalsh(M)
        assert ev.min() > 1e-9 * ev.max() and ev.min() > 0


def test_single_link_yaw_inertia_closed_form():
    """M_αα of one yawing link at rest = J_hub,zz + ρA L³/3 + L (rotary inertia about z): ρIz
    for roll = 0, ρIy for roll = π/2 (the section's y axis then points along the world z)."""
    L, rhoA = 0.7, 0.4
    for roll, rot in ((0.0, 1.2e-4), (math.pi / 2, 8e-5)):
        beam = _section(L, EA=1e5, rhoA=rhoA, roll=roll)
        hub = SpatialHub(0.3, (1e-3, 2e-3, 4e-3))
        case = _case(
            SpatialManipulator((SpatialLink(beam, SpatialJoint(), hub),)), [Drive("torque", Constant(0))]
        )
        M = sg.mass_matrix(case, 3, np.zeros(len(sg.coordinate_names(case, 3))))
        assert abs(M[0, 0] - (4e-3 + rhoA * L**3 / 3 + rot * L)) < 1e-15


def test_velocity_terms_are_lagranges():
    """h(q, q̇) − Q_g from the complex step equals Ṁq̇ − ∂T/∂q by central differences of the
    mass matrix (gravity off): the velocity terms are those of the kinetic energy ½q̇ᵀMq̇."""
    model = dataclasses.replace(arm(EA=7e5), gravity=(0.0, 0.0, 0.0))
    case = _case(model, _torque_drives(3))
    k = 1
    q, qd = _random_state(case, k, 7)
    h = -sg.generalized_forces(case, k, q, qd)
    d = 1e-6
    Mdot = (sg.mass_matrix(case, k, q + d * qd) - sg.mass_matrix(case, k, q - d * qd)) / (2 * d)
    dT = np.array(
        [
            0.5
            * qd
            @ (sg.mass_matrix(case, k, q + d * ej) - sg.mass_matrix(case, k, q - d * ej))
            @ qd
            / (2 * d)
            for ej in np.eye(q.size)
        ]
    )
    ref = Mdot @ qd - dT
    assert np.max(np.abs(h - ref)) < 1e-7 * np.max(np.abs(ref))


def test_gravity_force_is_minus_potential_gradient():
    case = _case(arm(EA=7e5), _torque_drives(3))
    k = 2
    q, _ = _random_state(case, k, 4)
    Qg = sg.generalized_forces(case, k, q, np.zeros_like(q))
    d = 1e-6
    grad = [
        (sg.energy(case, k, q + d * e, 0 * q)["gravity"] - sg.energy(case, k, q - d * e, 0 * q)["gravity"])
        / (2 * d)
        for e in np.eye(q.size)
    ]
    assert np.max(np.abs(Qg + np.array(grad))) < 1e-7 * np.max(np.abs(Qg))


@pytest.mark.parametrize("strain", ["linear", "second-order"])
def test_elastic_force_and_tangent_are_derivatives(strain):
    case = _case(arm(EA=7e5), _torque_drives(3))
    k = 2
    q, qd = _random_state(case, k, 5, scale=0.1)
    U, f, KT = sg.elastic_forces(case, k, q, strain)
    d = 1e-6
    fd = np.array(
        [
            (
                sg.elastic_forces(case, k, q + d * e, strain)[0]
                - sg.elastic_forces(case, k, q - d * e, strain)[0]
            )
            / (2 * d)
            for e in np.eye(q.size)
        ]
    )
    assert np.max(np.abs(f - fd)) < 1e-6 * np.max(np.abs(f))
    Kd = np.column_stack(
        [
            (
                sg.elastic_forces(case, k, q + d * e, strain)[1]
                - sg.elastic_forces(case, k, q - d * e, strain)[1]
            )
            / (2 * d)
            for e in np.eye(q.size)
        ]
    )
    assert np.max(np.abs(KT - Kd)) < 1e-6 * np.max(np.abs(KT))
    # damping force: μ times the gradient of the dissipation function
    model = arm(EA=7e5, damping=2e-3)
    case = _case(model, _torque_drives(3))
    fdmp, Dt = sg.damping_forces(case, k, q, qd, strain)
    if strain == "linear":
        assert np.max(np.abs(fdmp - 2e-3 * KT @ qd)) < 1e-12 * np.max(np.abs(fdmp))
    else:
        # R = ½μ[EA l ε̇² + ...] is quadratic in q̇: f_d = D_t q̇ with D_t the Hessian of R
        assert np.max(np.abs(fdmp - Dt @ qd)) < 1e-12 * np.max(np.abs(fdmp))
    assert np.array_equal(Dt, Dt.T)


# ----------------------------------------------------------------------------------------------
# Statics: cantilever tip deflections in both planes and twist against beam theory
# ----------------------------------------------------------------------------------------------


def _static(case, k, iterations=30):
    """Static equilibrium f_int(q) = Q_g(q) of a case without joint coordinates (fixed point)."""
    N = len(sg.coordinate_names(case, k))
    K = sg.elastic_forces(case, k, np.zeros(N))[2]
    q = np.zeros(N)
    for _ in range(iterations):
        q = np.linalg.solve(K, sg.generalized_forces(case, k, q, np.zeros(N)))
    return q


@pytest.mark.parametrize("k", [1, 3])
def test_cantilever_static_deflections(k):
    """Locked-root cantilever with a tip mass in gravity along −y, then −z, then −z with the
    mass offset along y: v_tip = −F L³/(3EIz) − w₀L⁴/(8EIz), w_tip likewise with EIy (w₀ = ρA g
    the beam's own weight), tip slopes F L²/(2EI) + w₀L³/(6EI), twist −F c L/GJ. Loads are small
    (δ/L ≈ 1e-6) so the geometric nonlinearity stays below 1e-9 relative; the deflection across
    the load plane is of second order (twist × deflection), below 1e-6 relative."""
    L, EIy, EIz, GJ, rhoA, m, g, c = 0.8, 30.0, 12.0, 9.0, 0.02, 0.05, 1e-3, 0.05
    beam = _section(L, EA=1e7, GJ=GJ, EIy=EIy, EIz=EIz, rhoA=rhoA)
    F, w0 = m * g, rhoA * g
    for grav, off in (
        ((0.0, -g, 0.0), (0.0, 0.0, 0.0)),
        ((0.0, 0.0, -g), (0.0, 0.0, 0.0)),
        ((0.0, 0.0, -g), (0.0, c, 0.0)),
    ):
        link = SpatialLink(beam, SpatialJoint(locked=True), None, SpatialPayload(m, off, (0.0, 0.0, 0.0)))
        case = _case(SpatialManipulator((link,), grav), [])
        q = _static(case, k)
        fr = sg.kinematics(case, k, q)
        defl, twist = fr["tip_deflection"][0], fr["twist"][0]
        psi = mech.log_so3(fr["tip_rotation"][0])
        EI = EIz if grav[1] else EIy
        delta = F * L**3 / (3 * EI) + w0 * L**4 / (8 * EI)
        slope = F * L**2 / (2 * EI) + w0 * L**3 / (6 * EI)
        if grav[1]:
            assert abs(defl[0] + delta) < 1e-9 * delta and abs(defl[1]) < 1e-6 * delta
            assert abs(psi[2] + slope) < 1e-9 * slope
        else:
            assert abs(defl[1] + delta) < 1e-9 * delta and abs(defl[0]) < 1e-6 * delta
            assert abs(psi[1] - slope) < 1e-9 * slope
            ref_twist = -F * off[1] * L / GJ
            assert abs(twist - ref_twist) < 1e-9 * max(abs(ref_twist), delta / L)


def test_cantilever_static_cut_loads():
    """At static equilibrium (q̈ = 0) the cut at x carries the weight outboard of it: force
    (0, 0, ρA g (L − x) + m g) and moment about the cut (0, −[ρA g (L − x)²/2 + m g (L − x)], 0)
    for gravity −z, beam along x (to the deflection's lever, 1e-6 relative); the tip cut holds
    the payload."""
    L, rhoA, m, g, k = 0.8, 0.3, 0.05, 1e-2, 4
    beam = _section(L, EA=1e7, GJ=90.0, EIy=300.0, EIz=120.0, rhoA=rhoA)
    link = SpatialLink(
        beam, SpatialJoint(locked=True), None, SpatialPayload(m, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    )
    case = _case(SpatialManipulator((link,), (0.0, 0.0, -g)), [])
    q = _static(case, k)
    loads = sg.cut_loads(case, k, q, np.zeros_like(q))
    x = np.arange(k + 1) * L / k
    Fz = rhoA * g * (L - x) + m * g
    My = -(rhoA * g * (L - x) ** 2 / 2 + m * g * (L - x))
    assert np.max(np.abs(loads[:, 2] - Fz)) < 1e-12 * Fz.max()
    assert np.max(np.abs(loads[:, [0, 1]])) < 1e-12 * Fz.max()
    assert np.max(np.abs(loads[:, 4] - My)) < 1e-6 * np.abs(My).max()
    assert np.max(np.abs(loads[:, [3, 5]])) < 1e-6 * np.abs(My).max()


# ----------------------------------------------------------------------------------------------
# The planar embedding reproduces the planar global solver
# ----------------------------------------------------------------------------------------------


def _planar_map(pcase, scase, k):
    pn, sn = gn.coordinate_names(pcase, k), sg.coordinate_names(scase, k)
    rename = {"alpha": "alpha", "u": "u", "v": "v", "phi": "phiz"}
    return np.array([sn.index(rename[n.split("_")[0]] + n[n.index("_") :]) for n in pn])


def _planar_case(duration=0.05):
    case = dttmm.load_case(CASES / "three_link.toml")
    return dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=duration, output_step=1e-3)
    )


@pytest.mark.parametrize("base_rpy", [(0.0, 0.0, 0.0), (0.4, -0.3, 0.7)])
def test_planar_embedding_accelerations(base_rpy):
    pcase = _planar_case()
    scase = SpatialCase(embed_planar(pcase.model, base_rpy=base_rpy), pcase.scenario)
    k = 2
    idx = _planar_map(pcase, scase, k)
    rng = np.random.default_rng(11)
    for _ in range(3):
        qp, qdp = 0.1 * rng.normal(size=idx.size), rng.normal(size=idx.size)
        q, qd = np.zeros(len(sg.coordinate_names(scase, k))), None
        qd = np.zeros_like(q)
        q[idx], qd[idx] = qp, qdp
        ref = gn.accelerations(pcase, k, qp, qdp, 0.1)
        got = sg.accelerations(scase, k, q, qd, 0.1)
        assert np.max(np.abs(got[idx] - ref)) < 1e-11 * np.max(np.abs(ref))
        assert np.max(np.abs(np.delete(got, idx))) < 1e-11 * np.max(np.abs(ref))
        assert (
            np.max(np.abs(sg.mass_matrix(scase, k, q)[np.ix_(idx, idx)] - gn.mass_matrix(pcase, k, qp)))
            < 1e-14
        )


@pytest.mark.parametrize("base_rpy", [(0.0, 0.0, 0.0), (0.4, -0.3, 0.7)])
def test_planar_embedding_trajectory(base_rpy):
    """three_link.toml, k = 2, 0.05 s at h = 1e-3, Newmark: the same joint angles, end-effector
    (in the plane of the base frame) and energy as the planar global solver, to round-off."""
    pcase = _planar_case()
    scase = SpatialCase(embed_planar(pcase.model, base_rpy=base_rpy), pcase.scenario)
    ref = gn.simulate(pcase, elements_per_link=2, h=1e-3, engine="numpy")
    res = sg.simulate(scase, elements_per_link=2, h=1e-3)
    assert res.success
    R = mech.rpy_matrix(base_rpy)
    ee = res.end_effector @ R  # base-frame components
    assert np.max(np.abs(res.joint_angle - ref.joint_angle)) < 1e-12
    assert np.max(np.abs(ee[:, :2] - ref.end_effector)) < 1e-12
    assert np.max(np.abs(ee[:, 2])) < 1e-12
    assert np.max(np.abs(res.tip_deflection[..., 0] - ref.tip_deflection)) < 1e-12
    assert np.max(np.abs(res.energy - ref.energy)) < 1e-10 * np.max(np.abs(ref.energy))


# ----------------------------------------------------------------------------------------------
# Energy conservation
# ----------------------------------------------------------------------------------------------


def _free_arm():
    model = arm(EA=None)
    drives = [Drive("torque", Constant(0.0), initial_rate=w) for w in (2.0, -1.5, 3.0)]
    return model, drives


def test_energy_conservation_shrinks_with_h_squared():
    """Undamped free motion of the yaw + pitch + pitch arm in gravity, k = 1, 0.1 s: the
    Newmark (trapezoidal) energy error max|E − E0| stays below 2e-5 of the energy and falls by
    ≈ 4 when h halves (second order). Measured: 4.7e-5, 1.2e-5, 3.0e-6 J of 5.14 J at
    h = 4, 2, 1 ms (ratios 3.93, 3.99)."""
    model, drives = _free_arm()
    case = _case(model, drives, duration=0.1, output_step=0.004)
    drift = []
    for h in (4e-3, 2e-3, 1e-3):
        res = sg.simulate(case, elements_per_link=1, h=h)
        assert res.success
        drift.append(np.max(np.abs(res.energy - res.energy[0])))
    assert drift[0] < 2e-5 * np.max(np.abs(res.energy))
    r1, r2 = drift[0] / drift[1], drift[1] / drift[2]
    assert 3.0 < r1 < 5.5 and 3.0 < r2 < 5.5, (drift, r1, r2)


def test_rk4_energy_and_agreement_with_newmark():
    """RK4 conserves the energy to ≲ 1e-7 (fourth order; measured 1.1e-10 J of 5.14 J at
    h = 0.5 ms) on the same free arm, and agrees with Newmark to its O(h²) error."""
    model, drives = _free_arm()
    case = _case(model, drives, duration=0.03, output_step=0.003)
    rk = sg.simulate(case, elements_per_link=1, h=5e-4, integrator="rk4")
    nm = sg.simulate(case, elements_per_link=1, h=5e-4)
    ga = sg.simulate(case, elements_per_link=1, h=5e-4, integrator="generalized-alpha", rho_inf=1.0)
    assert np.max(np.abs(rk.energy - rk.energy[0])) < 1e-7 * (np.max(np.abs(rk.energy)) + 1)
    assert np.max(np.abs(rk.joint_angle - nm.joint_angle)) < 1e-4
    # ρ∞ = 1: generalised-α is the trapezoidal rule
    assert np.max(np.abs(ga.joint_angle - nm.joint_angle)) < 1e-12


def test_damping_power_balance():
    """Free motion of the damped arm (Kelvin–Voigt μ = 2e-3 s, linear and second-order strain,
    RK4 at h = 1e-4, 0.02 s): the energy lost equals the dissipated work ∫ q̇ᵀ f_d(q, q̇) dt
    (Simpson's rule on the output grid) to 1e-4 of the loss (measured 2.3e-6)."""
    for strain in ("linear", "second-order"):
        model = arm(EA=2e4, damping=2e-3)
        drives = [Drive("torque", Constant(0.0), initial_rate=w) for w in (2.0, -1.5, 3.0)]
        case = _case(model, drives, duration=0.02, output_step=2.5e-4)
        res = sg.simulate(case, elements_per_link=1, h=1e-4, integrator="rk4", strain=strain)
        q, qd = res.meta["q"], res.meta["qd"]
        power = np.array(
            [qd[i] @ sg.damping_forces(case, 1, q[i], qd[i], strain)[0] for i in range(len(res.t))]
        )
        dt = res.t[1] - res.t[0]
        work = dt / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
        loss = res.energy[0] - res.energy[-1]
        assert loss > 0
        assert abs(loss - work) < 1e-4 * loss, (strain, loss, work)


# ----------------------------------------------------------------------------------------------
# Drives and bad input
# ----------------------------------------------------------------------------------------------


def test_motion_drive_torque_is_inverse_dynamics():
    """A prescribed yaw (a spin-up: no jerk at the start, so no vibration is excited) of a very
    stiff single link: the computed joint torque is (J_hub + ρA L³/3 + ρIz L) α̈ up to the
    link's quasi-static flexibility (measured 4e-9 relative, ∝ 1/EI)."""
    L, rhoA = 0.6, 0.5
    beam = _section(L, EA=1e12, GJ=1e9, EIy=1e9, EIz=1e9, rhoA=rhoA)
    hub = SpatialHub(0.0, (0.0, 0.0, 2e-3))
    drive = Drive("motion", dttmm.SpinUp(3.0, 0.2))
    case = _case(SpatialManipulator((SpatialLink(beam, SpatialJoint(), hub),)), [drive], duration=0.2)
    res = sg.simulate(case, elements_per_link=1, h=1e-3)
    J = 2e-3 + rhoA * L**3 / 3 + 1.2e-4 * L
    acc = np.array([drive.motion(t)[2] for t in res.t])
    assert np.max(np.abs(res.joint_angle[:, 0] - [drive.motion(t)[0] for t in res.t])) < 1e-15
    assert np.max(np.abs(res.joint_torque[:, 0] - J * acc)) < 1e-7 * np.max(np.abs(J * acc))


def test_divergence_raises_with_the_partial_result():
    """RK4 at h = 1e-3 is unstable for the axial modes of EA = 7e6: SimulationError naming the
    first non-finite coordinate, with the outputs up to the failure."""
    case = _case(arm(3, EA=7e6), _torque_drives(3), duration=0.05, output_step=1e-3)
    with pytest.raises(dttmm.SimulationError, match="non-finite") as err:
        sg.simulate(case, elements_per_link=1, h=1e-3, integrator="rk4")
    part = err.value.partial
    assert part.status == "failed" and 0 < part.t.size < 51
    assert np.all(np.isfinite(part.end_effector))


def test_bad_input():
    case = _case(arm(2), _torque_drives(2))
    with pytest.raises(dttmm.InputError, match="case"):
        sg.simulate("nope", elements_per_link=1, h=1e-3)
    with pytest.raises(dttmm.InputError, match="integrator"):
        sg.simulate(case, elements_per_link=1, h=1e-3, integrator="euler")
    with pytest.raises(dttmm.InputError, match="strain"):
        sg.simulate(case, elements_per_link=1, h=1e-3, strain="cubic")
    with pytest.raises(dttmm.InputError, match="rho_inf"):
        sg.simulate(case, elements_per_link=1, h=1e-3, rho_inf=0.5)
    with pytest.raises(dttmm.InputError, match="elements_per_link"):
        sg.simulate(case, elements_per_link=0, h=1e-3)
    with pytest.raises(dttmm.InputError, match="h"):
        sg.simulate(case, elements_per_link=1, h=-1.0)
    with pytest.raises(dttmm.InputError, match="q"):
        sg.mass_matrix(case, 1, np.zeros(3))
    pd = Drive("torque", PD(1.0, 0.1, Constant(0.0)))
    closed = _case(arm(2), [pd, _torque_drives(1)[0]])
    with pytest.raises(dttmm.InputError, match=r"scenario\.drives\[0\]\.law.*closed-loop.*'rk4'"):
        sg.simulate(closed, elements_per_link=1, h=1e-3, integrator="rk4")
    with pytest.raises(dttmm.InputError, match="closed-loop"):
        n_dof = len(sg.coordinate_names(closed, 1))
        sg.accelerations(closed, 1, np.zeros(n_dof), np.zeros(n_dof))


# ----------------------------------------------------------------------------------------------
# The spatial DT-TMM against the global solver: the same discretisation, the same integrator
# ----------------------------------------------------------------------------------------------

import dttmm.spatial as _spatial  # noqa: E402

needs_kernel = pytest.mark.skipif(
    not hasattr(_spatial, "simulate"), reason="the spatial DT-TMM (dttmm.spatial.simulate) is not available"
)


def _variant(name, n):
    """Arms for the comparisons: the test arm with torque drives, and variants."""
    model = arm(n, EA=7e6)
    drives = _torque_drives(n)
    strain = "linear"
    if name == "motion":
        drives[0] = Drive("motion", dttmm.SpinUp(3.0, 0.1))
    elif name == "second-order":
        strain = "second-order"
        model = arm(n, EA=2e4, damping=1e-3)
    elif name == "damped":
        model = arm(n, EA=7e6, damping=2e-3)
    elif name == "inextensible":
        model = arm(n, EA=None)
    elif name == "bang-bang":
        drives[0] = Drive("torque", dttmm.BangBang((1.0, -0.8, 0.3), (0.0235, 0.0371)))
    elif name == "locked":
        links = list(model.links)
        links[1] = dataclasses.replace(links[1], joint=dataclasses.replace(links[1].joint, locked=True))
        model = dataclasses.replace(model, links=tuple(links))
        drives = _torque_drives(model.n_joints)
    return model, drives, strain


@needs_kernel
@pytest.mark.parametrize("n", [2, 3])
@pytest.mark.parametrize("name", ["torque", "motion", "second-order", "damped", "inextensible", "locked"])
def test_dttmm_accelerations_equal_global(name, n):
    """q̈ of the DT-TMM forward dynamics at random states equals the global solver's,
    relative to max|q̈|, to 1e-10 (k = 2 and 4)."""
    model, drives, strain = _variant(name, n)
    case = _case(model, drives)
    worst = 0.0
    for k in (2, 4):
        names = sg.coordinate_names(case, k)
        a = [i for i, c in enumerate(names) if c.startswith("alpha")]
        for seed in range(3):
            q, qd = _random_state(case, k, seed)
            t = 0.037
            for j, d in enumerate(drives):  # the motion laws' values at t
                if d.kind == "motion":
                    q[a[j]], qd[a[j]] = d.motion(t)[:2]
            ref = sg.accelerations(case, k, q, qd, t, strain=strain)
            got = _spatial.accelerations(case, k, q, qd, t, strain=strain)
            worst = max(worst, np.max(np.abs(got - ref)) / np.max(np.abs(ref)))
    assert worst < 1e-10, worst


@needs_kernel
@pytest.mark.parametrize(("n", "k", "duration"), [(2, 2, 0.2), (2, 4, 0.1), (3, 2, 0.2), (3, 4, 0.1)])
def test_dttmm_trajectory_equals_global(n, k, duration):
    """yaw + pitch (+ pitch) arm in gravity, payload with an offset and a full inertia tensor,
    hubs with full inertia, EIy ≠ EIz, rolled sections, a tilted base: the DT-TMM end-effector,
    link tips and joint angles equal the global solver's within 1e-9 m (rad) over the run
    (Newmark, h = 1e-3, both iterated to the default tolerance)."""
    case = _case(arm(n, EA=7e6), _torque_drives(n), duration=duration, output_step=1e-3)
    ref = sg.simulate(case, elements_per_link=k, h=1e-3)
    res = _spatial.simulate(case, elements_per_link=k, h=1e-3)
    assert ref.success and res.success
    assert np.max(np.abs(res.end_effector - ref.end_effector)) < 1e-9
    assert np.max(np.abs(res.link_tip - ref.link_tip)) < 1e-9
    assert np.max(np.abs(res.joint_angle - ref.joint_angle)) < 1e-9
    assert np.max(np.abs(res.tip_deflection - ref.tip_deflection)) < 1e-9
    assert np.max(np.abs(res.twist - ref.twist)) < 1e-9
    assert np.max(np.abs(res.energy - ref.energy)) < 1e-8 * np.max(np.abs(ref.energy))


@needs_kernel
@pytest.mark.parametrize(
    ("name", "integrator"),
    [
        ("motion", "newmark"),
        ("second-order", "newmark"),
        ("damped", "generalized-alpha"),
        ("locked", "newmark"),
        ("bang-bang", "newmark"),
        ("bang-bang", "rk4"),
        ("torque", "rk4"),
    ],
)
def test_dttmm_variants_equal_global(name, integrator):
    """Motion drive, second-order strain with damping, generalised-α with damping, a locked joint,
    torque jumps between grid points (steps end and restart there), RK4 (inextensible links:
    the explicit step needs no axial modes): the same end-effector within 1e-9 m over 0.05 s,
    k = 2, h = 1e-3 (RK4: 2e-4)."""
    model, drives, strain = _variant(name, 3)
    h = 1e-3
    if integrator == "rk4":
        model, h = arm(3, EA=None), 2e-4
    case = _case(model, drives, duration=0.05, output_step=1e-3)
    ref = sg.simulate(case, elements_per_link=2, h=h, integrator=integrator, strain=strain)
    res = _spatial.simulate(case, elements_per_link=2, h=h, integrator=integrator, strain=strain)
    assert ref.success and res.success
    assert np.max(np.abs(res.end_effector - ref.end_effector)) < 1e-9
    assert np.max(np.abs(res.joint_angle - ref.joint_angle)) < 1e-9
    assert np.max(np.abs(res.joint_torque - ref.joint_torque)) < 1e-8 * max(
        1.0, np.max(np.abs(ref.joint_torque))
    )


@needs_kernel
@pytest.mark.parametrize("name", ["torque", "motion", "locked"])
def test_dttmm_cut_loads_equal_global(name):
    """The DT-TMM's cut loads (every element root and link tip, force and moment about the cut,
    W components) equal the global solver's Newton–Euler loads of the outboard bodies, relative
    to their largest value, to 1e-9 on the output grid (3-joint arm, k = 2, 0.03 s)."""
    model, drives, strain = _variant(name, 3)
    case = _case(model, drives, duration=0.03, output_step=1e-3)
    ref = sg.simulate(case, elements_per_link=2, h=1e-3, cut_loads=True)
    res = _spatial.simulate(case, elements_per_link=2, h=1e-3, cut_loads=True)
    assert res.cut_loads.shape == ref.cut_loads.shape
    scale = np.max(np.abs(ref.cut_loads))
    assert np.max(np.abs(res.cut_loads - ref.cut_loads)) < 1e-9 * scale


@pytest.mark.parametrize("strain", ["linear", "second-order"])
def test_planar_embedding_spin_up(strain):
    """spin_up.toml (a motion-driven hub, the geometric stiffening of the second-order strain),
    k = 2, the first 0.5 s at h = 1e-2, tilted base: the joint torque, tip deflection and
    end-effector equal the planar global solver's to round-off."""
    pcase = dttmm.load_case(CASES / "spin_up.toml")
    pcase = dataclasses.replace(
        pcase, scenario=dataclasses.replace(pcase.scenario, duration=0.5, output_step=1e-2)
    )
    rpy = (0.2, 0.5, -0.4)
    scase = SpatialCase(embed_planar(pcase.model, base_rpy=rpy), pcase.scenario)
    ref = gn.simulate(pcase, elements_per_link=2, h=1e-2, engine="numpy", strain=strain)
    res = sg.simulate(scase, elements_per_link=2, h=1e-2, strain=strain)
    ee = res.end_effector @ mech.rpy_matrix(rpy)
    torque = np.max(np.abs(ref.joint_torque))
    assert np.max(np.abs(res.joint_torque - ref.joint_torque)) < 1e-10 * torque
    assert np.max(np.abs(res.tip_deflection[..., 0] - ref.tip_deflection)) < 1e-12
    assert np.max(np.abs(ee[:, :2] - ref.end_effector)) < 1e-12
    assert np.max(np.abs(ee[:, 2])) < 1e-12
