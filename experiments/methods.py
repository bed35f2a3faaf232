"""The methods the studies compare, by name, imported lazily.

Every method is called the same way, ``run(method, case, k, h, **options) -> dttmm.Result``;
a method whose engine does not import, or whose ``simulate`` raises ``NotImplementedError``,
is *unavailable*: :func:`available` reports it with the reason instead of crashing.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Callable

__all__ = ["Method", "MethodUnavailable", "METHODS", "register", "resolve", "run", "available", "names"]


class MethodUnavailable(RuntimeError):
    """The method cannot run here (engine missing or not implemented); the message says why."""


@dataclass(frozen=True)
class Method:
    """A registered method: where its ``simulate`` lives and the options it always gets.

    ``uses_k`` is False for the rigid baseline (it gets ``elements_per_link=None``).
    """

    name: str
    module: str
    options: tuple[tuple[str, object], ...] = ()
    uses_k: bool = True
    label: str = ""


METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method("dttmm", "dttmm", (("integrator", "newmark"),), label="DT-TMM (Newmark)"),
        Method("dttmm-rk4", "dttmm", (("integrator", "rk4"),), label="DT-TMM (RK4)"),
    Method("dttmm-2nd", "dttmm", (("strain", "second-order"), ("integrator", "generalized-alpha"), ("rho_inf", 0.8)),
           label="DT-TMM (2nd-order strain, gen-α 0.8)"),
        Method(
            "global",
            "reference_models.global_newmark",
            (("integrator", "newmark"),),
            label="global equations (Newmark)",
        ),
        Method(
            "global-2nd",
            "reference_models.global_newmark",
            (("strain", "second-order"), ("integrator", "generalized-alpha"), ("rho_inf", 0.8)),
            label="global equations (2nd-order strain, gen-α 0.8)",
        ),
        Method("exudyn-ancf", "reference_models.exudyn_ancf", label="Exudyn ANCF"),
        # physical rotary inertia: measured to run on the suite's cases (see docs/peers.md)
        Method("exudyn-beam", "reference_models.exudyn_beam", (("cross_section_inertia", "physical"),),
               label="Exudyn GE beam"),
        Method(
            "pinocchio-rigid",
            "reference_models.pinocchio_rigid",
            (("integrator", "rk4"),),
            uses_k=False,
            label="Pinocchio rigid",
        ),
    )
}

# Methods registered at run time (user or test methods): name -> (simulate, uses_k).
_EXTRA: dict[str, tuple[Callable, bool]] = {}


def register(name: str, simulate: Callable, *, uses_k: bool = True) -> None:
    """Add a method ``simulate(case, *, elements_per_link, h, **options) -> Result`` under ``name``."""
    _EXTRA[name] = (simulate, uses_k)


def names() -> list[str]:
    """Every registered method name (built-in first)."""
    return list(METHODS) + [n for n in _EXTRA if n not in METHODS]


def uses_k(name: str) -> bool:
    """Whether the method discretises the links (False: rigid baseline, k is ignored)."""
    if name in _EXTRA:
        return _EXTRA[name][1]
    return METHODS[name].uses_k if name in METHODS else True


def label(name: str) -> str:
    """Human-readable name for legends."""
    m = METHODS.get(name)
    return m.label if m and m.label else name


def resolve(name: str) -> Callable:
    """The method as ``f(case, k, h, **options) -> Result``; raises MethodUnavailable."""
    if name in _EXTRA:
        sim, k_used = _EXTRA[name]
        return _Bound(sim, (), k_used)
    if name not in METHODS:
        raise MethodUnavailable(f"unknown method {name!r} (known: {', '.join(names())})")
    m = METHODS[name]
    try:
        module = importlib.import_module(m.module)
    except Exception as exc:  # any import failure makes the method unavailable, with the reason
        raise MethodUnavailable(f"cannot import {m.module}: {type(exc).__name__}: {exc}") from None
    sim = getattr(module, "simulate", None)
    if sim is None:
        raise MethodUnavailable(f"{m.module} has no simulate()")
    return _Bound(sim, m.options, m.uses_k)


@dataclass(frozen=True)
class _Bound:
    """A resolved method; picklable when ``simulate`` is a module-level function."""

    simulate: Callable
    options: tuple
    uses_k: bool

    def __call__(self, case, k, h, **options):
        opts = dict(self.options)
        opts.update(options)
        kk = int(k) if self.uses_k else None
        try:
            return self.simulate(case, elements_per_link=kk, h=float(h), **opts)
        except NotImplementedError as exc:
            raise MethodUnavailable(f"not implemented yet{': ' + str(exc) if str(exc) else ''}") from None


def run(method: str, case, k: int, h: float, **options):
    """Simulate ``case`` with ``method`` at k elements per link and step h (s); returns a Result."""
    return resolve(method)(case, k, h, **options)


def _probe_case():
    """A one-link arm for a few steps: enough to see whether a method runs at all."""
    from dttmm import Constant, Drive, Link, Manipulator, Scenario, Section
    from dttmm.case import Case

    link = Link(Section(1.0, 2.0, 0.3, 7e6), hub=None, payload=None)
    return Case(Manipulator((link,)), Scenario(0.004, 0.002, (Drive("torque", Constant(0.1)),)), "probe")


def available(methods=None, *, probe: bool = True) -> dict[str, str | None]:
    """Which methods run here: name -> None when available, else the reason.

    With ``probe`` each importable method is run for two steps of a one-link arm, so one that
    still raises ``NotImplementedError`` (or fails outright) is reported with the reason.
    """
    out = {}
    case = _probe_case() if probe else None
    for name in names() if methods is None else methods:
        try:
            f = resolve(name)
            if probe:
                f(case, 1, 0.002)
            out[name] = None
        except MethodUnavailable as exc:
            out[name] = str(exc)
        except Exception as exc:  # a crash on the probe is a reason too
            out[name] = f"probe run failed: {type(exc).__name__}: {exc}"
    return out
