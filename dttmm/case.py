"""A case = model + scenario, and its TOML file format (DESIGN.md, "Case files")."""
from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass
from pathlib import Path

from .drives import Drive, law_from_dict
from .errors import InputError
from .model import Hub, Link, Manipulator, Payload, Section
from .scenario import Scenario

__all__ = ["Case", "load_case", "save_case", "case_from_dict", "case_to_dict"]


@dataclass(frozen=True)
class Case:
    """The physical problem every method solves: a manipulator and a scenario."""

    model: Manipulator
    scenario: Scenario
    name: str = ""

    def __post_init__(self):
        if not isinstance(self.model, Manipulator):
            raise InputError("case.model", self.model, "must be a dttmm.Manipulator")
        if not isinstance(self.scenario, Scenario):
            raise InputError("case.scenario", self.scenario, "must be a dttmm.Scenario")
        n, m = self.model.n_links, len(self.scenario.drives)
        if n != m:
            raise InputError("scenario.drives", f"{m} drives",
                             f"needs exactly one drive per joint ({n} joints)")

    @property
    def n_joints(self) -> int:
        return self.model.n_links


_LINK_KEYS = {"length", "EI", "rhoA", "EA", "damping", "E", "rho", "width", "thickness",
              "hub", "payload", "inextensible"}
_DRIVE_KEYS = {"kind", "initial_angle", "initial_rate"}


def _body(cls, d, where):
    if d is None:
        return None
    if not isinstance(d, dict):
        raise InputError(where, d, "must be a table {mass = ..., inertia = ...}")
    unknown = set(d) - {"mass", "inertia"}
    if unknown:
        raise InputError(where, d, f"unknown keys {sorted(unknown)}")
    return cls(d.get("mass", 0.0), d.get("inertia", 0.0), _where=where)


def _link(d: dict, i: int) -> Link:
    w = f"model.links[{i}]"
    unknown = set(d) - _LINK_KEYS
    if unknown:
        raise InputError(w, sorted(unknown), "unknown keys")
    if "length" not in d:
        raise InputError(f"{w}.length", None, "is required")
    material = {"E", "rho", "width", "thickness"} & set(d)
    if material:
        missing = {"E", "rho", "width", "thickness"} - set(d)
        if missing:
            raise InputError(w, sorted(material), f"material form also needs {sorted(missing)}")
        if "EI" in d or "rhoA" in d:
            raise InputError(w, "EI/rhoA", "give either EI and rhoA or E, rho, width, thickness")
        ea = None if d.get("inextensible", False) else d.get("EA", True)
        beam = Section.from_material(d["length"], d["E"], d["rho"], d["width"], d["thickness"],
                                     EA=ea, damping=d.get("damping", 0.0), where=w)
    else:
        for key in ("EI", "rhoA"):
            if key not in d:
                raise InputError(f"{w}.{key}", None, "is required (or give E, rho, width, thickness)")
        beam = Section(d["length"], d["EI"], d["rhoA"], d.get("EA"), d.get("damping", 0.0), _where=w)
    return Link(beam, _body(Hub, d.get("hub"), f"{w}.hub"), _body(Payload, d.get("payload"), f"{w}.payload"))


def _drive(d: dict, i: int) -> Drive:
    w = f"scenario.drives[{i}]"
    if "kind" not in d:
        raise InputError(f"{w}.kind", None, "is required ('torque' or 'motion')")
    law = law_from_dict({k: v for k, v in d.items() if k not in _DRIVE_KEYS}, where=w)
    return Drive(d["kind"], law, d.get("initial_angle", 0.0), d.get("initial_rate", 0.0), _where=w)


def case_from_dict(data: dict) -> Case:
    """Build a :class:`Case` from the parsed TOML document."""
    try:
        model, scen = data["model"], data["scenario"]
    except KeyError as exc:
        raise InputError(str(exc.args[0]), None, "table is required") from None
    links = model.get("links")
    if not links:
        raise InputError("model.links", links, "needs at least one [[model.links]] table")
    manip = Manipulator(tuple(_link(d, i) for i, d in enumerate(links)),
                        tuple(model.get("gravity", (0.0, 0.0))))
    for key in ("duration", "output_step"):
        if key not in scen:
            raise InputError(f"scenario.{key}", None, "is required")
    drives = tuple(_drive(d, i) for i, d in enumerate(scen.get("drives", [])))
    return Case(manip, Scenario(scen["duration"], scen["output_step"], drives), str(data.get("name", "")))


def load_case(path) -> Case:
    """Read a case TOML file (format: DESIGN.md, "Case files")."""
    path = Path(path)
    with path.open("rb") as f:
        try:
            data = tomllib.load(f)
        except tomllib.TOMLDecodeError as exc:
            raise InputError(str(path), "<file>", f"is not valid TOML: {exc}") from None
    if "name" not in data:
        data["name"] = path.stem
    return case_from_dict(data)


def case_to_dict(case: Case) -> dict:
    links = []
    for link in case.model.links:
        b = link.beam
        d = {"length": b.length, "EI": b.EI, "rhoA": b.rhoA}
        if b.EA is not None:
            d["EA"] = b.EA
        if b.damping:
            d["damping"] = b.damping
        if link.hub is not None:
            d["hub"] = {"mass": link.hub.mass, "inertia": link.hub.inertia}
        if link.payload is not None:
            d["payload"] = {"mass": link.payload.mass, "inertia": link.payload.inertia}
        links.append(d)
    drives = []
    for dr in case.scenario.drives:
        d = {"kind": dr.kind, "law": dr.law.name, **dr.law.params()}
        if dr.kind == "torque":
            d["initial_angle"], d["initial_rate"] = dr.initial_angle, dr.initial_rate
        drives.append(d)
    s = case.scenario
    return {"name": case.name,
            "model": {"gravity": list(case.model.gravity), "links": links},
            "scenario": {"duration": s.duration, "output_step": s.output_step, "drives": drives}}


def _fmt(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        v = float(v)
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {_fmt(x)}" for k, x in v.items()) + " }"
    raise TypeError(f"cannot write {v!r} to TOML")


def save_case(case: Case, path) -> Path:
    """Write a case as TOML in the documented format; ``load_case`` reads it back equal."""
    d = case_to_dict(case)
    lines = []
    if d["name"]:
        lines.append(f"name = {_fmt(d['name'])}")
    lines += ["", "[model]", f"gravity = {_fmt(d['model']['gravity'])}"]
    for link in d["model"]["links"]:
        lines += ["", "[[model.links]]"] + [f"{k} = {_fmt(v)}" for k, v in link.items()]
    s = d["scenario"]
    lines += ["", "[scenario]", f"duration = {_fmt(s['duration'])}", f"output_step = {_fmt(s['output_step'])}"]
    for dr in s["drives"]:
        lines += ["", "[[scenario.drives]]"] + [f"{k} = {_fmt(v)}" for k, v in dr.items()]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path
