"""Exudyn reference model with geometrically exact 2D beam elements (ObjectBeamGeometricallyExact2D).

Each link: k shear-deformable (Reissner) beam elements on k + 1 ``NodeRigidBody2D`` nodes
(reference coordinates [x, y, θ]); the hub and tip bodies sit directly on the first and last beam
node (no clamp constraints). Exudyn has no 2D Euler–Bernoulli beam; the Euler–Bernoulli links of
the suite are approached with the physical shear stiffness κGA = ``shear_ratio``·EA (default
0.32: κ = 5/6, ν = 0.3) and a small rotary inertia per length ``cross_section_inertia`` (default
1e-5 kg·m, floor for stability of thin strips — the physical ρI of the suite's strips, ~1e-7,
makes multi-link runs unstable). For inextensible links EA is the stiff value of
:func:`reference_models._exudyn_common.stiff_axial_stiffness` and κGA follows from it.
Damping D = μK on all three strains: μ·EI, μ·EA, μ·κGA.
Everything else: :mod:`reference_models._exudyn_common`.
"""
from __future__ import annotations

import math

from dttmm import InputError

from ._exudyn_common import simulate_exudyn

__all__ = ["simulate", "METHOD", "SHEAR_RATIO", "CROSS_SECTION_INERTIA"]

METHOD = "exudyn-beam"
SHEAR_RATIO = 0.32
CROSS_SECTION_INERTIA = 1.0e-5


class _GE:
    method = METHOD

    @staticmethod
    def meta(case, k, axial, shear_ratio=SHEAR_RATIO, cross_section_inertia=CROSS_SECTION_INERTIA):
        return {"element": "ObjectBeamGeometricallyExact2D", "shear_ratio": shear_ratio,
                "shear_stiffness": [shear_ratio * ea for ea in axial],
                "cross_section_inertia": cross_section_inertia}

    @staticmethod
    def add_link(mbs, exu, ii, link, layout, i, k, EA, shear_ratio=SHEAR_RATIO,
                 cross_section_inertia=CROSS_SECTION_INERTIA):
        b = link.beam
        L, th, om = b.length, layout.theta[i], layout.omega[i]
        GA = shear_ratio * EA
        nodes = []
        for j in range(k + 1):
            p = layout.point(i, L * j / k)
            v = layout.velocity(i, L * j / k)
            nodes.append(mbs.AddNode(ii.NodeRigidBody2D(referenceCoordinates=[p[0], p[1], th],
                                                        initialVelocities=[v[0], v[1], om])))
        elements = [mbs.AddObject(ii.ObjectBeamGeometricallyExact2D(
            nodeNumbers=[nodes[j], nodes[j + 1]], length=L / k, massPerLength=b.rhoA,
            crossSectionInertia=cross_section_inertia, bendingStiffness=b.EI, axialStiffness=EA,
            shearStiffness=GA, bendingDamping=b.damping * b.EI, axialDamping=b.damping * EA,
            shearDamping=b.damping * GA)) for j in range(k)]
        return nodes[0], nodes[-1], elements, None


def simulate(case, *, elements_per_link, h, rho_inf=0.8, shear_ratio=SHEAR_RATIO,
             cross_section_inertia=CROSS_SECTION_INERTIA, **options):
    """Simulate ``case`` with k = ``elements_per_link`` geometrically exact beam elements per link.

    Options: ``rho_inf`` (generalized-α spectral radius, 0.8), ``shear_ratio`` (κGA/EA, 0.32),
    ``cross_section_inertia`` (ρI, kg·m, 1e-5), and the common ones of
    :func:`reference_models._exudyn_common.simulate_exudyn`: ``newton_rel_tol`` (1e-8),
    ``newton_abs_tol`` (None: scaled to the problem), ``newton_max_iterations`` (25),
    ``modified_newton`` (True), ``inextensible_axial_ratio`` (1e6).
    Returns a :class:`dttmm.Result` (meta["method"] = "exudyn-beam"); raises
    :class:`dttmm.InputError` on bad input and :class:`dttmm.SimulationError` on any failure.
    """
    for name, val in (("shear_ratio", shear_ratio), ("cross_section_inertia", cross_section_inertia)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not (math.isfinite(val) and val > 0):
            raise InputError(name, val, "must be a positive number")
    return simulate_exudyn(case, element=_GE, elements_per_link=elements_per_link, h=h, rho_inf=rho_inf,
                           element_options={"shear_ratio": float(shear_ratio),
                                            "cross_section_inertia": float(cross_section_inertia)},
                           **options)
