"""The compiler switch of the kernel: ``njit`` compiles with numba, or returns the function.

The kernel sources are compiled by numba when it imports. The same source files are also
imported a second time as the package ``dttmm.kernel_python`` (see that package): there
``njit`` returns the plain Python function, so the identical algorithm runs uncompiled — the
engine "python", and the only engine when numba is absent. The cache of the compiled code lives
in a folder named by a hash of all kernel sources (see :mod:`dttmm.jit`).
"""

from __future__ import annotations

from pathlib import Path

from dttmm.jit import CONTRACT, HAVE_NUMBA, cache_dir, cached_njit, is_pure
from dttmm.jit import source_hash as _hash

__all__ = ["CACHE_DIR", "CONTRACT", "HAVE_NUMBA", "PURE", "njit", "source_hash"]

#: True in the uncompiled copy of the kernel (package ``dttmm.kernel_python``) or without numba.
PURE = is_pure(__name__, "dttmm.kernel_python")

KERNEL_DIR = Path(__file__).resolve().parent

#: kernel files with no compiled code (their edits need no new cache)
NOT_COMPILED = ("__init__.py", "driver.py")

#: compiled sources outside the kernel folder: the closed-loop law (dttmm/control.py), the stop
#: rule of the iteration (dttmm/iteration.py) and the state a user law sees (dttmm/control_state.py)
OUTSIDE = tuple(KERNEL_DIR.parent / name for name in ("control.py", "iteration.py", "control_state.py"))

#: the compiled sources, in the order they are hashed
SOURCES = tuple(sorted(p for p in KERNEL_DIR.glob("*.py") if p.name not in NOT_COMPILED)) + OUTSIDE


def source_hash() -> str:
    """First 16 hex digits of the SHA-256 of every compiled kernel source file (by name), and of
    the files in :data:`OUTSIDE`."""
    return _hash(SOURCES)


CACHE_DIR = None if PURE else cache_dir("kernel-numba", KERNEL_DIR, SOURCES)


def njit(*, fastmath=False, inline="never", nrt=True):
    """``numba.njit(cache=True, boundscheck=False, ...)`` with the cache in :data:`CACHE_DIR`;
    the identity in the uncompiled kernel. ``nrt=False`` compiles without reference counting
    (only for functions that allocate nothing): a call then does not touch the reference count
    of every array in its named-tuple arguments."""
    return cached_njit(CACHE_DIR, cache=True, boundscheck=False, fastmath=fastmath, inline=inline, _nrt=nrt)
