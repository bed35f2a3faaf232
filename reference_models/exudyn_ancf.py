"""Exudyn reference model with ANCF cable elements (ObjectANCFCable2D).

Each link: k cable elements on k + 1 ``NodePoint2DSlope1`` nodes (reference coordinates
[x, y, cos θ, sin θ]); a hub and a tip ``NodeRigidBody2D`` at the link ends, each clamped to the
end node of the beam by an ``ObjectJointGeneric`` locking x, y and the rotation about z (the
orientation of a slope node is the angle of its slope vector). Everything else (joints, drives incl. closed-loop laws,
gravity, solver, outputs): :mod:`reference_models._exudyn2d`.

Options beyond the common ones: ``reduced_integration`` (bool, default False) switches the
element's ``useReducedOrderIntegration``.
"""

from __future__ import annotations

import math

from ._exudyn2d import simulate_exudyn
from ._exudyn_common import beam_elements, cable_properties

__all__ = ["simulate", "METHOD"]

METHOD = "exudyn-ancf"


class _ANCF:
    method = METHOD

    @staticmethod
    def meta(case, k, axial, reduced_integration=False):
        return {"element": "ObjectANCFCable2D", "reduced_integration": bool(reduced_integration)}

    @staticmethod
    def add_link(mbs, exu, ii, link, layout, i, k, EA, reduced_integration=False):
        b = link.beam
        L, th, om = b.length, layout.theta[i], layout.omega[i]
        c, s = math.cos(th), math.sin(th)
        nodes = [
            mbs.AddNode(
                ii.NodePoint2DSlope1(
                    referenceCoordinates=[p[0], p[1], c, s],
                    initialVelocities=[v[0], v[1], -om * s, om * c],
                )
            )
            for p, v in ((layout.point(i, L * j / k), layout.velocity(i, L * j / k)) for j in range(k + 1))
        ]
        elements = beam_elements(
            mbs,
            ii.ObjectANCFCable2D,
            nodes,
            **cable_properties(b, L / k, b.EI, EA),
            useReducedOrderIntegration=int(bool(reduced_integration)),
        )
        hub, tip = (layout.rigid_node(mbs, ii, i, s_) for s_ in (0.0, L))
        return hub, tip, elements, (nodes[0], nodes[-1])


def simulate(case, *, elements_per_link, h, rho_inf=0.8, reduced_integration=False, **options):
    """Simulate ``case`` with k = ``elements_per_link`` ANCF cable elements per link and step h.

    Options: ``rho_inf`` (generalized-α spectral radius, 0.8), ``reduced_integration`` (False),
    and the common ones of :func:`reference_models._exudyn2d.simulate_exudyn`:
    ``newton_rel_tol`` (1e-8), ``newton_abs_tol`` (None: scaled to the problem),
    ``newton_max_iterations`` (25), ``modified_newton`` (True), ``jacobian_per_step`` (True), ``drive_input``
    ("pre-step" or "user-function"), ``inextensible_axial_ratio`` (1e6).
    Returns a :class:`dttmm.Result` (meta["method"] = "exudyn-ancf"); raises
    :class:`dttmm.InputError` on bad input and :class:`dttmm.SimulationError` on any failure.
    """
    return simulate_exudyn(
        case,
        element=_ANCF,
        elements_per_link=elements_per_link,
        h=h,
        rho_inf=rho_inf,
        element_options={"reduced_integration": reduced_integration},
        **options,
    )
