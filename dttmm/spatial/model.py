"""The physical model of a spatial manipulator with flexible links (SI units, radians).

Fields and frames: docs/spatial.md §1. All classes are frozen dataclasses validated on
construction (every bad value an :class:`dttmm.InputError` naming the field); make variants
with :func:`dataclasses.replace`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, Strict

from ..errors import InputError
from ..model import BodyValue, Manipulator, _Beam
from ..schema import (
    Bounded,
    Checked,
    Finite,
    NonNegative,
    Positive,
    _set,
    _short,
    _Strict,
    check_fields,
    fields_model,
    tuple_of,
)
from .rotation import rpy_matrix

__all__ = [
    "CLOSURE_EQUATIONS",
    "SpatialClosure",
    "SpatialHub",
    "SpatialJoint",
    "SpatialLink",
    "SpatialManipulator",
    "SpatialPayload",
    "SpatialRigidBody",
    "SpatialSection",
    "embed_planar",
    "require_flexible",
    "require_open_chain",
    "require_serial",
]

Vector3 = Annotated[list[Finite], Strict(), Field(min_length=3, max_length=3)]
BoundedVector3 = Annotated[list[Bounded], Strict(), Field(min_length=3, max_length=3)]
#: an inertia tensor: a 3×3 matrix, or its diagonal (3 numbers)
InertiaValue = Annotated[
    list[Annotated[list[Bounded], Strict(), Field(min_length=3, max_length=3)]],
    Strict(),
    Field(min_length=3, max_length=3),
]


#: the value types of the spatial fields, kept as tuples
Vec3 = tuple_of(Finite, min_length=3, max_length=3)
BoundedVec3 = tuple_of(Bounded, min_length=3, max_length=3)
Name = Annotated[str, Strict()]


class InertiaFields(_Strict):
    inertia: InertiaValue


#: the number of position-level constraint equations of each closure kind
CLOSURE_EQUATIONS = {"revolute": 5, "spherical": 3, "weld": 6}


#: names a link may not take: the base frame and the ground of a closure
RESERVED_NAMES = ("base", "ground")


def _unit(value, field_: str) -> tuple:
    """The unit vector ``value`` (normalised); an InputError on ``field_`` when its norm is not 1."""
    a = np.array(value, dtype=float)
    n = float(np.linalg.norm(a))
    if not abs(n - 1.0) <= 1e-6:
        raise InputError(field_, value, f"must be a unit vector (its norm is {n:.6g})")
    return tuple(float(x) for x in a / n)


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


class _InertiaBody(Checked):
    """A rigid body whose ``inertia`` is a 3×3 tensor (three numbers give its diagonal), checked
    symmetric and positive semi-definite after the other fields."""

    def _rules(self):
        object.__setattr__(self, "inertia", _inertia(self.inertia, self._where))

    @property
    def inertia_matrix(self) -> np.ndarray:
        return np.array(self.inertia, dtype=float)


@dataclass(frozen=True)
class SpatialSection(Checked, _Beam):
    """Uniform spatial Euler-Bernoulli beam of one link (docs/spatial.md §1).

    length (m); EA (N, None: inextensible); GJ, EIy, EIz (N·m²: EIz bends along y, EIy along z);
    rhoA (kg/m); rhoJ, rhoIy, rhoIz (kg·m: mass moments of inertia per length about x, y, z);
    roll (rad: principal axes about x relative to the link frame); damping μ (s, D = μK).
    """

    length: Positive
    GJ: Positive
    EIy: Positive
    EIz: Positive
    rhoA: Positive
    rhoJ: Positive
    EA: Positive | None = None
    rhoIy: NonNegative = 0.0
    rhoIz: NonNegative = 0.0
    roll: Finite = 0.0
    damping: NonNegative = 0.0
    _where: str = field(default="section", repr=False, compare=False)


@dataclass(frozen=True)
class SpatialRigidBody(_InertiaBody):
    """The body of a rigid link, in place of its beam (docs/spatial.md §1): ``length`` L (m, ≥ 0:
    the tip frame is the link frame moved by L along its x axis), ``mass`` (kg), ``com`` (m, the
    centre of mass in the link frame), ``inertia`` (3×3, kg·m², about the centre of mass, in the
    link frame; three numbers give its diagonal). No elastic coordinates."""

    length: NonNegative = 0.0
    mass: NonNegative = 0.0
    com: BoundedVec3 = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="rigid", repr=False, compare=False)

    @property
    def com_vector(self) -> np.ndarray:
        return np.array(self.com, dtype=float)


@dataclass(frozen=True)
class SpatialJoint(Checked):
    """A revolute joint: ``axis`` (unit vector in the joint frame), ``origin_xyz`` (m) and
    ``origin_rpy`` (rad, URDF roll-pitch-yaw) of the joint frame in the parent frame, ``locked``
    (no coordinate: a rigid connection at the origin's angle)."""

    axis: Vec3 = (0.0, 0.0, 1.0)
    origin_xyz: BoundedVec3 = (0.0, 0.0, 0.0)
    origin_rpy: Vec3 = (0.0, 0.0, 0.0)
    locked: Annotated[bool, Strict()] = False
    _where: str = field(default="joint", repr=False, compare=False)

    def _rules(self):
        object.__setattr__(self, "axis", _unit(self.axis, f"{self._where}.axis"))

    @property
    def rotation(self) -> np.ndarray:
        """R_rpy of the origin (joint frame in the parent frame)."""
        return rpy_matrix(self.origin_rpy)


@dataclass(frozen=True)
class SpatialHub(_InertiaBody):
    """Rigid body at a link's root point: mass (kg), inertia (3×3, kg·m², about the root point,
    in the link frame; three numbers give its diagonal)."""

    mass: NonNegative = 0.0
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="hub", repr=False, compare=False)


@dataclass(frozen=True)
class SpatialPayload(_InertiaBody):
    """Rigid body fixed to a link's tip frame: mass (kg), offset (m, its centre in the tip frame),
    inertia (3×3, kg·m², about its centre, in the tip frame; three numbers give its diagonal)."""

    mass: NonNegative = 0.0
    offset: BoundedVec3 = (0.0, 0.0, 0.0)
    inertia: tuple = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    _where: str = field(default="payload", repr=False, compare=False)


@dataclass(frozen=True)
class SpatialLink:
    """One link: its beam (a :class:`SpatialSection`: flexible) or its body (a
    :class:`SpatialRigidBody`: rigid), the joint at its root, a hub at the root, a payload at the
    tip; ``name`` ("" → "link{i}", 1-based, resolved by the manipulator) and ``parent`` (None →
    the previous link, the base for the first; "base" → the base frame; otherwise the name of a
    link listed before this one: the joint's origin is in that link's tip frame)."""

    beam: SpatialSection | SpatialRigidBody
    joint: SpatialJoint = field(default_factory=SpatialJoint)
    hub: SpatialHub | None = None
    payload: SpatialPayload | None = None
    name: Name = ""
    parent: Name | None = None
    _where: str = field(default="link", repr=False, compare=False)

    def __post_init__(self):
        w = self._where
        _set(self, check_fields(SpatialLink, w, name=self.name, parent=self.parent))
        if self.name in RESERVED_NAMES:
            raise InputError(
                f"{w}.name", self.name, f"is reserved ({' and '.join(RESERVED_NAMES)} name frames)"
            )
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

    hub_mass = BodyValue("hub", "mass")
    hub_inertia = BodyValue("hub", "inertia_matrix", lambda: np.zeros((3, 3)))
    payload_mass = BodyValue("payload", "mass")
    payload_inertia = BodyValue("payload", "inertia_matrix", lambda: np.zeros((3, 3)))

    @property
    def payload_offset(self) -> np.ndarray:
        return np.array(self.payload.offset if self.payload else (0.0, 0.0, 0.0), dtype=float)


@dataclass(frozen=True)
class SpatialClosure(Checked):
    """A joint that closes a loop (docs/spatial.md "Trees and closed loops"): ``kind``
    "revolute" (5 equations), "spherical" (3) or "weld" (6) between the point ``point`` of link
    ``link`` (m, in its tip frame) and the point ``to_point`` of ``to`` (another link's name, in
    its tip frame, or "ground": world frame; None: where ``point`` is at the initial state);
    ``axis`` (revolute): unit vector in ``link``'s tip frame, its image in ``to``'s frame fixed at
    the initial state; ``name`` ("" → "closure{j}", 1-based)."""

    kind: Literal["revolute", "spherical", "weld"]
    link: Name
    to: Name = "ground"
    point: BoundedVec3 = (0.0, 0.0, 0.0)
    to_point: BoundedVec3 | None = None
    axis: Vec3 = (0.0, 0.0, 1.0)
    name: Name = ""
    _where: str = field(default="closure", repr=False, compare=False)

    def _rules(self):
        w = self._where
        object.__setattr__(self, "axis", _unit(self.axis, f"{w}.axis"))
        if self.link == "ground":
            raise InputError(f"{w}.link", self.link, "must name a link (`to` may be the ground)")
        if self.link == self.to:
            raise InputError(f"{w}.to", self.to, "must differ from `link` (a closure joins two bodies)")

    @property
    def n_equations(self) -> int:
        return CLOSURE_EQUATIONS[self.kind]


#: the strict models of the fields (derived from the dataclasses, the one declaration)
SpatialSectionFields = fields_model(SpatialSection)
SpatialJointFields = fields_model(SpatialJoint)
SpatialClosureFields = fields_model(SpatialClosure)


@dataclass(frozen=True)
class SpatialManipulator:
    """A spatial arm: revolute joints and flexible or rigid links, parents first (docs/spatial.md
    §1): a chain (every parent the previous link, the default), a tree (``SpatialLink.parent``)
    or a mechanism with closed loops (``closures``: :class:`SpatialClosure`).

    ``gravity`` (m/s², in the world frame); ``base_xyz`` (m) and ``base_rpy`` (rad) place the base
    frame in the world; ``end_effector``: a link name (None: the last link).
    """

    links: tuple
    gravity: BoundedVec3 = (0.0, 0.0, 0.0)
    base_xyz: BoundedVec3 = (0.0, 0.0, 0.0)
    base_rpy: Vec3 = (0.0, 0.0, 0.0)
    closures: tuple = ()
    end_effector: str | None = None

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
                SpatialManipulator,
                "model",
                gravity=self.gravity,
                base_xyz=self.base_xyz,
                base_rpy=self.base_rpy,
            ),
        )
        names = tuple(link.name or f"link{i + 1}" for i, link in enumerate(links))
        index: dict[str, int] = {}
        parents = []
        for i, (link, name) in enumerate(zip(links, names)):
            if name in index:
                raise InputError(
                    f"model.links[{i}].name",
                    name,
                    f"is the name of model.links[{index[name]}] (names are unique)",
                )
            p = link.parent
            if p is None:
                parents.append(i - 1)
            elif p == "base":
                parents.append(-1)
            elif p in index:
                parents.append(index[p])
            else:
                later = p in names
                raise InputError(
                    f"model.links[{i}].parent",
                    p,
                    "must name a link listed before this one (parents come first)"
                    if later
                    else f"names no link (links: {', '.join(names[:i]) or 'none before this one'}; or 'base')",
                )
            index[name] = i
        object.__setattr__(self, "_names", names)
        object.__setattr__(self, "_parents", tuple(parents))
        if not isinstance(self.closures, (tuple, list)):
            raise InputError(
                "model.closures", _short(self.closures), "must be a tuple of dttmm.spatial.SpatialClosure"
            )
        closures = tuple(self.closures)
        cnames = set()
        for j, cl in enumerate(closures):
            w = f"model.closures[{j}]"
            if not isinstance(cl, SpatialClosure):
                raise InputError(w, _short(cl), "must be a dttmm.spatial.SpatialClosure")
            if cl.link not in index:
                raise InputError(f"{w}.link", cl.link, f"names no link (links: {', '.join(names)})")
            if cl.to != "ground" and cl.to not in index:
                raise InputError(f"{w}.to", cl.to, f"names no link (links: {', '.join(names)}; or 'ground')")
            cname = cl.name or f"closure{j + 1}"
            if cname in cnames:
                raise InputError(f"{w}.name", cname, "is the name of an earlier closure (names are unique)")
            cnames.add(cname)
        object.__setattr__(self, "closures", closures)
        if self.end_effector is not None and (
            not isinstance(self.end_effector, str) or self.end_effector not in index
        ):
            raise InputError(
                "model.end_effector",
                _short(self.end_effector),
                f"must name a link (links: {', '.join(names)})",
            )

    @property
    def n_links(self) -> int:
        return len(self.links)

    @property
    def link_names(self) -> tuple[str, ...]:
        """Every link's name (the default "link{i}", 1-based, where none is given)."""
        return self._names

    @property
    def closure_names(self) -> tuple[str, ...]:
        return tuple(cl.name or f"closure{j + 1}" for j, cl in enumerate(self.closures))

    @property
    def parents(self) -> tuple[int, ...]:
        """The parent's index of every link (−1: the base); a parent comes before its children."""
        return self._parents

    def link_index(self, name: str) -> int:
        """The index of the link called ``name``."""
        try:
            return self._names.index(name)
        except ValueError:
            raise InputError("link", name, f"names no link (links: {', '.join(self._names)})") from None

    def children(self, i: int) -> tuple[int, ...]:
        """The indices of the links whose parent is link ``i`` (−1: the base)."""
        return tuple(j for j, p in enumerate(self._parents) if p == i)

    @property
    def leaves(self) -> tuple[int, ...]:
        """The links with no child (their tips are free ends of the tree)."""
        has_child = set(self._parents)
        return tuple(i for i in range(len(self.links)) if i not in has_child)

    @property
    def end_effector_index(self) -> int:
        """The index of the end-effector link (default: the last link)."""
        return len(self.links) - 1 if self.end_effector is None else self._names.index(self.end_effector)

    @property
    def n_closure_equations(self) -> int:
        return sum(cl.n_equations for cl in self.closures)

    @property
    def serial(self) -> bool:
        """Whether the arm is a serial chain (every parent the previous link, no closure)."""
        return not self.closures and all(p == i - 1 for i, p in enumerate(self._parents))

    @property
    def size(self) -> float:
        """The mechanism's size (m): the sum over links of the length and the joint origin's
        distance; the scale of the closures' position tolerances."""
        return float(
            sum(link.beam.length + float(np.linalg.norm(link.joint.origin_xyz)) for link in self.links)
        )

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

    Joint axes z, zero origins, in-plane bending EIz = EI; a rigid link becomes a
    :class:`SpatialRigidBody` (centre of mass (x, y, 0), inertia J about each axis), a payload's
    offset (x, y, 0); the out-of-plane data (never excited)
    are EIy = GJ = EI and rhoJ = rhoA·L², which keeps their natural frequencies at or below the
    in-plane ones (so an explicit integrator stable for the plane is stable for them too).
    Gravity (g_x, g_y) of the plane becomes R_base·(g_x, g_y, 0) in the world.
    """
    if not isinstance(manipulator, Manipulator):
        raise InputError("manipulator", _short(manipulator), "must be a dttmm.Manipulator")
    rot = rpy_matrix(check_fields(SpatialManipulator, "base", base_rpy=base_rpy)["base_rpy"])
    links = []
    for i, link in enumerate(manipulator.links):
        b, w = link.beam, f"model.links[{i}]"
        if link.rigid:  # in-plane inertia J about z; the out-of-plane axes (never excited) J too
            beam = SpatialRigidBody(
                length=b.length,
                mass=b.mass,
                com=(b.com[0], b.com[1], 0.0),
                inertia=(b.inertia, b.inertia, b.inertia),
                _where=f"{w}.rigid",
            )
        else:
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
            off = link.payload.offset
            pay = SpatialPayload(
                link.payload.mass,
                (off[0], off[1], 0.0),
                (0.0, 0.0, link.payload.inertia),
                _where=f"{w}.payload",
            )
        links.append(SpatialLink(beam, SpatialJoint(_where=f"{w}.joint"), hub, pay, _where=w))
    g = rot @ np.array([manipulator.gravity[0], manipulator.gravity[1], 0.0])
    return SpatialManipulator(tuple(links), tuple(float(x) for x in g), base_xyz, base_rpy)


def require_serial(model: SpatialManipulator, method: str) -> None:
    """Refuse a tree or a closed loop for an engine that runs serial chains only."""
    if model.serial:
        return
    if model.closures:
        field_, value = "model.closures", f"{len(model.closures)} closures"
    else:
        i = next(i for i, p in enumerate(model.parents) if p != i - 1)
        field_, value = f"model.links[{i}].parent", model.links[i].parent
    raise InputError(field_, value, f"trees and closed loops are not supported by {method} yet")


def require_open_chain(model: SpatialManipulator, method: str) -> None:
    """Refuse a closed loop (a tree runs) for a method that takes no loop closure."""
    if model.closures:
        raise InputError(
            "model.closures", f"{len(model.closures)} closures", f"closed loops are not supported by {method}"
        )


def require_flexible(model: SpatialManipulator, method: str) -> None:
    """Refuse an arm with rigid links (``SpatialRigidBody``) for an engine that models flexible
    links only (rigid links run in the spatial DT-TMM, the spatial global solver and Pinocchio)."""
    for i, link in enumerate(model.links):
        if link.rigid:
            raise InputError(
                f"model.links[{i}].rigid", _short(link.beam), f"rigid links are not supported by {method} yet"
            )
