"""The compiler switch of the spatial kernel (the pattern of :mod:`dttmm.kernel._jit`).

The sources of this folder are compiled by numba when they import; imported a second time as
the package ``dttmm.spatial.kernel_python`` they run uncompiled (``njit`` is the identity):
the engine "python", the same algorithm line for line. numba's on-disk cache lives in a folder
named by a hash of the sources of this folder (and of the stop rule and the pd law it inlines),
so an edit to any of them starts a fresh cache (see :mod:`dttmm.jit`).
"""

from __future__ import annotations

from pathlib import Path

from dttmm.jit import HAVE_NUMBA, cache_dir, cached_njit, is_pure
from dttmm.jit import source_hash as _hash

__all__ = ["CACHE_DIR", "HAVE_NUMBA", "PURE", "njit", "source_hash"]

PURE = is_pure(__name__, "dttmm.spatial.kernel_python")
KERNEL_DIR = Path(__file__).resolve().parent
OUTSIDE = tuple(KERNEL_DIR.parent.parent / f for f in ("iteration.py", "control.py", "control_state.py"))
#: the compiled sources, in the order they are hashed
SOURCES = tuple(sorted(KERNEL_DIR.glob("*.py"))) + OUTSIDE


def source_hash() -> str:
    return _hash(SOURCES)


CACHE_DIR = None if PURE else cache_dir("spatial-numba", KERNEL_DIR, SOURCES)


def njit(*, inline="never", nrt=True):
    """``numba.njit(cache=True, boundscheck=False)`` with the cache in :data:`CACHE_DIR`; the
    identity in the uncompiled kernel. ``nrt=False`` compiles without reference counting (only
    for functions that allocate nothing): a call then does not touch the reference count of
    every array of its named-tuple arguments, nor does taking a view."""
    return cached_njit(CACHE_DIR, cache=True, boundscheck=False, inline=inline, _nrt=nrt)
