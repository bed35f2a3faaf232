"""The physical model of a planar manipulator with flexible links (SI units, radians).

All classes are frozen dataclasses validated on construction; make variants with
:func:`dataclasses.replace`. The annotations of the case fields are their value types, the one
declaration the case-file layer (:mod:`dttmm.case`) uses too.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from .errors import InputError
from .schema import Bounded, Checked, NonNegative, Positive, check_fields, tuple_of

__all__ = ["Hub", "Link", "Manipulator", "Payload", "RigidBody", "Section"]


class _Beam:
    """What a beam (:class:`Section`, :class:`dttmm.spatial.SpatialSection`) derives from its
    ``length``, ``rhoA`` and ``EA``."""

    @property
    def mass(self) -> float:
        return self.rhoA * self.length

    @property
    def extensible(self) -> bool:
        return self.EA is not None


class BodyValue:
    """A link's property read from one of its bodies: ``attr`` of its ``body`` (``"hub"`` or
    ``"payload"``), or ``empty()`` when the link has no such body (planar and spatial links)."""

    def __init__(self, body: str, attr: str, empty=float):
        self.body, self.attr, self.empty = body, attr, empty

    def __get__(self, link, owner=None):
        if link is None:
            return self
        b = getattr(link, self.body)
        return self.empty() if b is None else getattr(b, self.attr)


@dataclass(frozen=True)
class Section(Checked, _Beam):
    """Uniform Euler-Bernoulli beam data of one link.

    Parameters
    ----------
    length : float
        Link length L (m).
    EI : float
        Bending stiffness (N·m²).
    rhoA : float
        Mass per unit length (kg/m).
    EA : float or None
        Axial stiffness (N); ``None`` makes the link inextensible (no axial coordinate).
    damping : float
        Stiffness-proportional (Kelvin-Voigt) coefficient μ (s): D = μK.
    """

    length: Positive
    EI: Positive
    rhoA: Positive
    EA: Positive | None = None
    damping: NonNegative = 0.0
    _where: str = field(default="section", repr=False, compare=False)

    @classmethod
    def from_material(
        cls, length, E, rho, width, thickness, *, EA=True, damping=0.0, where="section"
    ) -> Section:
        """Rectangular section from Young's modulus E (Pa), density ρ (kg/m³), width and
        thickness (m). ``EA=True`` derives E·A; ``EA=None`` makes the link inextensible."""
        m = check_fields(Material, where, E=E, rho=rho, width=width, thickness=thickness)
        return cls(length, *_of_material(**m, EA=EA), damping, _where=where)


def _of_material(E, rho, width, thickness, *, EA):
    """(EI, rhoA, EA) of a rectangular section; ``EA=True`` derives E·A, else it is kept."""
    b, t = width, thickness
    return E * b * t**3 / 12.0, rho * b * t, E * b * t if EA is True else EA


@dataclass(frozen=True)
class Material:
    """Rectangular section from material: E (Pa), rho (kg/m³), width and thickness (m); the
    fields of :meth:`Section.from_material` and of a link table's material form."""

    E: Positive
    rho: Positive
    width: Positive
    thickness: Positive


@dataclass(frozen=True)
class _Body(Checked):
    """A rigid body on the beam axis: mass (kg) and inertia (kg·m²) about its attachment point."""

    mass: NonNegative = 0.0
    inertia: NonNegative = 0.0
    _where: str = field(default="body", repr=False, compare=False)


@dataclass(frozen=True)
class Hub(_Body):
    """Rigid body at a link root, on the outboard side of the joint (kg, kg·m² about the joint)."""

    _where: str = field(default="hub", repr=False, compare=False)


@dataclass(frozen=True)
class Payload(_Body):
    """Rigid body at a link tip, fixed to the tip cross-section: mass (kg), ``offset`` (m, its
    centre of mass in the tip frame: x along the link's tip tangent, y across; default on the
    axis) and inertia (kg·m² about its centre of mass; with a zero offset that is the tip)."""

    offset: tuple_of(Bounded, min_length=2, max_length=2) = (0.0, 0.0)
    _where: str = field(default="payload", repr=False, compare=False)

    @property
    def offset_set(self) -> bool:
        """Whether the centre of mass is off the tip."""
        return any(x != 0.0 for x in self.offset)


@dataclass(frozen=True)
class RigidBody(Checked):
    """The body of a rigid link, in place of its beam (the planar form of
    :class:`dttmm.spatial.SpatialRigidBody`): ``length`` L (m: the next joint, the link's tip,
    lies L along the link's x axis), ``mass`` (kg), ``com`` (m, the centre of mass in the link
    frame: x along the link, y across), ``inertia`` (kg·m², about the centre of mass). A rigid
    link has no elastic coordinates."""

    length: Positive
    mass: NonNegative = 0.0
    com: tuple_of(Bounded, min_length=2, max_length=2) = (0.0, 0.0)
    inertia: NonNegative = 0.0
    _where: str = field(default="rigid", repr=False, compare=False)


@dataclass(frozen=True)
class Link:
    """One link: its beam (a :class:`Section`: flexible) or its body (a :class:`RigidBody`:
    rigid), an optional hub at the root and payload at the tip."""

    beam: Section | RigidBody
    hub: Hub | None = None
    payload: Payload | None = None

    def __post_init__(self):
        if not isinstance(self.beam, (Section, RigidBody)):
            raise InputError("link.beam", self.beam, "must be a dttmm.Section or a dttmm.RigidBody")
        if self.hub is not None and not isinstance(self.hub, Hub):
            raise InputError("link.hub", self.hub, "must be a dttmm.Hub or None")
        if self.payload is not None and not isinstance(self.payload, Payload):
            raise InputError("link.payload", self.payload, "must be a dttmm.Payload or None")

    @property
    def rigid(self) -> bool:
        """Whether the link is rigid (its ``beam`` a :class:`RigidBody`)."""
        return isinstance(self.beam, RigidBody)

    @property
    def length(self) -> float:
        return self.beam.length

    payload_offset = BodyValue("payload", "offset", lambda: (0.0, 0.0))
    hub_mass = BodyValue("hub", "mass")
    hub_inertia = BodyValue("hub", "inertia")
    payload_mass = BodyValue("payload", "mass")
    payload_inertia = BodyValue("payload", "inertia")


@dataclass(frozen=True)
class Manipulator(Checked):
    """A planar serial arm: n revolute joints (about z) and n links (flexible or rigid), base
    first.

    Joint i sits at the root of link i; joint 1 at the origin of the ground frame.
    ``gravity`` is the gravitational acceleration in the plane (m/s²).
    """

    links: tuple[Link, ...]
    gravity: tuple_of(Bounded, min_length=2, max_length=2) = (0.0, 0.0)
    _where = "model"

    def _rules(self):
        if not isinstance(self.links, (tuple, list)):
            raise InputError("model.links", self.links, "must be a tuple of dttmm.Link")
        links = tuple(self.links)
        if not links:
            raise InputError("model.links", self.links, "needs at least one link")
        for i, link in enumerate(links):
            if not isinstance(link, Link):
                raise InputError(f"model.links[{i}]", link, "must be a dttmm.Link")
        object.__setattr__(self, "links", links)

    @property
    def n_links(self) -> int:
        return len(self.links)

    @property
    def rigid_links(self) -> tuple[int, ...]:
        """Indices of the rigid links."""
        return tuple(i for i, link in enumerate(self.links) if link.rigid)

    @property
    def flexible_only(self) -> bool:
        """Whether every link is a beam and every payload sits on its tip (the arms every
        planar method models; rigid links and offset payloads need :func:`require_flexible`'s
        methods)."""
        return not any(
            link.rigid or (link.payload is not None and link.payload.offset_set) for link in self.links
        )


def require_flexible(model: Manipulator, method: str) -> None:
    """Refuse a planar arm with a rigid link or an offset payload for a method that models
    flexible links with bodies on the beam axis only (one line naming the field)."""
    for i, link in enumerate(model.links):
        if link.rigid:
            raise InputError(
                f"model.links[{i}].rigid", link.beam, f"rigid links are not supported by {method}"
            )
        if link.payload is not None and link.payload.offset_set:
            raise InputError(
                f"model.links[{i}].payload.offset",
                link.payload.offset,
                f"an offset payload is not supported by {method}",
            )
