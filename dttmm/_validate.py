"""Validators of single values, built on the value types of :mod:`dttmm.schema`.

The constructors validate whole field sets with :func:`dttmm.schema.check_fields`; these are for
single values outside a model (solver settings) and share the same rules.
"""

from __future__ import annotations

import numbers

from pydantic import TypeAdapter, ValidationError

from .errors import InputError
from .schema import Finite, NonNegative, Positive, _plain, input_error

__all__ = ["elements_per_link", "finite", "non_negative", "positive", "step_size"]

_ADAPTERS = {
    name: TypeAdapter(tp)
    for name, tp in (("finite", Finite), ("positive", Positive), ("non_negative", NonNegative))
}


def _check(kind: str, field: str, value) -> float:
    try:
        return float(_ADAPTERS[kind].validate_python(_plain(value)))
    except ValidationError as exc:
        err = input_error(exc, None)
        raise InputError(field, value, err.reason) from None


def finite(field: str, value) -> float:
    """A finite real number (an int is fine; a bool or a string is refused)."""
    return _check("finite", field, value)


def positive(field: str, value) -> float:
    """A finite number > 0."""
    return _check("positive", field, value)


def non_negative(field: str, value) -> float:
    """A finite number >= 0."""
    return _check("non_negative", field, value)


def step_size(h) -> float:
    """Validate a time step ``h`` (s): a finite number > 0, not a bool or a string.

    For ``simulate(h=...)`` and every fixed-step method; raises InputError on field ``h``.
    """
    return positive("h", h)


def elements_per_link(k) -> int:
    """Validate the number of elements per link: an integer >= 1 (not a bool, not a float)."""
    if isinstance(k, bool) or not isinstance(k, numbers.Integral) or k < 1:
        raise InputError("elements_per_link", k, "must be an integer >= 1")
    return int(k)
