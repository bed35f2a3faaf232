"""Typed parameters of the studies: one frozen record per study.

A plan (:mod:`experiments.plan`) holds one record per study it runs, by study name; the study
modules (:mod:`experiments.studies`) read them by attribute. Every record checks its fields on
construction and raises :class:`dttmm.errors.InputError` naming the study, the field and the
value (``plan.studies.cost.ks = [0]: must be positive integers``). :func:`study_params` builds
the record of a study from a plain dict (the form tests and the command line write), refusing
an unknown study or parameter by name.

``methods`` (every record): only these methods, in this order (tests name them); None, the
default, runs every registered method that takes part (``experiments.methods.takes_part``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields

from dttmm.errors import InputError

__all__ = [
    "PARAMS",
    "ControlModes",
    "ControlParams",
    "ConvergenceHParams",
    "ConvergenceKParams",
    "CostParams",
    "EnergyReference",
    "PaperParams",
    "ProblemsParams",
    "SchemeParams",
    "StudyParams",
    "WorkPrecisionParams",
    "as_dicts",
    "study_params",
]

#: the closed-loop study's case file, relative to experiments/cases
CONTROL_CASE_FILE = "control/closed_loop_three_link.toml"
#: the clamped De Luca links whose frequencies the closed-loop study compares (benchmark problems)
MODE_SYSTEMS = ("benchmarks/deluca_link1_clamped.toml", "benchmarks/deluca_link2_clamped.toml")


def _ints(v) -> bool:
    """A sequence of positive integers (k values)."""
    return not isinstance(v, (str, Mapping)) and all(isinstance(x, int) and x >= 1 for x in v)


def _step(x) -> bool:
    """A positive finite step (s)."""
    return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) and x > 0


def _finite(v) -> bool:
    """A sequence of finite numbers."""
    return not isinstance(v, (str, Mapping)) and all(
        isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v
    )


def _steps(v) -> bool:
    return not isinstance(v, (str, Mapping)) and all(_step(x) for x in v)


def _names(v) -> bool:
    return not isinstance(v, (str, Mapping)) and all(isinstance(x, str) for x in v)


@dataclass(frozen=True, kw_only=True)
class StudyParams:
    """Fields every study has (see the module docstring)."""

    STUDY = ""  # the study's name, in messages

    methods: list | tuple | None = None

    def need(self, name: str, ok: bool, reason: str) -> None:
        """Raise InputError naming the field ``name`` and its value unless ``ok``."""
        if not ok:
            raise InputError(f"plan.studies.{self.STUDY}.{name}", getattr(self, name), reason)

    def __post_init__(self):
        self.need("methods", self.methods is None or _names(self.methods), "must be method names or None")
        self.check()

    def check(self) -> None:
        """The study's own field checks (each a :meth:`need`)."""


@dataclass(frozen=True, kw_only=True)
class ConvergenceKParams(StudyParams):
    """Error against k: every method at each k of ``ks`` and step ``h`` on each case."""

    STUDY = "convergence_k"
    cases: list | tuple = ()
    ks: list | tuple = ()
    h: float = 1e-3

    def check(self):
        self.need("cases", _names(self.cases), "must be case names")
        self.need("ks", _ints(self.ks), "must be positive integers")
        self.need("h", _step(self.h), "must be a positive step (s)")


@dataclass(frozen=True, kw_only=True)
class ConvergenceHParams(StudyParams):
    """Error against h: every flexible method at each h of ``hs`` (an explicit one at
    ``explicit_hs``, default ``hs``) and k elements per link on each case."""

    STUDY = "convergence_h"
    cases: list | tuple = ()
    hs: list | tuple = ()
    k: int = 8
    explicit_hs: list | tuple | None = None

    def check(self):
        self.need("cases", _names(self.cases), "must be case names")
        self.need("hs", _steps(self.hs), "must be positive steps (s)")
        self.need("k", _ints([self.k]), "must be a positive integer")
        self.need(
            "explicit_hs", self.explicit_hs is None or _steps(self.explicit_hs), "must be positive steps (s)"
        )


@dataclass(frozen=True, kw_only=True)
class WorkPrecisionParams(StudyParams):
    """Cost against error: each flexible method along the (k, h) ``path``, the rigid methods at
    the steps ``rigid_h``."""

    STUDY = "work_precision"
    cases: list | tuple = ()
    path: list | tuple = ()
    rigid_h: list | tuple = ()

    def check(self):
        self.need("cases", _names(self.cases), "must be case names")
        ok = all(len(kh) == 2 and _ints([kh[0]]) and _step(kh[1]) for kh in self.path)
        self.need("path", ok, "must be (k, h) pairs")
        self.need("rigid_h", _steps(self.rigid_h), "must be positive steps (s)")


@dataclass(frozen=True, kw_only=True)
class SchemeParams(StudyParams):
    """The paper's scheme: ``method`` in each sweep/iterations variant over ``ks`` at ``h`` and
    over ``hs`` at ``k``."""

    STUDY = "scheme"
    cases: list | tuple = ()
    variants: list | tuple = ()
    ks: list | tuple = ()
    h: float = 1e-3
    hs: list | tuple = ()
    k: int = 8
    method: str = "dttmm"

    def check(self):
        self.need("cases", _names(self.cases), "must be case names")
        ok = all(isinstance(v, Mapping) and set(v) <= {"sweep", "iterations"} for v in self.variants)
        self.need("variants", ok, "must be dicts of sweep and iterations")
        self.need("ks", _ints(self.ks), "must be positive integers")
        self.need("h", _step(self.h), "must be a positive step (s)")
        self.need("hs", _steps(self.hs), "must be positive steps (s)")
        self.need("k", _ints([self.k]), "must be a positive integer")
        self.need("method", isinstance(self.method, str), "must be a method name")


@dataclass(frozen=True, kw_only=True)
class EnergyReference:
    """The run the paper study takes energy errors against (its ``method``, default the first
    method taking part that records energy)."""

    k: int
    h: float
    method: str | None = None

    def __post_init__(self):
        for name, ok, reason in (
            ("k", _ints([self.k]), "must be a positive integer"),
            ("h", _step(self.h), "must be a positive step (s)"),
            ("method", self.method is None or isinstance(self.method, str), "must be a method name"),
        ):
            if not ok:
                raise InputError(f"plan.studies.paper.energy_reference.{name}", getattr(self, name), reason)


@dataclass(frozen=True, kw_only=True)
class PaperParams(StudyParams):
    """Time histories: every method at k and h (an explicit method without a ``max_step`` at
    ``explicit_h``, default h) on each case, and the ``energy_reference`` run (None: none)."""

    STUDY = "paper"
    cases: list | tuple = ()
    k: int = 8
    h: float = 1e-3
    explicit_h: float | None = None
    energy_reference: EnergyReference | None = None

    def __post_init__(self):
        e = self.energy_reference
        if isinstance(e, Mapping):
            object.__setattr__(self, "energy_reference", _build(EnergyReference, e, "paper.energy_reference"))
        super().__post_init__()

    def check(self):
        self.need("cases", _names(self.cases), "must be case names")
        self.need("k", _ints([self.k]), "must be a positive integer")
        self.need("h", _step(self.h), "must be a positive step (s)")
        self.need(
            "explicit_h", self.explicit_h is None or _step(self.explicit_h), "must be a positive step (s)"
        )
        ok = self.energy_reference is None or isinstance(self.energy_reference, EnergyReference)
        self.need("energy_reference", ok, "must be {k, h[, method]} or None")


@dataclass(frozen=True, kw_only=True)
class CostParams(StudyParams):
    """CPU time against k: every flexible method at each k of ``ks`` and step ``h`` on ``case``
    (a planar arm), and at each k of ``spatial_ks`` and the same h on ``spatial_case`` (a
    spatial arm; '' and no ``spatial_ks``: none)."""

    STUDY = "cost"
    case: str = "three_link"
    ks: list | tuple = ()
    h: float = 1e-3
    spatial_case: str = ""
    spatial_ks: list | tuple = ()

    def check(self):
        self.need("case", isinstance(self.case, str), "must be a case name")
        self.need("ks", _ints(self.ks), "must be positive integers")
        self.need("h", _step(self.h), "must be a positive step (s)")
        self.need("spatial_case", isinstance(self.spatial_case, str), "must be a case name or '' (none)")
        self.need(
            "spatial_case", not self.spatial_case or self.spatial_case != self.case, "must differ from case"
        )
        self.need("spatial_ks", _ints(self.spatial_ks), "must be positive integers")
        if self.spatial_case:
            self.need("spatial_ks", len(self.spatial_ks) > 0, "must name the k values of spatial_case")
        else:
            self.need("spatial_ks", len(self.spatial_ks) == 0, "needs a spatial_case")

    def case_ks(self) -> list[tuple[str, tuple]]:
        """(case, its ks) of every case the study times: ``case`` first, then ``spatial_case``."""
        out = [(self.case, tuple(self.ks))]
        return out + ([(self.spatial_case, tuple(self.spatial_ks))] if self.spatial_case else [])


@dataclass(frozen=True, kw_only=True)
class ProblemsParams(StudyParams):
    """The benchmark problems (study ``benchmarks``): every method that takes part at each k of
    ``ks`` (``ks_by_problem``: problem name -> its own ks) on each problem of ``problems``
    (case-file names; None: all), shortened to ``durations`` (problem name -> s)."""

    STUDY = "benchmarks"
    ks: list | tuple = ()
    problems: list | tuple | None = None
    durations: dict = field(default_factory=dict)
    ks_by_problem: dict = field(default_factory=dict)

    def check(self):
        self.need("ks", _ints(self.ks), "must be positive integers")
        self.need("problems", self.problems is None or _names(self.problems), "must be problem names or None")
        ok = isinstance(self.durations, Mapping) and all(_step(T) for T in self.durations.values())
        self.need("durations", ok, "must map problem names to positive durations (s)")
        ok = isinstance(self.ks_by_problem, Mapping) and all(_ints(v) for v in self.ks_by_problem.values())
        self.need("ks_by_problem", ok, "must map problem names to positive integers")


@dataclass(frozen=True, kw_only=True)
class ControlModes:
    """Natural frequencies of the closed-loop study: DT-TMM at ``k``, Exudyn at ``exudyn_k``,
    ``n`` modes per system, the case files ``systems`` (relative to experiments/cases)."""

    k: int = 8
    exudyn_k: int = 32
    n: int = 4
    systems: list | tuple = MODE_SYSTEMS

    def __post_init__(self):
        for name, ok, reason in (
            ("k", _ints([self.k]), "must be a positive integer"),
            ("exudyn_k", _ints([self.exudyn_k]), "must be a positive integer"),
            ("n", _ints([self.n]), "must be a positive integer"),
            ("systems", _names(self.systems), "must be case files"),
        ):
            if not ok:
                raise InputError(f"plan.studies.control.modes.{name}", getattr(self, name), reason)


@dataclass(frozen=True, kw_only=True)
class ControlParams(StudyParams):
    """The closed-loop study (see :mod:`experiments.studies.control` for each field)."""

    STUDY = "control"
    case_file: str = CONTROL_CASE_FILE
    duration: float | None = None
    k: int = 8
    h: float = 1e-3
    rigid_h: float | None = None
    reference: list | tuple = ()
    gains: list | tuple = ()
    window: float = 1.0
    modes: ControlModes = field(default_factory=ControlModes)
    runs: list | tuple | None = None
    rigid_runs: list | tuple | None = None
    gain_runs: list | tuple | None = None

    def __post_init__(self):
        if isinstance(self.modes, Mapping):
            object.__setattr__(self, "modes", _build(ControlModes, self.modes, "control.modes"))
        super().__post_init__()

    def check(self):
        self.need("case_file", isinstance(self.case_file, str), "must be a case file")
        self.need(
            "duration",
            self.duration is None or _step(self.duration),
            "must be a positive duration (s) or None",
        )
        self.need("k", _ints([self.k]), "must be a positive integer")
        self.need("h", _step(self.h), "must be a positive step (s)")
        self.need("rigid_h", self.rigid_h is None or _step(self.rigid_h), "must be a positive step (s)")
        ref = self.reference
        ok = (len(ref) == 2 and _ints([ref[0]]) and _step(ref[1])) or all(
            len(r) == 3 and isinstance(r[0], str) and _ints([r[1]]) and _step(r[2]) for r in ref
        )
        self.need("reference", ok, "must be (k, h) or (method, k, h) candidates")
        self.need("gains", _finite(self.gains), "must be finite numbers")
        self.need("window", _step(self.window), "must be a positive duration (s)")
        self.need("modes", isinstance(self.modes, ControlModes), "must be {k, exudyn_k, n, systems}")


#: study name -> its parameter record
PARAMS = {
    c.STUDY: c
    for c in (
        ConvergenceKParams,
        ConvergenceHParams,
        WorkPrecisionParams,
        SchemeParams,
        PaperParams,
        CostParams,
        ProblemsParams,
        ControlParams,
    )
}


def _build(cls, values: Mapping, where: str):
    known = [f.name for f in fields(cls)]
    for name in values:
        if name not in known:
            raise InputError(f"plan.studies.{where}", name, f"no such parameter; known: {', '.join(known)}")
    return cls(**values)


def study_params(study: str, value):
    """The parameter record of ``study`` from ``value`` (its record, returned as it is, or a
    dict of its fields). Raises InputError for an unknown study, parameter or bad value."""
    cls = PARAMS.get(study)
    if cls is None:
        raise InputError("plan.studies", study, f"no such study; known: {', '.join(PARAMS)}")
    if isinstance(value, cls):
        return value
    if not isinstance(value, Mapping):
        raise InputError(f"plan.studies.{study}", value, f"must be a {cls.__name__} or a dict of its fields")
    return _build(cls, value, study)


def as_dicts(studies: Mapping) -> dict:
    """study name -> its parameters as a plain dict (for JSON)."""
    return {name: asdict(study_params(name, p)) for name, p in studies.items()}
