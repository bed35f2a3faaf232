"""dttmm.spatial — spatial (3-D) manipulators with flexible links (docs/spatial.md).

The model (:class:`SpatialManipulator` and its parts), cases (:class:`SpatialCase`: a spatial
manipulator with the planar suite's :class:`dttmm.Scenario`, or a :class:`SpatialScenario` that
adds external loads, :class:`SpatialLoad`), the embedding of a planar arm
(:func:`embed_planar`; :meth:`SpatialCase.from_planar` makes a planar :class:`dttmm.Case` the
spatial case it is, and :func:`load_case` reads a case file of any kind as one), the rotation
helpers of the discretisation and the static equilibrium with the joints held
(:func:`statics`). :func:`dttmm.simulate` runs a spatial case on this package's kernel
(:func:`simulate`); link shapes at any coordinates: :func:`link_shapes`.
"""

from ..casefiles import load_spatial_case as load_case
from .case import SpatialCase, case_from_dict
from .model import (
    SpatialClosure,
    SpatialHub,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialRigidBody,
    SpatialSection,
    embed_planar,
)
from .result import SpatialResult
from .rotation import axis_angle_matrix, exp_so3, hat, left_jacobian, log_so3, rpy_matrix
from .scenario import SpatialLoad, SpatialScenario

__all__ = [
    "SpatialResult",
    "accelerations",
    "link_shapes",
    "simulate",
    "SpatialCase",
    "SpatialLoad",
    "SpatialScenario",
    "SpatialHub",
    "SpatialJoint",
    "SpatialClosure",
    "SpatialLink",
    "SpatialManipulator",
    "SpatialPayload",
    "SpatialRigidBody",
    "SpatialSection",
    "axis_angle_matrix",
    "case_from_dict",
    "embed_planar",
    "load_case",
    "exp_so3",
    "hat",
    "left_jacobian",
    "log_so3",
    "rpy_matrix",
    "StaticResult",
    "statics",
]

from .solver import accelerations, link_shapes, simulate  # noqa: E402
from .statics import StaticResult, statics  # noqa: E402
