"""One spatial element in numpy (docs/spatial.md §2): the 4-point Gauss bodies of its kinetic
energy and its mass matrix — the readable statement of the element that the kernel's sweep
(:mod:`dttmm.spatial.kernel.core`) accumulates body by body.

An element's kinetic energy is T = ½ yᵀ M(e) y with y = (v, ω, ė): v, ω the velocity of its
frame's origin and its angular velocity (frame components), ė (6,) the padded elastic rates.
"""

from __future__ import annotations

import numpy as np

from .build import gauss_points, shape_tables, stiffness
from .model import SpatialSection
from .rotation import exp_so3, hat, left_jacobian

__all__ = ["element_bodies", "element_mass", "element_stiffness"]


def element_bodies(beam: SpatialSection, l: float, e):
    """Per Gauss point g: (mass, inertia (3, 3) in frame components, X_g (6, 12)) with the body's
    twist (v_g, ω_g) = X_g y at its centre r(ξ_g)."""
    xi, w = gauss_points()
    s0, sig, psi = shape_tables(l, beam.EA is not None, xi)
    e = np.asarray(e, float)
    out = []
    for g in range(4):
        s = s0[g] + sig[g] @ e
        p = psi[g] @ e
        E = exp_so3(p)
        X = np.zeros((6, 12))
        X[:3, :3] = np.eye(3)
        X[:3, 3:6] = -hat(s)
        X[:3, 6:] = sig[g]
        X[3:, 3:6] = np.eye(3)
        X[3:, 6:] = left_jacobian(p) @ psi[g]
        J = E @ np.diag(w[g] * l * np.array([beam.rhoJ, beam.rhoIy, beam.rhoIz])) @ E.T
        out.append((w[g] * beam.rhoA * l, J, X))
    return out


def element_mass(beam: SpatialSection, l: float, e) -> np.ndarray:
    """The element's mass matrix M(e) (12, 12) over y = (v, ω, ė) (inextensible: the u column
    and row are zero)."""
    M = np.zeros((12, 12))
    for m, J, X in element_bodies(beam, l, e):
        Mb = np.zeros((6, 6))
        Mb[:3, :3] = m * np.eye(3)
        Mb[3:, 3:] = J
        M += X.T @ Mb @ X
    return M


def element_stiffness(beam: SpatialSection, l: float) -> np.ndarray:
    """The padded 6×6 linear stiffness (docs/spatial.md §2)."""
    return stiffness(beam, l)
