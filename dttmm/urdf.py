"""The rigid arm of a case as URDF (``dttmm urdf CASE``), for robotics tools.

Layout (all joints and links in the x–y plane, z up out of the plane):

* ``base`` — the ground; ``joint{i}`` — revolute about z at the tip of link i−1 (at the
  origin for i = 1), with wide limits so that parsers make a plain 1-DOF joint (a
  ``continuous`` joint would become a (cos, sin) joint in Pinocchio);
* ``link{i}`` — the link as a uniform rigid rod: mass ρA·L at L/2, inertia mL²/12 about
  y and z of its centre;
* ``hub{i}`` / ``payload{i}`` — rigid bodies on fixed joints at the link root / tip
  (mass, inertia about z), present when the case has them;
* ``link{i}_tip`` — massless marker at each link tip, and ``tip`` at the end-effector.

Gravity is not part of URDF: the file records ``model.gravity`` in a comment only, and the
loading tool must set it (for Pinocchio: ``model.gravity.linear = [gx, gy, 0]``; its default
is −z, which does nothing to a planar arm). The flexibility of the links (EI, EA, damping)
has no URDF form and is dropped.

A spatial case (:class:`dttmm.spatial.SpatialCase` or ``SpatialManipulator``, docs/spatial.md)
gives its rigid limit: ``world`` and a fixed ``base_joint`` at the base frame (``base_xyz``,
``base_rpy``); ``joint{i}`` with the joint's ``axis``, its origin at the parent's tip frame
(x = L of the inboard link, in the rigid limit the tip frame is the link frame moved by L)
plus ``origin_xyz``/``origin_rpy``, ``fixed`` when the joint is locked (unlocked joints keep
the wide limits); ``link{i}`` the beam as a rigid body, mass ρA·L at (L/2, 0, 0), inertia about
its centre diag(0, mL²/12, mL²/12) + L·Rx(roll) diag(ρJ, ρIy, ρIz) Rx(roll)ᵀ (link frame), or a
rigid link's own body (mass, centre of mass, inertia about it);
``hub{i}`` at the root with its 3×3 inertia; ``payload{i}`` at (L, 0, 0) + offset with its
inertia about its centre; the ``link{i}_tip`` and ``tip`` markers as above. The gravity comment
has three components.
"""

from __future__ import annotations

import sys
import xml.etree.ElementTree as ET
from pathlib import Path

from .case import Case
from .cliparse import OneLineParser
from .errors import InputError
from .model import Manipulator

__all__ = ["case_to_urdf", "main"]

_WIDE = "1e9"  # joint limits (rad, N·m, rad/s) wide enough never to act


def _num(x: float) -> str:
    return repr(float(x))  # shortest round-trip form: the file holds the case's values exactly


def _origin(parent: ET.Element, x: float = 0.0):
    ET.SubElement(parent, "origin", xyz=f"{_num(x)} 0 0", rpy="0 0 0")


def _link(robot, name, mass=None, com_x=0.0, iyy=0.0, izz=0.0):
    link = ET.SubElement(robot, "link", name=name)
    if mass is not None:
        inertial = ET.SubElement(link, "inertial")
        _origin(inertial, com_x)
        ET.SubElement(inertial, "mass", value=_num(mass))
        ET.SubElement(inertial, "inertia", ixx="0", ixy="0", ixz="0", iyy=_num(iyy), iyz="0", izz=_num(izz))
    return link


def _fixed(robot, name, parent, child, x=0.0):
    joint = ET.SubElement(robot, "joint", name=name, type="fixed")
    _origin(joint, x)
    ET.SubElement(joint, "parent", link=parent)
    ET.SubElement(joint, "child", link=child)


def _link_tip(robot, i: int, L: float) -> tuple[str, float]:
    """Link ``i``'s tip frame, ``L`` along its x axis; the (parent, offset) of the next joint."""
    _fixed(robot, f"link{i}_tip_joint", f"link{i}", f"link{i}_tip", L)
    _link(robot, f"link{i}_tip")
    return f"link{i}", L


def _robot_text(robot, parent: str, x: float) -> str:
    """The URDF text of ``robot``, closed by the arm's ``tip`` frame (``x`` along ``parent``)."""
    _fixed(robot, "tip_joint", parent, "tip", x)
    _link(robot, "tip")
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def _inertia(parent, mass, xyz, J):
    inertial = ET.SubElement(parent, "inertial")
    ET.SubElement(inertial, "origin", xyz=" ".join(_num(v) for v in xyz), rpy="0 0 0")
    ET.SubElement(inertial, "mass", value=_num(mass))
    ET.SubElement(
        inertial,
        "inertia",
        ixx=_num(J[0][0]),
        ixy=_num(J[0][1]),
        ixz=_num(J[0][2]),
        iyy=_num(J[1][1]),
        iyz=_num(J[1][2]),
        izz=_num(J[2][2]),
    )


def _spatial_urdf(case, name):
    import numpy as np

    from .spatial import SpatialCase
    from .spatial.build import rx
    from .spatial.model import require_serial

    model = case.model if isinstance(case, SpatialCase) else case
    require_serial(model, "the URDF export")
    name = name or (case.name if isinstance(case, SpatialCase) and case.name else "arm")
    robot = ET.Element("robot", name=name)
    g = model.gravity
    robot.append(
        ET.Comment(
            " gravity (m/s^2, not part of URDF; set it in the loading tool): "
            f"[{_num(g[0])}, {_num(g[1])}, {_num(g[2])}] "
        )
    )
    vec = lambda v: " ".join(_num(x) for x in v)  # noqa: E731
    ET.SubElement(robot, "link", name="world")
    j = ET.SubElement(robot, "joint", name="base_joint", type="fixed")
    ET.SubElement(j, "origin", xyz=vec(model.base_xyz), rpy=vec(model.base_rpy))
    ET.SubElement(j, "parent", link="world")
    ET.SubElement(j, "child", link="base")
    ET.SubElement(robot, "link", name="base")
    parent, x = "base", 0.0
    for i, link in enumerate(model.links, start=1):
        b, jt = link.beam, link.joint
        L, m = b.length, b.mass
        joint = ET.SubElement(robot, "joint", name=f"joint{i}", type="fixed" if jt.locked else "revolute")
        o = jt.origin_xyz
        ET.SubElement(joint, "origin", xyz=vec((x + o[0], o[1], o[2])), rpy=vec(jt.origin_rpy))
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=f"link{i}")
        if not jt.locked:
            ET.SubElement(joint, "axis", xyz=vec(jt.axis))
            ET.SubElement(joint, "limit", lower="-" + _WIDE, upper=_WIDE, effort=_WIDE, velocity=_WIDE)
        if link.rigid:  # a rigid link's own body: mass at its centre of mass, inertia about it
            _inertia(ET.SubElement(robot, "link", name=f"link{i}"), m, b.com, b.inertia)
        else:
            Q = rx(b.roll)
            J = (
                np.diag([0.0, m * L * L / 12, m * L * L / 12])
                + L * Q @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Q.T
            )
            _inertia(ET.SubElement(robot, "link", name=f"link{i}"), m, (L / 2, 0.0, 0.0), J)
        if link.hub is not None:
            _fixed(robot, f"hub{i}_joint", f"link{i}", f"hub{i}")
            _inertia(
                ET.SubElement(robot, "link", name=f"hub{i}"), link.hub.mass, (0.0, 0.0, 0.0), link.hub.inertia
            )
        if link.payload is not None:
            pj = ET.SubElement(robot, "joint", name=f"payload{i}_joint", type="fixed")
            c = link.payload.offset
            ET.SubElement(pj, "origin", xyz=vec((L + c[0], c[1], c[2])), rpy="0 0 0")
            ET.SubElement(pj, "parent", link=f"link{i}")
            ET.SubElement(pj, "child", link=f"payload{i}")
            _inertia(
                ET.SubElement(robot, "link", name=f"payload{i}"),
                link.payload.mass,
                (0.0, 0.0, 0.0),
                link.payload.inertia,
            )
        parent, x = _link_tip(robot, i, L)
    return _robot_text(robot, parent, x)


def case_to_urdf(case: Case | Manipulator, name: str | None = None) -> str:
    """URDF text of the rigid arm of ``case`` (a Case or a Manipulator, or a spatial case or
    manipulator); see the module notes."""
    from .spatial import SpatialCase, SpatialManipulator

    if isinstance(case, (SpatialCase, SpatialManipulator)):
        return _spatial_urdf(case, name)
    model = case.model if isinstance(case, Case) else case
    if not isinstance(model, Manipulator):
        raise InputError("case", case, "must be a dttmm.Case or dttmm.Manipulator (or a spatial case)")
    name = name or (case.name if isinstance(case, Case) and case.name else "arm")
    robot = ET.Element("robot", name=name)
    gx, gy = model.gravity
    robot.append(
        ET.Comment(
            f" gravity (m/s^2, not part of URDF; set it in the loading tool): [{_num(gx)}, {_num(gy)}, 0.0] "
        )
    )
    _link(robot, "base")
    parent, x = "base", 0.0
    for i, link in enumerate(model.links, start=1):
        L, m = link.beam.length, link.beam.mass
        joint = ET.SubElement(robot, "joint", name=f"joint{i}", type="revolute")
        _origin(joint, x)
        ET.SubElement(joint, "parent", link=parent)
        ET.SubElement(joint, "child", link=f"link{i}")
        ET.SubElement(joint, "axis", xyz="0 0 1")
        ET.SubElement(joint, "limit", lower="-" + _WIDE, upper=_WIDE, effort=_WIDE, velocity=_WIDE)
        _link(robot, f"link{i}", m, L / 2, m * L * L / 12, m * L * L / 12)
        if link.hub is not None:
            _fixed(robot, f"hub{i}_joint", f"link{i}", f"hub{i}")
            _link(robot, f"hub{i}", link.hub.mass, izz=link.hub.inertia)
        if link.payload is not None:
            _fixed(robot, f"payload{i}_joint", f"link{i}", f"payload{i}", L)
            _link(robot, f"payload{i}", link.payload.mass, izz=link.payload.inertia)
        parent, x = _link_tip(robot, i, L)
    return _robot_text(robot, parent, x)


def _load_any(path):
    """A case file of any kind (``dttmm.load_case``: planar, spatial, or a robot from its URDF)."""
    from .casefiles import load_case as load_any

    return load_any(path)


def main(argv=None) -> int:
    """``dttmm urdf CASE [--out FILE]``: print (or write) the rigid arm of a case as URDF."""

    p = OneLineParser(
        prog="dttmm urdf",
        description="Print the rigid arm of a case as URDF "
        "(gravity is noted in a comment: URDF has no field for it).",
    )
    p.add_argument("case", help="case TOML file")
    p.add_argument("--out", metavar="FILE", help="write to FILE instead of standard output")
    a = p.parse_args(argv)
    try:
        text = case_to_urdf(_load_any(a.case))
    except (InputError, OSError) as exc:
        print(f"dttmm urdf: {exc}", file=sys.stderr)
        return 2
    if a.out:
        try:
            Path(a.out).write_text(text)
        except OSError as exc:
            print(f"dttmm urdf: --out = {a.out!r}: cannot write ({exc.strerror or exc})", file=sys.stderr)
            return 2
    else:
        sys.stdout.write(text)
    return 0
