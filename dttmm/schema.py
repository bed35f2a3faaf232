"""The case schema: every field of a case, its type and its allowed values, in one place.

Two consumers share these definitions:

* the case-file loader (:mod:`dttmm.case`) validates a parsed TOML document against
  :class:`CaseFile` — strict types (no bool or string is read as a number; an integer is a
  fine float), unknown keys refused at any depth with the nearest valid key;
* the Python constructors (:class:`dttmm.Section`, :class:`dttmm.Drive`, the drive laws, …)
  validate their fields through the ``*Fields`` models below via :func:`check_fields`.

Cross-field rules (bang-bang levels vs switch times, a motion drive's initial state vs its law,
output step vs duration, one drive per joint) live in the constructors, which the loader calls,
so they also hold for both. The reference for users is docs/cases.md.
"""

from __future__ import annotations

import difflib
import math
import numbers
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, Strict, ValidationError, model_validator

from .errors import InputError

__all__ = [
    "LAW_FIELDS",
    "OPEN_LAW_FIELDS",
    "BodyFields",
    "CaseFile",
    "DriveFields",
    "Finite",
    "LinkFile",
    "MaterialFields",
    "NonNegative",
    "PDFields",
    "PDGainFields",
    "PIDFields",
    "PIDGainFields",
    "Positive",
    "ScenarioFields",
    "SectionFields",
    "Until",
    "check_fields",
    "input_error",
    "validate_case_file",
]

# --- value types (units are those of the field that uses them) -----------------------------
#: Magnitude window of the model's numbers and of every positive quantity (SI units): wide
#: enough for any arm, narrow enough that the products the solvers form (EI/l³, ρA·l⁴, …) stay
#: finite and nonzero in double precision. Drive values (torques, angles) need only be finite:
#: an absurd torque makes a run diverge, which the solvers report as a SimulationError.
BIG, SMALL = 1e30, 1e-30
Finite = Annotated[float, Strict(), Field(allow_inf_nan=False)]
Bounded = Annotated[float, Strict(), Field(ge=-BIG, le=BIG, allow_inf_nan=False)]
Positive = Annotated[float, Strict(), Field(ge=SMALL, le=BIG, allow_inf_nan=False)]
NonNegative = Annotated[float, Strict(), Field(ge=0.0, le=BIG, allow_inf_nan=False)]
Until = Annotated[float, Strict(), Field(gt=0.0)]  # positive, inf allowed (nan fails gt)
FiniteList = Annotated[list[Finite], Strict()]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


# --- fields of the Python objects -----------------------------------------------------------
class BodyFields(_Strict):
    """Hub or payload: mass (kg), inertia (kg·m²) about its attachment point."""

    mass: NonNegative = 0.0
    inertia: NonNegative = 0.0


class SectionFields(_Strict):
    """Beam of one link: length (m), EI (N·m²), rhoA (kg/m), EA (N, None: inextensible),
    damping (s, stiffness-proportional)."""

    length: Positive
    EI: Positive
    rhoA: Positive
    EA: Positive | None = None
    damping: NonNegative = 0.0


class MaterialFields(_Strict):
    """Rectangular section from material: E (Pa), rho (kg/m³), width and thickness (m)."""

    E: Positive
    rho: Positive
    width: Positive
    thickness: Positive


class ModelFields(_Strict):
    """gravity (m/s²) in the plane of motion."""

    gravity: Annotated[list[Bounded], Strict(), Field(min_length=2, max_length=2)] = [0.0, 0.0]


class ScenarioFields(_Strict):
    """duration (s) and output_step (s) of the common output grid."""

    duration: Positive
    output_step: Positive


class DriveFields(_Strict):
    """Joint drive: kind, and the joint state at t = 0 (rad, rad/s)."""

    kind: Literal["torque", "motion"]
    initial_angle: Finite = 0.0
    initial_rate: Finite = 0.0


class ConstantFields(_Strict):
    value: Finite = 0.0


class BangBangFields(_Strict):
    levels: Annotated[FiniteList, Field(min_length=1)]
    switch_times: FiniteList


class SineFields(_Strict):
    amplitude: Finite
    frequency: Positive
    phase: Finite = 0.0
    offset: Finite = 0.0
    until: Until = math.inf


class SpinUpFields(_Strict):
    rate: Finite
    ramp_time: Positive


class TableFields(_Strict):
    times: Annotated[FiniteList, Field(min_length=2)]
    values: Annotated[FiniteList, Field(min_length=2)]


#: open-loop law name -> the model of its parameters
OPEN_LAW_FIELDS: dict[str, type[_Strict]] = {
    "constant": ConstantFields,
    "bang_bang": BangBangFields,
    "sine": SineFields,
    "spin_up": SpinUpFields,
    "table": TableFields,
}
MOTION_LAWS = ("constant", "sine", "spin_up", "table")  # laws that can give an angle α(t)
TORQUE_LAWS = ("constant", "bang_bang", "sine", "table")  # laws that can give a torque τ(t)


def _tagged(name: str, fields: type[_Strict]) -> type[_Strict]:
    """``fields`` plus the tag ``law = name``: one member of a nested law table's union."""
    return type(
        f"{fields.__name__[:-6]}Table",
        (fields,),
        {"__annotations__": {"law": Literal[name]}, "__module__": __name__},
    )


class ComputedTorqueTable(_Strict):
    """``{ law = "computed_torque" }``: rigid-model inverse dynamics of the reference motion."""

    law: Literal["computed_torque"]


ReferenceLaw = Annotated[
    Union[tuple(_tagged(n, OPEN_LAW_FIELDS[n]) for n in MOTION_LAWS)],  # noqa: UP007
    Field(discriminator="law"),
]
FeedforwardLaw = Annotated[
    Union[(*(_tagged(n, OPEN_LAW_FIELDS[n]) for n in TORQUE_LAWS), ComputedTorqueTable)],
    Field(discriminator="law"),
]
Limit = Annotated[float, Strict(), Field(gt=0.0)]  # positive, inf (no saturation) allowed


class PDGainFields(_Strict):
    """Gains of a PD law: kp (N·m/rad), kd (N·m·s/rad), moment_gain (1), limit (N·m)."""

    kp: NonNegative
    kd: NonNegative
    # > −1: at −1 the torque loop through the root bending moment has no solution
    moment_gain: Annotated[float, Strict(), Field(gt=-1.0, allow_inf_nan=False)] = 0.0
    limit: Limit = math.inf


class PIDGainFields(PDGainFields):
    """PD gains plus ki (N·m/(rad·s))."""

    ki: NonNegative


class PDFields(PDGainFields):
    reference: ReferenceLaw
    feedforward: FeedforwardLaw | None = None


class PIDFields(PIDGainFields):
    reference: ReferenceLaw
    feedforward: FeedforwardLaw | None = None


#: law name -> the model of its parameters (every law a case file can name)
LAW_FIELDS: dict[str, type[_Strict]] = {**OPEN_LAW_FIELDS, "pd": PDFields, "pid": PIDFields}


# --- the file format --------------------------------------------------------------------------
class LinkFile(_Strict):
    """One ``[[model.links]]`` table: EI and rhoA, or E, rho, width and thickness."""

    length: Positive
    EI: Positive | None = None
    rhoA: Positive | None = None
    EA: Positive | None = None
    E: Positive | None = None
    rho: Positive | None = None
    width: Positive | None = None
    thickness: Positive | None = None
    inextensible: bool = False
    damping: NonNegative = 0.0
    hub: BodyFields | None = None
    payload: BodyFields | None = None

    @model_validator(mode="after")
    def _one_form(self):
        mat = [k for k in ("E", "rho", "width", "thickness") if getattr(self, k) is not None]
        sec = [k for k in ("EI", "rhoA") if getattr(self, k) is not None]
        if mat and sec:
            raise InputError(
                sec[0],
                getattr(self, sec[0]),
                "give either EI and rhoA or E, rho, width and thickness, not both",
            )
        if mat and len(mat) < 4:
            miss = [k for k in ("E", "rho", "width", "thickness") if k not in mat]
            raise InputError(miss[0], None, f"is required with {', '.join(mat)} (material form)")
        if not mat:
            for k in ("EI", "rhoA"):
                if getattr(self, k) is None:
                    raise InputError(k, None, "is required (or give E, rho, width, thickness)")
        if self.inextensible and self.EA is not None:
            raise InputError("EA", self.EA, "contradicts inextensible = true")
        return self


class ModelFile(ModelFields):
    links: Annotated[list[LinkFile], Strict(), Field(min_length=1)]


def _drive_file(name: str, fields: type[_Strict]) -> type[_Strict]:
    cls = type(
        f"{fields.__name__[:-6]}Drive",
        (DriveFields, fields),
        {"__annotations__": {"law": Literal[name]}, "__module__": __name__},
    )
    return cls


_DRIVE_FILES = tuple(_drive_file(n, f) for n, f in LAW_FIELDS.items())
DriveFile = Annotated[Union[_DRIVE_FILES], Field(discriminator="law")]  # noqa: UP007


class ScenarioFile(ScenarioFields):
    drives: Annotated[list[DriveFile], Strict()] = []


class CaseFile(_Strict):
    """A whole case file. ``provenance`` is free-form metadata kept on the Case."""

    name: str = ""
    model: ModelFile
    scenario: ScenarioFile
    provenance: dict[str, Any] | None = None


# --- errors -------------------------------------------------------------------------------------
def _unwrap(tp):
    """Strip Annotated / Optional / list to the model (or discriminated union) inside."""
    while True:
        origin = get_origin(tp)
        if origin is Annotated:
            args = get_args(tp)
            if any(getattr(m, "discriminator", None) for m in args[1:]):
                return ("union", get_args(args[0]))
            tp = args[0]
        elif origin in (Union, types.UnionType):
            args = [a for a in get_args(tp) if a is not type(None)]
            if len(args) != 1:
                return ("union", tuple(args))
            tp = args[0]
        elif origin in (list, tuple, dict):
            return ("seq", get_args(tp)[-1] if get_args(tp) else Any)
        else:
            return tp


def _walk(root, loc) -> tuple[str, object]:
    """Dotted path of a pydantic ``loc`` and the model whose keys apply at its last step."""
    path, cur = "", root
    items = list(loc)
    while items:
        item = items.pop(0)
        u = _unwrap(cur) if cur is not None else None
        if isinstance(u, tuple) and u[0] == "seq":
            path += f"[{item}]" if isinstance(item, int) else f".{item}"
            cur = u[1]
            continue
        if isinstance(u, tuple) and u[0] == "union":  # tag of a drive law: not part of the path
            cur = (
                next(
                    (
                        m
                        for m in u[1]
                        if isinstance(item, str) and get_args(m.model_fields.get("law").annotation) == (item,)
                    ),
                    None,
                )
                if all(isinstance(m, type) and "law" in m.model_fields for m in u[1])
                else None
            )
            continue
        path += f"[{item}]" if isinstance(item, int) else (f".{item}" if path else str(item))
        if isinstance(u, type) and issubclass(u, BaseModel) and item in u.model_fields:
            cur = u.model_fields[item].annotation
        else:
            cur = None
    u = _unwrap(cur) if cur is not None else None
    return path, u


class Elided(str):
    """Stands for a value too long to print in a one-line message; its repr is the cut text."""

    def __repr__(self) -> str:
        return str(self)


def _short(v, n: int = 80):
    """``v`` itself, or an :class:`Elided` of its repr when that is longer than ``n``."""
    s = repr(v)
    return v if len(s) <= n else Elided(s[: n - 4] + " ...")


def _reason(err: dict, keys) -> str:
    t, ctx, inp = err["type"], err.get("ctx") or {}, err.get("input")
    kind = type(inp).__name__
    if t == "missing":
        return "is required"
    if t == "extra_forbidden":
        allowed = sorted(keys) if keys else []
        near = difflib.get_close_matches(str(err["loc"][-1]), allowed, n=1, cutoff=0.6)
        hint = f"; did you mean {near[0]!r}?" if near else ""
        return f"unknown key{hint} (allowed: {', '.join(allowed)})"
    if t == "greater_than":
        return "must be positive" if ctx.get("gt") == 0 else f"must be > {ctx.get('gt')}"
    if t == "greater_than_equal":
        if ctx.get("ge") == 0:
            return "must be non-negative"
        if ctx.get("ge") == SMALL:
            return (
                f"must be positive (and >= {SMALL:g})"
                if isinstance(inp, (int, float)) and inp > 0
                else "must be positive"
            )
        return f"must be >= {ctx.get('ge'):g}"
    if t == "less_than_equal":
        return f"must be <= {ctx.get('le'):g} (numbers lie within ±{BIG:g} in SI units)"
    if t == "finite_number":
        return "must be finite"
    if t in ("float_type", "int_type", "float_parsing"):
        return f"must be a number, got {kind}"
    if t == "bool_type":
        return f"must be true or false, got {kind}"
    if t == "string_type":
        return f"must be a string, got {kind}"
    if t in ("list_type", "tuple_type"):
        return f"must be a list, got {kind}"
    if t in ("model_type", "dict_type", "model_attributes_type"):
        return f"must be a table, got {kind}"
    if t == "literal_error":
        return f"must be one of {ctx.get('expected')}"
    if t in ("too_short", "too_long"):
        lo = err.get("ctx", {}).get("min_length")
        hi = err.get("ctx", {}).get("max_length")
        if t == "too_short" and lo is not None:
            return f"needs at least {lo} entries"
        return f"needs at most {hi} entries"
    if t == "union_tag_not_found":
        return f"is required (one of: {', '.join(keys or LAW_FIELDS)})"
    if t == "union_tag_invalid":
        tags = ctx.get("expected_tags") or ", ".join(LAW_FIELDS)
        return f"unknown drive law (one of: {tags})"
    return err.get("msg", t)


def _tags(u) -> list[str] | None:
    """The law names a discriminated union of law tables accepts (None: not such a union)."""
    if not (isinstance(u, tuple) and u[0] == "union"):
        return None
    tags = [
        get_args(m.model_fields["law"].annotation)
        for m in u[1]
        if isinstance(m, type) and issubclass(m, BaseModel) and "law" in m.model_fields
    ]
    return [a[0] for a in tags if a] or None


def input_error(exc: ValidationError, root, prefix: str = "") -> InputError:
    """The first error of a pydantic ``ValidationError`` as a one-line :class:`InputError`.

    ``root`` is the model validated; ``prefix`` the path of that model in the case ("" for a
    whole file, e.g. "model.links[0]" for a Section).
    """
    # a misspelt key also shows as a missing one: report the unknown key, it names both
    errs = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    err = errs[0]
    loc = tuple(err["loc"])
    if err["type"] in ("union_tag_invalid", "union_tag_not_found"):
        path, u = _walk(root, loc)
        field = f"{path}.law" if path else "law"
        value = (err.get("input") or {}).get("law") if isinstance(err.get("input"), dict) else None
        out = InputError(field, value, _reason(err, _tags(u)))
    elif err["type"] == "value_error" and isinstance((err.get("ctx") or {}).get("error"), InputError):
        inner = err["ctx"]["error"]
        path, _ = _walk(root, loc)
        field = ".".join(p for p in (path, inner.field) if p)
        out = InputError(field, inner.value, inner.reason)
    else:
        if err["type"] == "extra_forbidden":
            _, keys = _walk(root, loc[:-1])
            path, _ = _walk(root, loc)
            keys = list(keys.model_fields) if isinstance(keys, type) and issubclass(keys, BaseModel) else None
            if keys is not None and "law" in keys:
                keys = [k for k in keys if k != "law"] + ["law"]
        else:
            path, keys = _walk(root, loc)
        value = None if err["type"] == "missing" else err.get("input")
        out = InputError(path, value, _reason(err, keys))
    out = InputError(out.field, _short(out.value), out.reason)
    if prefix:
        out = InputError(f"{prefix}.{out.field}" if out.field else prefix, out.value, out.reason)
    if len(errs) > 1:
        out = InputError(out.field, out.value, f"{out.reason} (and {len(errs) - 1} more errors)")
    return out


def validate_case_file(data) -> CaseFile:
    """Validate a parsed case document; raises :class:`InputError` naming the first bad key."""
    if not isinstance(data, dict):
        raise InputError("case", _short(data), "must be a table (a TOML document)")
    try:
        return CaseFile.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, CaseFile) from None


# --- the Python constructors --------------------------------------------------------------------
def _plain(v):
    """numpy scalars and tuples/arrays to the plain Python values strict validation expects;
    bools and strings stay as they are (and are refused where a number is expected)."""
    if isinstance(v, (bool, np.bool_, str, bytes)) or v is None:
        return v
    if isinstance(v, np.ndarray):
        return [_plain(x) for x in v.tolist()]
    if isinstance(v, (tuple, list)):
        return [_plain(x) for x in v]
    if isinstance(v, numbers.Integral):
        return int(v)
    if isinstance(v, numbers.Real):
        return float(v)
    return v


def check_fields(model: type[_Strict], where: str, **values) -> dict:
    """Validate constructor arguments through ``model``; return the validated values (lists
    as tuples). Raises :class:`InputError` with the path ``where.field``."""
    try:
        m = model.model_validate({k: _plain(v) for k, v in values.items()})
    except ValidationError as exc:
        raise input_error(exc, model, where) from None
    out = {}
    for k in values:
        v = getattr(m, k)
        out[k] = tuple(v) if isinstance(v, list) else v
    return out
