"""Timing protocol for every cost figure: repeats, CPU time next to wall time, load recorded.

A measurement calls a function ``repeats`` times under one BLAS thread and keeps, per repeat,
the CPU time of the process (``time.process_time``: what the run itself consumed, largely
insensitive to other work on the machine), the wall time (``time.perf_counter``) and, when
the call returns a :class:`dttmm.Result`, the method's own solve-only wall time
(``Result.wall_time``). The figures use the minimum over repeats (the least disturbed run);
the median is kept beside it. The 1-minute load average is sampled before and after every
repeat; a measurement is marked *noisy* when that load exceeded the number of cores or when
the median CPU time lies more than ``SPREAD_MAX`` above the minimum.

Repeats are spent where they matter. A run of a few milliseconds is disturbed alike in all of
a few calls on a busy machine, so a measurement may also ask for ``min_cpu``: it then keeps
calling (up to ``MAX_REPEATS`` calls) until the number of calls times the least CPU time of a
call reaches that, and while the median CPU time lies more than ``SPREAD_MAX`` above the
minimum as long as calls × least CPU time stay below ``SPREAD_BUDGET`` (1 s); the sweep asks
for :data:`MIN_CPU` wherever it asks for more than one call. A call of at least
:data:`LONG_CPU` CPU seconds is timed once: its CPU time varies between repeats by less than
:data:`LONG_NOISE` (measured, see the constant), inside the spread the report calls noise, so
further calls would buy nothing. The sweep runs such a method once, untimed, on a few steps of
the same case before timing it in a worker (JIT compilation or loading of cached machine code
would otherwise land in the one timed call).

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
#: CPU time (s), calls × least CPU time, up to which a short run is called again while its spread
#: is wide.
SPREAD_BUDGET = 1.0
#: CPU time (s) from which one call is timed once.
LONG_CPU = 2.0
#: Largest (median − min)/min of the CPU times of calls of ≥ LONG_CPU seen over the quick report's
#: cost runs timed 3 times each: 3-15 %, 8 % at the longest (114 s), with 2 workers on this 2-core
#: machine under a load of 7-12 (docs/peers.md "Timing rule"). Within the 20 % the report calls noise.
LONG_NOISE = 0.15


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


def measure(
    fn: Callable[[], Any], repeats: int = COST_REPEATS, min_cpu: float = 0.0, long_cpu: float | None = None
) -> tuple[Any, Timing]:
    """Call ``fn()`` ``repeats`` times (≥ 1) under one BLAS thread, and more (at most
    ``MAX_REPEATS`` in all) until calls × least CPU time reaches ``min_cpu`` (s) and the median
    lies within ``SPREAD_MAX`` of the least; return (first value, Timing).

    A first call of at least ``long_cpu`` CPU seconds (default :data:`LONG_CPU`; ``math.inf``:
    never) ends the measurement when more than one call was asked for: it is timed once, and its
    ``noise`` says so. An exception in any repeat propagates (the run failed; nothing is timed).
    """
    long_cpu = LONG_CPU if long_cpu is None else long_cpu
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        from dttmm import InputError

        raise InputError("repeats", repeats, "must be an integer >= 1")
    cpu, wall, solve, loads = [], [], [], [load_average()]
    first = None
    with one_blas_thread() as threads:
        i = 0
        while _more(i, cpu, repeats, min_cpu, long_cpu):
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
    if repeats > 1 and len(cpu) == 1:
        once = (
            f"timed once: a call of ≥ {long_cpu:g} s CPU varies by < {100 * LONG_NOISE:.0f} % between repeats"
        )
        return first, Timing(
            **{**asdict(t), "noisy": bool(why), "noise": "; ".join(filter(None, [once, why]))}
        )
    return first, Timing(**{**asdict(t), "noisy": bool(why), "noise": why})


def _more(i: int, cpu: list, repeats: int, min_cpu: float, long_cpu: float) -> bool:
    """Whether a measurement makes another call after ``i`` calls of CPU times ``cpu``."""
    if i == 0:
        return True
    if repeats > 1 and i == 1 and cpu[0] >= long_cpu:
        return False  # a long run: timed once
    if i < repeats:
        return True
    if i >= max(repeats, MAX_REPEATS):
        return False
    # calls × least CPU time, not the sum: a first call that compiles (JIT) must not end it
    if i * min(cpu) < min_cpu:
        return True
    # short runs asked to add up (min_cpu): also until the spread is small, while the calls stay
    # cheap (a loaded machine can keep the spread wide: a longer run is not called on and on)
    if i * min(cpu) >= SPREAD_BUDGET:
        return False
    return repeats > 1 and min_cpu > 0 and statistics.median(cpu) > (1 + SPREAD_MAX) * min(cpu)
