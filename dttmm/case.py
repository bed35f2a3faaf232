"""A case = model + scenario, and its TOML file format (reference: docs/cases.md)."""

from __future__ import annotations

import datetime
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import Field, Strict, create_model, model_validator

from .casedoc import (
    MAX_FILE_BYTES,  # noqa: F401  (the file-size limit, kept importable here)
    case_file_model,
    read_case_document,
    read_case_text,
    validate_document,
)
from .drives import LAW_FIELDS, Drive, _prefixed, law_from_table
from .errors import InputError
from .model import Hub, Link, Manipulator, Material, Payload, RigidBody, Section, _of_material
from .scenario import Scenario
from .schema import _Strict, build, check_fields, field_types, fields_model

__all__ = [
    "Case",
    "CaseFile",
    "LinkFile",
    "ModelFile",
    "ScenarioFile",
    "case_from_dict",
    "case_to_dict",
    "load_case",
    "read_case_text",
    "save_case",
    "validate_case_file",
]


def check_case(case, model_type: type, model_name: str, count: str, joint: str) -> None:
    """The checks every case class makes on construction: ``case.model`` a ``model_type``, a
    Scenario with one drive per ``joint`` (the model's attribute ``count`` says how many), a
    string name, and a provenance dict with string keys (kept as a copy) or None."""
    if not isinstance(case.model, model_type):
        raise InputError("case.model", case.model, f"must be a {model_name}")
    if not isinstance(case.scenario, Scenario):
        raise InputError("case.scenario", case.scenario, "must be a dttmm.Scenario")
    if not isinstance(case.name, str):
        raise InputError("case.name", case.name, "must be a string")
    if case.provenance is not None:
        if not isinstance(case.provenance, dict) or not all(isinstance(k, str) for k in case.provenance):
            raise InputError("case.provenance", case.provenance, "must be a dict with string keys or None")
        object.__setattr__(case, "provenance", dict(case.provenance))
    n_joints, m = getattr(case.model, count), len(case.scenario.drives)
    if n_joints != m:
        raise InputError(
            "scenario.drives", f"{m} drives", f"needs exactly one drive per {joint} ({n_joints} joints)"
        )


@dataclass(frozen=True)
class CaseBase:
    """The fields and checks every case class shares (planar :class:`Case`, spatial
    :class:`dttmm.spatial.SpatialCase`): ``model``, ``scenario``, ``name`` and ``provenance``.
    ``MODEL`` says (model class, its name in errors, the model's attribute counting the joints,
    what a joint is) for :func:`check_case`."""

    model: Any
    scenario: Scenario
    name: str = ""
    provenance: dict | None = field(default=None, compare=False)
    MODEL = (Manipulator, "dttmm.Manipulator", "n_links", "joint")

    def __post_init__(self):
        check_case(self, *self.MODEL)

    @property
    def n_joints(self) -> int:
        return getattr(self.model, self.MODEL[2])


@dataclass(frozen=True)
class Case(CaseBase):
    """The physical problem every method solves: a manipulator and a scenario.

    ``provenance`` is free-form metadata of the case (source, published values, tolerance, …),
    kept as read from the file's ``[provenance]`` table; it takes no part in equality.
    """

    model: Manipulator


# --- the file format: models composed from the fields the classes declare ---------------------
class _OneForm(_Strict):
    """The link-table rules: EI and rhoA, or E, rho, width and thickness; EA or inextensible;
    or a rigid link (``rigid``: no beam data at all)."""

    @model_validator(mode="after")
    def _one_form(self):
        mat = [k for k in field_types(Material) if getattr(self, k) is not None]
        sec = [k for k in ("EI", "rhoA") if getattr(self, k) is not None]
        if self.rigid is not None:
            beam = [k for k in ("EI", "rhoA", "EA", *mat) if getattr(self, k) is not None]
            beam += [k for k, v in (("damping", self.damping), ("inextensible", self.inextensible)) if v]
            if beam:
                raise InputError(
                    beam[0], getattr(self, beam[0]), "contradicts rigid (a rigid link has no beam)"
                )
            return self
        if mat and sec:
            raise InputError(
                sec[0],
                getattr(self, sec[0]),
                "give either EI and rhoA or E, rho, width and thickness, not both",
            )
        if mat and len(mat) < 4:
            miss = [k for k in field_types(Material) if k not in mat]
            raise InputError(miss[0], None, f"is required with {', '.join(mat)} (material form)")
        if not mat:
            for k in ("EI", "rhoA"):
                if getattr(self, k) is None:
                    raise InputError(k, None, "is required (or give E, rho, width, thickness)")
        if self.inextensible and self.EA is not None:
            raise InputError("EA", self.EA, "contradicts inextensible = true")
        return self


def _optional(types: dict, names) -> dict:
    return {k: (tp | None, None) if k in names else (tp, d) for k, (tp, d) in types.items()}


#: one ``[[model.links]]`` table: the Section's fields (EI and rhoA optional) or the material
#: form's, ``inextensible``, and a hub and payload table (keys in the order errors are reported)
_SECTION = _optional(field_types(Section), ("EI", "rhoA"))
LinkFile = create_model(
    "LinkFile",
    __base__=_OneForm,
    __module__=__name__,
    **{k: v for k, v in _SECTION.items() if k != "damping"},
    **_optional(field_types(Material), field_types(Material)),
    inextensible=(bool, False),
    damping=_SECTION["damping"],
    hub=(fields_model(Hub) | None, None),
    payload=(fields_model(Payload) | None, None),
    rigid=(fields_model(RigidBody, ("mass", "com", "inertia")) | None, None),
)


class ModelFile(fields_model(Manipulator)):
    links: Annotated[list[LinkFile], Strict(), Field(min_length=1)]


def _drive_file(name: str, fields):
    """A drive table of law ``name``: the Drive's fields, the law's parameters and the tag."""
    return create_model(
        f"{fields.__name__[:-6]}Drive",
        __base__=(fields_model(Drive), fields),
        __module__=__name__,
        law=(Literal[name], ...),
    )


DriveFile = Annotated[
    Union[tuple(_drive_file(n, f) for n, f in LAW_FIELDS.items())],  # noqa: UP007
    Field(discriminator="law"),
]


class ScenarioFile(fields_model(Scenario)):
    drives: Annotated[list[DriveFile], Strict()] = []


CaseFile = case_file_model("CaseFile", __name__, ModelFile, ScenarioFile)


def validate_case_file(data) -> CaseFile:
    """Validate a parsed case document; raises :class:`InputError` naming the first bad key."""
    return validate_document(CaseFile, data)


# --- objects from a validated file (its values are not validated again) -----------------------
#: the Section fields a material-form link derives (checked once, as they are new numbers)
_DERIVED = fields_model(Section, ("EI", "rhoA", "EA"))


def _link(spec, i: int) -> Link:
    w = f"model.links[{i}]"
    hub = None if spec.hub is None else build(Hub, **dict(spec.hub), _where=f"{w}.hub")
    pay = None if spec.payload is None else build(Payload, **dict(spec.payload), _where=f"{w}.payload")
    if spec.rigid is not None:
        return Link(build(RigidBody, length=spec.length, **dict(spec.rigid), _where=f"{w}.rigid"), hub, pay)
    if spec.E is not None:
        material = {k: getattr(spec, k) for k in field_types(Material)}
        ea = None if spec.inextensible else (True if spec.EA is None else spec.EA)
        derived = dict(zip(("EI", "rhoA", "EA"), _of_material(**material, EA=ea), strict=True))
        section = {"length": spec.length, **check_fields(_DERIVED, w, **derived), "damping": spec.damping}
    else:
        ea = None if spec.inextensible else spec.EA
        section = {"length": spec.length, "EI": spec.EI, "rhoA": spec.rhoA, "EA": ea, "damping": spec.damping}
    beam = build(Section, **section, _where=w)
    return Link(beam, hub, pay)


def _drive(spec, i: int) -> Drive:
    """The drive of the validated drive table ``spec``, joint ``i``."""
    w = f"scenario.drives[{i}]"
    try:
        law = law_from_table(spec.law, spec)
    except InputError as exc:
        raise _prefixed(exc, w) from None
    values = {k: getattr(spec, k) for k in field_types(Drive)}
    return build(Drive, **values, law=law, _where=w)


def case_from_spec(spec: CaseFile) -> Case:
    """Build a :class:`Case` from a validated :class:`CaseFile`."""
    links = tuple(_link(d, i) for i, d in enumerate(spec.model.links))
    manip = build(Manipulator, links=links, gravity=spec.model.gravity)
    scen = spec.scenario
    drives = tuple(_drive(d, i) for i, d in enumerate(scen.drives))
    prov = None if spec.provenance is None else dict(spec.provenance)
    scenario = build(Scenario, duration=scen.duration, output_step=scen.output_step, drives=drives)
    return Case(manip, scenario, spec.name, prov)


def case_from_dict(data: dict) -> Case:
    """Build a :class:`Case` from a parsed case document (the TOML format of docs/cases.md)."""
    return case_from_spec(validate_case_file(data))


def load_case(path) -> Case:
    """Read a case TOML file (format: docs/cases.md). The name defaults to the file's stem.

    Raises
    ------
    InputError
        For an unreadable file, invalid TOML, or any key or value the schema refuses.
    """
    data, _ = read_case_document(path)
    return case_from_dict(data)


def case_to_dict(case: Case) -> dict:
    """The case as a document in the file format (what :func:`save_case` writes)."""
    links = []
    for link in case.model.links:
        b = link.beam
        if link.rigid:
            d = {"length": b.length, "rigid": {"mass": b.mass, "com": list(b.com), "inertia": b.inertia}}
        else:
            d = {"length": b.length, "EI": b.EI, "rhoA": b.rhoA}
            if b.EA is not None:
                d["EA"] = b.EA
            if b.damping:
                d["damping"] = b.damping
        if link.hub is not None:
            d["hub"] = {"mass": link.hub.mass, "inertia": link.hub.inertia}
        if link.payload is not None:
            d["payload"] = {"mass": link.payload.mass, "inertia": link.payload.inertia}
            if link.payload.offset_set:
                d["payload"]["offset"] = list(link.payload.offset)
        links.append(d)
    out = {
        "name": case.name,
        "model": {"gravity": list(case.model.gravity), "links": links},
        "scenario": scenario_to_dict(case.scenario),
    }
    if case.provenance is not None:
        out["provenance"] = dict(case.provenance)
    return out


def scenario_to_dict(s: Scenario) -> dict:
    """The ``[scenario]`` table of a case document (planar and spatial cases share it)."""
    drives = []
    for dr in s.drives:
        d = {"kind": dr.kind, "law": dr.law.name, **dr.law.params()}
        if dr.kind == "torque":
            d["initial_angle"], d["initial_rate"] = dr.initial_angle, dr.initial_rate
        drives.append(d)
    return {"duration": s.duration, "output_step": s.output_step, "drives": drives}


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
