"""Natural frequencies of a spatial case from Exudyn's ``ComputeODE2Eigenvalues`` (3-D
geometrically exact beam model).

The arm is built exactly as :mod:`reference_models.exudyn_beam3d` builds it for a run (k
``ObjectBeamGeometricallyExact`` elements per link on ``NodeRigidBodyEP`` nodes, hubs and
payloads as rigid bodies on the end nodes, ``ObjectJointGeneric`` joints; a locked joint fixes
all six axes, a motion-driven joint is held at its initial angle, a torque-driven joint is
free), assembled at rest, and Exudyn linearises it and projects it on the null space of the
constraint Jacobian (dense); its eigenvalues are ω² (rad²/s²).

The element is shear-deformable (GA = ``shear_ratio``·EA, the Euler–Bernoulli limit at the
default 10³) with linear interpolation and one-point integration: its frequencies converge as
O(1/k²), so a comparison with the Euler–Bernoulli DT-TMM at the 1e-5 level needs fine meshes
or Richardson extrapolation in k (tests/test_spatial_modes.py). Its nodes carry rotational
inertia only through the section's ``inertia`` diag(ρJ, ρIy, ρIz): a section with ρIy = 0 or
ρIz = 0 gives a singular mass matrix (refused). Gravity and external loads are refused: the
eigenvalues are taken at the undeformed rest state, an equilibrium only without them.
"""

from __future__ import annotations

from dttmm.errors import InputError
from dttmm.spatial import SpatialCase
from dttmm.spatial.model import require_flexible, require_serial

from ._exudyn_common import eigen_frequencies, modes_check, modes_rest
from .exudyn_beam3d import SHEAR_RATIO, _build

__all__ = ["METHOD", "frequencies"]

METHOD = "exudyn-beam3d"


def _check(case, elements_per_link, n) -> int:
    k = modes_check(case, SpatialCase, "dttmm.spatial.SpatialCase", elements_per_link, n)
    if getattr(case.scenario, "loads", ()):
        raise InputError("scenario.loads", "...", "the Exudyn eigenvalues are taken without external loads")
    require_flexible(case.model, METHOD)
    require_serial(case.model, METHOD)
    for i, lk in enumerate(case.model.links):
        if lk.beam.rhoIy <= 0.0 or lk.beam.rhoIz <= 0.0:
            raise InputError(
                f"model.links[{i}].rhoIy/rhoIz",
                (lk.beam.rhoIy, lk.beam.rhoIz),
                "must be > 0 (the beam element's nodes have no other rotary inertia about y, z)",
            )
    modes_rest(case)
    return k


def frequencies(case, elements_per_link: int, n: int | None = None, *, shear_ratio: float = SHEAR_RATIO):
    """Natural frequencies (Hz, ascending) of a spatial ``case`` at rest by Exudyn's 3-D beam.

    Returns (n,) frequencies; the lowest one per torque-driven joint is its rigid-body mode,
    reported as 0 (Exudyn returns it as a round-off-sized ω² of either sign).
    """
    k = _check(case, elements_per_link, n)
    arm = _build(case, k, shear_ratio, "EP", [])
    arm.set_inputs(0.0, False)
    arm.mbs.Assemble()
    return eigen_frequencies(arm.mbs, case, n, METHOD)
