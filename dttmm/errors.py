"""Errors raised by dttmm: bad input and failed simulations."""

from __future__ import annotations

from typing import Any

__all__ = ["InputError", "SimulationError"]


class InputError(ValueError):
    """A model, scenario or solver setting was refused.

    The message names the field and the offending value, e.g.
    ``model.links[0].EI = -1.0: must be positive and finite``.
    """

    def __init__(self, field: str, value: Any, reason: str):
        self.field = field
        self.value = value
        self.reason = reason
        super().__init__(f"{field} = {value!r}: {reason}")


class SimulationError(RuntimeError):
    """A simulation failed (NaN/inf, runaway, solver breakdown).

    Attributes
    ----------
    t : float
        Time (s) of the step that failed.
    step : int
        Index of the failed step (0-based).
    component : str
        Which quantity failed (e.g. ``"link 2, element 5, v"``).
    partial : dttmm.Result or None
        What was computed up to the last good output sample.
    """

    def __init__(self, message: str, *, t: float, step: int, component: str, partial=None):
        self.t = t
        self.step = step
        self.component = component
        self.partial = partial
        super().__init__(f"{message} at t = {t:.6g} s (step {step}), component: {component}")
