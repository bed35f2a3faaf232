"""Memory guard: refuse a run whose arrays would not fit before allocating them.

A fixed-step run allocates per-step arrays (the step schedule and the drive tables, about
``40 + 256·n_joints`` bytes a step, RK4 included) and per-output-sample arrays (joint angles,
rates, torques, link roots and tips, energy, then copied into the result: about
``2·8·(8·n_joints + 2)`` bytes a sample), plus the cut loads, which the recorder thins to at most
2·10⁶ cut samples (≤ 48 MB). A spatial run (:mod:`dttmm.spatial`) keeps per step its drive and
load tables (three instants of ``1 + 15`` columns and the closed-loop tables: about
``40 + 456·n_links`` bytes a step) and per output sample its coordinates and rates (n_dof each)
with the outputs (positions, frames, deflections, twist: about ``8·(2·n_dof + 28·n_links + 2)``
bytes), and unthinned cut loads (6 per cut). Link shapes (``shape_points`` p) add their
points (and, spatial, the element frames they come from) per sample.
:func:`check_run_size` adds these up and refuses a run above half of the memory available now
(read from ``/proc/meminfo`` or ``os.sysconf``).
"""

from __future__ import annotations

import math
import os

from ._validate import elements_per_link as _check_k
from ._validate import step_size
from .errors import InputError

__all__ = ["available_memory", "check_run_size", "estimate_run_bytes"]

_STEP_BYTES, _STEP_BYTES_PER_JOINT = 40, 256
_SPATIAL_STEP_BYTES_PER_LINK = 456  # 3 instants × (1 + 15) columns × 8 B + closed-loop tables
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


def _spatial(case) -> bool:
    return hasattr(case.model, "unlocked")  # a dttmm.spatial.SpatialManipulator


def _step_bytes(case) -> float:
    n = case.model.n_links
    per_link = _SPATIAL_STEP_BYTES_PER_LINK if _spatial(case) else _STEP_BYTES_PER_JOINT
    return float(_STEP_BYTES + per_link * n)


def estimate_run_bytes(
    case,
    elements_per_link: int,
    h: float,
    *,
    cut_loads: bool = True,
    energy: bool = True,
    shape_points: int = 0,
) -> tuple[float, float, float]:
    """(total bytes, number of steps, number of output samples) of a fixed-step run of a planar
    or a spatial case (see the module notes).

    Floats, not ints: an absurd input (h = 1e-300) must give a number, not an overflow.
    """
    scen = case.scenario
    n = case.model.n_links
    k = elements_per_link
    ratio_h, ratio_out = scen.duration / h, scen.duration / scen.output_step  # may be inf
    n_steps = (math.ceil(ratio_h) if math.isfinite(ratio_h) else math.inf) + len(scen.breakpoints)
    n_out = (math.floor(ratio_out) if math.isfinite(ratio_out) else math.inf) + 1
    ncuts = n * (k + 1)
    if _spatial(case):
        n_dof = n + 6 * n * k
        per_out = 8 * (2 * n_dof + 28 * n + 1 + (1 if energy else 0))
        per_out += 8 * 6 * ncuts if cut_loads else 0
        per_out += 8 * (3 * n * shape_points + 18 * n * k) if shape_points else 0
        loads = 0.0
    else:
        per_out = 2 * 8 * (8 * n + 1 + (1 if energy else 0))
        per_out += 8 * (2 * n * shape_points + 3 * n * (k + 1)) if shape_points else 0
        loads = min(float(n_out) * ncuts * 3 * 8, _LOADS_CAP_BYTES) if cut_loads else 0.0
    total = float(n_steps) * _step_bytes(case) + float(n_out) * per_out + loads
    return total, float(n_steps), float(n_out)


def _gib(x: float) -> str:
    return f"{x / 2**30:.3g} GiB"


def check_run_size(
    case, elements_per_link: int, h: float, *, limit_bytes: float | None = None, **recorded
) -> float:
    """Refuse a run whose arrays would exceed ``limit_bytes`` (default: half the available memory).

    Parameters
    ----------
    case : dttmm.Case or dttmm.spatial.SpatialCase
    elements_per_link : int, elements per link k (≥ 1)
    h : float, time step (s)
    limit_bytes : float, optional
    recorded : what the run records, as in :func:`estimate_run_bytes`: ``cut_loads``,
        ``energy`` (whether the cut loads and the energy; default True) and ``shape_points``
        (link shape points per link; default 0: none)

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
    total, n_steps, n_out = estimate_run_bytes(case, k, h, **recorded)
    limit = available_memory() / 2 if limit_bytes is None else float(limit_bytes)
    if total <= limit:
        return total
    step_part = n_steps * _step_bytes(case)
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
