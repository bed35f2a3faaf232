"""Memory guard: refuse a run whose arrays would not fit before allocating them.

A fixed-step run allocates per-step arrays (the step schedule and the drive tables, about
``40 + 256·n_joints`` bytes a step, RK4 included) and per-output-sample arrays (joint angles,
rates, torques, link roots and tips, energy, then copied into the result: about
``2·8·(8·n_joints + 2)`` bytes a sample), plus the cut loads, which the recorder thins to at most
2·10⁶ cut samples (≤ 48 MB). :func:`check_run_size` adds these up and refuses a run above half
of the memory available now (read from ``/proc/meminfo`` or ``os.sysconf``).
"""

from __future__ import annotations

import math
import os

from ._validate import elements_per_link as _check_k
from ._validate import step_size
from .errors import InputError

__all__ = ["available_memory", "check_run_size", "estimate_run_bytes"]

_STEP_BYTES, _STEP_BYTES_PER_JOINT = 40, 256
_LOADS_CAP_BYTES = 2.0e6 * 3 * 8
_FALLBACK_BYTES = 8 * 2**30  # when the platform tells nothing


def available_memory() -> int:
    """Bytes of memory available to a new allocation now (MemAvailable on Linux)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return _FALLBACK_BYTES


def estimate_run_bytes(
    case, elements_per_link: int, h: float, *, cut_loads: bool = True, energy: bool = True
) -> tuple[float, float, float]:
    """(total bytes, number of steps, number of output samples) of a fixed-step run.

    Floats, not ints: an absurd input (h = 1e-300) must give a number, not an overflow.
    """
    scen = case.scenario
    n = case.model.n_links
    ratio_h, ratio_out = scen.duration / h, scen.duration / scen.output_step  # may be inf
    n_steps = (math.ceil(ratio_h) if math.isfinite(ratio_h) else math.inf) + len(scen.breakpoints)
    n_out = (math.floor(ratio_out) if math.isfinite(ratio_out) else math.inf) + 1
    per_out = 2 * 8 * (8 * n + 1 + (1 if energy else 0))
    ncuts = n * (elements_per_link + 1)
    loads = min(float(n_out) * ncuts * 3 * 8, _LOADS_CAP_BYTES) if cut_loads else 0.0
    total = float(n_steps) * (_STEP_BYTES + _STEP_BYTES_PER_JOINT * n) + float(n_out) * per_out + loads
    return total, float(n_steps), float(n_out)


def _gib(x: float) -> str:
    return f"{x / 2**30:.3g} GiB"


def check_run_size(
    case,
    elements_per_link: int,
    h: float,
    *,
    cut_loads: bool = True,
    energy: bool = True,
    limit_bytes: float | None = None,
) -> float:
    """Refuse a run whose arrays would exceed ``limit_bytes`` (default: half the available memory).

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int, elements per link k (≥ 1)
    h : float, time step (s)
    cut_loads, energy : whether the run records the cut loads and the energy
    limit_bytes : float, optional

    Returns
    -------
    float
        The estimated bytes (see the module notes for the model).

    Raises
    ------
    InputError
        On ``h``, ``scenario.output_step`` or ``elements_per_link`` (whichever dominates) with
        the estimate and the knob to change.
    """
    k = _check_k(elements_per_link)
    h = step_size(h)
    total, n_steps, n_out = estimate_run_bytes(case, k, h, cut_loads=cut_loads, energy=energy)
    limit = available_memory() / 2 if limit_bytes is None else float(limit_bytes)
    if total <= limit:
        return total
    n = case.model.n_links
    step_part = n_steps * (_STEP_BYTES + _STEP_BYTES_PER_JOINT * n)
    dur = case.scenario.duration
    if step_part >= total / 2:
        raise InputError(
            "h",
            h,
            f"gives {n_steps:.3g} steps over {dur:g} s, about {_gib(total)} of "
            f"arrays (limit {_gib(limit)}): raise h or shorten scenario.duration",
        )
    raise InputError(
        "scenario.output_step",
        case.scenario.output_step,
        f"gives {n_out:.3g} output samples over {dur:g} s, about {_gib(total)} of arrays "
        f"(limit {_gib(limit)}): raise output_step or shorten scenario.duration",
    )
