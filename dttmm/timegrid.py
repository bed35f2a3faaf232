"""The step schedule shared by every fixed-step integrator of the suite.

Steps of size h from t = 0; a drive breakpoint inside a step splits it so that a step ends
exactly at the jump (the integrator then restarts with the right-hand limit); the last step
ends exactly at the duration.
"""

from __future__ import annotations

import numpy as np

from ._validate import positive
from .errors import InputError

__all__ = ["step_schedule"]


def step_schedule(duration: float, h: float, breakpoints=()) -> tuple[np.ndarray, np.ndarray]:
    """Return (t_end, restart): step end times (n_steps,) and a flag per step end that marks a
    drive breakpoint (restart the integrator after this step)."""
    h = positive("h", h)
    if h > duration * (1 + 1e-12):
        raise InputError("h", h, f"must not exceed the duration {duration}")
    n = int(np.ceil(duration / h - 1e-9))
    grid = np.arange(1, n + 1) * h
    grid[-1] = duration
    bps = np.array([b for b in breakpoints if 0.0 < b < duration], float)
    tol = 1e-9 * h
    if bps.size:
        new = [b for b in bps if np.min(np.abs(grid - b)) > tol]
        grid = np.sort(np.concatenate([grid, new]))
    restart = np.zeros(grid.size, bool)
    for b in bps:
        i = int(np.argmin(np.abs(grid - b)))
        grid[i] = b
        restart[i] = True
    return grid, restart
