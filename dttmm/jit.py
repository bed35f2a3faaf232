"""The one compiler switch of the compiled engines: ``numba.njit`` with its on-disk cache in a
folder named by a hash of the sources, or the identity in an uncompiled copy.

The planar kernel (:mod:`dttmm.kernel._jit`), the spatial kernel
(:mod:`dttmm.spatial.kernel._jit`) and the global solver's engine
(:mod:`reference_models._global_numba`) each compile with numba when they import and run
uncompiled when imported a second time under another name (``dttmm.kernel_python``,
``dttmm.spatial.kernel_python``, ``reference_models._global_python``): the same algorithm line
for line, the engine "python". Each names its own compiler options and source files; this
module holds the mechanics they share.

numba's on-disk cache (``cache=True``) checks only the source file of each compiled function,
not the files of the functions it calls, so an edit to one module could leave stale machine
code for a caller in another. Each engine's cache therefore lives in a folder named by a hash of
all its compiled sources: any edit starts a fresh cache.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Iterable
from pathlib import Path

try:  # numba is an optional dependency (pip install dttmm[fast])
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised in a subprocess without numba
    numba = None
    HAVE_NUMBA = False

#: floating-point contraction (a·b + c → FMA) only: no reassociation, no finite-math assumptions
CONTRACT = {"contract"}


def is_pure(module: str, uncompiled: str) -> bool:
    """True where the module named ``module`` runs uncompiled: without numba, or imported as
    the uncompiled copy (its name starts with ``uncompiled``)."""
    return not HAVE_NUMBA or module.startswith(uncompiled)


def source_hash(paths: Iterable[Path]) -> str:
    """First 16 hex digits of the SHA-256 of the files ``paths`` (each by name and content, in
    the order given)."""
    h = hashlib.sha256()
    for path in paths:
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def cache_dir(label: str, beside: Path, paths: Iterable[Path]) -> str:
    """The cache folder ``{label}-{hash of paths}``: under $NUMBA_CACHE_DIR (prefixed
    ``dttmm-``) if set, else in ``beside/__pycache__`` if writable, else in the user's cache
    folder."""
    name = f"{label}-{source_hash(paths)}"
    if os.environ.get("NUMBA_CACHE_DIR"):
        return str(Path(os.environ["NUMBA_CACHE_DIR"]) / f"dttmm-{name}")
    if os.access(beside, os.W_OK):
        return str(beside / "__pycache__" / name)
    return str(Path.home() / ".cache" / "dttmm" / name)


def cached_njit(folder: str | None, **options):
    """``numba.njit(**options)`` with its cache in ``folder``; the identity where ``folder`` is
    None (the uncompiled copy)."""

    def deco(f):
        if folder is None:
            return f
        # numba fixes a function's cache folder when it is decorated, from config.CACHE_DIR:
        # point it at the per-hash folder for this decoration only
        old = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = folder
        try:
            return numba.njit(**options)(f)
        finally:
            numba.config.CACHE_DIR = old

    return deco
