"""The case document: one reader of a case file of any kind (:func:`read_case_document`: TOML
text → a parsed document and its kind) and the parts every case-file schema shares
(:func:`case_file_model`, :func:`validate_document`). The kinds' schemas are in
:mod:`dttmm.case` (planar), :mod:`dttmm.spatial.case` and :mod:`dttmm.urdf_import`;
:mod:`dttmm.casefiles` loads a file of any kind."""

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
    "document_kind",
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
