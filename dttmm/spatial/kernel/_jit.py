"""The compiler switch of the spatial kernel (the pattern of :mod:`dttmm.kernel._jit`).

The sources of this folder are compiled by numba when they import; imported a second time as
the package ``dttmm.spatial.kernel_python`` they run uncompiled (``njit`` is the identity):
the engine "python", the same algorithm line for line. numba's on-disk cache lives in a folder
named by a hash of the sources of this folder (and of the stop rule and the pd law it inlines), so an edit to
any of them starts a fresh cache.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

try:
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover
    numba = None
    HAVE_NUMBA = False

PURE = not HAVE_NUMBA or __name__.startswith("dttmm.spatial.kernel_python")
KERNEL_DIR = Path(__file__).resolve().parent
OUTSIDE = tuple(KERNEL_DIR.parent.parent / f for f in ("iteration.py", "control.py", "control_state.py"))


def source_hash() -> str:
    h = hashlib.sha256()
    for path in sorted(KERNEL_DIR.glob("*.py")) + list(OUTSIDE):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cache_dir() -> str:
    name = f"numba-{source_hash()}"
    if os.environ.get("NUMBA_CACHE_DIR"):
        return str(Path(os.environ["NUMBA_CACHE_DIR"]) / f"dttmm-spatial-{name}")
    if os.access(KERNEL_DIR, os.W_OK):
        return str(KERNEL_DIR / "__pycache__" / name)
    return str(Path.home() / ".cache" / "dttmm" / f"spatial-{name}")


CACHE_DIR = None if PURE else _cache_dir()


def njit(*, inline="never", nrt=True):
    """``numba.njit(cache=True, boundscheck=False)`` with the cache in :data:`CACHE_DIR`; the
    identity in the uncompiled kernel. ``nrt=False`` compiles without reference counting (only
    for functions that allocate nothing): a call then does not touch the reference count of
    every array of its named-tuple arguments, nor does taking a view."""

    def deco(f):
        if PURE:
            return f
        old = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = CACHE_DIR
        try:
            return numba.njit(cache=True, boundscheck=False, inline=inline, _nrt=nrt)(f)
        finally:
            numba.config.CACHE_DIR = old

    return deco
