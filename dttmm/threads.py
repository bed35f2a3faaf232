"""One BLAS/OpenMP thread for timed runs, enforced in the process (not only by the environment).

Timings compare single-threaded solvers: a BLAS library that spreads a factorisation over
every core would make a method look faster on an idle machine and slower on a busy one. The
environment variables (``OPENBLAS_NUM_THREADS=1``) only act before the library loads; the
limit here (threadpoolctl) acts on libraries already loaded.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

__all__ = ["blas_threads", "one_blas_thread"]


@contextlib.contextmanager
def one_blas_thread() -> Iterator[int]:
    """Limit every loaded BLAS and OpenMP pool to one thread inside the block.

    Yields the largest thread count seen in a pool inside the block (1 when the limit holds,
    0 when no pool is loaded). Without threadpoolctl the block runs unchanged and yields -1.
    """
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # optional: the timing then relies on the environment variables
        yield -1
        return
    with threadpool_limits(limits=1):
        yield blas_threads()


def blas_threads() -> int:
    """Largest number of threads of any loaded BLAS/OpenMP pool (0 when none is loaded, -1
    when threadpoolctl is missing)."""
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return -1
    return max((int(p.get("num_threads", 0)) for p in threadpool_info()), default=0)
