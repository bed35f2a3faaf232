"""Fitted exponents on log-log data (observed orders of convergence, cost exponents)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["slope", "decreasing_prefix"]


def slope(x, y) -> tuple[float, int]:
    """Least-squares slope of log y against log x over the finite, positive points.

    Returns (slope, number of points used); NaN with fewer than two points.
    """
    x, y = np.asarray(x, float), np.asarray(y, float)
    ok = np.isfinite(x) & np.isfinite(y) & (x > 0) & (y > 0)
    if ok.sum() < 2 or np.unique(x[ok]).size < 2:
        return math.nan, int(ok.sum())
    p = np.polyfit(np.log(x[ok]), np.log(y[ok]), 1)
    return float(p[0]), int(ok.sum())


def decreasing_prefix(x, y) -> np.ndarray:
    """Mask of the points (sorted by refinement order as given) up to the smallest error.

    Past the minimum an error has reached its floor (reference accuracy, the other
    discretisation parameter, round-off), so an order fitted there would mean nothing.
    """
    y = np.asarray(y, float)
    fin = np.isfinite(y)
    mask = np.zeros(y.size, bool)
    if not fin.any():
        return mask
    stop = int(np.nanargmin(np.where(fin, y, np.nan)))
    mask[: stop + 1] = fin[: stop + 1]
    return mask
