"""Small validators shared by the model and scenario dataclasses."""
from __future__ import annotations

import math

from .errors import InputError


def finite(field: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise InputError(field, value, "must be a real number") from None
    if not math.isfinite(x):
        raise InputError(field, value, "must be finite")
    return x


def positive(field: str, value) -> float:
    x = finite(field, value)
    if x <= 0.0:
        raise InputError(field, value, "must be positive")
    return x


def non_negative(field: str, value) -> float:
    x = finite(field, value)
    if x < 0.0:
        raise InputError(field, value, "must be non-negative")
    return x


def finite_vector(field: str, value, n: int | None = None) -> tuple[float, ...]:
    try:
        items = tuple(value)
    except TypeError:
        raise InputError(field, value, "must be a list of numbers") from None
    if n is not None and len(items) != n:
        raise InputError(field, value, f"must have {n} entries")
    return tuple(finite(f"{field}[{i}]", x) for i, x in enumerate(items))
