"""The physical model of a spatial manipulator with flexible links (SI units, radians).

Fields and frames: docs/spatial.md §1. All classes are frozen dataclasses validated on
construction (every bad value an :class:`dttmm.InputError` naming the field); make variants
with :func:`dataclasses.replace`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

import numpy as np
from pydantic import Field, Strict

from ..errors import InputError
from ..model import Manipulator
from ..schema import Bounded, Finite, NonNegative, Positive, _short, _Strict, check_fields
from .rotation import rpy_matrix

__all__ = [
    "SpatialHub",
    "SpatialJoint",
    "SpatialLink",
    "SpatialManipulator",
    "SpatialPayload",
    "SpatialRigidBody",
    "SpatialSection",
    "embed_planar",
    "require_flexible",
]

Vector3 = Annotated[list[Finite], Strict(), Field(min_length=3, max_length=3)]
BoundedVector3 = Annotated[list[Bounded], Strict(), Field(min_length=3, max_length=3)]
#: an inertia tensor: a 3×3 matrix, or its diagonal (3 numbers)
InertiaValue = Annotated[
    list[Annotated[list[Bounded], Strict(), Field(min_length=3, max_length=3)]],
    Strict(),
    Field(min_length=3, max_length=3),
]


class SpatialSectionFields(_Strict):
    """Beam of one link (docs/spatial.md §1)."""

    length: Positive
    EA: Positive | None = None
    GJ: Positive
    EIy: Positive
    EIz: Positive
    rhoA: Positive
    rhoJ: Positive
    rhoIy: NonNegative = 0.0
    rhoIz: NonNegative = 0.0
    roll: Finite = 0.0
    damping: NonNegative = 0.0


class SpatialJointFields(_Strict):
    axis: Vector3 = [0.0, 0.0, 1.0]
    origin_xyz: BoundedVector3 = [0.0, 0.0, 0.0]
    origin_rpy: Vector3 = [0.0, 0.0, 0.0]
    locked: bool = False


class MassFields(_Strict):
    mass: NonNegative = 0.0


class OffsetFields(_Strict):
    offset: BoundedVector3 = [0.0, 0.0, 0.0]


class InertiaFields(_Strict):
    inertia: InertiaValue


class RigidBodyFields(_Strict):
    length: NonNegative = 0.0
    mass: NonNegative = 0.0
    com: BoundedVector3 = [0.0, 0.0, 0.0]


class GravityFields(_Strict):
    gravity: BoundedVector3 = [0.0, 0.0, 0.0]
    base_xyz: BoundedVector3 = [0.0, 0.0, 0.0]
    base_rpy: Vector3 = [0.0, 0.0, 0.0]


def _set(obj, values: dict):
    for k, v in values.items():
        object.__setattr__(obj, k, v)


def _inertia(value, where: str) -> tuple:
    """A 3×3 symmetric positive semi-definite inertia (a 3-vector is its diagonal), as a tuple
    of row tuples."""
    arr = value
    if isinstance(value, np.ndarray):
        arr = value.tolist()
    if (
        isinstance(arr, (list, tuple))
        and len(arr) == 3
        and all(not isinstance(x, (list, tuple, np.ndarray)) for x in arr)
    ):
        arr = [[arr[0], 0.0, 0.0], [0.0, arr[1], 0.0], [0.0, 0.0, arr[2]]]
    rows = check_fields(InertiaFields, where, inertia=arr)["inertia"]
    m = np.array(rows, dtype=float)
    field_ = f"{where}.inertia"
    if not np.allclose(m, m.T, rtol=1e-12, atol=1e-12 * max(1.0, float(np.abs(m).max()))):
        raise InputError(field_, _short(value), "must be symmetric")
    m = 0.5 * (m + m.T)
    ev = np.linalg.eigvalsh(m)
    if ev.min() < -1e-12 * max(1.0, ev.max()):
        raise InputError(field_, _short(value), f"must be positive semi-definite (eigenvalue {ev.min():.3g})")
    return tuple(tuple(float(x) for x in r) for r in m)


@dataclass(frozen=True)
class SpatialSection:
    """Uniform spatial Euler-Bernoulli beam of one link (docs/spatial.md §1).

    length (m); EA (N, None: inextensible); GJ, EIy, EIz (N·m²: EIz bends along y, EIy along z);
    rhoA (kg/m); rhoJ, rhoIy, rhoIz (kg·m: mass moments of inertia per length about x, y, z);
    roll (rad: principal axes about x relative to the link frame); damping μ (s, D = μK).
    """

    length: float
    GJ: float
    EIy: float
    EIz: float
    rhoA: float
    rhoJ: float
    EA: float | None = None
    rhoIy: float = 0.0
    rhoIz: float = 0.0
    roll: float = 0.0
    damping: float = 0.0
    _where: str = field(default="section", repr=False, compare=False)

    def __post_init__(self):
        names = ("length", "EA", "GJ", "EIy", "EIz", "rhoA", "rhoJ", "rhoIy", "rhoIz", "roll", "damping")
        _set(self, check_fields(SpatialSectionFields, self._where, **{k: getattr(self, k) for k in names}))

    @property
    def mass(self) -> float:
        return self.rhoA * self.length

    @property
    def extensible(self) -> bool:
        return self.EA is not None


@dataclass(frozen=True)
class SpatialRigidBody:
    """The body of a rigid link, in place of its beam (docs/spatial.md §1): ``length`` L (m, ≥ 0:
    the tip frame is the link frame moved by L along its x axis), ``mass`` (kg), ``com`` (m, the
    centre of mass in the link frame), ``inertia`` (3×3, kg·m², about the centre of mass, in the
    link frame; three numbers give its diagonal). No elastic coordinates."""

    length: float = 0.0
    mass: float = 0.0
    com: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="rigid", repr=False, compare=False)

    def __post_init__(self):
        ok = check_fields(RigidBodyFields, self._where, length=self.length, mass=self.mass, com=self.com)
        ok["com"] = tuple(float(x) for x in ok["com"])
        _set(self, ok)
        object.__setattr__(self, "inertia", _inertia(self.inertia, self._where))

    @property
    def inertia_matrix(self) -> np.ndarray:
        return np.array(self.inertia, dtype=float)

    @property
    def com_vector(self) -> np.ndarray:
        return np.array(self.com, dtype=float)


@dataclass(frozen=True)
class SpatialJoint:
    """A revolute joint: ``axis`` (unit vector in the joint frame), ``origin_xyz`` (m) and
    ``origin_rpy`` (rad, URDF roll-pitch-yaw) of the joint frame in the parent frame, ``locked``
    (no coordinate: a rigid connection at the origin's angle)."""

    axis: tuple = (0.0, 0.0, 1.0)
    origin_xyz: tuple = (0.0, 0.0, 0.0)
    origin_rpy: tuple = (0.0, 0.0, 0.0)
    locked: bool = False
    _where: str = field(default="joint", repr=False, compare=False)

    def __post_init__(self):
        ok = check_fields(
            SpatialJointFields,
            self._where,
            axis=self.axis,
            origin_xyz=self.origin_xyz,
            origin_rpy=self.origin_rpy,
            locked=self.locked,
        )
        a = np.array(ok["axis"], dtype=float)
        n = float(np.linalg.norm(a))
        if not abs(n - 1.0) <= 1e-6:
            raise InputError(
                f"{self._where}.axis", ok["axis"], f"must be a unit vector (its norm is {n:.6g})"
            )
        ok["axis"] = tuple(float(x) for x in a / n)
        _set(self, ok)

    @property
    def rotation(self) -> np.ndarray:
        """R_rpy of the origin (joint frame in the parent frame)."""
        return rpy_matrix(self.origin_rpy)


@dataclass(frozen=True)
class SpatialHub:
    """Rigid body at a link's root point: mass (kg), inertia (3×3, kg·m², about the root point,
    in the link frame; three numbers give its diagonal)."""

    mass: float = 0.0
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="hub", repr=False, compare=False)

    def __post_init__(self):
        _set(self, check_fields(MassFields, self._where, mass=self.mass))
        object.__setattr__(self, "inertia", _inertia(self.inertia, self._where))

    @property
    def inertia_matrix(self) -> np.ndarray:
        return np.array(self.inertia, dtype=float)


@dataclass(frozen=True)
class SpatialPayload:
    """Rigid body fixed to a link's tip frame: mass (kg), offset (m, its centre in the tip frame),
    inertia (3×3, kg·m², about its centre, in the tip frame; three numbers give its diagonal)."""

    mass: float = 0.0
    offset: tuple = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="payload", repr=False, compare=False)

    def __post_init__(self):
        _set(self, check_fields(MassFields, self._where, mass=self.mass))
        _set(self, check_fields(OffsetFields, self._where, offset=self.offset))
        object.__setattr__(self, "inertia", _inertia(self.inertia, self._where))

    @property
    def inertia_matrix(self) -> np.ndarray:
        return np.array(self.inertia, dtype=float)


@dataclass(frozen=True)
class SpatialLink:
    """One link: its beam (a :class:`SpatialSection`: flexible) or its body (a
    :class:`SpatialRigidBody`: rigid), the joint at its root, a hub at the root, a payload at the
    tip."""

    beam: SpatialSection | SpatialRigidBody
    joint: SpatialJoint = field(default_factory=SpatialJoint)
    hub: SpatialHub | None = None
    payload: SpatialPayload | None = None
    _where: str = field(default="link", repr=False, compare=False)

    def __post_init__(self):
        w = self._where
        if not isinstance(self.beam, (SpatialSection, SpatialRigidBody)):
            raise InputError(
                f"{w}.beam",
                _short(self.beam),
                "must be a dttmm.spatial.SpatialSection or a dttmm.spatial.SpatialRigidBody",
            )
        if not isinstance(self.joint, SpatialJoint):
            raise InputError(f"{w}.joint", _short(self.joint), "must be a dttmm.spatial.SpatialJoint")
        if self.hub is not None and not isinstance(self.hub, SpatialHub):
            raise InputError(f"{w}.hub", _short(self.hub), "must be a dttmm.spatial.SpatialHub or None")
        if self.payload is not None and not isinstance(self.payload, SpatialPayload):
            raise InputError(
                f"{w}.payload", _short(self.payload), "must be a dttmm.spatial.SpatialPayload or None"
            )

    @property
    def rigid(self) -> bool:
        """Whether the link is rigid (its ``beam`` a :class:`SpatialRigidBody`)."""
        return isinstance(self.beam, SpatialRigidBody)

    @property
    def roll(self) -> float:
        """The section's roll (0 for a rigid link: its element frames are its link frame)."""
        return 0.0 if self.rigid else self.beam.roll

    @property
    def hub_mass(self) -> float:
        return self.hub.mass if self.hub else 0.0

    @property
    def hub_inertia(self) -> np.ndarray:
        return self.hub.inertia_matrix if self.hub else np.zeros((3, 3))

    @property
    def payload_mass(self) -> float:
        return self.payload.mass if self.payload else 0.0

    @property
    def payload_offset(self) -> np.ndarray:
        return np.array(self.payload.offset if self.payload else (0.0, 0.0, 0.0), dtype=float)

    @property
    def payload_inertia(self) -> np.ndarray:
        return self.payload.inertia_matrix if self.payload else np.zeros((3, 3))


@dataclass(frozen=True)
class SpatialManipulator:
    """A spatial serial arm: revolute joints and flexible or rigid links, base first (docs/spatial.md §1).

    ``gravity`` (m/s², in the world frame); ``base_xyz`` (m) and ``base_rpy`` (rad) place the base
    frame in the world.
    """

    links: tuple
    gravity: tuple = (0.0, 0.0, 0.0)
    base_xyz: tuple = (0.0, 0.0, 0.0)
    base_rpy: tuple = (0.0, 0.0, 0.0)

    def __post_init__(self):
        if not isinstance(self.links, (tuple, list)):
            raise InputError(
                "model.links", _short(self.links), "must be a tuple of dttmm.spatial.SpatialLink"
            )
        links = tuple(self.links)
        if not links:
            raise InputError("model.links", self.links, "needs at least one link")
        for i, link in enumerate(links):
            if not isinstance(link, SpatialLink):
                raise InputError(f"model.links[{i}]", _short(link), "must be a dttmm.spatial.SpatialLink")
        object.__setattr__(self, "links", links)
        _set(
            self,
            check_fields(
                GravityFields, "model", gravity=self.gravity, base_xyz=self.base_xyz, base_rpy=self.base_rpy
            ),
        )

    @property
    def n_links(self) -> int:
        return len(self.links)

    @property
    def n_joints(self) -> int:
        """The number of unlocked joints (each has a coordinate and a drive)."""
        return sum(not link.joint.locked for link in self.links)

    @property
    def unlocked(self) -> tuple[int, ...]:
        """Indices of the links whose joint is unlocked."""
        return tuple(i for i, link in enumerate(self.links) if not link.joint.locked)

    @property
    def rigid_links(self) -> tuple[int, ...]:
        """Indices of the rigid links."""
        return tuple(i for i, link in enumerate(self.links) if link.rigid)

    @property
    def base_rotation(self) -> np.ndarray:
        return rpy_matrix(self.base_rpy)


def embed_planar(manipulator: Manipulator, base_rpy=(0.0, 0.0, 0.0), base_xyz=(0.0, 0.0, 0.0)):
    """The planar arm as a spatial arm (docs/spatial.md "A planar case is a spatial case").

    Joint axes z, zero origins, in-plane bending EIz = EI; the out-of-plane data (never excited)
    are EIy = GJ = EI and rhoJ = rhoA·L², which keeps their natural frequencies at or below the
    in-plane ones (so an explicit integrator stable for the plane is stable for them too).
    Gravity (g_x, g_y) of the plane becomes R_base·(g_x, g_y, 0) in the world.
    """
    if not isinstance(manipulator, Manipulator):
        raise InputError("manipulator", _short(manipulator), "must be a dttmm.Manipulator")
    rot = rpy_matrix(check_fields(GravityFields, "base", base_rpy=base_rpy)["base_rpy"])
    links = []
    for i, link in enumerate(manipulator.links):
        b, w = link.beam, f"model.links[{i}]"
        beam = SpatialSection(
            length=b.length,
            GJ=b.EI,
            EIy=b.EI,
            EIz=b.EI,
            rhoA=b.rhoA,
            rhoJ=b.rhoA * b.length**2,
            EA=b.EA,
            damping=b.damping,
            _where=f"{w}.beam",
        )
        hub = None
        if link.hub is not None:
            hub = SpatialHub(link.hub.mass, (0.0, 0.0, link.hub.inertia), _where=f"{w}.hub")
        pay = None
        if link.payload is not None:
            pay = SpatialPayload(
                link.payload.mass, (0.0, 0.0, 0.0), (0.0, 0.0, link.payload.inertia), _where=f"{w}.payload"
            )
        links.append(SpatialLink(beam, SpatialJoint(_where=f"{w}.joint"), hub, pay, _where=w))
    g = rot @ np.array([manipulator.gravity[0], manipulator.gravity[1], 0.0])
    return SpatialManipulator(tuple(links), tuple(float(x) for x in g), base_xyz, base_rpy)


def require_flexible(model: SpatialManipulator, method: str) -> None:
    """Refuse an arm with rigid links (``SpatialRigidBody``) for an engine that models flexible
    links only (rigid links run in the spatial DT-TMM, the spatial global solver and Pinocchio)."""
    for i, link in enumerate(model.links):
        if link.rigid:
            raise InputError(
                f"model.links[{i}].rigid", _short(link.beam), f"rigid links are not supported by {method} yet"
            )
