"""The methods the studies compare: one registry for how each runs and how it is shown.

Every method is called the same way, ``run(method, case, k, h, **options) -> dttmm.Result``;
a method whose engine does not import, or whose ``simulate`` raises ``NotImplementedError``,
is *unavailable*: :func:`available` reports it with the reason instead of crashing.

Each entry also carries its legend label and plot style (colour, marker, line style, marker
size); figures, tables and sentences of the report take them from here (:func:`label`,
:func:`style`). To add a method, append one ``Method(...)`` line to ``_BUILTIN``, e.g.
``Method("mujoco-chain", "reference_models.mujoco_chain", label="MuJoCo chain", style=Style("C5", "X"))``.
Names that are shown but not run (the reference curve, benchmark variants) live in ``_SHOWN``.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = [
    "METHODS",
    "Method",
    "MethodUnavailable",
    "Style",
    "available",
    "label",
    "names",
    "register",
    "resolve",
    "run",
    "style",
    "uses_k",
]


class MethodUnavailable(RuntimeError):
    """The method cannot run here (engine missing or not implemented); the message says why."""


@dataclass(frozen=True)
class Style:
    """How a method is drawn: matplotlib colour, marker, line style and marker size (points).

    ``hollow`` draws the marker unfilled, so a curve lying exactly under it stays visible.
    """

    color: str = "C7"
    marker: str = "o"
    linestyle: str = "-"
    size: float = 5.0
    hollow: bool = False


@dataclass(frozen=True)
class Method:
    """A registered method: where its ``simulate`` lives, the options it always gets, and how
    it is shown (``label``, ``style``). ``uses_k`` is False for the rigid baseline (it gets
    ``elements_per_link=None``); ``module`` None marks a name that is shown but never run."""

    name: str
    module: str | None
    options: tuple[tuple[str, object], ...] = ()
    uses_k: bool = True
    label: str = ""
    style: Style = field(default_factory=Style)


# DT-TMM and the global solver often agree to round-off: their markers differ in shape and size
# (DT-TMM large and hollow) so both stay visible.
_BUILTIN = (
    Method(
        "dttmm",
        "dttmm",
        (("integrator", "newmark"),),
        label="DT-TMM (Newmark)",
        style=Style("C0", "o", "-", 7, hollow=True),
    ),
    Method(
        "dttmm-rk4", "dttmm", (("integrator", "rk4"),), label="DT-TMM (RK4)", style=Style("C4", "v", "-", 5)
    ),
    Method(
        "dttmm-2nd",
        "dttmm",
        (("strain", "second-order"), ("integrator", "generalized-alpha"), ("rho_inf", 0.8)),
        label="DT-TMM (2nd-order strain, gen-α 0.8)",
        style=Style("C9", "P", "-", 6),
    ),
    Method(
        "global",
        "reference_models.global_newmark",
        (("integrator", "newmark"), ("engine", "numba")),
        label="global equations (Newmark, compiled)",
        style=Style("C3", "^", "--", 4),
    ),
    Method(
        "exudyn-ancf", "reference_models.exudyn_ancf", label="Exudyn ANCF", style=Style("C1", "s", "-", 5)
    ),
    Method(
        "global-2nd",
        "reference_models.global_newmark",
        (
            ("strain", "second-order"),
            ("integrator", "generalized-alpha"),
            ("rho_inf", 0.8),
            ("engine", "numba"),
        ),
        label="global equations (2nd-order strain, gen-α 0.8, compiled)",
        style=Style("C6", "<", "--", 5),
    ),
    # physical rotary inertia: measured to run on the suite's cases (see docs/peers.md)
    Method(
        "exudyn-beam",
        "reference_models.exudyn_beam",
        (("cross_section_inertia", "physical"),),
        label="Exudyn GE beam",
        style=Style("C2", "D", "-", 5),
    ),
    Method(
        "mujoco-chain",
        "reference_models.mujoco_chain",
        (("integrator", "implicitfast"),),
        label="MuJoCo hinge chain",
        style=Style("C5", "X", "-.", 6),
    ),
    Method(
        "pinocchio-rigid",
        "reference_models.pinocchio_rigid",
        (("integrator", "rk4"),),
        uses_k=False,
        label="Pinocchio rigid",
        style=Style("k", "*", ":", 9),
    ),
)

# Shown in figures and text but not run by the studies.
_SHOWN = (
    Method("reference", None, label="reference", style=Style("0.3", "", "-", 0)),
    Method("dttmm-converged", None, label="DT-TMM (Newmark), converged", style=Style("C0", "o")),
    Method("dttmm-one-shot", None, label="DT-TMM (Newmark), one sweep per step", style=Style("C9", "v")),
)

METHODS: dict[str, Method] = {m.name: m for m in _BUILTIN}
_LOOKS: dict[str, Method] = {m.name: m for m in (*_BUILTIN, *_SHOWN)}
_FALLBACK_MARKERS = "osD^v<>ph*"

# Methods registered at run time (user or test methods): name -> (simulate, uses_k).
_EXTRA: dict[str, tuple[Callable, bool]] = {}


def register(
    name: str, simulate: Callable, *, uses_k: bool = True, label: str = "", style: Style | None = None
) -> None:
    """Add a method ``simulate(case, *, elements_per_link, h, **options) -> Result`` under ``name``."""
    _EXTRA[name] = (simulate, uses_k)
    if label or style:
        _LOOKS[name] = Method(name, None, label=label or name, style=style or Style())


def names() -> list[str]:
    """Every registered method name (built-in first)."""
    return list(METHODS) + [n for n in _EXTRA if n not in METHODS]


def uses_k(name: str) -> bool:
    """Whether the method discretises the links (False: rigid baseline, k is ignored)."""
    if name in _EXTRA:
        return _EXTRA[name][1]
    return METHODS[name].uses_k if name in METHODS else True


def label(name: str) -> str:
    """Human-readable name for legends, tables and sentences (the name itself if unknown)."""
    m = _LOOKS.get(name)
    return m.label if m and m.label else name


def source_of(name: str) -> tuple[tuple[str, ...], tuple]:
    """(modules whose code makes the method's runs, options it always gets), for cache keys;
    ((), ()) for an unknown name."""
    if name in _EXTRA:
        return (_EXTRA[name][0].__module__,), ()
    if name in METHODS:
        return (METHODS[name].module,), METHODS[name].options
    return (), ()


def style(name: str, index: int = 0) -> Style:
    """Plot style of ``name``; an unknown name gets a colour and marker picked by ``index``."""
    m = _LOOKS.get(name)
    if m is not None:
        return m.style
    return Style(f"C{index % 10}", _FALLBACK_MARKERS[index % len(_FALLBACK_MARKERS)])


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
    except Exception as exc:  # noqa: BLE001 - any import failure makes the method unavailable, with the reason
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
        if getattr(self.simulate, "__module__", "").startswith("dttmm."):
            # runs of a sweep report through the sweep's own progress bar, not one bar each
            opts.setdefault("progress", False)
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
        except Exception as exc:  # noqa: BLE001 - a crash on the probe is a reason too
            out[name] = f"probe run failed: {type(exc).__name__}: {exc}"
    return out
