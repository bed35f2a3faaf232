"""A spatial case = a spatial manipulator + a scenario: the planar suite's (one drive per
unlocked joint, base first), or a :class:`SpatialScenario` that adds external loads."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated, Union

from pydantic import Field, Strict, create_model

from ..case import Case, CaseBase, ScenarioFile, _drive
from ..casedoc import case_file_model, read_case_document, validate_document
from ..drives import OPEN_LAWS, _prefixed, _tagged, _union, law_from_table
from ..errors import InputError
from ..schema import Finite, NonNegative, _Strict, build, check_fields, field_types, fields_model
from . import model as _m
from .model import BoundedVector3, InertiaValue, SpatialManipulator, SpatialSection, Vector3
from .scenario import LOAD_LAWS, SpatialLoad, SpatialLoadFields, SpatialScenario, check_load_links

__all__ = [
    "SpatialCase",
    "SpatialCaseFile",
    "case_from_dict",
    "case_to_dict",
    "load_case",
    "validate_spatial_file",
]


@dataclass(frozen=True)
class SpatialCase(CaseBase):
    """The physical problem of a spatial arm: ``model`` and ``scenario`` (a :class:`dttmm.Scenario`,
    or a :class:`SpatialScenario` with external loads); ``provenance`` is free-form metadata (no
    part in equality)."""

    model: SpatialManipulator
    MODEL = (SpatialManipulator, "dttmm.spatial.SpatialManipulator", "n_joints", "unlocked joint")

    def __post_init__(self):
        super().__post_init__()
        check_load_links(self)
        if self.model.closures:
            from .topology import check_initial_closures

            check_initial_closures(self)

    @classmethod
    def from_planar(cls, case: Case, base_rpy=(0.0, 0.0, 0.0), base_xyz=(0.0, 0.0, 0.0)) -> SpatialCase:
        """The planar ``case`` (a :class:`dttmm.Case`) as the spatial case it is (docs/spatial.md
        §1): its manipulator embedded by :func:`dttmm.spatial.embed_planar` in the plane of the
        base frame (``base_rpy``, ``base_xyz``; default the world's x–y plane), with the same
        scenario object, name and provenance. InputError (one line) for anything else."""
        if not isinstance(case, Case):
            raise InputError("case", type(case).__name__, "must be a dttmm.Case (a planar case) to embed")
        prov = None if case.provenance is None else dict(case.provenance)
        return cls(_m.embed_planar(case.model, base_rpy, base_xyz), case.scenario, case.name, prov)


# --- the spatial case file (docs/cases.md "Spatial cases") ----------------------------------
JointFile = fields_model(_m.SpatialJoint)

InertiaEntry = Union[InertiaValue, BoundedVector3]  # noqa: UP007


def _body_file(cls, name: str, doc: str):
    """The file table of the spatial body ``cls``: its fields (a rigid body's ``length`` is the
    link's) and its inertia, a 3×3 matrix or its diagonal (default 0)."""
    body = {k: v for k, v in field_types(cls).items() if k != "length"}
    return create_model(
        name,
        __base__=_Strict,
        __module__=__name__,
        __doc__=doc,
        **body,
        inertia=(InertiaEntry, [0.0, 0.0, 0.0]),
    )


HubFile = _body_file(_m.SpatialHub, "HubFile", "A link's ``hub`` table.")
PayloadFile = _body_file(_m.SpatialPayload, "PayloadFile", "A link's ``payload`` table.")
RigidFile = _body_file(
    _m.SpatialRigidBody,
    "RigidFile",
    "A rigid link's body: ``rigid = { mass, com, inertia }`` (docs/cases.md).",
)

#: the keys of a spatial link's beam (SpatialSection's fields): those a flexible link must give,
#: every beam key (a rigid link takes none), and the beam data proper (no roll or damping)
_SECTION = field_types(SpatialSection)
BEAM_REQUIRED = tuple(k for k, (_, d) in _SECTION.items() if d is ... and k != "length")
BEAM_KEYS = tuple(k for k in _SECTION if k != "length")
BEAM_DATA = tuple(k for k in BEAM_KEYS if k not in ("roll", "damping"))
_LENGTH = fields_model(SpatialSection, ("length",))


def _optional(keys, **types) -> dict:
    """The SpatialSection fields ``keys``, each optional (None when absent)."""
    return {k: (types.get(k, _SECTION[k][0]) | None, None) for k in keys}


BeamDataFile = create_model(
    "BeamDataFile",
    __base__=_Strict,
    __module__=__name__,
    __doc__="The beam data of a spatial link as a file gives them, each optional (what a link "
    "needs is checked where the link is built): EA, GJ, EIy, EIz (N, N·m²), rhoA (kg/m), rhoJ, "
    "rhoIy, rhoIz (kg·m).",
    **_optional(BEAM_DATA),
)

SpatialLinkFile = create_model(
    "SpatialLinkFile",
    __base__=BeamDataFile,
    __module__=__name__,
    __doc__="One ``[[model.links]]`` table of a spatial case: a flexible link (the beam keys) or a "
    "rigid one (``rigid``, and ``length`` ≥ 0 to its tip frame, default 0).",
    **_optional(("length", "roll", "damping"), length=NonNegative),
    rigid=(RigidFile | None, None),
    joint=(JointFile, JointFile()),
    hub=(HubFile | None, None),
    payload=(PayloadFile | None, None),
    **field_types(_m.SpatialLink),
)


class BaseFile(_Strict):
    xyz: BoundedVector3 = [0.0, 0.0, 0.0]
    rpy: Vector3 = [0.0, 0.0, 0.0]


class SpatialModelFile(_Strict):
    gravity: BoundedVector3 = [0.0, 0.0, 0.0]
    base: BaseFile = BaseFile()
    links: Annotated[list[SpatialLinkFile], Strict(), Field(min_length=1)]
    closures: Annotated[list[_m.SpatialClosureFields], Strict()] = []
    end_effector: Annotated[str, Strict()] | None = None


def _factor_table(name: str):
    """The table of a load factor following law ``name``; a constant's ``value`` is required
    (its default, 0, would silently remove the load)."""
    fields = fields_model(OPEN_LAWS[name])
    if name == "constant":
        fields = create_model(
            "ConstantFactorFields", __base__=_Strict, __module__=__name__, value=(Finite, ...)
        )
    return _tagged(name, fields)


FactorFile = _union(_factor_table(n) for n in LOAD_LAWS)


class LoadFile(SpatialLoadFields):
    """One ``[[scenario.loads]]`` table of a spatial case (docs/cases.md)."""

    factor: FactorFile | None = None


class SpatialScenarioFile(ScenarioFile):
    loads: Annotated[list[LoadFile], Strict()] = []


SpatialCaseFile = case_file_model("SpatialCaseFile", __name__, SpatialModelFile, SpatialScenarioFile, True)


def validate_spatial_file(data) -> SpatialCaseFile:
    """Validate a parsed spatial case document (:func:`dttmm.casefiles.validate_document`)."""
    return validate_document(SpatialCaseFile, data)


def case_from_dict(data: dict) -> SpatialCase:
    """Build a :class:`SpatialCase` from a parsed spatial case document: validated once by
    :data:`SpatialCaseFile`, its parts built from the validated values (:func:`dttmm.schema.build`
    runs only the rules that span fields: unit axes, inertia tensors, closures)."""
    spec = validate_spatial_file(data)
    links = []
    for i, d in enumerate(spec.model.links):
        w = f"model.links[{i}]"
        beam = _link_body(d, w)
        joint = build(_m.SpatialJoint, **dict(d.joint), _where=f"{w}.joint")
        hub = None if d.hub is None else build(_m.SpatialHub, **dict(d.hub), _where=f"{w}.hub")
        pay = (
            None if d.payload is None else build(_m.SpatialPayload, **dict(d.payload), _where=f"{w}.payload")
        )
        links.append(_m.SpatialLink(beam, joint, hub, pay, d.name, d.parent, _where=w))
    m = spec.model
    closures = tuple(
        build(_m.SpatialClosure, **dict(c), _where=f"model.closures[{j}]") for j, c in enumerate(m.closures)
    )
    manip = SpatialManipulator(
        tuple(links), tuple(m.gravity), tuple(m.base.xyz), tuple(m.base.rpy), closures, m.end_effector
    )
    sc = spec.scenario
    drives = tuple(_drive(d, i) for i, d in enumerate(sc.drives))
    loads = tuple(_load(d, j) for j, d in enumerate(sc.loads))
    prov = None if spec.provenance is None else dict(spec.provenance)
    return SpatialCase(manip, SpatialScenario(sc.duration, sc.output_step, drives, loads), spec.name, prov)


def _link_body(d, w: str):
    """The link's :class:`SpatialSection` (flexible) or :class:`SpatialRigidBody` (``rigid``)."""
    if d.rigid is not None:
        for key in BEAM_KEYS:
            if getattr(d, key) is not None:
                raise InputError(
                    f"{w}.{key}", getattr(d, key), "is a beam key; a rigid link (`rigid`) takes none"
                )
        return build(_m.SpatialRigidBody, length=d.length or 0.0, **dict(d.rigid), _where=f"{w}.rigid")
    for key in ("length", *BEAM_REQUIRED):
        if getattr(d, key) is None:
            raise InputError(f"{w}.{key}", None, "is required (a rigid link gives `rigid` instead)")
    given = {k: getattr(d, k) for k in _SECTION if getattr(d, k) is not None}
    check_fields(_LENGTH, w, length=d.length)  # a beam's length is positive, a rigid link's ≥ 0
    return build(SpatialSection, **given, _where=w)


def _load(spec, j: int) -> SpatialLoad:
    w = f"scenario.loads[{j}]"
    factor = {}
    if spec.factor is not None:
        try:
            factor = {"factor": law_from_table(spec.factor.law, spec.factor)}
        except InputError as exc:
            raise _prefixed(exc, f"{w}.factor") from None
    return SpatialLoad(tuple(spec.force), tuple(spec.moment), spec.link, spec.frame, **factor, _where=w)


def load_case(path) -> SpatialCase:
    """Read a spatial case TOML file (docs/cases.md "Spatial cases"); the name defaults to the
    file's stem. Raises InputError for an unreadable file, invalid TOML, or any key or value the
    schema refuses. :func:`dttmm.spatial.load_case` reads a case file of any kind as a
    :class:`SpatialCase` (:func:`dttmm.casefiles.load_spatial_case`)."""
    data, _ = read_case_document(path)
    return case_from_dict(data)


def _load_to_dict(ld: SpatialLoad) -> dict:
    """A ``[[scenario.loads]]`` table of the load ``ld``."""
    d = {} if ld.link is None else {"link": ld.link}
    d.update(force=list(ld.force), moment=list(ld.moment), frame=ld.frame)
    d["factor"] = {"law": ld.factor.name, **ld.factor.params()}
    return d


def _closure_to_dict(cl: _m.SpatialClosure) -> dict:
    """A ``[[model.closures]]`` table of the closure ``cl``."""
    d = {"kind": cl.kind, "link": cl.link, "to": cl.to, "point": list(cl.point)}
    if cl.to_point is not None:
        d["to_point"] = list(cl.to_point)
    d["axis"] = list(cl.axis)
    if cl.name:
        d["name"] = cl.name
    return d


def case_to_dict(case: SpatialCase) -> dict:
    """The spatial case as a spatial case document (``kind = "spatial"``): what
    :func:`case_from_dict` builds the same case from (inertias as full 3×3 rows)."""
    from ..case import scenario_to_dict

    def rows(m):
        return [list(r) for r in m]

    links = []
    for link in case.model.links:
        b, j = link.beam, link.joint
        joint = {
            "axis": list(j.axis),
            "origin_xyz": list(j.origin_xyz),
            "origin_rpy": list(j.origin_rpy),
            "locked": j.locked,
        }
        if link.rigid:
            d = {
                "length": b.length,
                "rigid": {"mass": b.mass, "com": list(b.com), "inertia": rows(b.inertia)},
                "joint": joint,
            }
        else:
            d = {
                "length": b.length,
                **({"EA": b.EA} if b.EA is not None else {}),
                "GJ": b.GJ,
                "EIy": b.EIy,
                "EIz": b.EIz,
                "rhoA": b.rhoA,
                "rhoJ": b.rhoJ,
                "rhoIy": b.rhoIy,
                "rhoIz": b.rhoIz,
                "roll": b.roll,
                "damping": b.damping,
                "joint": joint,
            }
        if link.hub is not None:
            d["hub"] = {"mass": link.hub.mass, "inertia": rows(link.hub.inertia)}
        if link.payload is not None:
            p = link.payload
            d["payload"] = {"mass": p.mass, "offset": list(p.offset), "inertia": rows(p.inertia)}
        if link.name:
            d["name"] = link.name
        if link.parent is not None:
            d["parent"] = link.parent
        links.append(d)
    m = case.model
    model = {
        "gravity": list(m.gravity),
        "base": {"xyz": list(m.base_xyz), "rpy": list(m.base_rpy)},
        "links": links,
    }
    if m.closures:
        model["closures"] = [_closure_to_dict(cl) for cl in m.closures]
    if m.end_effector is not None:
        model["end_effector"] = m.end_effector
    out = {
        "kind": "spatial",
        "name": case.name,
        "model": model,
        "scenario": scenario_to_dict(case.scenario),
    }
    loads = [_load_to_dict(ld) for ld in getattr(case.scenario, "loads", ())]
    if loads:
        out["scenario"]["loads"] = loads
    if case.provenance is not None:
        out["provenance"] = dict(case.provenance)
    return out
