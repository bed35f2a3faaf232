"""Exudyn reference model with geometrically exact 2D beam elements (ObjectBeamGeometricallyExact2D).

Each link: k shear-deformable (Reissner) beam elements on k + 1 ``NodeRigidBody2D`` nodes
(reference coordinates [x, y, θ]); the hub and tip bodies sit directly on the first and last beam
node (no clamp constraints). Exudyn has no 2D Euler–Bernoulli beam; the Euler–Bernoulli links of
the suite are approached with the physical shear stiffness κGA = ``shear_ratio``·EA (default
0.32: κ = 5/6, ν = 0.3) and the rotary inertia per length ``cross_section_inertia``: a number
(kg·m), or ``"physical"`` for ρI = ρA·EI/EA of a homogeneous section (9e-8 kg·m for the
suite's 50 × 2 mm aluminium strips). The default is 1e-5 kg·m, about 100 times the physical
value, because the physical one is not robust: it runs on the suite's ``single_link`` and
``three_link`` cases (k = 1…64, h = 5e-4…4e-3, with one Jacobian per step), but Newton fails in
the first steps of a two-link arm with a step torque at h = 1e-3 (k = 2 and 4, also with 1e-6),
which runs with 1e-5 and at h = 5e-4. The report's studies use ``"physical"`` on their cases.
For inextensible links EA is the stiff value of
:func:`reference_models._exudyn2d.stiff_axial_stiffness`, and κGA and ρI follow from it.
Damping D = μK on all three strains: μ·EI, μ·EA, μ·κGA.
Everything else (joints, drives incl. closed-loop laws, solver): :mod:`reference_models._exudyn2d`.
"""

from __future__ import annotations

import math

from dttmm import InputError

from ._exudyn2d import simulate_exudyn
from ._exudyn_common import beam_elements, cable_properties

__all__ = ["simulate", "METHOD", "SHEAR_RATIO", "CROSS_SECTION_INERTIA", "rotary_inertia"]

METHOD = "exudyn-beam"
SHEAR_RATIO = 0.32
#: Default rotary inertia per length (kg·m); ``"physical"`` gives ρA·EI/EA (see :func:`rotary_inertia`).
CROSS_SECTION_INERTIA = 1.0e-5


def rotary_inertia(link, EA: float, cross_section_inertia=CROSS_SECTION_INERTIA) -> float:
    """Rotary inertia per length ρI (kg·m) of ``link``: ρA·EI/EA for ``"physical"`` (I/A = EI/EA
    for a homogeneous section), else the given number."""
    if cross_section_inertia == "physical":
        return link.beam.rhoA * link.beam.EI / EA
    return float(cross_section_inertia)


class _GE:
    method = METHOD

    @staticmethod
    def meta(case, k, axial, shear_ratio=SHEAR_RATIO, cross_section_inertia=CROSS_SECTION_INERTIA):
        return {
            "element": "ObjectBeamGeometricallyExact2D",
            "shear_ratio": shear_ratio,
            "shear_stiffness": [shear_ratio * ea for ea in axial],
            "cross_section_inertia_rule": str(cross_section_inertia),
            "cross_section_inertia": [
                rotary_inertia(link, ea, cross_section_inertia) for link, ea in zip(case.model.links, axial)
            ],
        }

    @staticmethod
    def add_link(
        mbs,
        exu,
        ii,
        link,
        layout,
        i,
        k,
        EA,
        shear_ratio=SHEAR_RATIO,
        cross_section_inertia=CROSS_SECTION_INERTIA,
    ):
        b = link.beam
        L = b.length
        GA = shear_ratio * EA
        nodes = [layout.rigid_node(mbs, ii, i, L * j / k) for j in range(k + 1)]
        elements = beam_elements(
            mbs,
            ii.ObjectBeamGeometricallyExact2D,
            nodes,
            **cable_properties(b, L / k, b.EI, EA),
            crossSectionInertia=rotary_inertia(link, EA, cross_section_inertia),
            shearStiffness=GA,
            shearDamping=b.damping * GA,
        )
        return nodes[0], nodes[-1], elements, None


def simulate(
    case,
    *,
    elements_per_link,
    h,
    rho_inf=0.8,
    shear_ratio=SHEAR_RATIO,
    cross_section_inertia=CROSS_SECTION_INERTIA,
    **options,
):
    """Simulate ``case`` with k = ``elements_per_link`` geometrically exact beam elements per link.

    Options: ``rho_inf`` (generalized-α spectral radius, 0.8), ``shear_ratio`` (κGA/EA, 0.32),
    ``cross_section_inertia`` (ρI in kg·m, or ``"physical"``: ρA·EI/EA per link), and the common
    ones of :func:`reference_models._exudyn2d.simulate_exudyn`: ``newton_rel_tol`` (1e-8),
    ``newton_abs_tol`` (None: scaled to the problem), ``newton_max_iterations`` (25),
    ``modified_newton`` (True), ``jacobian_per_step`` (True), ``drive_input``
    ("pre-step" or "user-function"), ``inextensible_axial_ratio`` (1e6).
    Returns a :class:`dttmm.Result` (meta["method"] = "exudyn-beam"); raises
    :class:`dttmm.InputError` on bad input and :class:`dttmm.SimulationError` on any failure.
    """
    checks = (("shear_ratio", shear_ratio),) + (
        (("cross_section_inertia", cross_section_inertia),) if cross_section_inertia != "physical" else ()
    )
    for name, val in checks:
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not (math.isfinite(val) and val > 0):
            raise InputError(name, val, "must be a positive number")
    return simulate_exudyn(
        case,
        element=_GE,
        elements_per_link=elements_per_link,
        h=h,
        rho_inf=rho_inf,
        element_options={
            "shear_ratio": float(shear_ratio),
            "cross_section_inertia": (
                cross_section_inertia if cross_section_inertia == "physical" else float(cross_section_inertia)
            ),
        },
        **options,
    )
