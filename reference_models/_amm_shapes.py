"""Assumed mode shapes of one link and the modal integrals of the assumed modes method.

The shapes are the lowest eigenvectors of the link's own beam eigenproblem, clamped at the
root, solved on a fine mesh of cubic Hermite beam elements (``N_ELEMENTS``, at least 20 per
mode). The tip boundary is either free (``"clamped-free"``) or loaded by the rigid inertia of
everything outboard of the link (``"clamped-mass"``): a point mass M_o on the tip deflection and
a rotary inertia J_o (about the tip) on the tip slope, with the static moment of the outboard
arm left out — the convention of De Luca & Siciliano (1991), whose quoted frequencies it
reproduces.

A shape is then a piecewise cubic; every modal integral is a polynomial integral on each mesh
element, computed exactly by 5-point Gauss quadrature (exact to degree 9). Shapes are scaled
so that ∫ρA φ_j² dx equals the link mass.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import numpy as np
import scipy.linalg

__all__ = ["BOUNDARIES", "LinkModes", "N_ELEMENTS", "link_modes", "outboard_inertia"]

BOUNDARIES = ("clamped-mass", "clamped-free")
N_ELEMENTS = 200  # mesh of the link eigenproblem (≥ 20 elements per mode are used)

_GX, _GW = np.polynomial.legendre.leggauss(5)
_GX, _GW = 0.5 * (_GX + 1.0), 0.5 * _GW  # on [0, 1]


class LinkModes(NamedTuple):
    """Assumed modes of one link (N modes) and their integrals (SI units).

    Attributes
    ----------
    freq : (N,) Hz, eigenfrequencies of the link eigenproblem with its tip inertia
    M : (N, N) kg, ∫ρA φφᵀ dx (link only) · K : (N, N) N/m, ∫EI φ''φ''ᵀ dx
    c : (N,) kg, ∫ρA φ dx · d : (N,) kg·m, ∫ρA x φ dx
    phi_L, dphi_L : (N,) shape and slope at the tip (1, 1/m) · ddphi_0 : (N,) curvature at the root (1/m²)
    G_L : (N, N) 1/m, ∫₀ᴸ φ'φ'ᵀ dx (foreshortening of the tip: u_L = −½ δᵀG_L δ)
    H : (N, N) kg/m, ∫ρA G(x) dx = ∫ρA (L − s) φ'φ'ᵀ ds (first moment of the foreshortening)
    P : (N, N) kg, ∫ρA x G(x) dx = ∫ ρA (L² − s²)/2 φ'φ'ᵀ ds (its second moment)
    x, shape : (p,) m and (N, p), the shapes at the mesh nodes (for drawing)
    """

    freq: np.ndarray
    M: np.ndarray
    K: np.ndarray
    c: np.ndarray
    d: np.ndarray
    phi_L: np.ndarray
    dphi_L: np.ndarray
    ddphi_0: np.ndarray
    G_L: np.ndarray
    H: np.ndarray
    P: np.ndarray
    x: np.ndarray
    shape: np.ndarray


def outboard_inertia(manipulator, i: int) -> tuple[float, float]:
    """Mass (kg) and inertia about the tip of link i (kg·m²) of everything outboard of that tip
    (its payload, every later hub, link and payload), the arm straight (outboard joints at 0)."""
    links = manipulator.links
    mass = links[i].payload_mass
    inertia = links[i].payload_inertia
    r = 0.0  # distance from link i's tip along the straight arm
    for lk in links[i + 1 :]:
        L, m = lk.beam.length, lk.beam.mass
        mass += lk.hub_mass + m + lk.payload_mass
        inertia += lk.hub_inertia + lk.hub_mass * r * r
        inertia += m * (L * L / 12.0 + (r + L / 2.0) ** 2)
        r += L
        inertia += lk.payload_inertia + lk.payload_mass * r * r
    return float(mass), float(inertia)


def _hermite(xi, le):
    """Cubic Hermite shape functions on [0, 1] for DOFs (w_a, w'_a, w_b, w'_b) and their
    first and second x-derivatives, each (4, len(xi))."""
    n = np.array(
        [
            1 - 3 * xi**2 + 2 * xi**3,
            le * (xi - 2 * xi**2 + xi**3),
            3 * xi**2 - 2 * xi**3,
            le * (xi**3 - xi**2),
        ]
    )
    d1 = (
        np.array(
            [
                -6 * xi + 6 * xi**2,
                le * (1 - 4 * xi + 3 * xi**2),
                6 * xi - 6 * xi**2,
                le * (3 * xi**2 - 2 * xi),
            ]
        )
        / le
    )
    d2 = np.array([-6 + 12 * xi, le * (-4 + 6 * xi), 6 - 12 * xi, le * (6 * xi - 2)]) / le**2
    return n, d1, d2


def _assemble(L, EI, rhoA, ne):
    le = L / ne
    k = EI / le**3 * np.array(
        [[12, 6 * le, -12, 6 * le], [6 * le, 4 * le**2, -6 * le, 2 * le**2],
         [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le**2, -6 * le, 4 * le**2]]
    )  # fmt: skip
    m = rhoA * le / 420.0 * np.array(
        [[156, 22 * le, 54, -13 * le], [22 * le, 4 * le**2, 13 * le, -3 * le**2],
         [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le**2, -22 * le, 4 * le**2]]
    )  # fmt: skip
    nd = 2 * (ne + 1)
    K, M = np.zeros((nd, nd)), np.zeros((nd, nd))
    for e in range(ne):
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += k
        M[s, s] += m
    return K[2:, 2:], M[2:, 2:], le  # root clamped: w(0) = w'(0) = 0


def link_modes(beam, n_modes: int, tip_mass: float = 0.0, tip_inertia: float = 0.0) -> LinkModes:
    """The ``n_modes`` lowest clamped-root modes of a uniform beam with a tip mass and inertia
    (cached: a repeated call with the same data returns the same arrays).

    Parameters
    ----------
    beam : dttmm.Section
        Length L (m), EI (N·m²), ρA (kg/m).
    n_modes : int
        N ≥ 1.
    tip_mass, tip_inertia : float
        Rigid inertia at the tip (kg, kg·m² about the tip); 0 for a free tip.

    Returns
    -------
    LinkModes
    """
    return _link_modes(beam.length, beam.EI, beam.rhoA, int(n_modes), float(tip_mass), float(tip_inertia))


@functools.lru_cache(maxsize=256)
def _link_modes(L, EI, rhoA, n_modes, tip_mass, tip_inertia) -> LinkModes:
    """Uncached :func:`link_modes` on plain numbers."""
    ne = max(N_ELEMENTS, 20 * n_modes)
    K, M_link, le = _assemble(L, EI, rhoA, ne)
    M = M_link.copy()
    M[-2, -2] += tip_mass
    M[-1, -1] += tip_inertia
    # flexibility form M φ = (1/ω²) K φ: the lowest ω² are the largest 1/ω², to full accuracy
    # (K φ = ω² M φ loses digits of the lowest ω² as the mesh is refined: λ_max/λ_min ~ ne⁴)
    nd = K.shape[0]
    mu, vec = scipy.linalg.eigh(M, K, subset_by_index=[nd - n_modes, nd - 1])
    vec = vec[:, ::-1]
    lam = np.einsum("ij,ik,kj->j", vec, K, vec) / np.einsum("ij,ik,kj->j", vec, M, vec)
    full = np.zeros((2 * (ne + 1), n_modes))
    full[2:] = vec
    # scale: ∫ρA φ_j² = link mass, sign: positive tip deflection (positive tip slope if it is 0)
    mj = np.einsum("ij,ik,kj->j", vec, M_link, vec)
    full *= np.sqrt(rhoA * L / mj)
    sgn = np.where(np.abs(full[-2]) > 1e-9 * np.abs(full[-2]).max(), np.sign(full[-2]), np.sign(full[-1]))
    full *= sgn
    vec = full[2:]

    n, d1, d2 = _hermite(_GX, le)
    c = np.zeros(n_modes)
    d = np.zeros(n_modes)
    H = np.zeros((n_modes, n_modes))
    P = np.zeros((n_modes, n_modes))
    G = np.zeros((n_modes, n_modes))
    for e in range(ne):
        ue = full[2 * e : 2 * e + 4]  # (4, N)
        x = (e + _GX) * le
        w = _GW * le
        ph, dph = n.T @ ue, d1.T @ ue  # (5, N)
        c += rhoA * (w @ ph)
        d += rhoA * ((w * x) @ ph)
        G += dph.T @ (w[:, None] * dph)
        H += dph.T @ ((w * rhoA * (L - x))[:, None] * dph)
        P += dph.T @ ((w * rhoA * 0.5 * (L * L - x * x))[:, None] * dph)
    ddphi0 = (d2[:, :1].T @ full[0:4])[0]
    sym = lambda a: 0.5 * (a + a.T)
    return LinkModes(
        freq=np.sqrt(np.maximum(lam, 0.0)) / (2 * np.pi),
        M=sym(vec.T @ M_link @ vec),
        K=sym(vec.T @ K @ vec),
        c=c,
        d=d,
        phi_L=full[-2].copy(),
        dphi_L=full[-1].copy(),
        ddphi_0=ddphi0,
        G_L=sym(G),
        H=sym(H),
        P=sym(P),
        x=np.linspace(0.0, L, ne + 1),
        shape=full[0::2].T.copy(),
    )
