"""Plumbing shared by the solvers of the suite: option validation (the one check of the common
call's ``elements_per_link`` and ``h``, :func:`discretisation`, used by every method), the
Newmark-family coefficients, cubic Hermite output sampling of the uncompiled solvers
(:func:`hermite_sample`), failures with a partial result, and provenance. Public names, so
that other solvers can use the same definitions."""

from __future__ import annotations

import platform

import numpy as np
import scipy
from scipy.interpolate import CubicHermiteSpline

from . import _validate
from ._version import __version__
from .case import Case
from .errors import InputError, SimulationError
from .integrators import NewmarkFamily, newmark_family

__all__ = [
    "NewmarkFamily",
    "check_case",
    "choice",
    "discretisation",
    "elements_per_link",
    "hermite_sample",
    "iterations_setting",
    "newmark_family",
    "open_fraction",
    "positive_integer",
    "positive_number",
    "simulation_failure",
    "step_size",
    "versions",
]


def positive_integer(field: str, value, minimum: int = 1) -> int:
    """``value`` as an int ≥ ``minimum`` (bools refused), else InputError naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise InputError(field, value, f"must be an integer ≥ {minimum}")
    return int(value)


def elements_per_link(value) -> int:
    """The mesh size k: an integer ≥ 1 (a bool, a float such as 4.0 or a string is refused)."""
    return _validate.elements_per_link(value)


def step_size(value, duration: float | None = None) -> float:
    """The step h (s): a positive finite real number (a bool or a string is refused), at most
    ``duration`` when given."""
    h = _validate.step_size(value)
    if duration is not None and h > duration * (1 + 1e-12):
        raise InputError("h", value, f"must not exceed the duration {duration}")
    return h


def check_case(value) -> Case:
    """``value`` if it is a :class:`dttmm.Case`, else InputError."""
    if not isinstance(value, Case):
        raise InputError("case", value, "must be a dttmm.Case")
    return value


def discretisation(case: Case, k, h, *, uses_k: bool = True) -> tuple[int | None, float]:
    """The common call's checks, the same in every method: ``case`` a Case, k =
    ``elements_per_link`` (:func:`elements_per_link`; with ``uses_k`` False, None or a valid k is
    accepted and None returned) and h (:func:`step_size`, at most the case's duration).
    Returns (k, h)."""
    check_case(case)
    if uses_k or k is not None:
        k = elements_per_link(k)
    return (k if uses_k else None), step_size(h, case.scenario.duration)


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


def hermite_sample(t, nodes, y, dy, dy_end=None, *, snap: float = 0.0, derivative: bool = False):
    """Cubic Hermite interpolation through step nodes (scipy's ``CubicHermiteSpline``): the
    output sampler of the solvers that are not compiled (the compiled loops use
    :func:`dttmm.kernel.recorder.hermite_weights`).

    t (m,) times (s); nodes (N,) strictly increasing times; y, dy (N, ...) values and their
    time derivatives at the nodes. ``dy_end`` (N, ...), optional: the derivative at the end of
    the interval that ends at each node where it differs from the one at the start of the next
    (a restart at a drive jump); the spline is cut there. A time within ``snap`` of a node gets
    the node's value exactly. Returns y(t) (m, ...), and ẏ(t) with ``derivative``."""
    t = np.atleast_1d(np.asarray(t, float))
    nodes = np.asarray(nodes, float)
    y, dy = np.asarray(y, float), np.asarray(dy, float)
    out = np.empty((t.size, *y.shape[1:]))
    dout = np.empty_like(out)
    cuts = (
        []
        if dy_end is None
        else [j for j in range(1, nodes.size - 1) if not np.array_equal(dy_end[j], dy[j])]
    )
    bounds = [0, *cuts, nodes.size - 1]
    piece = np.clip(np.searchsorted(nodes, t, side="right") - 1, 0, nodes.size - 2)
    for a, b in zip(bounds[:-1], bounds[1:]):
        sel = (piece >= a) & (piece < b)
        if not sel.any() or not out[0].size:
            continue
        d = dy[a : b + 1].copy()
        if dy_end is not None:
            d[-1] = dy_end[b]
        spline = CubicHermiteSpline(nodes[a : b + 1], y[a : b + 1], d, axis=0)
        out[sel] = spline(t[sel])
        if derivative:
            dout[sel] = spline(t[sel], 1)
    if snap > 0.0:
        j = np.clip(np.searchsorted(nodes, t), 0, nodes.size - 1)
        for jj in (j, np.maximum(j - 1, 0)):
            hit = np.abs(nodes[jj] - t) <= snap
            out[hit] = y[jj[hit]]
            if derivative:
                dout[hit] = (dy if dy_end is None else dy_end)[jj[hit]]
    return (out, dout) if derivative else out


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
