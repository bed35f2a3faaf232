"""Case files of both kinds: ``load_case`` reads a planar case file (docs/cases.md), a spatial
one (``kind = "spatial"``, docs/cases.md "Spatial cases") or a robot from its URDF (a
``[model]`` naming a ``urdf``, docs/urdf.md); ``case_to_dict`` writes either kind of case as
its document. These are ``dttmm.load_case`` and ``dttmm.case_to_dict``; ``dttmm.case`` and
``dttmm.spatial.case`` hold each kind's own, all read by :func:`dttmm.casedoc.read_case_document`."""

from __future__ import annotations

from pathlib import Path

from .casedoc import read_case_document

__all__ = ["case_from_document", "case_to_dict", "load_case", "load_spatial_case"]


def load_case(path):
    """A :class:`dttmm.Case`, or a :class:`dttmm.spatial.SpatialCase` for a file with
    ``kind = "spatial"`` or a ``[model]`` naming a ``urdf`` (docs/urdf.md); the name defaults to
    the file's stem. InputError (one line, naming the
    field and value) for an unreadable file, invalid TOML, or any key or value the schema
    refuses."""
    data, kind = read_case_document(path)
    return case_from_document(data, kind, Path(path).parent)


def case_from_document(data: dict, kind: str, folder):
    """The case of a parsed case document of ``kind`` (:func:`dttmm.casedoc.read_case_document`),
    built by that kind's reader; ``folder``: the file's folder (a URDF path is relative to it)."""
    if kind == "urdf":  # a robot from its URDF (docs/urdf.md)
        from .urdf_import import case_from_urdf_dict

        return case_from_urdf_dict(data, folder)
    if kind == "spatial":
        from .spatial.case import case_from_dict as spatial_from_dict

        return spatial_from_dict(data)
    from .case import case_from_dict

    return case_from_dict(data)


def load_spatial_case(path):
    """Read a case file of any kind as a :class:`SpatialCase`; the name defaults to the file's
    stem. A spatial file (``kind = "spatial"``, docs/cases.md "Spatial cases") and a URDF case
    document (a ``[model]`` naming a ``urdf``, docs/urdf.md) are read as
    :func:`dttmm.load_case` reads them; a planar case file is read by the planar reader and
    embedded (:meth:`SpatialCase.from_planar`, its plane the world's x–y plane). The
    ``kind = "spatial"`` marker is optional here: a file without it that the planar reader
    refuses is read as a spatial file when the spatial schema takes it (else the planar
    reader's error stands). Raises InputError (one line, naming the field and value) for an
    unreadable file, invalid TOML, or any key or value the schema refuses."""
    from .case import Case
    from .errors import InputError
    from .spatial.case import SpatialCase, case_from_dict

    data, kind = read_case_document(path)
    if kind == "planar" and "kind" not in data:
        try:
            case = case_from_document(data, kind, Path(path).parent)
        except InputError as exc:
            try:
                return case_from_dict(data)  # a spatial file without its marker
            except InputError:
                raise exc from None
    else:
        case = case_from_document(data, kind, Path(path).parent)
    return SpatialCase.from_planar(case) if isinstance(case, Case) else case


def case_to_dict(case) -> dict:
    """The case as a document of its file format (planar or spatial)."""
    from .case import Case
    from .case import case_to_dict as planar_to_dict

    if isinstance(case, Case):
        return planar_to_dict(case)
    from .spatial.case import case_to_dict as spatial_to_dict

    return spatial_to_dict(case)
