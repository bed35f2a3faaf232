"""Case files of both kinds: one reader of a case document and the parts every case-file
schema shares.

``load_case`` reads a planar case file (docs/cases.md), a spatial one (``kind = "spatial"``,
docs/cases.md "Spatial cases") or a robot from its URDF (a ``[model]`` naming a ``urdf``,
docs/urdf.md); ``case_to_dict`` writes either kind of case as its document. These are
``dttmm.load_case`` and ``dttmm.case_to_dict``; ``dttmm.case`` and ``dttmm.spatial.case`` hold
each kind's schema and objects, built on :func:`read_case_document`, :func:`case_file_model`
and :func:`validate_document`.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import ValidationError, create_model

from .errors import InputError
from .schema import _short, _Strict, input_error

__all__ = [
    "MAX_FILE_BYTES",
    "case_file_model",
    "case_to_dict",
    "document_kind",
    "load_case",
    "read_case_document",
    "read_case_text",
    "validate_document",
]

#: a case file larger than this is refused before parsing (bytes)
MAX_FILE_BYTES = 16 * 2**20


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


def document_kind(data: dict) -> str:
    """The kind of a parsed case document: "urdf" (a ``[model]`` naming a ``urdf``), "spatial"
    (``kind = "spatial"``) or "planar"."""
    model = data.get("model")
    if isinstance(model, dict) and "urdf" in model:
        return "urdf"
    return "spatial" if data.get("kind") == "spatial" else "planar"


def read_case_document(path) -> tuple[dict, str]:
    """The parsed TOML document of a case file (its ``name`` defaulting to the file's stem) and
    its :func:`document_kind`. InputError for an unreadable file or invalid TOML."""
    text = read_case_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(str(path), "<file>", f"is not valid TOML: {exc}") from None
    if "name" not in data:
        data["name"] = Path(path).stem
    return data, document_kind(data)


def case_file_model(name: str, module: str, model, scenario, spatial: bool = False, doc: str = ""):
    """The schema of a whole case file: ``kind`` (spatial files: ``"spatial"``, optional),
    ``name``, the ``model`` and ``scenario`` tables, and ``provenance`` (free-form metadata kept
    on the case); ``module`` is the module that defines it, ``doc`` its docstring."""
    kind = {"kind": (Literal["spatial"], "spatial")} if spatial else {}
    marked = ' (``kind = "spatial"`` marks it, optional)' if spatial else ""
    doc = (
        doc
        or f"A whole {'spatial ' if spatial else ''}case file{marked}; ``provenance`` is free-form metadata."
    )
    return create_model(
        name,
        __base__=_Strict,
        __module__=module,
        __doc__=doc,
        **kind,
        name=(str, ""),
        model=(model, ...),
        scenario=(scenario, ...),
        provenance=(dict[str, Any] | None, None),
    )


def validate_document(schema, data):
    """``data`` (a parsed case document) validated by ``schema`` (a :func:`case_file_model`);
    InputError naming the first bad key (an unknown key with the nearest valid one)."""
    if not isinstance(data, dict):
        raise InputError("case", _short(data), "must be a table (a TOML document)")
    try:
        return schema.model_validate(data)
    except ValidationError as exc:
        raise input_error(exc, schema) from None


def load_case(path):
    """A :class:`dttmm.Case`, or a :class:`dttmm.spatial.SpatialCase` for a file with
    ``kind = "spatial"`` or a ``[model]`` naming a ``urdf`` (docs/urdf.md); the name defaults to
    the file's stem. InputError (one line, naming the
    field and value) for an unreadable file, invalid TOML, or any key or value the schema
    refuses."""
    data, kind = read_case_document(path)
    if kind == "urdf":  # a robot from its URDF (docs/urdf.md)
        from .urdf_import import case_from_urdf_dict

        return case_from_urdf_dict(data, Path(path).parent)
    if kind == "spatial":
        from .spatial.case import case_from_dict as spatial_from_dict

        return spatial_from_dict(data)
    from .case import case_from_dict

    return case_from_dict(data)


def case_to_dict(case) -> dict:
    """The case as a document of its file format (planar or spatial)."""
    from .case import Case
    from .case import case_to_dict as planar_to_dict

    if isinstance(case, Case):
        return planar_to_dict(case)
    from .spatial.case import case_to_dict as spatial_to_dict

    return spatial_to_dict(case)
