"""Case files of both kinds: ``load_case`` reads a planar case file (docs/cases.md) or, when
the file says ``kind = "spatial"``, a spatial one (docs/cases.md "Spatial cases");
``case_to_dict`` writes either kind of case as its document. These are ``dttmm.load_case`` and
``dttmm.case_to_dict``; ``dttmm.case`` and ``dttmm.spatial.case`` hold each kind's own."""

from __future__ import annotations

import tomllib
from pathlib import Path

from . import case as planar
from .errors import InputError

__all__ = ["case_to_dict", "load_case"]


def load_case(path):
    """A :class:`dttmm.Case`, or a :class:`dttmm.spatial.SpatialCase` for a file with
    ``kind = "spatial"`` or a ``[model]`` naming a ``urdf`` (docs/urdf.md); the name defaults to
    the file's stem. InputError (one line, naming the
    field and value) for an unreadable file, invalid TOML, or any key or value the schema
    refuses."""
    text = planar.read_case_text(path)
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(str(path), "<file>", f"is not valid TOML: {exc}") from None
    if "name" not in data:
        data["name"] = Path(path).stem
    model = data.get("model")
    if isinstance(model, dict) and "urdf" in model:  # a robot from its URDF (docs/urdf.md)
        from .urdf_import import case_from_urdf_dict

        return case_from_urdf_dict(data, Path(path).parent)
    if data.get("kind") == "spatial":
        from .spatial.case import case_from_dict as spatial_from_dict

        return spatial_from_dict(data)
    return planar.case_from_dict(data)


def case_to_dict(case) -> dict:
    """The case as a document of its file format (planar or spatial)."""
    if isinstance(case, planar.Case):
        return planar.case_to_dict(case)
    from .spatial.case import case_to_dict as spatial_to_dict

    return spatial_to_dict(case)
