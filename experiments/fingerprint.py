"""Content fingerprints for the caches: what a cached run or reference was computed from.

A cached entry is valid only for the exact physics, method settings and code that made it, so
its key hashes

* the case *content* — canonical JSON of ``dttmm.case_to_dict`` (model and scenario values, not
  the TOML bytes, so reformatting a file keeps the cache and changing a payload does not);
* the method name, its registered options and the run's own options, k, h and duration;
* the *code version* of the method: the dttmm version, the versions of the numerical
  libraries, and a hash of every ``.py`` file under the ``dttmm`` package and under the
  top-level package (or single module) that defines the method's ``simulate``. Whole directory
  trees are hashed, not a list of files, so a file moved or added inside them counts too.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.metadata
import importlib.util
import json
import math
import sys
from pathlib import Path

__all__ = ["canonical_json", "case_digest", "code_version", "digest", "file_sha256", "tree_hash"]


def _plain(v):
    """JSON-able, canonical form: floats by repr (exact), tuples as lists, NaN/inf as text."""
    if isinstance(v, float):
        return v if math.isfinite(v) else repr(v)
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if hasattr(v, "item") and callable(v.item):  # numpy scalar
        return _plain(v.item())
    if isinstance(v, (str, int, bool, type(None))):
        return v
    return repr(v)


def canonical_json(obj) -> str:
    """Key-sorted, whitespace-free JSON of ``obj``: equal values give equal text."""
    return json.dumps(_plain(obj), sort_keys=True, separators=(",", ":"), allow_nan=False)


def digest(obj) -> str:
    """sha256 (hex) of the canonical JSON of ``obj``."""
    return hashlib.sha256(canonical_json(obj).encode()).hexdigest()


def case_digest(case) -> str:
    """sha256 of the case's content (name, model and scenario values)."""
    from dttmm import case_to_dict

    return digest(case_to_dict(case))


def file_sha256(path) -> str:
    """sha256 (hex) of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def tree_hash(root) -> str:
    """sha256 over every ``.py`` file under ``root`` (a folder, or one file): relative path and
    bytes, in sorted order. Caches (``__pycache__``) are left out."""
    root = Path(root)
    files = (
        [root] if root.is_file() else sorted(p for p in root.rglob("*.py") if "__pycache__" not in p.parts)
    )
    h = hashlib.sha256()
    for p in files:
        h.update(str(p.relative_to(root.parent)).encode() + b"\0")
        h.update(p.read_bytes() + b"\0")
    return h.hexdigest()


def _source_root(module_name: str) -> Path | None:
    """Folder of the top-level package of ``module_name`` (or its file when it is a plain
    module), found without importing it; None when it cannot be located."""
    top = module_name.split(".")[0]
    mod = sys.modules.get(top)
    spec = getattr(mod, "__spec__", None) if mod is not None else None
    if spec is None:
        try:
            spec = importlib.util.find_spec(top)
        except (ImportError, ValueError):
            return None
    if spec is None:
        return None
    if spec.submodule_search_locations:
        return Path(next(iter(spec.submodule_search_locations)))
    return Path(spec.origin) if spec.origin and spec.origin.endswith(".py") else None


#: Libraries every run depends on (through dttmm's model and metrics), whatever the method.
_ALWAYS = ("numpy", "scipy")


@functools.cache
def _library_versions(names: tuple) -> dict:
    out = {}
    for name in names:  # an engine that is absent is listed as None
        try:
            out[name] = importlib.metadata.version(name)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    return out


@functools.cache
def _packages_distributions() -> dict:
    """Top-level package -> distributions, read once per process: it reads every installed
    package's file list (most of a small sweep's time when read per run)."""
    return importlib.metadata.packages_distributions()


def _distribution_of(module: str) -> str | None:
    """The installed distribution that provides ``module``'s top-level package (None: not installed)."""
    top = module.split(".")[0]
    dists = _packages_distributions().get(top) or []
    return dists[0] if dists else None


@functools.cache
def _roots_hash(module_names: tuple) -> dict:
    roots = {"dttmm": _source_root("dttmm")}
    for m in module_names:
        roots.setdefault(m.split(".")[0], _source_root(m))
    return {name: (tree_hash(p) if p is not None else None) for name, p in sorted(roots.items())}


def code_version(method: str) -> dict:
    """The code a run of ``method`` depends on, as a JSON-able dict.

    Sources hashed: the ``dttmm`` package and the top-level package (or module) of the
    method's ``simulate`` (``reference_models`` for the reference engines; the defining
    module for a method added with ``methods.register``). The method's registered options
    are part of it, as are the versions of the libraries its registry record names (and numpy,
    scipy), and, for a method from an installed package, that package's version.
    """
    import dttmm

    from . import methods

    modules, fixed = methods.source_of(method)
    try:
        libs = methods.get(method).libraries
    except methods.MethodUnavailable:
        libs = ()
    dists = [d for m in modules if (d := _distribution_of(m)) and d != "dttmm"]
    return {
        "method": method,
        "method_options": [list(x) for x in fixed],
        "dttmm": dttmm.__version__,
        "python": f"{sys.version_info[0]}.{sys.version_info[1]}",
        "libraries": dict(_library_versions(tuple(dict.fromkeys((*_ALWAYS, *libs, *dists))))),
        "sources": _roots_hash(tuple(modules)),
    }
