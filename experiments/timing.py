"""Timing protocol for every cost figure: repeats, CPU time next to wall time, load recorded.

A measurement calls a function ``repeats`` times under one BLAS thread and keeps, per repeat,
the CPU time of the process (``time.process_time``: what the run itself consumed, largely
insensitive to other work on the machine), the wall time (``time.perf_counter``) and, when
the call returns a :class:`dttmm.Result`, the method's own solve-only wall time
(``Result.wall_time``). The figures use the minimum over repeats (the least disturbed run);
the median is kept beside it. The 1-minute load average is sampled before and after every
repeat; a measurement is marked *noisy* when that load exceeded the number of cores or when
the median CPU time lies more than ``SPREAD_MAX`` above the minimum.

A run of a few milliseconds is disturbed alike in all of a few calls on a busy machine, so a
measurement may also ask for ``min_cpu``: it then keeps calling (up to ``MAX_REPEATS`` calls)
until the number of calls times the least CPU time of a call reaches that; the sweep asks for :data:`MIN_CPU` wherever it asks
for more than one call.

The first repeat's return value is the one kept (every repeat computes the same result), so
accuracy-only studies run with ``repeats=1`` and pay nothing extra.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from dttmm.threads import one_blas_thread

__all__ = [
    "COST_REPEATS",
    "MAX_REPEATS",
    "MIN_CPU",
    "SPREAD_MAX",
    "Timing",
    "cores",
    "load_average",
    "measure",
]

#: Largest accepted (median − min) / min of the CPU times before a point is marked noisy.
SPREAD_MAX = 0.10
#: Repeats used by every cost figure (studies that report time); accuracy-only studies use 1.
COST_REPEATS = 3
#: CPU time (s) that calls × least CPU time of a cost measurement reaches at least. Measured on a loaded
#: 2-core machine (experiments/loaded_check.py): runs of 3-7 ms timed 3 times differed by up
#: to 21 % between two sweeps, runs of 50 ms and more by about 10 %.
MIN_CPU = 0.1
#: Most calls of one measurement when ``min_cpu`` asks for more than ``repeats``.
MAX_REPEATS = 50


def cores() -> int:
    """Cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def load_average() -> float:
    """1-minute load average (NaN where the platform has none)."""
    try:
        return float(os.getloadavg()[0])
    except (AttributeError, OSError):
        return math.nan


@dataclass(frozen=True)
class Timing:
    """One measurement: times in s over ``repeats`` calls.

    ``cpu_*``/``wall_*`` cover the whole call (model build and solve); ``solve_*`` is the
    method's own solve-only wall time (NaN when the call returns no Result). ``load_max`` is
    the largest 1-minute load average sampled, ``blas_threads`` the largest BLAS pool size
    seen inside the measurement (1 when the limit held).
    """

    repeats: int
    cpu_min: float
    cpu_median: float
    wall_min: float
    wall_median: float
    solve_min: float
    solve_median: float
    load_max: float
    cores: int
    blas_threads: int
    noisy: bool
    noise: str

    @property
    def spread(self) -> float:
        """(median − min) / min of the CPU times (0 for a single repeat)."""
        return self.cpu_median / self.cpu_min - 1.0 if self.cpu_min > 0 else math.nan

    def columns(self) -> dict:
        """Flat ``timing_*`` columns for a run table."""
        return {f"timing_{k}": v for k, v in asdict(self).items()}


def _noise(load: float, n_cores: int, spread: float) -> str:
    why = []
    if math.isfinite(load) and load > n_cores:
        why.append(f"load {load:.2g} > {n_cores} cores")
    if math.isfinite(spread) and spread > SPREAD_MAX:
        why.append(f"median CPU time {100 * spread:.0f} % above the minimum")
    return "; ".join(why)


def measure(fn: Callable[[], Any], repeats: int = COST_REPEATS, min_cpu: float = 0.0) -> tuple[Any, Timing]:
    """Call ``fn()`` ``repeats`` times (≥ 1) under one BLAS thread, and more (at most
    ``MAX_REPEATS`` in all) until calls × least CPU time reaches ``min_cpu`` (s); return
    (first value, Timing).

    An exception in any repeat propagates (the run failed; nothing is timed).
    """
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        from dttmm import InputError

        raise InputError("repeats", repeats, "must be an integer >= 1")
    cpu, wall, solve, loads = [], [], [], [load_average()]
    first = None
    with one_blas_thread() as threads:
        i = 0
        # calls × least CPU time, not the sum: a first call that compiles (JIT) must not end it
        while i < repeats or (i * min(cpu) < min_cpu and i < max(repeats, MAX_REPEATS)):
            c0, w0 = time.process_time(), time.perf_counter()
            value = fn()
            wall.append(time.perf_counter() - w0)
            cpu.append(time.process_time() - c0)
            solve.append(float(getattr(value, "wall_time", math.nan)))
            loads.append(load_average())
            if i == 0:
                first = value
            i += 1
    n = cores()
    load = max((x for x in loads if math.isfinite(x)), default=math.nan)
    t = Timing(
        len(cpu),
        min(cpu),
        statistics.median(cpu),
        min(wall),
        statistics.median(wall),
        min(solve),
        statistics.median(solve),
        load,
        n,
        int(threads),
        False,
        "",
    )
    why = _noise(load, n, t.spread)
    return first, Timing(**{**asdict(t), "noisy": bool(why), "noise": why})
