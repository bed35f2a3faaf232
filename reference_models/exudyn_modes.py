"""Natural frequencies of a case from Exudyn's ``ComputeODE2Eigenvalues`` (ANCF cable model).

The arm is built as in :mod:`reference_models.exudyn_ancf`: per link k ``ObjectANCFCable2D``
elements, a hub and a payload ``ObjectRigidBody2D`` at the link ends, each clamped to the end
node of the beam (``ObjectJointGeneric`` locking x, y and the rotation); revolute joints between
a link's hub and the inboard link's payload body (joint 1: the ground). A motion-driven joint is
held: a coordinate constraint fixes the relative rotation. A torque-driven joint is free. At
rest (initial angles, undeformed, no velocity) Exudyn linearises the model and projects it on
the null space of the constraint Jacobian; its eigenvalues are ω² (rad²/s²).

Links given as inextensible get the finite axial stiffness of the Exudyn models
(EA = 1e6·EI/L², see :func:`reference_models._exudyn_common.stiff_axial_stiffness`): their axial
modes then lie far above the bending ones, which EA does not change at rest (no axial preload
without gravity). Gravity is refused: the eigenvalues at a rest state that is not an
equilibrium would not be the natural frequencies.
"""

from __future__ import annotations

import numpy as np

from dttmm import plumbing
from dttmm.case import Case
from dttmm.errors import InputError

from ._exudyn_common import _Layout, stiff_axial_stiffness
from .exudyn_ancf import _ANCF

__all__ = ["frequencies", "METHOD"]

METHOD = "exudyn-ancf"


def _check(case, elements_per_link, n) -> int:
    if not isinstance(case, Case):
        raise InputError("case", case, "must be a dttmm.Case")
    plumbing.elements_per_link(elements_per_link)
    if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1):
        raise InputError("n", n, "must be an integer >= 1 (number of modes)")
    if any(case.model.gravity):
        raise InputError(
            "model.gravity",
            list(case.model.gravity),
            "the Exudyn eigenvalues are taken at rest, which is an equilibrium only without gravity",
        )
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and d.initial_rate != 0.0:
            raise InputError(
                f"scenario.drives[{i}].initial_rate", d.initial_rate, "must be 0 (modes at rest)"
            )
    return int(elements_per_link)


def _build(case: Case, k: int):
    """The assembled Exudyn system (SystemContainer, MainSystem) of the case at rest."""
    import exudyn as exu
    import exudyn.itemInterface as ii

    SC = exu.SystemContainer()
    mbs = SC.AddSystem()
    layout = _Layout(case)
    ground = mbs.AddObject(ii.ObjectGround())
    ground_node = mbs.AddNode(ii.NodePointGround())
    m_ground = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=ground, localPosition=[0, 0, 0]))
    c_ground = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=ground_node, coordinate=0))
    prev_tip_body, prev_tip_node = None, None
    for i, (link, drive) in enumerate(zip(case.model.links, case.scenario.drives)):
        EA = stiff_axial_stiffness(link.beam)
        hub_node, tip_node, _, (root_beam, tip_beam) = _ANCF.add_link(mbs, exu, ii, link, layout, i, k, EA)
        bodies = []
        for node, mass, inertia, beam_node in (
            (hub_node, link.hub_mass, link.hub_inertia, root_beam),
            (tip_node, link.payload_mass, link.payload_inertia, tip_beam),
        ):
            body = mbs.AddObject(
                ii.ObjectRigidBody2D(nodeNumber=node, mass=float(mass), inertia=float(inertia))
            )
            m0 = mbs.AddMarker(ii.MarkerBodyRigid(bodyNumber=body))
            m1 = mbs.AddMarker(ii.MarkerNodeRigid(nodeNumber=beam_node))
            mbs.AddObject(ii.ObjectJointGeneric(markerNumbers=[m0, m1], constrainedAxes=[1, 1, 0, 0, 0, 1]))
            bodies.append(body)
        m_in = (
            m_ground
            if i == 0
            else mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=prev_tip_body, localPosition=[0, 0, 0]))
        )
        m_out = mbs.AddMarker(ii.MarkerBodyPosition(bodyNumber=bodies[0], localPosition=[0, 0, 0]))
        mbs.AddObject(ii.ObjectJointRevolute2D(markerNumbers=[m_in, m_out]))
        if drive.kind == "motion":  # held: relative rotation fixed at its initial value
            c_in = (
                c_ground
                if i == 0
                else mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=prev_tip_node, coordinate=2))
            )
            c_out = mbs.AddMarker(ii.MarkerNodeCoordinate(nodeNumber=hub_node, coordinate=2))
            mbs.AddObject(ii.ObjectConnectorCoordinate(markerNumbers=[c_in, c_out], offset=0.0))
        prev_tip_body, prev_tip_node = bodies[1], tip_node
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
    k = _check(case, elements_per_link, n)
    try:
        import exudyn.solver  # noqa: F401
    except ImportError as exc:
        raise ImportError(
            f"{METHOD} modes need the exudyn package (pip install 'dttmm[exudyn]'): {exc}"
        ) from exc
    _, mbs = _build(case, k)
    return eigen_frequencies(mbs, case, n, METHOD)


def eigen_frequencies(mbs, case, n, method: str) -> np.ndarray:
    """Natural frequencies (Hz) of an assembled Exudyn system: one rigid-body mode (ω² = 0 up to
    Exudyn's round-off) per torque-driven joint, then the elastic ones; ArithmeticError when the
    two are not separated. ``method`` names the peer in that message."""
    from exudyn.solver import ComputeODE2Eigenvalues

    lam, _ = ComputeODE2Eigenvalues(mbs, useAbsoluteValues=False, computeComplexEigenvalues=False)
    lam = np.sort(np.asarray(lam, float).real)
    n_rigid = sum(d.kind == "torque" for d in case.scenario.drives)
    rigid, rest = lam[:n_rigid], lam[n_rigid:]
    if rest.size and (np.any(np.abs(rigid) > 1e-3 * rest[0]) or rest[0] <= 0):
        raise ArithmeticError(
            f"{method} modes: rigid-body ω² {rigid} not separated from the elastic {rest[:1]}"
        )
    lam = np.concatenate([np.zeros(n_rigid), rest])
    lam = lam if n is None else lam[:n]
    return np.sqrt(lam) / (2 * np.pi)
