"""Plumbing shared by the solvers of the suite: option validation, the Newmark-family
coefficients and predictor, cubic Hermite sampling, failures with a partial result, and
provenance. Public names, so that other solvers can use the same definitions."""

from __future__ import annotations

import platform

import numpy as np
import scipy

from . import _validate
from ._version import __version__
from .errors import InputError, SimulationError
from .integrators import NewmarkFamily, newmark_family
from .kernel.loop import predict
from .kernel.recorder import hermite_weights

__all__ = [
    "NewmarkFamily",
    "choice",
    "elements_per_link",
    "hermite_sample",
    "iterations_setting",
    "newmark_family",
    "open_fraction",
    "positive_integer",
    "positive_number",
    "predict",
    "simulation_failure",
    "versions",
]


def positive_integer(field: str, value, minimum: int = 1) -> int:
    """``value`` as an int ≥ ``minimum`` (bools refused), else InputError naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(field, value, f"must be an integer ≥ {minimum}")
    return int(value)


def elements_per_link(value) -> int:
    """The mesh size k (integer ≥ 1); the same rule as the case schema's validators."""
    return _validate.elements_per_link(value)


def positive_number(field: str, value) -> float:
    """A positive finite real number (bools and strings refused); the case schema's rule."""
    return _validate.positive(field, value)


def open_fraction(field: str, value) -> float:
    """A real number in (0, 1)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating)) or not 0 < value < 1:
        raise InputError(field, value, "must lie in (0, 1)")
    return float(value)


def choice(field: str, value, options) -> str:
    """``value`` if it is one of ``options``, else InputError listing them."""
    if value not in options:
        raise InputError(field, value, f"unknown (one of: {', '.join(options)})")
    return value


def iterations_setting(value):
    """None (to tolerance), "auto", or a fixed count m ≥ 0 (m + 1 sweeps per step)."""
    if value is None or value == "auto":
        return value
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0:
        raise InputError("iterations", value, 'must be None, "auto" or an integer ≥ 0')
    return int(value)


def hermite_sample(t, t0: float, t1: float, y0, yd0, y1, yd1):
    """Cubic Hermite value and derivative at times ``t`` (scalar or (m,)) in [t0, t1] from the
    values and derivatives at both ends (arrays (...)). Returns (y, ẏ), shapes (m, ...) or
    (...) for a scalar t — the interpolation the DT-TMM recorder uses."""
    h = t1 - t0
    ts = np.atleast_1d(np.asarray(t, float))
    y = np.empty((ts.size, *np.shape(y0)))
    yd = np.empty_like(y)
    for j, tj in enumerate(ts):
        w0, w1, w2, w3, v0, v1, v2, v3 = hermite_weights((tj - t0) / h, h)
        y[j] = w0 * np.asarray(y0) + w1 * np.asarray(yd0) + w2 * np.asarray(y1) + w3 * np.asarray(yd1)
        yd[j] = v0 * np.asarray(y0) + v1 * np.asarray(yd0) + v2 * np.asarray(y1) + v3 * np.asarray(yd1)
    return (y[0], yd[0]) if np.ndim(t) == 0 else (y, yd)


def simulation_failure(
    reason: str, *, t: float, step: int, component: str, meta: dict, partial, message: str | None = None
) -> SimulationError:
    """The SimulationError of a run that stopped: ``meta`` gets success False and
    ``failure = reason``; ``partial(meta)`` builds the Result of what was computed. Returns the
    error (the caller raises it)."""
    meta.update(success=False, failure=reason, status="failed")
    return SimulationError(
        message or reason, t=float(t), step=int(step), component=component, partial=partial(meta)
    )


def versions() -> dict:
    """Versions of the interpreter and numeric packages, for Result.meta."""
    out = {
        "dttmm": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
    }
    try:
        import numba

        out["numba"] = numba.__version__
    except ImportError:  # pragma: no cover - numba is optional
        pass
    return out
