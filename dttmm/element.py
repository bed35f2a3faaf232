"""One beam element in its corotational floating frame.

Frame origin at the inboard node I, frame angle θ = cross-section angle at I. Elastic
coordinates of the outboard node in the frame: e = (u, v, φ) (extensible) or (v, φ)
(inextensible). A material point at ξ ∈ [0, 1], x = ξl, sits at the local position

    s(ξ, e) = s0(ξ) + S(ξ) e,   s0 = (x, 0),
    S = [[ξ, 0, 0], [0, N3, N4]]  (u, v, φ)   or  [[0, 0], [N3, N4]]  (v, φ),
    N3 = 3ξ² − 2ξ³,  N4 = l(ξ³ − ξ²),

and globally at r = r_I + A(θ) s. Every mass and velocity term is a polynomial moment of
s0 and S over the element; they are integrated once, exactly, by 4-point Gauss quadrature
(degree ≤ 6 integrands) and kept as constants of the element type.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["E2", "ElementType", "element_type"]

E2 = np.array([[0.0, -1.0], [1.0, 0.0]])  # rotation by +90°: d A(θ)/dθ = E A(θ)


def shape(xi: np.ndarray, l: float, extensible: bool):
    """s0 (m, 2) and S (m, 2, ne) at the points ξ (m,)."""
    xi = np.asarray(xi, float)
    n3 = 3 * xi**2 - 2 * xi**3
    n4 = l * (xi**3 - xi**2)
    s0 = np.stack([xi * l, np.zeros_like(xi)], axis=-1)
    z = np.zeros_like(xi)
    if extensible:
        S = np.stack([np.stack([xi, z, z], -1), np.stack([z, n3, n4], -1)], axis=-2)
    else:
        S = np.stack([np.stack([z, z], -1), np.stack([n3, n4], -1)], axis=-2)
    return s0, S


@dataclass(frozen=True)
class ElementType:
    """Constant moments of one element (all integrals ∫ … ρA dx over the element).

    m : mass ρA·l
    c_s0 (2,) = ∫ s0, C_S (2, ne) = ∫ S, c_s0s0 = ∫ s0·s0, c_s0S (ne,) = ∫ s0ᵀS,
    d1 (ne,) = ∫ s0ᵀEᵀS, D2 (ne, ne) = ∫ SᵀEᵀS, C_SS (ne, ne) = ∫ SᵀS (the elastic mass),
    C_SES (ne, ne) = ∫ SᵀES; K, D the elastic stiffness and damping (ne, ne);
    sO0 (2,) = s0(1), SO (2, ne) = S(1); iphi, iu: indices of φ and u (iu = -1 if absent).
    """

    l: float
    ne: int
    m: float
    c_s0: np.ndarray
    C_S: np.ndarray
    c_s0s0: float
    c_s0S: np.ndarray
    d1: np.ndarray
    D2: np.ndarray
    C_SS: np.ndarray
    C_SES: np.ndarray
    K: np.ndarray
    D: np.ndarray
    sO0: np.ndarray
    SO: np.ndarray
    iphi: int
    iv: int
    iu: int
    EA: float = 0.0  # axial stiffness (0: inextensible)
    G: np.ndarray | None = None  # (2, 2) = ∫₀¹ N'ᵀN' dξ, N = (N3, N4), ' = d/dx
    second_order: bool = False  # axial strain ε = u/l + ½ wᵀGw (see elastic_forces)
    mu: float = 0.0  # Kelvin-Voigt coefficient μ (s): D = μK (see damping_tangent)


def element_type(
    length: float, EI: float, rhoA: float, EA: float | None, damping: float, strain: str = "linear"
) -> ElementType:
    """Moments, stiffness and damping of a uniform element of the given length.

    ``strain``: "linear" (axial strain u/l) or "second-order" (u/l + ½ wᵀGw, w = (v, φ): the
    shortening of the chord by bending; only for extensible elements)."""
    l = float(length)
    ext = EA is not None
    xg, wg = np.polynomial.legendre.leggauss(4)
    xi = 0.5 * (xg + 1.0)
    dm = 0.5 * wg * rhoA * l  # mass weights
    s0, S = shape(xi, l, ext)
    Es0 = s0 @ E2.T  # E s0
    ES = np.einsum("ij,mjk->mik", E2, S)
    c_s0 = dm @ s0
    C_S = np.einsum("m,mik->ik", dm, S)
    c_s0s0 = float(dm @ np.einsum("mi,mi->m", s0, s0))
    c_s0S = np.einsum("m,mi,mik->k", dm, s0, S)
    d1 = np.einsum("m,mi,mik->k", dm, Es0, S)  # (E s0)ᵀ S = s0ᵀ Eᵀ S
    D2 = np.einsum("m,mij,mik->jk", dm, ES, S)  # (E S)ᵀ S = Sᵀ Eᵀ S
    C_SS = np.einsum("m,mij,mik->jk", dm, S, S)
    C_SES = np.einsum("m,mij,mik->jk", dm, S, ES)
    kb = EI / l**3 * np.array([[12.0, -6.0 * l], [-6.0 * l, 4.0 * l * l]])
    if ext:
        K = np.zeros((3, 3))
        K[0, 0] = EA / l
        K[1:, 1:] = kb
    else:
        K = kb
    sO0, SO = shape(np.array([1.0]), l, ext)
    ne = 3 if ext else 2
    dN = np.stack([(6 * xi - 6 * xi**2) / l, 3 * xi**2 - 2 * xi], axis=-1)  # (N3', N4') at the points
    G = np.einsum("m,mi,mj->ij", 0.5 * wg, dN, dN)
    return ElementType(
        l=l,
        ne=ne,
        m=rhoA * l,
        c_s0=c_s0,
        C_S=C_S,
        c_s0s0=c_s0s0,
        c_s0S=c_s0S,
        d1=d1,
        D2=D2,
        C_SS=C_SS,
        C_SES=C_SES,
        K=K,
        D=damping * K,
        sO0=sO0[0],
        SO=SO[0],
        iphi=ne - 1,
        iv=ne - 2,
        iu=0 if ext else -1,
        EA=float(EA or 0.0),
        G=G,
        second_order=ext and strain == "second-order",
        mu=float(damping),
    )


def elastic_forces(et: ElementType, e: np.ndarray):
    """Elastic forces f(e) (k, ne) and their tangent K_T(e) (k, ne, ne) of a batch of elements.

    Strain energy U = ½ EA l ε² + ½ wᵀ K_b w, w = (v, φ), K_b = EI/l³ [[12, −6l], [−6l, 4l²]],
    with the axial strain ε = u/l (linear) or ε = u/l + ½ wᵀGw (second order: the element's
    mean axial strain including the chord's shortening by bending, G = ∫₀¹ N'ᵀN' dξ). Then
    f_u = EA ε, f_w = EA l ε G w + K_b w, and K_T = ∂f/∂e. The linear form is f = K e.
    """
    k = e.shape[0]
    if not et.second_order:
        return e @ et.K.T, np.broadcast_to(et.K, (k, et.ne, et.ne))
    EA, l, G = et.EA, et.l, et.G
    Kb = et.K[1:, 1:]
    w = e[:, 1:]
    Gw = w @ G.T
    eps = e[:, 0] / l + 0.5 * np.einsum("ki,ki->k", w, Gw)
    f = np.empty((k, 3))
    f[:, 0] = EA * eps
    f[:, 1:] = (EA * l * eps)[:, None] * Gw + w @ Kb.T
    KT = np.empty((k, 3, 3))
    KT[:, 0, 0] = EA / l
    KT[:, 0, 1:] = KT[:, 1:, 0] = EA * Gw
    KT[:, 1:, 1:] = EA * l * Gw[:, :, None] * Gw[:, None, :] + (EA * l * eps)[:, None, None] * G + Kb
    return f, KT


def damping_tangent(et: ElementType, e: np.ndarray) -> np.ndarray:
    """Kelvin-Voigt damping matrices D(e) (k, ne, ne) of a batch of elements: f_d = D(e) ė.

    The damping acts on the rate of the strain measure of :func:`elastic_forces`: dissipation
    R = ½ μ [EA l ε̇² + ẇᵀK_b ẇ]. Linear strain: ε̇ = u̇/l, D = μK. Second order:
    ε̇ = u̇/l + wᵀGẇ, so f_d,u = μ EA ε̇, f_d,w = μ (EA l ε̇ Gw + K_b ẇ), i.e.
    D(e) = μ [[EA/l, EA (Gw)ᵀ], [EA Gw, EA l (Gw)(Gw)ᵀ + K_b]] (= μ K_T(e) without its ε G
    term). f_d is linear in ė, so D(e) is also the exact rate tangent ∂f_d/∂ė; its dependence
    on e is taken at the iterate (frozen), like the global model's iteration matrix.
    """
    k = e.shape[0]
    if not et.second_order or et.mu == 0.0:
        return np.broadcast_to(et.D, (k, et.ne, et.ne))
    EA, l, mu = et.EA, et.l, et.mu
    Gw = e[:, 1:] @ et.G.T
    Dt = np.empty((k, 3, 3))
    Dt[:, 0, 0] = mu * EA / l
    Dt[:, 0, 1:] = Dt[:, 1:, 0] = mu * EA * Gw
    Dt[:, 1:, 1:] = mu * (EA * l * Gw[:, :, None] * Gw[:, None, :] + et.K[1:, 1:])
    return Dt


def strain_energy(et: ElementType, e: np.ndarray) -> float:
    """Σ U over a batch of elements (J), consistent with :func:`elastic_forces`."""
    if not et.second_order:
        return 0.5 * float(np.einsum("ki,ij,kj->", e, et.K, e))
    w = e[:, 1:]
    eps = e[:, 0] / et.l + 0.5 * np.einsum("ki,ij,kj->k", w, et.G, w)
    return float(0.5 * et.EA * et.l * np.sum(eps**2) + 0.5 * np.einsum("ki,ij,kj->", w, et.K[1:, 1:], w))


def rot(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices A(θ), shape (..., 2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def element_terms(et: ElementType, theta, thetad, e, ed, gravity):
    """Mass, velocity and gravity terms of a batch of elements of one type.

    Parameters
    ----------
    theta, thetad : (k,) frame angle and rate; e, ed : (k, ne) elastic coordinates and rates;
    gravity : (2,).

    Returns
    -------
    M_aa (k, 3, 3), M_ae (k, 3, ne), hbar_a (k, 3) = h_a − Q_a, hbar_e (k, ne) = h_e − Q_e,
    R (k, 2, 2). M_ee = et.C_SS is constant.
    """
    k = theta.shape[0]
    R = rot(theta)
    g = np.asarray(gravity, float)
    ms = et.c_s0 + e @ et.C_S.T  # ∫ s  (k, 2)
    Ems = ms @ E2.T
    REms = np.einsum("kij,kj->ki", R, Ems)  # R E ∫s
    M_aa = np.zeros((k, 3, 3))
    M_aa[:, 0, 0] = M_aa[:, 1, 1] = et.m
    M_aa[:, :2, 2] = REms
    M_aa[:, 2, :2] = REms
    M_aa[:, 2, 2] = et.c_s0s0 + 2 * e @ et.c_s0S + np.einsum("ki,ij,kj->k", e, et.C_SS, e)
    M_ae = np.empty((k, 3, et.ne))
    M_ae[:, :2, :] = R @ et.C_S
    M_ae[:, 2, :] = et.d1 + e @ et.D2
    # velocity terms ∫ Jᵀ γ, γ = −θ̇² A s + 2θ̇ A E S ė
    td = thetad[:, None]
    hr_loc = -(td**2) * ms + 2 * td * ((ed @ et.C_S.T) @ E2.T)
    hbar_a = np.empty((k, 3))
    hbar_a[:, :2] = np.einsum("kij,kj->ki", R, hr_loc) - et.m * g
    hbar_a[:, 2] = 2 * thetad * np.einsum("ki,ki->k", et.c_s0S + e @ et.C_SS, ed) - REms @ g
    Rtg = np.einsum("kji,j->ki", R, g)  # Aᵀ g
    hbar_e = -(td**2) * (et.c_s0S + e @ et.C_SS) + 2 * td * (ed @ et.C_SES.T) - Rtg @ et.C_S
    return M_aa, M_ae, hbar_a, hbar_e, R


def outboard_maps(et: ElementType, R, thetad, e, ed):
    """Outboard-node kinematics a_O = B_a a_I + B_e ë + γ̄_O (and v_O = B_a v_I + B_e ė).

    Returns B_a (k, 3, 3), B_e (k, 3, ne), gbar (k, 3), rso (k, 2) = A s_O.
    """
    k = R.shape[0]
    sO = et.sO0 + e @ et.SO.T  # (k, 2)
    rso = np.einsum("kij,kj->ki", R, sO)
    B_a = np.zeros((k, 3, 3))
    B_a[:, 0, 0] = B_a[:, 1, 1] = B_a[:, 2, 2] = 1.0
    B_a[:, 0, 2] = -rso[:, 1]
    B_a[:, 1, 2] = rso[:, 0]
    B_e = np.zeros((k, 3, et.ne))
    B_e[:, :2, :] = R @ et.SO
    B_e[:, 2, et.iphi] = 1.0
    td = thetad[:, None]
    gbar = np.zeros((k, 3))
    gbar[:, :2] = -(td**2) * rso + 2 * td * np.einsum("kij,kj->ki", R, (ed @ et.SO.T) @ E2.T)
    return B_a, B_e, gbar, rso
