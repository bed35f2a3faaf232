"""The beam element: its mass matrix at rest is the consistent Hermite mass; SPD in general."""

import numpy as np
import pytest

from dttmm.element import element_terms, element_type


def hermite_mass(rhoA, l):
    """Consistent mass of the 2-node Euler-Bernoulli bar/beam, dofs (u1, v1, φ1, u2, v2, φ2)
    (textbook closed form)."""
    M = np.zeros((6, 6))
    M[np.ix_([0, 3], [0, 3])] = rhoA * l / 6 * np.array([[2, 1], [1, 2]])
    b = (
        rhoA
        * l
        / 420
        * np.array(
            [
                [156, 22 * l, 54, -13 * l],
                [22 * l, 4 * l * l, 13 * l, -3 * l * l],
                [54, 13 * l, 156, -22 * l],
                [-13 * l, -3 * l * l, -22 * l, 4 * l * l],
            ]
        )
    )
    M[np.ix_([1, 2, 4, 5], [1, 2, 4, 5])] = b
    return M


def element_mass(et, theta=0.0, e=None):
    e = np.zeros((1, et.ne)) if e is None else e[None, :]
    M_aa, M_ae, *_ = element_terms(et, np.array([theta]), np.zeros(1), e, np.zeros_like(e), np.zeros(2))
    ne = et.ne
    M = np.zeros((3 + ne, 3 + ne))
    M[:3, :3], M[:3, 3:], M[3:, :3], M[3:, 3:] = M_aa[0], M_ae[0], M_ae[0].T, et.C_SS
    return M


@pytest.mark.parametrize("l", [0.05, 0.5, 1.3])
def test_mass_at_rest_is_consistent_hermite_mass(l):
    rhoA = 0.27
    et = element_type(l, 2.0, rhoA, 7e6, 0.0)
    # element coordinates p = (x_I, y_I, θ, u, v, φ) → nodal dofs at rest (small motion)
    T = np.array(
        [
            [1, 0, 0, 0, 0, 0],  # u1 = x_I
            [0, 1, 0, 0, 0, 0],  # v1 = y_I
            [0, 0, 1, 0, 0, 0],  # φ1 = θ
            [1, 0, 0, 1, 0, 0],  # u2 = x_I + u
            [0, 1, l, 0, 1, 0],  # v2 = y_I + lθ + v
            [0, 0, 1, 0, 0, 1],
        ]
    )  # φ2 = θ + φ
    expected = T.T @ hermite_mass(rhoA, l) @ T
    np.testing.assert_allclose(element_mass(et), expected, rtol=1e-13, atol=1e-15 * rhoA * l)


def test_inextensible_mass_is_bending_part():
    l, rhoA = 0.3, 1.2
    et = element_type(l, 2.0, rhoA, None, 0.0)
    T = np.array(
        [[1, 0, 0, 0, 0], [0, 1, 0, 0, 0], [0, 0, 1, 0, 0], [1, 0, 0, 0, 0], [0, 1, l, 1, 0], [0, 0, 1, 0, 1]]
    )
    np.testing.assert_allclose(element_mass(et), T.T @ hermite_mass(rhoA, l) @ T, rtol=1e-13, atol=1e-16)


def test_mass_spd_and_rotation_invariant_at_random_states():
    rng = np.random.default_rng(1)
    et = element_type(0.25, 2.3, 0.27, 7e6, 0.0)
    for _ in range(20):
        e = rng.normal(size=3) * np.array([0.01, 0.05, 0.3])
        th = rng.uniform(-np.pi, np.pi)
        M = element_mass(et, th, e)
        np.testing.assert_allclose(M, M.T, atol=1e-15)
        assert np.linalg.eigvalsh(M).min() > 0
        # kinetic energy is frame invariant: rotating the frame rotates the (r_I) rows only
        M0 = element_mass(et, 0.0, e)
        c, s = np.cos(th), np.sin(th)
        Rb = np.eye(6)
        Rb[:2, :2] = [[c, -s], [s, c]]
        np.testing.assert_allclose(Rb.T @ M @ Rb, M0, atol=1e-14)


def test_stiffness_is_cantilever_stiffness():
    """Statics of one element: K (v, φ) under a tip force F gives FL³/3EI and FL²/2EI."""
    EI, L, F = 3.0, 0.7, 2.0
    et = element_type(L, EI, 1.0, None, 0.0)
    v, phi = np.linalg.solve(et.K, [F, 0.0])
    assert v == pytest.approx(F * L**3 / (3 * EI), rel=1e-13)
    assert phi == pytest.approx(F * L**2 / (2 * EI), rel=1e-13)
