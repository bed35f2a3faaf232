"""Mechanics of the spatial global-equation solver as functions of plain arrays.

SO(3) maps (exact exponential, left Jacobian, logarithm), the element shape matrices of
docs/spatial.md §2 and the element strain energy. Every map that the velocity terms
differentiate (:func:`exp_so3`, :func:`left_jacobian`, :func:`skew`, :func:`rot_axis`) is
written with analytic operations only (θ² = ψ·ψ without a complex conjugate, the even
functions of θ as functions of θ²), so that a complex argument q + iε q̇ gives the exact
directional derivative in its imaginary part (complex-step differentiation).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "GAUSS_POINTS",
    "GAUSS_WEIGHTS",
    "element_stiffness",
    "exp_so3",
    "left_jacobian",
    "log_so3",
    "rot_axis",
    "rpy_matrix",
    "section_rotation",
    "shape_matrices",
    "skew",
    "strain_terms",
]

_N_GAUSS = 4
_xg, _wg = np.polynomial.legendre.leggauss(_N_GAUSS)
#: 4-point Gauss–Legendre abscissae and weights on ξ ∈ [0, 1]
GAUSS_POINTS = 0.5 * (_xg + 1.0)
GAUSS_WEIGHTS = 0.5 * _wg

_SMALL = 1e-6  # |θ²| below which the Taylor series are used (truncation error < 1e-25)


def skew(v: np.ndarray) -> np.ndarray:
    """[v]× (..., 3, 3) of vectors v (..., 3): [v]× x = v × x."""
    v = np.asarray(v)
    out = np.zeros(v.shape + (3,), dtype=v.dtype)
    out[..., 0, 1] = -v[..., 2]
    out[..., 0, 2] = v[..., 1]
    out[..., 1, 0] = v[..., 2]
    out[..., 1, 2] = -v[..., 0]
    out[..., 2, 0] = -v[..., 1]
    out[..., 2, 1] = v[..., 0]
    return out


def _even_functions(t: np.ndarray):
    """sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³ as analytic functions of t = θ² (..., )."""
    t = np.asarray(t)
    small = np.abs(t) < _SMALL
    ts = np.where(small, 1.0, t)
    th = np.sqrt(ts + 0j) if np.iscomplexobj(t) else np.sqrt(ts)
    a = np.sin(th) / th
    b = (1.0 - np.cos(th)) / ts
    c = (th - np.sin(th)) / (ts * th)
    a_s = 1.0 - t / 6.0 + t * t / 120.0 - t**3 / 5040.0
    b_s = 0.5 - t / 24.0 + t * t / 720.0 - t**3 / 40320.0
    c_s = 1.0 / 6.0 - t / 120.0 + t * t / 5040.0 - t**3 / 362880.0
    return np.where(small, a_s, a), np.where(small, b_s, b), np.where(small, c_s, c)


def _quadratic(psi: np.ndarray, first: int) -> np.ndarray:
    """I + x[ψ]× + y[ψ]×² (..., 3, 3), with (x, y) two consecutive of :func:`_even_functions`'
    (a, b, c) at θ² = |ψ|², from index ``first``."""
    psi = np.asarray(psi)
    t = np.sum(psi * psi, axis=-1)
    x, y = _even_functions(t)[first : first + 2]
    K = skew(psi)
    return np.eye(3) + x[..., None, None] * K + y[..., None, None] * (K @ K)


def exp_so3(psi: np.ndarray) -> np.ndarray:
    """exp([ψ]×) (..., 3, 3) by Rodrigues' formula: I + (sin θ/θ)[ψ]× + ((1 − cos θ)/θ²)[ψ]×²."""
    return _quadratic(psi, 0)


def left_jacobian(psi: np.ndarray) -> np.ndarray:
    """J_L(ψ) = I + ((1 − cos θ)/θ²)[ψ]× + ((θ − sin θ)/θ³)[ψ]×² (..., 3, 3): the spatial
    angular velocity of exp([ψ]×) is J_L(ψ) ψ̇."""
    return _quadratic(psi, 1)


def log_so3(R: np.ndarray) -> np.ndarray:
    """The rotation vector ψ (..., 3) with exp([ψ]×) = R, |ψ| ≤ π (real R only)."""
    R = np.asarray(R, float)
    w = 0.5 * np.stack(
        [R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1
    )
    cos = np.clip(0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0), -1.0, 1.0)
    sin = np.linalg.norm(w, axis=-1)
    th = np.arctan2(sin, cos)
    small = sin < 1e-8
    fac = np.where(small, 1.0 + th * th / 6.0, th / np.where(small, 1.0, sin))
    out = fac[..., None] * w
    near_pi = small & (cos < 0)
    if np.any(near_pi):  # θ ≈ π: the axis from the symmetric part
        for idx in zip(*np.nonzero(np.atleast_1d(near_pi))):
            Ri = R[idx] if R.ndim > 2 else R
            B = 0.5 * (Ri + np.eye(3))
            j = int(np.argmax(np.diag(B)))
            axis = B[:, j] / np.sqrt(B[j, j])
            val = th[idx] * axis if R.ndim > 2 else th * axis
            if R.ndim > 2:
                out[idx] = val
            else:
                out = val
    return out


def rot_axis(axis: np.ndarray, angle) -> np.ndarray:
    """Rot(a, α) = exp(α[a]×) (3, 3) for a unit axis a (analytic in α)."""
    a = np.asarray(axis, float)
    K = skew(a)
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def rpy_matrix(rpy) -> np.ndarray:
    """R_rpy = Rz(y) · Ry(p) · Rx(r) (URDF convention)."""
    r, p, y = (float(x) for x in rpy)
    return rot_axis((0, 0, 1), y) @ rot_axis((0, 1, 0), p) @ rot_axis((1, 0, 0), r)


def shape_matrices(length: float, xi: np.ndarray = GAUSS_POINTS):
    """Element shape matrices at the material points ξ (ng,), on e = (u, v, w, φx, φy, φz):

    s0 (ng, 3), S (ng, 3, 6) with s(ξ) = s0 + S e = (x + ξu, N3 v + N4 φz, N3 w − N4 φy),
    x = ξl, N3 = 3ξ² − 2ξ³, N4 = l(ξ³ − ξ²); and P (ng, 3, 6) with the section rotation
    vector ψ(ξ) = P e = (ξ φx, −∂s_z/∂x, ∂s_y/∂x).
    """
    xi = np.atleast_1d(np.asarray(xi, float))
    l = float(length)
    n3 = 3 * xi**2 - 2 * xi**3
    n4 = l * (xi**3 - xi**2)
    d3 = 6 * (xi - xi**2) / l if l > 0 else np.zeros_like(xi)  # dN3/dx (l = 0: a rigid link)
    d4 = 3 * xi**2 - 2 * xi  # dN4/dx
    s0 = np.zeros((xi.size, 3))
    s0[:, 0] = xi * l
    S = np.zeros((xi.size, 3, 6))
    S[:, 0, 0] = xi
    S[:, 1, 1] = n3
    S[:, 1, 5] = n4
    S[:, 2, 2] = n3
    S[:, 2, 4] = -n4
    P = np.zeros((xi.size, 3, 6))
    P[:, 0, 3] = xi
    P[:, 1, 2] = -d3
    P[:, 1, 4] = d4
    P[:, 2, 1] = d3
    P[:, 2, 5] = d4
    return s0, S, P


def section_rotation(RI: np.ndarray, e: np.ndarray, length: float, xi) -> tuple[np.ndarray, np.ndarray]:
    """Position offset R_I s(ξ) and rotation R_s(ξ) = R_I exp([ψ(ξ)]×) of the sections at ξ
    of one element with inboard rotation R_I and coordinates e (6,); returns (ng, 3), (ng, 3, 3)."""
    s0, S, P = shape_matrices(length, xi)
    s = s0 + S @ e
    return s @ RI.T, RI @ exp_so3(P @ e)


def element_stiffness(length, EA, GJ, EIy, EIz) -> np.ndarray:
    """Linear-strain stiffness (6, 6) on e = (u, v, w, φx, φy, φz); EA None or 0: no axial term."""
    l = float(length)
    K = np.zeros((6, 6))
    K[0, 0] = 0.0 if EA is None else EA / l
    K[3, 3] = GJ / l
    cz, cy = EIz / l**3, EIy / l**3
    vz = [1, 5]  # (v, φz)
    K[np.ix_(vz, vz)] = cz * np.array([[12.0, -6 * l], [-6 * l, 4 * l * l]])
    wy = [2, 4]  # (w, φy)
    K[np.ix_(wy, wy)] = cy * np.array([[12.0, 6 * l], [6 * l, 4 * l * l]])
    return K


def _chord(length: float) -> np.ndarray:
    """G = ∫₀¹ N'ᵀN' dξ on (v, φz), N' = (dN3/dx, dN4/dx)."""
    l = float(length)
    return np.array([[6.0 / (5.0 * l * l), -1.0 / (10.0 * l)], [-1.0 / (10.0 * l), 2.0 / 15.0]])


def strain_terms(length, EA, e: np.ndarray, second_order: bool):
    """Axial strain ε, its gradient ∇ε (6,) and Hessian ∇²ε (6, 6) on e.

    ε = u/l (+ ½ (bᵀGb + cᵀGc) at second order), b = (v, φz), c = (w, −φy).
    """
    l = float(length)
    grad = np.zeros(6)
    hess = np.zeros((6, 6))
    grad[0] = 1.0 / l
    eps = e[0] / l
    if second_order and EA is not None:
        G = _chord(l)
        b = np.array([e[1], e[5]])
        c = np.array([e[2], -e[4]])
        Gb, Gc = G @ b, G @ c
        eps = eps + 0.5 * (b @ Gb + c @ Gc)
        grad[1], grad[5] = Gb
        grad[2], grad[4] = Gc[0], -Gc[1]
        hess[np.ix_([1, 5], [1, 5])] = G
        T = np.diag([1.0, -1.0])
        hess[np.ix_([2, 4], [2, 4])] = T @ G @ T
    return eps, grad, hess
