"""The compiler switch of the kernel: ``njit`` compiles with numba, or returns the function.

The kernel sources are compiled by numba when it imports. The same source files are also
imported a second time as the package ``dttmm.kernel_python`` (see that package): there
``njit`` returns the plain Python function, so the identical algorithm runs uncompiled — the
engine "python", and the only engine when numba is absent.

numba's on-disk cache (``cache=True``) checks only the source file of each compiled function,
not the files of the functions it calls, so an edit to one kernel module could leave stale
machine code for a caller in another. The cache therefore lives in a folder named by a hash of
all kernel sources: any edit starts a fresh cache.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

try:  # numba is an optional dependency (pip install dttmm[fast])
    import numba

    HAVE_NUMBA = True
except ImportError:  # pragma: no cover - exercised in a subprocess without numba
    numba = None
    HAVE_NUMBA = False

#: True in the uncompiled copy of the kernel (package ``dttmm.kernel_python``) or without numba.
PURE = not HAVE_NUMBA or __name__.startswith("dttmm.kernel_python")

#: floating-point contraction (a·b + c → FMA) only: no reassociation, no finite-math assumptions
CONTRACT = {"contract"}

KERNEL_DIR = Path(__file__).resolve().parent


#: kernel files with no compiled code (their edits need no new cache)
NOT_COMPILED = ("__init__.py", "driver.py")


#: compiled sources outside the kernel folder: the closed-loop law (dttmm/control.py), the stop
#: rule of the iteration (dttmm/iteration.py) and the state a user law sees (dttmm/control_state.py)
OUTSIDE = tuple(KERNEL_DIR.parent / name for name in ("control.py", "iteration.py", "control_state.py"))


def source_hash() -> str:
    """First 16 hex digits of the SHA-256 of every compiled kernel source file (by name), and of
    the files in :data:`OUTSIDE`."""
    h = hashlib.sha256()
    for path in sorted(p for p in KERNEL_DIR.glob("*.py") if p.name not in NOT_COMPILED) + list(OUTSIDE):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _cache_dir() -> str:
    """Per-hash cache folder: under $NUMBA_CACHE_DIR if set, else beside the sources if
    writable, else in the user's cache folder."""
    name = f"numba-{source_hash()}"
    if os.environ.get("NUMBA_CACHE_DIR"):
        return str(Path(os.environ["NUMBA_CACHE_DIR"]) / f"dttmm-kernel-{name}")
    if os.access(KERNEL_DIR, os.W_OK):
        return str(KERNEL_DIR / "__pycache__" / name)
    return str(Path.home() / ".cache" / "dttmm" / name)


CACHE_DIR = None if PURE else _cache_dir()


def njit(*, fastmath=False, inline="never", nrt=True):
    """``numba.njit(cache=True, boundscheck=False, ...)`` with the cache in :data:`CACHE_DIR`;
    the identity in the uncompiled kernel. ``nrt=False`` compiles without reference counting
    (only for functions that allocate nothing): a call then does not touch the reference count
    of every array in its named-tuple arguments."""

    def deco(f):
        if PURE:
            return f
        # numba fixes a function's cache folder when it is decorated, from config.CACHE_DIR:
        # point it at the per-hash folder for this decoration only
        old = numba.config.CACHE_DIR
        numba.config.CACHE_DIR = CACHE_DIR
        try:
            return numba.njit(cache=True, boundscheck=False, fastmath=fastmath, inline=inline, _nrt=nrt)(f)
        finally:
            numba.config.CACHE_DIR = old

    return deco
