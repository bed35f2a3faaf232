"""A robot from its URDF: the spatial arm of a URDF file, with the links you name made flexible
(docs/urdf.md).

:func:`load_urdf` reads a URDF (the standard library's XML parser; meshes are ignored) into a
:class:`dttmm.spatial.SpatialManipulator`; :func:`read_urdf` returns the same with the joint
names, the joints' limits and the provenance (:class:`UrdfArm`), and :meth:`UrdfArm.case`
makes a :class:`dttmm.spatial.SpatialCase` with a scenario. A spatial case file whose
``[model]`` names ``urdf = "..."`` is read by :func:`case_from_urdf_dict` (``dttmm.load_case``
sends it here).

The mapping (docs/urdf.md "What the import does"):

* ``revolute`` and ``continuous`` joints → revolute joints (``SpatialJoint``: the URDF
  ``origin`` and ``axis``; URDF's default axis is x); ``fixed`` joints, and the joints named in
  ``lock`` (held at zero), weld their child to the parent: the child's inertia is merged into the
  moving body it hangs on (mass, centre of mass and inertia about it; links welded to the ground
  carry nothing), and the origins of the joints beyond it are composed through it. So every
  model link is one moving body, a rigid link of length 0 (its tip frame is its link frame, the
  URDF link frame) whose next joint's origin carries the offset — Pinocchio's reading of a URDF.
* a kinematic tree (a body carrying several moving joints, directly or through links welded to
  it; several moving joints on the ground): the bodies are listed depth first in the URDF's
  joint order (a chain: base first), each link's ``parent`` the model link of the body its joint
  hangs on (``"base"`` on the ground); the model links take the URDF link names (a kept body
  before its beam ``<link>.body``; a reserved name, ``base`` or ``ground``, takes a "_"). A
  chain's model is the plain chain it always was (no names, no parents).
* refused, one line each (:class:`dttmm.InputError` naming the joint or link): ``prismatic``,
  ``planar`` and ``floating`` joints (unless locked), a link with two parents (a closed loop:
  a URDF cannot describe one), more than one root or a link not connected to the root, a link
  carried by a moving joint without ``<inertial>``, a tree with several leaves and no ``tool``.
* ``flexible = {link: overlay}`` (see :class:`FlexibleFile`): the beam of that link runs from
  its joint to the origin of the next moving joint; the link frame is turned (R_a, x along the
  beam, z along the part of the joint axis normal to it) so that its x axis points there. With
  ``keep_inertia = false`` the link is one flexible link: its joint's ``origin_rpy`` is that of
  R_rpy·R_a and its ``axis`` R_aᵀa, the beam's own mass replaces the URDF body. With
  ``keep_inertia = true`` the URDF body stays as a rigid link of length 0 on the joint (its
  centre of mass and inertia as in the URDF) and the beam follows it on a locked joint at the
  same point turned by R_a (docs/spatial.md §5: a rigid link of length 0 followed by a flexible
  link on a locked joint is a body with an offset centre of mass at the beam's root); the
  beam's mass adds to the body's. Either way the next joint's origin becomes
  (R_aᵀ o − L e_x, R_aᵀ R_c) in the beam's tip frame (o, R_c: its URDF origin). In a tree the
  flexible link must carry exactly one moving joint (the next one).
* ``tool = "<link>"``: the end-effector is that link's origin (a link welded to the last body of
  a chain, to a leaf body of a tree): a massless rigid link on a locked joint reaches it; in a
  tree, a leaf's own link is the end-effector itself (its frame is its tip frame). A tree with
  several leaves needs a tool (``SpatialManipulator.end_effector``).
"""

from __future__ import annotations

import difflib
import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Annotated, Any

import numpy as np
from pydantic import Strict, ValidationError

from .case import _drive
from .casedoc import case_file_model, validate_document
from .errors import InputError
from .schema import BIG, Finite, NonNegative, _short, _Strict, input_error
from .sections import IBeam, Material, Rectangle, Tube, section_properties
from .spatial.case import (
    BEAM_DATA,
    BEAM_REQUIRED,
    BaseFile,
    BeamDataFile,
    SpatialCase,
    SpatialScenarioFile,
    _load,
)
from .spatial.model import (
    RESERVED_NAMES,
    BoundedVector3,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialRigidBody,
    SpatialSection,
)
from .spatial.rotation import rpy_matrix
from .spatial.scenario import SpatialScenario

__all__ = [
    "ROBOTS_PREFIX",
    "FlexibleFile",
    "JointLimits",
    "UrdfArm",
    "UrdfCaseFile",
    "case_from_urdf_dict",
    "load_urdf",
    "matrix_rpy",
    "read_urdf",
    "resolve_urdf",
    "robots_dir",
]

#: a URDF named ``example-robot-data:<path under robots/>`` is taken from that package
ROBOTS_PREFIX = "example-robot-data:"
_MOVING = ("revolute", "continuous")
_REFUSED = ("prismatic", "planar", "floating")


# --- where a URDF comes from ------------------------------------------------------------------
def robots_dir() -> Path:
    """The ``robots/`` folder of the installed ``example-robot-data`` (the cmeel wheel installs
    its URDFs under ``cmeel.prefix/share/example-robot-data/robots``; it has no Python module)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        raise InputError(
            "urdf", ROBOTS_PREFIX, "needs the package example-robot-data (pip install 'dttmm[robots]')"
        ) from None
    return Path(dist.locate_file("cmeel.prefix/share/example-robot-data/robots"))


def resolve_urdf(spec, base_dir=None) -> Path:
    """The file of a URDF reference: ``example-robot-data:<path under robots/>``, or a path
    (relative to ``base_dir``, default the working folder)."""
    s = str(spec)
    if s.startswith(ROBOTS_PREFIX):
        path = robots_dir() / s[len(ROBOTS_PREFIX) :]
    else:
        path = Path(s)
        if not path.is_absolute() and base_dir is not None:
            path = Path(base_dir) / path
    if not path.is_file():
        raise InputError("urdf", s, f"no such file ({path})")
    return path


# --- rotations --------------------------------------------------------------------------------
def matrix_rpy(r) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of a rotation matrix (R = Rz(y) Ry(p) Rx(r)); at p = ±π/2 the roll
    is 0."""
    r = np.asarray(r, dtype=float)
    cp = math.hypot(r[0, 0], r[1, 0])
    p = math.atan2(-r[2, 0], cp)
    if cp < 1e-12:
        return 0.0, p, math.atan2(-r[0, 1], r[1, 1])
    return math.atan2(r[2, 1], r[2, 2]), p, math.atan2(r[1, 0], r[0, 0])


def _beam_frame(d: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """R_a: columns x along ``d``, z along the part of ``axis`` normal to it (another axis of
    the link frame when ``axis`` runs along the beam), y = z × x."""
    x = d / np.linalg.norm(d)
    for z in (axis, np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.0, 0.0])):
        z = z - np.dot(z, x) * x
        if np.linalg.norm(z) > 1e-6:
            break
    z = z / np.linalg.norm(z)
    return np.column_stack([x, np.cross(z, x), z])


# --- the URDF document ------------------------------------------------------------------------
@dataclass(frozen=True)
class JointLimits:
    """A moving joint's ``<limit>`` as the URDF gives it (rad, rad/s, N·m; None: not given)."""

    joint: str
    lower: float | None = None
    upper: float | None = None
    velocity: float | None = None
    effort: float | None = None

    def as_dict(self) -> dict:
        keys = ("lower", "upper", "velocity", "effort")
        return {k: getattr(self, k) for k in keys if getattr(self, k) is not None}


@dataclass
class _Joint:
    name: str
    type: str
    parent: str
    child: str
    xyz: np.ndarray
    rpy: np.ndarray
    axis: np.ndarray
    limits: JointLimits


@dataclass
class _Body:
    """A moving body: the link its joint carries and every link welded to it."""

    link: str
    joint: _Joint
    rot: np.ndarray  # the joint frame in the parent body's frame (the base frame for the first)
    pos: np.ndarray
    parts: list = field(default_factory=list)  # (mass, centre, inertia about it) in the body frame
    frames: dict = field(default_factory=dict)  # link name -> (R, p) in the body frame
    moving: list = field(default_factory=list)  # the moving joints it carries
    rpy: tuple | None = None  # the joint's own origin rpy when no fixed joint comes between
    index: int = 0  # its place in the list of bodies
    parent: int = -1  # the index of the moving body it hangs on (−1: the ground)
    children: list = field(default_factory=list)  # the indices of the bodies it carries


def _numbers(el, attr: str, n: int, default, where: str) -> np.ndarray:
    text = None if el is None else el.get(attr)
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    try:
        vals = np.array([float(x) for x in parts], dtype=float)
    except ValueError:
        vals = None
    if vals is None or vals.size != n or not np.all(np.isfinite(vals)) or np.any(np.abs(vals) > BIG):
        raise InputError(where, text, f"must be {n} finite numbers")
    return vals


def _number(el, attr: str, where: str) -> float | None:
    text = None if el is None else el.get(attr)
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not math.isfinite(v):
        raise InputError(where, text, "must be a finite number")
    return v


def _inertial(el, name: str):
    """(mass, centre, inertia about it) of a ``<link>``'s ``<inertial>`` in the link frame, or
    None."""
    inert = el.find("inertial")
    if inert is None:
        return None
    w = f"link '{name}'.inertial"
    mass = _number(inert.find("mass"), "value", f"{w}.mass")
    if mass is None or mass < 0:
        raise InputError(f"{w}.mass", mass, "must be a non-negative number")
    origin = inert.find("origin")
    c = _numbers(origin, "xyz", 3, (0, 0, 0), f"{w}.origin.xyz")
    rot = rpy_matrix(_numbers(origin, "rpy", 3, (0, 0, 0), f"{w}.origin.rpy"))
    ie = inert.find("inertia")
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    v = {k: (_number(ie, k, f"{w}.inertia.{k}") or 0.0) for k in keys}
    j = np.array(
        [[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]]
    )
    return mass, c, rot @ j @ rot.T


def _parse(root) -> tuple[str, dict, list]:
    if root.tag != "robot":
        raise InputError("urdf", f"<{root.tag}>", "must be a <robot> document")
    links = {}
    for el in root.findall("link"):
        name = el.get("name")
        if not name:
            raise InputError("urdf.link", None, "every <link> needs a name")
        links[name] = el
    joints = []
    for el in root.findall("joint"):
        name = el.get("name") or "<unnamed>"
        w = f"joint '{name}'"
        jtype = el.get("type")
        parent, child = el.find("parent"), el.find("child")
        parent = None if parent is None else parent.get("link")
        child = None if child is None else child.get("link")
        for role, ln in (("parent", parent), ("child", child)):
            if ln not in links:
                raise InputError(f"{w}.{role}", ln, "is not a link of the URDF")
        origin = el.find("origin")
        axis = _numbers(el.find("axis"), "xyz", 3, (1, 0, 0), f"{w}.axis")
        lim = el.find("limit")
        limits = JointLimits(
            name,
            *(_number(lim, k, f"{w}.limit.{k}") for k in ("lower", "upper", "velocity", "effort")),
        )
        joints.append(
            _Joint(
                name,
                jtype,
                parent,
                child,
                _numbers(origin, "xyz", 3, (0, 0, 0), f"{w}.origin.xyz"),
                _numbers(origin, "rpy", 3, (0, 0, 0), f"{w}.origin.rpy"),
                axis,
                limits,
            )
        )
    return root.get("name") or "robot", links, joints


def _merge(parts) -> tuple[float, np.ndarray, np.ndarray]:
    """One rigid body of several: mass, centre of mass, inertia about it."""
    m = sum(p[0] for p in parts)
    if m <= 0.0:
        return 0.0, np.zeros(3), sum((p[2] for p in parts), np.zeros((3, 3)))
    c = sum(p[0] * p[1] for p in parts) / m
    j = np.zeros((3, 3))
    for mi, ci, ji in parts:
        r = ci - c
        j += ji + mi * (np.dot(r, r) * np.eye(3) - np.outer(r, r))
    return m, c, 0.5 * (j + j.T)


def _nearest(name: str, names) -> str:
    close = difflib.get_close_matches(name, list(names), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


def _bodies(links: dict, joints: list, lock) -> tuple[list[_Body], dict]:
    """The moving bodies, parents first (depth first in the URDF's joint order: a chain base
    first), each with its parent body, and the frames welded to the ground."""
    names = {j.name for j in joints}
    for j in lock:
        if j not in names:
            raise InputError("lock", j, f"is not a joint of the URDF{_nearest(j, names)}")
    parent_of, children = {}, {name: [] for name in links}
    for j in joints:
        if j.child in parent_of:
            raise InputError(
                f"link '{j.child}'",
                f"parents {parent_of[j.child].parent!r} and {j.parent!r}",
                "has two parents (a closed loop, which a URDF cannot describe): chains and trees only",
            )
        parent_of[j.child] = j
        children[j.parent].append(j)
    roots = [n for n in links if n not in parent_of]
    if len(roots) != 1:
        reason = "no root link (a closed loop)" if not roots else f"{len(roots)} root links: one tree needed"
        raise InputError("urdf", ", ".join(roots) or "<none>", reason)
    bodies: list[_Body] = []
    ground = {"frames": {}, "moving": []}
    seen = set()

    def visit(link, body, rot, pos):
        seen.add(link)
        link_is_body = body is not None and link == body.link or body is None and link == roots[0]
        if body is not None:
            inert = _inertial(links[link], link)
            if inert is not None:
                m, c, jj = inert
                body.parts.append((m, pos + rot @ c, rot @ jj @ rot.T))
            body.frames[link] = (rot, pos)
        else:
            ground["frames"][link] = (rot, pos)
        for j in children[link]:
            r2, p2 = rot @ rpy_matrix(j.rpy), pos + rot @ j.xyz
            locked = j.name in lock
            if j.type == "fixed" or locked:
                visit(j.child, body, r2, p2)
            elif j.type in _MOVING:
                if _inertial(links[j.child], j.child) is None:
                    raise InputError(
                        f"link '{j.child}'.inertial",
                        None,
                        f"is missing: the link moves (joint '{j.name}') and needs its mass and inertia",
                    )
                (ground["moving"] if body is None else body.moving).append(j.name)
                new = _Body(j.child, j, r2, p2, index=len(bodies))
                if link_is_body:
                    new.rpy = tuple(float(x) for x in j.rpy)
                if body is not None:
                    new.parent = body.index
                    body.children.append(new.index)
                bodies.append(new)
                visit(j.child, new, np.eye(3), np.zeros(3))
            elif j.type in _REFUSED:
                raise InputError(
                    f"joint '{j.name}'.type",
                    j.type,
                    "is not supported (revolute, continuous and fixed joints only; "
                    "lock = [...] holds a joint at zero)",
                )
            else:
                raise InputError(f"joint '{j.name}'.type", j.type, "is not a URDF joint type")

    visit(roots[0], None, np.eye(3), np.zeros(3))
    lost = [n for n in links if n not in seen]
    if lost:
        raise InputError(f"link '{lost[0]}'", None, "is not connected to the root (a closed loop)")
    if not bodies:
        raise InputError("urdf", roots[0], "has no revolute or continuous joint: nothing moves")
    return bodies, ground["frames"]


# --- the flexible-link overlay ----------------------------------------------------------------
class SectionFile(_Strict):
    """One section shape (dttmm.sections): ``tube``, ``rectangle`` or ``i_beam``."""

    tube: Tube | None = None
    rectangle: Rectangle | None = None
    i_beam: IBeam | None = None


class FlexibleFile(BeamDataFile):
    """The overlay of one flexible link (``[model.flexible.<link>]``, docs/urdf.md): a
    ``section`` and a ``material`` (dttmm.sections), or the beam data themselves (EA, GJ, EIy,
    EIz, rhoA, rhoJ, rhoIy, rhoIz); ``keep_inertia`` (required): keep the URDF body as a rigid
    body at the beam's root (the beam's mass adds) or replace it by the beam;
    ``extensible`` (false: EA dropped, an inextensible beam), ``roll``, ``damping`` as in a
    spatial link."""

    keep_inertia: bool
    section: SectionFile | None = None
    material: Annotated[str, Strict()] | Material | None = None
    extensible: bool = True
    roll: Finite = 0.0
    damping: NonNegative = 0.0


def _overlay(spec, where: str) -> FlexibleFile:
    if isinstance(spec, FlexibleFile):
        return spec
    try:
        return FlexibleFile.model_validate(spec)
    except ValidationError as exc:
        raise input_error(exc, FlexibleFile, where) from None


def _section_data(ov: FlexibleFile, where: str) -> dict:
    given = [k for k in BEAM_DATA if getattr(ov, k) is not None]
    if ov.section is not None:
        if given:
            raise InputError(
                f"{where}.{given[0]}", getattr(ov, given[0]), "give a section or the beam data, not both"
            )
        shapes = {k: v for k, v in ov.section.model_dump().items() if v is not None}
        if len(shapes) != 1:
            raise InputError(
                f"{where}.section", _short(shapes), "must give exactly one of tube, rectangle, i_beam"
            )
        if ov.material is None:
            raise InputError(f"{where}.material", None, "is required with a section")
        mat = ov.material if isinstance(ov.material, str) else ov.material.model_dump(exclude_none=True)
        data = section_properties(shapes, mat, f"{where}.section", f"{where}.material")
    else:
        if ov.material is not None:
            raise InputError(f"{where}.material", _short(ov.material), "needs a section")
        for k in BEAM_REQUIRED:
            if getattr(ov, k) is None:
                raise InputError(f"{where}.{k}", None, "is required (or give section and material)")
        data = {k: getattr(ov, k) for k in given}
    if not ov.extensible:
        data.pop("EA", None)
    return data


# --- the arm ----------------------------------------------------------------------------------
@dataclass(frozen=True)
class UrdfArm:
    """A URDF read as a spatial arm: ``model``; ``joints`` the URDF names of its unlocked joints
    (base first: one drive each); ``links`` the URDF link of each model link (a flexible link
    with its URDF body kept is two model links, the body and the beam); ``limits`` each unlocked
    joint's ``<limit>``; ``flexible`` the URDF links made flexible; ``source`` the file."""

    model: SpatialManipulator
    joints: tuple
    links: tuple
    limits: tuple
    flexible: tuple
    source: str
    name: str

    def provenance(self) -> dict:
        """The import's record (no None values: a case file's provenance table can hold it)."""
        return {
            "urdf": self.source,
            "joints": list(self.joints),
            "links": list(self.links),
            "flexible": list(self.flexible),
            "limits": {lim.joint: lim.as_dict() for lim in self.limits},
        }

    def case(self, scenario, name: str | None = None, provenance: dict | None = None):
        """A :class:`dttmm.spatial.SpatialCase` of this arm and ``scenario`` (one drive per
        unlocked joint, in the order of :attr:`joints`); the provenance records the import."""
        prov = {**(provenance or {}), **self.provenance()}
        return SpatialCase(self.model, scenario, self.name if name is None else name, prov)


def _text_or_path(source) -> tuple[Any, str]:
    if isinstance(source, str) and source.lstrip().startswith("<"):
        try:
            return ET.fromstring(source), "<text>"
        except ET.ParseError as exc:
            raise InputError("urdf", "<text>", f"is not valid XML: {exc}") from None
    path = resolve_urdf(source)
    try:
        return ET.parse(path).getroot(), str(source)
    except ET.ParseError as exc:
        raise InputError("urdf", str(source), f"is not valid XML: {exc}") from None


def read_urdf(
    source,
    flexible: dict | None = None,
    *,
    lock=(),
    tool: str | None = None,
    gravity=(0.0, 0.0, -9.81),
    base_xyz=(0.0, 0.0, 0.0),
    base_rpy=(0.0, 0.0, 0.0),
) -> UrdfArm:
    """The spatial arm of a URDF (a path, ``example-robot-data:<path under robots/>``, or the
    URDF text itself) with the links named in ``flexible`` (``{link: overlay}``, each overlay a
    :class:`FlexibleFile` or its table) made flexible; ``lock`` names joints held at zero (e.g.
    a gripper's prismatic fingers); ``tool`` a link welded to the last body (a chain) or to a
    leaf body (a tree: required with several leaves) whose origin is the end-effector;
    ``gravity`` (m/s², world; URDF has none, the default is −9.81 along z as in Pinocchio),
    ``base_xyz``/``base_rpy`` the base frame in the world. See the module notes."""
    root, src = _text_or_path(source)
    name, links, joints = _parse(root)
    lock = tuple(lock)
    bodies, _ = _bodies(links, joints, lock)
    tree = any(b.parent != i - 1 for i, b in enumerate(bodies))
    flexible = dict(flexible or {})
    by_link = {b.link: i for i, b in enumerate(bodies)}
    for ln in flexible:
        if ln not in by_link:
            owner = next((b.link for b in bodies if ln in b.frames), None)
            if owner is not None:
                reason = f"is welded to '{owner}' (a fixed joint): name '{owner}'"
            elif ln in links:
                reason = "does not move"
            else:
                reason = f"is not a link of the URDF{_nearest(ln, links)}"
            raise InputError(f"flexible.{ln}", ln, reason)
        after = bodies[by_link[ln]].children
        if not after:
            where = "a leaf of the tree" if tree else "the last moving link"
            raise InputError(f"flexible.{ln}", ln, f"is {where}: a flexible link runs to the next joint")
        if len(after) > 1:
            nxt = ", ".join(bodies[c].joint.name for c in after)
            raise InputError(
                f"flexible.{ln}",
                ln,
                f"carries {len(after)} moving joints ({nxt}): a flexible link runs to its one next joint",
            )
    leaves = [b for b in bodies if not b.children]
    owner = _tool_owner(tool, bodies, leaves, links, tree)
    taken: set = set()

    def model_name(ln: str) -> str:
        """A tree's model link is named after its URDF link (a reserved name takes a "_")."""
        while ln in RESERVED_NAMES or ln in taken:
            ln += "_"
        taken.add(ln)
        return ln

    out, out_names = [], []
    tips: list[str] = []  # a tree: the model link whose tip frame is each body's frame
    moved = {}  # body index -> the joint's origin (R, p), where a flexible parent has moved it
    for i, body in enumerate(bodies):
        jt, w = body.joint, f"link '{body.link}'"
        rot, pos = moved.get(i, (body.rot, body.pos))
        topo = {}
        if tree:
            topo["parent"] = "base" if body.parent < 0 else tips[body.parent]
        m, c, jj = _merge(body.parts)
        axis = jt.axis / np.linalg.norm(jt.axis) if np.linalg.norm(jt.axis) > 0 else jt.axis
        rpy = body.rpy if body.rpy is not None and rot is body.rot else matrix_rpy(rot)
        if body.link not in flexible:
            rigid = SpatialRigidBody(0.0, m, tuple(c), jj, _where=f"{w}.inertial")
            joint = SpatialJoint(tuple(axis), tuple(pos), rpy, _where=f"joint '{jt.name}'")
            if tree:
                topo["name"] = model_name(body.link)
            out.append(SpatialLink(rigid, joint, _where=w, **topo))
            out_names.append(body.link)
            tips.append(topo.get("name", ""))
            continue
        fw = f"flexible.{body.link}"
        ov = _overlay(flexible[body.link], fw)
        nxt = bodies[body.children[0]]
        d = nxt.pos
        length = float(np.linalg.norm(d))
        if length < 1e-6:
            raise InputError(
                fw, body.link, f"the next joint '{nxt.joint.name}' is at its joint: no beam length"
            )
        ra = _beam_frame(d, axis)
        beam = SpatialSection(
            length=length, **_section_data(ov, fw), roll=ov.roll, damping=ov.damping, _where=f"{fw}.beam"
        )
        if ov.keep_inertia:
            rigid = SpatialRigidBody(0.0, m, tuple(c), jj, _where=f"{w}.inertial")
            joint = SpatialJoint(tuple(axis), tuple(pos), rpy, _where=f"joint '{jt.name}'")
            if tree:
                topo["name"] = model_name(f"{body.link}.body")
            out.append(SpatialLink(rigid, joint, _where=w, **topo))
            lock_joint = SpatialJoint(origin_rpy=matrix_rpy(ra), locked=True, _where=f"{fw}.joint")
            if tree:
                topo = {"name": model_name(body.link), "parent": topo["name"]}
            out.append(SpatialLink(beam, lock_joint, _where=fw, **topo))
            out_names += [body.link, body.link]
        else:
            joint = SpatialJoint(
                tuple(ra.T @ axis), tuple(pos), matrix_rpy(rot @ ra), _where=f"joint '{jt.name}'"
            )
            if tree:
                topo["name"] = model_name(body.link)
            out.append(SpatialLink(beam, joint, _where=fw, **topo))
            out_names.append(body.link)
        tips.append(topo.get("name", ""))
        moved[body.children[0]] = (ra.T @ nxt.rot, ra.T @ nxt.pos - np.array([length, 0.0, 0.0]))
    end_effector = None
    if owner is not None and tree and tool == owner.link:
        end_effector = tips[owner.index]  # a leaf's own link: its frame is its tip frame
    elif owner is not None:
        rot, pos = owner.frames[tool]
        reach = float(np.linalg.norm(pos))
        ra = _beam_frame(pos, np.array([0.0, 0.0, 1.0])) if reach > 0 else rot
        topo = {"name": model_name(tool), "parent": tips[owner.index]} if tree else {}
        out.append(
            SpatialLink(
                SpatialRigidBody(reach, _where="tool"),
                SpatialJoint(origin_rpy=matrix_rpy(ra), locked=True, _where="tool.joint"),
                _where="tool",
                **topo,
            )
        )
        out_names.append(tool)
        end_effector = topo.get("name")
    model = SpatialManipulator(
        tuple(out), tuple(gravity), tuple(base_xyz), tuple(base_rpy), end_effector=end_effector
    )
    return UrdfArm(
        model,
        tuple(b.joint.name for b in bodies),
        tuple(out_names),
        tuple(b.joint.limits for b in bodies),
        tuple(ln for ln in flexible),
        src,
        name,
    )


def _tool_owner(tool, bodies, leaves, links, tree):
    """The leaf body that carries the link ``tool`` (None without a tool); a tree with several
    leaves needs one."""
    if tool is None:
        if len(leaves) > 1:
            names = ", ".join(b.link for b in leaves)
            raise InputError(
                "tool",
                None,
                f"must name the end-effector: the tree has {len(leaves)} leaves ({names}); "
                "give one of them or a link welded to one",
            )
        return None
    owner = next((b for b in leaves if tool in b.frames), None)
    if owner is not None:
        return owner
    if not tree:
        raise InputError("tool", tool, f"is not a link welded to the last moving link '{bodies[-1].link}'")
    names = ", ".join(b.link for b in leaves)
    inner = next((b.link for b in bodies if tool in b.frames), None)
    if inner is not None:
        reason = f"is on '{inner}', which carries moving joints: the end-effector is on a leaf ({names})"
    elif tool in links:
        reason = f"does not move: the end-effector is on a leaf ({names})"
    else:
        reason = f"is not a link of the URDF{_nearest(tool, links)}"
    raise InputError("tool", tool, reason)


def load_urdf(source, flexible: dict | None = None, **options) -> SpatialManipulator:
    """The :class:`dttmm.spatial.SpatialManipulator` of a URDF (:func:`read_urdf`'s ``model``;
    the same arguments)."""
    return read_urdf(source, flexible, **options).model


# --- the case file ----------------------------------------------------------------------------
class UrdfModelFile(_Strict):
    """``[model]`` of a case read from a URDF (docs/urdf.md "Case files")."""

    urdf: Annotated[str, Strict()]
    gravity: BoundedVector3 = [0.0, 0.0, -9.81]
    base: BaseFile = BaseFile()
    lock: Annotated[list[Annotated[str, Strict()]], Strict()] = []
    tool: Annotated[str, Strict()] | None = None
    flexible: dict[str, FlexibleFile] = {}


UrdfCaseFile = case_file_model(
    "UrdfCaseFile",
    __name__,
    UrdfModelFile,
    SpatialScenarioFile,
    spatial=True,
    doc='A whole case file whose arm comes from a URDF (``kind = "spatial"``, optional).',
)


def case_from_urdf_dict(data: dict, base_dir=None):
    """A :class:`dttmm.spatial.SpatialCase` from a parsed case document whose ``[model]`` names a
    ``urdf`` (a path relative to ``base_dir``, or ``example-robot-data:<path>``)."""
    spec = validate_document(UrdfCaseFile, data)
    m = spec.model
    try:
        path = resolve_urdf(m.urdf, base_dir)
    except InputError as exc:
        raise InputError("model.urdf", exc.value, exc.reason) from None
    arm = read_urdf(
        path,
        m.flexible,
        lock=m.lock,
        tool=m.tool,
        gravity=tuple(m.gravity),
        base_xyz=tuple(m.base.xyz),
        base_rpy=tuple(m.base.rpy),
    )
    arm = UrdfArm(arm.model, arm.joints, arm.links, arm.limits, arm.flexible, m.urdf, arm.name)
    sc = spec.scenario
    drives = tuple(_drive(d, i) for i, d in enumerate(sc.drives))
    if len(drives) != len(arm.joints):
        raise InputError(
            "scenario.drives",
            f"{len(drives)} drives",
            f"needs one per moving joint, base first: {', '.join(arm.joints)}",
        )
    loads = tuple(_load(d, j) for j, d in enumerate(sc.loads))
    scenario = SpatialScenario(sc.duration, sc.output_step, drives, loads)
    return arm.case(scenario, spec.name or arm.name, spec.provenance)
