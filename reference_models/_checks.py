"""Input checks the reference models share: the integrator's name, the names of its options and
the strain measure. Each raises :class:`dttmm.InputError` naming the field and its value."""

from __future__ import annotations

from dttmm.errors import InputError

#: the element strain measures of the global solvers (planar and spatial)
STRAINS = ("linear", "second-order")


def strain(value) -> str:
    """``value`` when it is one of :data:`STRAINS`."""
    if not isinstance(value, str) or value not in STRAINS:
        raise InputError("strain", value, f"unknown strain measure (one of: {', '.join(STRAINS)})")
    return value


def integrator(name, integrators) -> None:
    """InputError unless ``name`` is one of ``integrators``."""
    if name not in integrators:
        raise InputError("integrator", name, f"unknown integrator (one of: {', '.join(integrators)})")


def integrator_options(name, options: dict, allowed) -> None:
    """InputError naming the first key of ``options`` that is not one of the ``allowed`` options
    of integrator ``name`` ("unknown option for integrator …")."""
    for key in options:
        if key not in allowed:
            raise InputError(
                key,
                options[key],
                f"unknown option for integrator {name!r} (allowed: {', '.join(allowed) or 'none'})",
            )


def option_names(options: dict, known, owner: str) -> None:
    """InputError naming the first key of ``options`` that is not in ``known`` ("is not an option
    of ``owner``")."""
    for key in options:
        if key not in known:
            raise InputError(
                key, options[key], f"is not an option of {owner} (options: {', '.join(known) or 'none'})"
            )
