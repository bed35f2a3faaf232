"""The value types of case fields, their validation and the one-line errors it raises.

Every case field is declared once, as a field of a frozen dataclass (:class:`dttmm.Section`,
:class:`dttmm.Drive`, the drive laws, …) annotated with a value type below (``length:
Positive``, ``kind: Literal["torque", "motion"]``). From those annotations

* :func:`fields_model` derives a strict pydantic model per class, which the constructors use
  (:class:`Checked`, :func:`check_fields`): strict types (no bool or string is read as a number;
  an integer is a fine float), unknown keys refused with the nearest valid key;
* the case-file layer (:mod:`dttmm.case`, the law tables in :mod:`dttmm.drives`) composes its
  file models from the same derived models, validates a document once, and builds the objects
  from the validated values with :func:`build`, which runs only the rules that span several
  fields (``_rules``: bang-bang levels vs switch times, a motion drive's initial state vs its
  law, output step vs duration, …).

The reference for users is docs/cases.md.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import numbers
import types
from typing import Annotated, Any, Literal, Union, get_args, get_origin, get_type_hints

import numpy as np
from pydantic import AfterValidator, BaseModel, ConfigDict, Field, Strict, ValidationError, create_model

from .errors import InputError

__all__ = [
    "Bounded",
    "Checked",
    "Finite",
    "Limit",
    "NonNegative",
    "Positive",
    "Until",
    "build",
    "check_fields",
    "field_types",
    "fields_model",
    "input_error",
    "tuple_of",
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
Limit = Annotated[float, Strict(), Field(gt=0.0)]  # positive, inf (no saturation) allowed


def tuple_of(item, **length):
    """A list of ``item`` values (``min_length``, ``max_length``), kept as a tuple."""
    return Annotated[list[item], Strict(), Field(**length), AfterValidator(tuple)]


class _Strict(BaseModel):
    model_config = ConfigDict(strict=True, extra="forbid", frozen=True)


# --- fields declared by dataclasses -----------------------------------------------------------
def _is_value(tp) -> bool:
    """Whether a field annotation is a value type (Annotated or Literal, possibly optional);
    other fields (a law object, a tuple of links) are checked by their class."""
    if get_origin(tp) in (Union, types.UnionType):
        return all(_is_value(a) for a in get_args(tp) if a is not type(None))
    return get_origin(tp) in (Annotated, Literal)


@functools.cache
def field_types(cls) -> dict[str, tuple]:
    """name -> (value type, default or ``...`` when required) of the case fields of dataclass
    ``cls``: its public init fields annotated with a value type, in declaration order. A
    default of None on a type that refuses None (``ki`` of a PID law) marks a required field."""
    hints = get_type_hints(cls, include_extras=True)
    out = {}
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        if f.name.startswith("_") or not f.init or not _is_value(tp):
            continue
        required = f.default is dataclasses.MISSING or (f.default is None and type(None) not in get_args(tp))
        out[f.name] = (tp, ... if required else f.default)
    return out


@functools.cache
def fields_model(cls, only: tuple[str, ...] | None = None) -> type[BaseModel]:
    """The strict pydantic model of the case fields of dataclass ``cls`` (``SectionFields``, …),
    or of the fields named in ``only``."""
    types_ = {k: v for k, v in field_types(cls).items() if only is None or k in only}
    name = f"{cls.__name__.lstrip('_')}Fields"
    return create_model(name, __base__=_Strict, __module__=cls.__module__, **types_)


def _set(obj, values: dict) -> None:
    for k, v in values.items():
        object.__setattr__(obj, k, v)


class Checked:
    """Base of the dataclasses whose fields are case fields.

    On construction the fields annotated with a value type are validated (an error names
    ``<_where>.<field>``), then :meth:`_rules` checks what spans several fields.
    """

    _where = "value"

    def __post_init__(self):
        cls = type(self)
        _set(self, check_fields(cls, self._where, **{k: getattr(self, k) for k in field_types(cls)}))
        self._rules()

    def _rules(self) -> None:
        """Rules that span several fields (none by default); raise :class:`InputError`."""


def build(cls, **values):
    """An instance of the :class:`Checked` dataclass ``cls`` from values its fields model has
    validated already (a case file's): they are set as given (defaults for the others) and only
    :meth:`Checked._rules` runs."""
    obj = object.__new__(cls)
    for f in dataclasses.fields(cls):
        if f.name in values:
            v = values[f.name]
        else:
            v = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        object.__setattr__(obj, f.name, v)
    obj._rules()
    return obj


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
        return f"is required (one of: {', '.join(keys or ())})"
    if t == "union_tag_invalid":
        tags = ctx.get("expected_tags")
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


def check_fields(model, where: str, **values) -> dict:
    """Validate constructor arguments through ``model`` (a pydantic model, or a dataclass whose
    :func:`fields_model` is used); return the validated values (lists as tuples). Raises
    :class:`InputError` with the path ``where.field``."""
    if dataclasses.is_dataclass(model):
        model = fields_model(model)
    try:
        m = model.model_validate({k: _plain(v) for k, v in values.items()})
    except ValidationError as exc:
        raise input_error(exc, model, where) from None
    out = {}
    for k in values:
        v = getattr(m, k)
        out[k] = tuple(v) if isinstance(v, list) else v
    return out
