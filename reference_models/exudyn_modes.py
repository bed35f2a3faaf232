"""Natural frequencies of a case from Exudyn's ``ComputeODE2Eigenvalues`` (ANCF cable model).

The arm is built as in :mod:`reference_models.exudyn_ancf`: per link k ``ObjectANCFCable2D``
elements, a hub and a payload ``ObjectRigidBody2D`` at the link ends, each clamped to the end
node of the beam (``ObjectJointGeneric`` locking x, y and the rotation); revolute joints between
a link's hub and the inboard link's payload body (joint 1: the ground). A motion-driven joint is
held: a coordinate constraint fixes the relative rotation. A torque-driven joint is free. At
rest (initial angles, undeformed, no velocity) Exudyn linearises the model and projects it on
the null space of the constraint Jacobian; its eigenvalues are ω² (rad²/s²).

Links given as inextensible get the finite axial stiffness of the Exudyn models
(EA = 1e6·EI/L², see :func:`reference_models._exudyn2d.stiff_axial_stiffness`): their axial
modes then lie far above the bending ones, which EA does not change at rest (no axial preload
without gravity). Gravity is refused: the eigenvalues at a rest state that is not an
equilibrium would not be the natural frequencies.
"""

from __future__ import annotations

import numpy as np

from dttmm.case import Case

from ._exudyn2d import _Layout, clamp, joint_markers, stiff_axial_stiffness
from ._exudyn_common import eigen_frequencies, import_exudyn, modes_check, modes_rest
from .exudyn_ancf import _ANCF

__all__ = ["frequencies", "METHOD"]

METHOD = "exudyn-ancf"


def _build(case: Case, k: int):
    """The assembled Exudyn system (SystemContainer, MainSystem) of the case at rest."""
    exu, ii = import_exudyn(f"{METHOD} modes need")
    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    layout = _Layout(case)
    ground = mbs.AddObject(ii.ObjectGround())
    ground_node = mbs.AddNode(ii.NodePointGround())
    m_ground = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    c_ground = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    hub_nodes, tip_nodes, hub_bodies, tip_bodies = [], [], [], []
    for i, (link, drive) in enumerate(zip(case.model.links, case.scenario.drives)):
        EA = stiff_axial_stiffness(link.beam)
        hub_node, tip_node, _, (root_beam, tip_beam) = _ANCF.add_link(mbs, exu, ii, link, layout, i, k, EA)
        hub_nodes.append(hub_node)
        tip_nodes.append(tip_node)
        for node, mass, inertia, beam_node, bodies in (
            (hub_node, link.hub_mass, link.hub_inertia, root_beam, hub_bodies),
            (tip_node, link.payload_mass, link.payload_inertia, tip_beam, tip_bodies),
        ):
            bodies.append(
                mbs.AddObject(ii.ObjectRigidBody2D(nodeNumber=node, mass=float(mass), inertia=float(inertia)))
            )
            clamp(mbs, ii, bodies[-1], beam_node)
        coordinates = joint_markers(
            mbs, ii, i, m_ground, c_ground, tip_bodies, hub_bodies, tip_nodes, hub_nodes
        )
        if drive.kind == "motion":  # held: relative rotation fixed at its initial value
            mbs.AddObject(ii.ObjectConnectorCoordinate(markerNumbers=list(coordinates()), offset=0.0))
    mbs.Assemble()
    return SC, mbs


def frequencies(case: Case, elements_per_link: int, n: int | None = None) -> np.ndarray:
    """Natural frequencies (Hz, ascending) of ``case`` at rest by Exudyn, held joints clamped.

    Parameters
    ----------
    case : dttmm.Case
        Without gravity; torque-driven joints start at rest.
    elements_per_link : int
        ANCF cable elements per link.
    n : int or None
        Number of lowest frequencies (None: all).

    Returns
    -------
    (n,) ndarray
        Frequencies (Hz) from ``ComputeODE2Eigenvalues`` (dense, constraints by null-space
        projection); the lowest one per torque-driven joint is its rigid-body mode, reported
        as 0 (Exudyn returns it as a round-off-sized ω² of either sign).
    """
    k = modes_check(case, Case, "dttmm.Case", elements_per_link, n)
    modes_rest(case)
    _, mbs = _build(case, k)
    return eigen_frequencies(mbs, case, n, METHOD)
