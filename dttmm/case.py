"""A case = model + scenario, and its TOML file format (reference: docs/cases.md)."""

from __future__ import annotations

import datetime
import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from .drives import LAWS, Drive
from .errors import InputError
from .model import Hub, Link, Manipulator, Payload, Section
from .scenario import Scenario
from .schema import CaseFile, LinkFile, validate_case_file

__all__ = ["Case", "case_from_dict", "case_to_dict", "load_case", "read_case_text", "save_case"]

#: a case file larger than this is refused before parsing (bytes)
MAX_FILE_BYTES = 16 * 2**20


@dataclass(frozen=True)
class Case:
    """The physical problem every method solves: a manipulator and a scenario.

    ``provenance`` is free-form metadata of the case (source, published values, tolerance, …),
    kept as read from the file's ``[provenance]`` table; it takes no part in equality.
    """

    model: Manipulator
    scenario: Scenario
    name: str = ""
    provenance: dict | None = field(default=None, compare=False)

    def __post_init__(self):
        if not isinstance(self.model, Manipulator):
            raise InputError("case.model", self.model, "must be a dttmm.Manipulator")
        if not isinstance(self.scenario, Scenario):
            raise InputError("case.scenario", self.scenario, "must be a dttmm.Scenario")
        if not isinstance(self.name, str):
            raise InputError("case.name", self.name, "must be a string")
        if self.provenance is not None:
            if not isinstance(self.provenance, dict) or not all(isinstance(k, str) for k in self.provenance):
                raise InputError(
                    "case.provenance", self.provenance, "must be a dict with string keys or None"
                )
            object.__setattr__(self, "provenance", dict(self.provenance))
        n, m = self.model.n_links, len(self.scenario.drives)
        if n != m:
            raise InputError(
                "scenario.drives", f"{m} drives", f"needs exactly one drive per joint ({n} joints)"
            )

    @property
    def n_joints(self) -> int:
        return self.model.n_links


def _link(spec: LinkFile, i: int) -> Link:
    w = f"model.links[{i}]"
    if spec.E is not None:
        ea = None if spec.inextensible else (spec.EA if spec.EA is not None else True)
        beam = Section.from_material(
            spec.length, spec.E, spec.rho, spec.width, spec.thickness, EA=ea, damping=spec.damping, where=w
        )
    else:
        beam = Section(
            spec.length, spec.EI, spec.rhoA, None if spec.inextensible else spec.EA, spec.damping, _where=w
        )
    hub = None if spec.hub is None else Hub(spec.hub.mass, spec.hub.inertia, _where=f"{w}.hub")
    pay = (
        None
        if spec.payload is None
        else Payload(spec.payload.mass, spec.payload.inertia, _where=f"{w}.payload")
    )
    return Link(beam, hub, pay)


def _drive(spec, i: int) -> Drive:
    w = f"scenario.drives[{i}]"
    params = spec.model_dump(exclude={"law", "kind", "initial_angle", "initial_rate"})
    try:
        law = LAWS[spec.law](**params)
    except InputError as exc:
        raise InputError(exc.field.replace("law.", f"{w}.", 1), exc.value, exc.reason) from None
    return Drive(spec.kind, law, spec.initial_angle, spec.initial_rate, _where=w)


def case_from_spec(spec: CaseFile) -> Case:
    """Build a :class:`Case` from a validated :class:`dttmm.schema.CaseFile`."""
    links = tuple(_link(d, i) for i, d in enumerate(spec.model.links))
    manip = Manipulator(links, tuple(spec.model.gravity))
    scen = spec.scenario
    drives = tuple(_drive(d, i) for i, d in enumerate(scen.drives))
    prov = None if spec.provenance is None else dict(spec.provenance)
    return Case(manip, Scenario(scen.duration, scen.output_step, drives), spec.name, prov)


def case_from_dict(data: dict) -> Case:
    """Build a :class:`Case` from a parsed case document (the TOML format of docs/cases.md)."""
    return case_from_spec(validate_case_file(data))


def read_case_text(path) -> str:
    """The text of a case file; every way it can be unreadable is an InputError on the path."""
    path = Path(path)
    where = str(path)
    try:
        if path.is_dir():
            raise InputError(where, "<directory>", "is a directory, not a case file")
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise InputError(
                where, f"<{size} bytes>", f"is too large for a case file (limit {MAX_FILE_BYTES})"
            )
        raw = path.read_bytes()
    except FileNotFoundError:
        raise InputError(where, "<file>", "does not exist") from None
    except PermissionError:
        raise InputError(where, "<file>", "cannot be read (permission denied)") from None
    except OSError as exc:
        raise InputError(where, "<file>", f"cannot be read ({exc.strerror or exc})") from None
    if b"\x00" in raw:
        raise InputError(where, "<file>", "is a binary file, not a TOML case file")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(
            where, "<file>", f"is not UTF-8 text (byte {raw[exc.start]:#04x} at offset {exc.start})"
        ) from None


def load_case(path) -> Case:
    """Read a case TOML file (format: docs/cases.md). The name defaults to the file's stem.

    Raises
    ------
    InputError
        For an unreadable file, invalid TOML, or any key or value the schema refuses.
    """
    text = read_case_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(str(path), "<file>", f"is not valid TOML: {exc}") from None
    if "name" not in data:
        data["name"] = Path(path).stem
    return case_from_dict(data)


def case_to_dict(case: Case) -> dict:
    """The case as a document in the file format (what :func:`save_case` writes)."""
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
    out = {
        "name": case.name,
        "model": {"gravity": list(case.model.gravity), "links": links},
        "scenario": {"duration": s.duration, "output_step": s.output_step, "drives": drives},
    }
    if case.provenance is not None:
        out["provenance"] = dict(case.provenance)
    return out


def _key(k: str) -> str:
    bare = k and all(c.isascii() and (c.isalnum() or c in "_-") for c in k)
    return k if bare else _fmt(k)


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
        return "{ " + ", ".join(f"{_key(k)} = {_fmt(x)}" for k, x in v.items()) + " }"
    if isinstance(v, (datetime.date, datetime.time)):
        return v.isoformat()
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
    lines += [
        "",
        "[scenario]",
        f"duration = {_fmt(s['duration'])}",
        f"output_step = {_fmt(s['output_step'])}",
    ]
    for dr in s["drives"]:
        lines += ["", "[[scenario.drives]]"] + [f"{k} = {_fmt(v)}" for k, v in dr.items()]
    if "provenance" in d:
        lines += ["", "[provenance]"] + [f"{_key(k)} = {_fmt(v)}" for k, v in d["provenance"].items()]
    path = Path(path)
    path.write_text("\n".join(lines) + "\n")
    return path
