"""The methods the studies compare: one record per method, every trait the harness reads.

A :class:`Method` holds where the method's ``simulate`` lives and the options it always gets,
the physics it solves (element and strain: like-for-like pairs are derived from it), its
discretisation parameter and what that means, what it supports (:data:`CAPABILITIES`), its
libraries (for the cache key), its role, the settings it is run with and their sources (the
report's "Peer configuration" section), the studies it sits out with the reason, and its label
and plot style. Studies, figures, tables and the cache read these records; no other module
keeps a list of method names (``tests/test_registry.py`` checks it).

Every method is called the same way, ``simulate(case, *, elements_per_link, h, **options) ->
dttmm.Result``; :func:`run` and :func:`resolve` do that with the record's fixed options. A
method whose engine does not import, or whose ``simulate`` raises ``NotImplementedError``, is
*unavailable*: :func:`available` reports it with the reason instead of crashing.

Methods from outside the package come in through :func:`register` (a record or a bare
function), :func:`load_spec` (``my_pkg.my_solver:simulate`` or ``path/to/solver.py:simulate``,
the ``--method`` option of ``dttmm report`` and ``dttmm validate``) or the entry-point group
``dttmm.methods`` (:func:`entry_points`); see docs/methods.md.
"""

from __future__ import annotations

import contextlib
import difflib
import functools
import importlib
import importlib.metadata
import importlib.util
import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

__all__ = [
    "CAPABILITIES",
    "METHODS",
    "ROLES",
    "Method",
    "MethodShippingError",
    "MethodUnavailable",
    "Physics",
    "Setting",
    "Style",
    "available",
    "base_of",
    "by_role",
    "entry_points",
    "get",
    "label",
    "load_spec",
    "names",
    "register",
    "resolve",
    "run",
    "style",
    "takes_part",
    "uses_k",
]


class MethodUnavailable(RuntimeError):
    """The method cannot run here (engine missing or not implemented); the message says why."""


#: What a method may support; a study or check that needs one skips a method without it, with
#: the reason ("<label> has no <capability>").
CAPABILITIES = {
    "torque": "torque drives",
    "motion": "prescribed-motion drives",
    "closed_loop": "closed-loop drives (pd, pid, user laws)",
    "moment_feedback": "root bending-moment feedback",
    "gravity": "gravity",
    "damping": "structural damping",
    "payload": "hubs and payloads",
    "energy": "total energy as an output",
    "cut_loads": "cut loads (root bending moment) as an output",
    "modes": "natural modes from its own linearisation",
}
#: subject: the DT-TMM runs the suite is about; reference: computes the converged references;
#: peer: another flexible model; baseline: a deliberately simpler model (its error is a floor).
ROLES = ("subject", "reference", "peer", "baseline")
#: What the common ``elements_per_link`` argument means, per discretisation.
DISCRETISATIONS = ("elements per link", "modes per link", "pieces per link", None)


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
class Physics:
    """What a method solves. ``element``: the link model (``hermite-fe``, ``ancf-cable``,
    ``ge-beam``, ``hinge-chain``, ``modal``, ``rigid``, or any name of an outside method);
    ``strain``: ``linear`` or ``nonlinear`` (the axial strain's quadratic term and beyond), or
    ``rigid``. Runs are compared like for like only within one strain class."""

    element: str = "unknown"
    strain: str = "unknown"


@dataclass(frozen=True)
class Setting:
    """One documented setting a method is run with: value, why (the measurement behind it) and
    its documentation source."""

    setting: str
    value: str
    why: str
    source: str


_ALL_CAPS = frozenset(CAPABILITIES)


@dataclass(frozen=True)
class Method:
    """A registered method (see the module docstring).

    name, module : registry name; module of ``simulate`` (None: a name shown but never run)
    entry : the function's name in ``module`` (default ``simulate``)
    options : (name, value) pairs every call gets
    role : one of :data:`ROLES`
    physics : :class:`Physics`
    discretisation : what ``elements_per_link`` means, or None (it gets ``None``)
    capabilities : subset of :data:`CAPABILITIES`
    libraries : distributions whose version changes its numbers (part of the cache key)
    settings : :class:`Setting` rows for the report's "Peer configuration" section
    explicit : explicit in time (a stable step limit): studies that refine k at a fixed h, or h
        at a fixed k on the implicit grid, use the plan's explicit steps or ``max_step``
    max_step : f(k) -> the largest step (s) the studies use at k (explicit methods)
    skip : study -> why the method sits that study out; a key ``study:kind`` names one kind of
        problem of a study, ``study@size`` one plan size ("quick" or "full")
    max_k : ``study@size``, ``study`` or ``*`` -> the largest k it runs there
    study_options : study -> extra (name, value) options its runs get there
    base : the DT-TMM method its costs are measured against (default: the subject of its strain)
    reference_rank, check_rank : its place (1, 2, ...) among the candidates of the converged
        references and among their cross-checks (0: not one); ``check_refine`` multiplies the
        reference's k when it checks
    scans : the pytest-benchmark scans (benchmarks/) it is timed in: "elements", "links"
    alias_of : for a name shown but not run, the method it is a variant of (benchmark variants)
    frequencies : ``module:function`` with ``f(case, k, n) -> Hz`` (lowest n natural frequencies at
        rest, held joints clamped), for methods with the "modes" capability
    label, style : legend label and plot style
    spatial : ``module:function`` that runs spatial cases (``dttmm.spatial.SpatialCase``) with
        the same common call, '' when the method runs planar arms only; ``spatial_options``:
        the (name, value) pairs its spatial calls get instead of ``options`` (None: the same);
        ``spatial_max_k``: the largest k its spatial runs take in the studies (their cost);
        ``spatial_max_step``: ``max_step`` for its spatial runs, called with (k, case)
        (None: ``max_step``; :func:`step_rule`);
        ``spatial_check``: ``module:function`` that raises InputError for a spatial case the
        method cannot model (its message is the reason the method sits that case out);
        ``spatial_label``: the label of its spatial engine where it differs from ``label``;
        ``spatial_cut_loads``: its spatial runs record the cut loads of docs/spatial.md §4 (k + 1
        cuts per link) when called with ``cut_loads=True`` (the paper study asks for them: the
        root bending moment of a spatial arm needs them); ``spatial_loads_note``: why its
        spatial runs give no root bending moment, when there is more to say than that they
        record no cut loads
    rigid_links : it runs planar arms with rigid links and payloads off the tip (False: it sits
        such a case out, with the reason)
    """

    name: str
    module: str | None
    options: tuple[tuple[str, object], ...] = ()
    role: str = "peer"
    physics: Physics = field(default_factory=Physics)
    discretisation: str | None = "elements per link"
    capabilities: frozenset = _ALL_CAPS
    libraries: tuple[str, ...] = ()
    settings: tuple[Setting, ...] = ()
    explicit: bool = False
    max_step: Callable[[int], float] | None = None
    skip: tuple[tuple[str, str], ...] = ()
    max_k: tuple[tuple[str, int], ...] = ()
    study_options: tuple[tuple[str, tuple], ...] = ()
    base: str = ""
    reference_rank: int = 0
    check_rank: int = 0
    check_refine: int = 1
    frequencies: str = ""
    scans: tuple[str, ...] = ()
    alias_of: str = ""
    label: str = ""
    style: Style = field(default_factory=Style)
    entry: str = "simulate"
    simulate: Callable | None = None  # a function given directly (outside methods)
    timeout: float = math.inf  # s per call; a run past it is an omission
    spatial: str = ""
    spatial_options: tuple[tuple[str, object], ...] | None = None
    spatial_max_k: float = math.inf
    spatial_max_step: Callable[..., float] | None = None
    spatial_check: str = ""
    spatial_label: str = ""
    spatial_cut_loads: bool = False
    spatial_loads_note: str = ""
    rigid_links: bool = False

    def __post_init__(self):
        from dttmm.errors import InputError

        if self.role not in ROLES:
            raise InputError(f"method {self.name}: role", self.role, f"must be one of {', '.join(ROLES)}")
        if self.discretisation not in DISCRETISATIONS:
            raise InputError(
                f"method {self.name}: discretisation",
                self.discretisation,
                "must be one of " + ", ".join(map(repr, DISCRETISATIONS)),
            )
        unknown = set(self.capabilities) - _ALL_CAPS
        if unknown:
            raise InputError(
                f"method {self.name}: capabilities", sorted(unknown), f"known: {', '.join(CAPABILITIES)}"
            )
        object.__setattr__(self, "capabilities", frozenset(self.capabilities))
        object.__setattr__(self, "skip", tuple(dict(self.skip).items()))
        for key in ("spatial", "spatial_check"):
            spec = getattr(self, key)
            if spec and (spec.count(":") != 1 or not all(spec.split(":"))):
                raise InputError(f"method {self.name}: {key}", spec, "must be 'module:function'")

    def runs_on(self, case, k: int | None = None) -> bool:
        """Whether the method runs ``case`` (at k elements per link, when given): every method
        runs planar cases, those with a ``spatial`` entry the spatial ones it can model (see
        :meth:`why_not_case`), up to ``spatial_max_k``."""
        if k is not None and is_spatial(case) and k > self.spatial_max_k:
            return False
        return not self.why_not_case(case)

    def why_not_case(self, case) -> str:
        """Why the method cannot run ``case`` ('' when it can): a spatial arm needs a
        ``spatial`` entry, and passes its ``spatial_check``; a planar arm with rigid links or an
        offset payload needs ``rigid_links``."""
        if not is_spatial(case):
            if self.rigid_links or getattr(case.model, "flexible_only", True):
                return ""
            return (
                "no rigid links or offset payloads (planar arms of flexible links, bodies on the beam axis)"
            )
        if not self.spatial:
            return "no spatial engine (planar arms only)"
        return _spatial_refusal(self.spatial_check, case) if self.spatial_check else ""

    def why_no_spatial_moment(self) -> str:
        """Why the method's spatial runs give no root bending moment ('' when they do)."""
        if self.spatial_cut_loads:
            return ""
        return self.spatial_loads_note or "its spatial engine records no cut loads"

    def options_for(self, study: str) -> tuple:
        """Extra options the method's runs get in ``study``."""
        return tuple(dict(self.study_options).get(study, ()))

    def k_limit(self, study: str, size: str | None = None) -> float:
        """Largest k the method runs in ``study`` at ``size`` (inf: no limit)."""
        lim = dict(self.max_k)
        return float(lim.get(f"{study}@{size}", lim.get(study, lim.get("*", math.inf))))

    @property
    def uses_k(self) -> bool:
        """Whether the method discretises the links (False: ``elements_per_link=None``)."""
        return self.discretisation is not None

    def has(self, capability: str) -> bool:
        return capability in self.capabilities

    def why_not(self, study: str, kind: str | None = None, size: str | None = None) -> str:
        """Why the method sits out ``study`` (of a ``kind`` of problem, at a plan ``size``); ''
        when it takes part."""
        skip = dict(self.skip)
        keys = [study, *([f"{study}:{kind}"] if kind else []), *([f"{study}@{size}"] if size else [])]
        return next((skip[k] for k in keys if k in skip), "")


# ----------------------------------------------------------------------------- built-in records
_EXUDYN_DOC = "Exudyn 1.13 reference manual (exudyn.readthedocs.io)"
_EXUDYN_SHARED = (
    Setting(
        "drive torques",
        "plain LoadTorqueVector values set once per step in a PreStepUserFunction",
        "the load user function was called ~35 times per step (5-15 % of the time at k ≤ 16); "
        "results equal to 5e-13 m",
        "MainSystem.SetPreStepUserFunction docstring: 'recommended e.g. for prescribing forces or set "
        "values of actuators'; the time argument is the step end",
    ),
    Setting(
        "prescribed joint angles",
        "ObjectConnectorCoordinate offset set once per step (PreStep)",
        "same mechanism as the torques",
        f"{_EXUDYN_DOC}: ObjectConnectorCoordinate.offset",
    ),
    Setting(
        "integrator",
        "generalized-α, spectralRadius 0.8, fixed step (adaptiveStep False)",
        "the suite's common integrator setting; a Newton failure must be visible, not a silent step halving",
        f"{_EXUDYN_DOC}: SimulationSettings.timeIntegration.generalizedAlpha / adaptiveStep",
    ),
    Setting(
        "Newton",
        "modified Newton with modifiedNewtonJacUpdatePerStep = True",
        "default reuse across steps thrashes at h ≥ 2e-3 (7.4 iterations, 1.2 Jacobians per step "
        "at k = 4, h = 2e-3); per step 4.5 and 1.0",
        f"{_EXUDYN_DOC}: TimeIntegrationSettings.newton.modifiedNewtonJacUpdatePerStep ('compute Jacobian at "
        "every time step, but not in every Newton iteration')",
    ),
    Setting(
        "Newton tolerances",
        "relative 1e-8; absolute 1e3·eps·max(EA·k/L)·(chain length), ≥ 1e-8",
        "the absolute test is on the residual (force units) and cannot go below its round-off floor; "
        "a relaxed relative 1e-5 is part of the work-precision grid and wins only where its error "
        "is as small (rule: cheapest run at equal accuracy)",
        f"{_EXUDYN_DOC}: NewtonSettings.relativeTolerance / absoluteTolerance",
    ),
    Setting(
        "linear solver",
        "EigenSparse",
        "EigenDense is 3.5× slower at k = 16, 22× at k = 64",
        f"{_EXUDYN_DOC}: SimulationSettings.linearSolverType",
    ),
    Setting(
        "threads, output",
        "parallel.numberOfThreads = 1; no solution file; sensors stored in memory",
        "same scope as DT-TMM (one thread, no file output)",
        f"{_EXUDYN_DOC}: SimulationSettings.parallel / solutionSettings.writeSolutionToFile",
    ),
    Setting(
        "timing scope",
        "CPU time (time.process_time) of the whole simulate call; repeats by the suite's timing rule; "
        "solve-only times kept beside it",
        "the same scope for every method",
        "this suite",
    ),
)
_DTTMM_LIBS = ("numpy", "scipy", "numba")
_DTTMM_SPATIAL = "dttmm.spatial:simulate"  # the spatial kernel (docs/spatial.md), same options
_NO_MODES = _ALL_CAPS - {"modes"}
_SAME_DISCRETISATION = "the same discretisation as {0}, equal to it to round-off (the cross-checks show it)"
_EXPLICIT_K = (
    "explicit in time: its stable step falls with k, so k is not refined at the common step "
    "(its order in k shows on the work-precision path)"
)


_AMM_VARIANT = "a variant of the assumed modes method, shown where the variants part ways"
_AMM_LARGE = tuple(
    (
        f"benchmarks:{kind}",
        "large deflections: beyond a small-deflection modal model (off by up to 92 %, measured)",
    )
    for kind in ("static_tip_displacement", "tip_path_rms")
)


def _mujoco_step(k: int) -> float:
    """Largest step the studies give the MuJoCo chain at k pieces per link: its joint springs are
    explicit and the stable step ∝ 1/k² (h_stable ≈ 0.02/k² s on the suite's arms, measured;
    docs/mujoco.md), with 20 % margin, and at most 2 ms."""
    return min(2e-3, 0.016 / max(int(k), 1) ** 2)


def _mujoco_spatial_step(k: int, case=None) -> float:
    """Largest step the studies give the spatial MuJoCo chain at k stations per link: 2 ms
    halved until it is at most 0.0032/k^1.6 s. The stable step (2/ω_max, implicitfast) on
    three_joint_arm is 5.4e-3, 1.4e-3, 5.4e-4, 1.8e-4 and 7.6e-5 s at k = 1…16 (measured; the
    section's rotary inertia makes it fall slower than 1/k²), so this keeps 20-60 % margin and
    divides the 4 ms output grid. On a ``case`` that is a tree or has loop closures (the rule
    above, tuned on chains, let the branched arm and the four-bar diverge at k = 2; the four-bar's
    steel links need about 1e-5 s) the step is halved further until it is below half the stable
    step of that case's own chain
    (:func:`reference_models.mujoco_spatial.stability_limit` at rest)."""
    h = 2e-3
    while h > 0.0032 / max(int(k), 1) ** 1.6:
        h /= 2
    if case is not None and not getattr(case.model, "serial", True):
        from reference_models import mujoco_spatial

        m, d, _ = mujoco_spatial.build(case.model, max(int(k), 1))
        limit = mujoco_spatial.stability_limit(m, d)[1]
        while h > 0.5 * limit:
            h /= 2
    return h


def step_rule(rec, case=None):
    """The record's step rule for ``case`` as a function of k, or None: its
    ``spatial_max_step`` (given the case) on a spatial case where it has one, else ``max_step``."""
    if case is not None and is_spatial(case) and rec.spatial_max_step is not None:
        return lambda k: rec.spatial_max_step(k, case)
    return rec.max_step


#: RK4's stability bound on the imaginary axis: |R(iωh)| ≤ 1 for ωh ≤ 2√2 (2.83)
_RK4_BOUND = 2 * math.sqrt(2)
#: the k and the smallest step (s) the studies give the explicit DT-TMM on a spatial arm: the
#: paper study's k = 8, the quick size's finest explicit step (experiments/plan.py, rk4_h)
_RK4_SPATIAL_K, _RK4_SPATIAL_H = 8, 1e-5


def rk4_stable_step(case, k: int) -> float:
    """RK4's largest stable step (s) on ``case`` at k elements per link: 2√2/ω_max, ω_max the
    highest natural frequency of the DT-TMM's own linearisation at rest (:func:`dttmm.linear.
    frequencies`; measured: ur5 9.9e-6 s, panda 6.9e-6 s at k = 4, where RK4 ran at 1e-5 s on
    the UR5 and diverged on the Panda; three_joint_arm 2.5e-5 s at k = 8); unbounded on an arm of
    rigid links only."""
    from dttmm.linear import frequencies

    if all(link.rigid for link in case.model.links):
        return math.inf  # no element modes: nothing stiff limits the step
    return _RK4_BOUND / (2 * math.pi * float(max(frequencies(case, k))))


def check_rk4_spatial(case) -> None:
    """Refuse (InputError) a spatial arm whose stiffest element modes need a smaller RK4 step
    at the studies' k (8) than the smallest step they give it (1e-5 s): the robots' tubes."""
    from dttmm.errors import InputError

    if getattr(case.model, "closures", ()):
        raise InputError("integrator", "rk4", "closed loops run with the Newmark family only (not rk4)")
    h = rk4_stable_step(case, _RK4_SPATIAL_K)
    if h < _RK4_SPATIAL_H:
        raise InputError(
            "integrator",
            "rk4",
            f"explicit: its stable step on this arm at k = {_RK4_SPATIAL_K} is {h:.2g} s (2√2/ω_max of the "
            f"arm's modes at rest), below the studies' smallest explicit step {_RK4_SPATIAL_H:g} s",
        )


_BUILTIN = (
    # DT-TMM and the global solver often agree to round-off: their markers differ in shape and
    # size (DT-TMM large and hollow) so both stay visible.
    Method(
        "dttmm",
        "dttmm",
        (("integrator", "newmark"),),
        rigid_links=True,
        role="subject",
        physics=Physics("hermite-fe", "linear"),
        libraries=_DTTMM_LIBS,
        reference_rank=2,
        check_rank=1,
        frequencies="dttmm.linear:frequencies",
        scans=("links",),  # its element scans are the converged and one-shot variants below
        spatial=_DTTMM_SPATIAL,
        spatial_cut_loads=True,
        label="DT-TMM (Newmark)",
        style=Style("C0", "o", "-", 7, hollow=True),
    ),
    Method(
        "dttmm-rk4",
        "dttmm",
        (("integrator", "rk4"),),
        rigid_links=True,
        role="subject",
        physics=Physics("hermite-fe", "linear"),
        libraries=_DTTMM_LIBS,
        explicit=True,
        skip=(
            ("convergence_k", _EXPLICIT_K),
            ("work_precision", "explicit: its stable step is far below the implicit methods' steps"),
            ("cost", "explicit: its cost per step is in the pytest-benchmark scaling"),
            ("control", "the stiff element modes' damping limits RK4 to h ≈ 2.5e-7 s on this arm"),
            ("benchmarks", "explicit: the problems' stiff links need steps of ~1e-6 s"),
        ),
        base="dttmm",
        scans=("elements",),
        spatial=_DTTMM_SPATIAL,
        spatial_check="experiments.methods:check_rk4_spatial",
        spatial_cut_loads=True,
        label="DT-TMM (RK4)",
        style=Style("C4", "v", "-", 5),
    ),
    Method(
        "dttmm-2nd",
        "dttmm",
        (("strain", "second-order"), ("integrator", "generalized-alpha"), ("rho_inf", 0.8)),
        rigid_links=True,
        role="subject",
        physics=Physics("hermite-fe", "nonlinear"),
        libraries=_DTTMM_LIBS,
        # measured on three_link, k = 2…16, h = 2.5e-4…4e-3: with iterations="auto" the runs reach
        # the same end-effector error (within 3 %, most points equal to 3 digits) at 0.5-0.6× the CPU time
        study_options=(("work_precision", (("iterations", "auto"),)),),
        skip=(
            (
                "benchmarks:static_tip_displacement",
                "its Kelvin-Voigt damping acts on the linear element coordinates, so a damped run to rest "
                "with the second-order strain creeps",
            ),
        ),
        scans=("elements",),
        spatial=_DTTMM_SPATIAL,
        spatial_cut_loads=True,
        label="DT-TMM (2nd-order strain, gen-α 0.8)",
        style=Style("C9", "P", "-", 6),
    ),
    Method(
        "global",
        "reference_models.global_newmark",
        (("integrator", "newmark"), ("engine", "numba")),
        rigid_links=True,
        role="reference",
        physics=Physics("hermite-fe", "linear"),
        libraries=_DTTMM_LIBS,
        reference_rank=3,
        frequencies="reference_models.global_modes:frequencies",
        max_k=(("cost@quick", 16),),
        skip=(
            (
                "benchmarks@quick",
                "it repeats DT-TMM's discretisation to round-off and costs ~90 % of the problems' runs",
            ),
            ("control:gains", _SAME_DISCRETISATION.format("DT-TMM")),
        ),
        scans=("elements", "links"),
        spatial="reference_models.spatial_global:simulate",
        spatial_options=(("integrator", "newmark"),),
        # compiled mechanics (reference_models/_spatial_numba.py): on three_joint_arm with cut
        # loads at every step, 1.6 ms a step at k = 4, 3.2 ms at k = 8, 9.0 ms at k = 16, 47 ms at
        # k = 32 (benchmarks/spatial_global_cpu.py; the numpy engine 13, 29 and 115 ms)
        spatial_cut_loads=True,
        label="global equations (Newmark, compiled)",
        spatial_label="global equations (Newmark, compiled)",
        style=Style("C3", "^", "--", 4),
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
        rigid_links=True,
        role="reference",
        physics=Physics("hermite-fe", "nonlinear"),
        libraries=_DTTMM_LIBS,
        capabilities=_NO_MODES,
        skip=tuple(
            (s, _SAME_DISCRETISATION.format("DT-TMM with the second-order strain"))
            for s in ("convergence_k", "convergence_h", "paper", "cost", "benchmarks", "control:gains")
        ),
        spatial="reference_models.spatial_global:simulate",
        spatial_options=(("strain", "second-order"), ("integrator", "generalized-alpha"), ("rho_inf", 0.8)),
        spatial_cut_loads=True,
        label="global equations (2nd-order strain, gen-α 0.8, compiled)",
        spatial_label="global equations (2nd-order strain, gen-α 0.8, compiled)",
        style=Style("C6", "<", "--", 5),
    ),
    Method(
        "exudyn-ancf",
        "reference_models.exudyn_ancf",
        role="reference",
        physics=Physics("ancf-cable", "nonlinear"),
        libraries=("numpy", "exudyn"),
        capabilities=_ALL_CAPS - {"energy", "cut_loads"},
        reference_rank=1,
        frequencies="reference_models.exudyn_modes:frequencies",
        # spatial arms: ObjectANCFCable (3-D), torsionally rigid, one bending stiffness (docs/peers.md)
        spatial="reference_models.exudyn_ancf3d:simulate",
        spatial_check="reference_models.exudyn_ancf3d:check_case",
        settings=(
            Setting(
                "element",
                "ObjectANCFCable2D, k per link, slope nodes clamped to hub/tip bodies",
                "Euler-Bernoulli cable with nonlinear strain",
                f"{_EXUDYN_DOC}: ObjectANCFCable2D",
            ),
            *_EXUDYN_SHARED,
        ),
        scans=("elements", "links"),
        skip=(
            (
                "benchmarks:tip_extrema",
                "a torsion-free cable: the right-angle cantilever's legs twist (its tip extrema came out "
                "off by a relative 1.7, measured)",
            ),
        ),
        label="Exudyn ANCF",
        style=Style("C1", "s", "-", 5),
    ),
    # physical rotary inertia: measured to run on the suite's cases (see docs/peers.md)
    Method(
        "exudyn-beam",
        "reference_models.exudyn_beam",
        (("cross_section_inertia", "physical"),),
        role="peer",
        physics=Physics("ge-beam", "nonlinear"),
        libraries=("numpy", "exudyn"),
        capabilities=_ALL_CAPS - {"energy", "cut_loads", "modes"},
        check_rank=2,
        check_refine=2,  # a shear-flexible Reissner element: it checks at twice the reference's k
        settings=(
            Setting(
                "element",
                "ObjectBeamGeometricallyExact2D, hub/tip bodies on the end nodes",
                "Reissner beam; Exudyn has no 2D Euler-Bernoulli beam",
                f"{_EXUDYN_DOC}: ObjectBeamGeometricallyExact2D",
            ),
            Setting(
                "shearStiffness",
                "κGA = 0.32·EA (κ = 5/6, ν = 0.3)",
                "physical value; 1e3·EA made Newton fail",
                f"{_EXUDYN_DOC}: ObjectBeamGeometricallyExact2D.shearStiffness",
            ),
            Setting(
                "crossSectionInertia",
                "physical ρI = ρA·EI/EA (9e-8 kg·m for the strips) in the studies; adapter default 1e-5",
                "physical runs on single_link and three_link for k = 1…64, h = 5e-4…4e-3; on a two-link arm "
                "with a step torque it fails Newton at h = 1e-3 (1e-5 runs), so 1e-5 stays the safe default",
                f"{_EXUDYN_DOC}: ObjectBeamGeometricallyExact2D.crossSectionInertia",
            ),
            *_EXUDYN_SHARED,
        ),
        scans=("elements",),
        # spatial arms: ObjectBeamGeometricallyExact (3-D) at its adapter's settings
        # (generalized-α ρ∞ = 1: with 0.8 Newton failed on three_joint_arm at k = 4, h = 5e-4, measured)
        spatial="reference_models.exudyn_beam3d:simulate",
        spatial_options=(),
        spatial_check="reference_models.exudyn_beam3d:check_case",
        # its section_loads option: ForceLocal/TorqueLocal of the first element, one-point integration
        spatial_loads_note="its 3-D beam gives section loads only at the middle of each link's first element, "
        "not at the link's root",
        label="Exudyn GE beam",
        style=Style("C2", "D", "-", 5),
    ),
    Method(
        "mujoco-chain",
        "reference_models.mujoco_chain",
        (("integrator", "implicitfast"),),
        role="peer",
        physics=Physics("hinge-chain", "linear"),
        discretisation="pieces per link",
        libraries=("numpy", "mujoco"),
        capabilities=_ALL_CAPS - {"energy", "modes"},
        explicit=True,
        max_step=_mujoco_step,
        skip=(
            ("convergence_k", _EXPLICIT_K),
            ("convergence_h", "explicit in its springs: the step is tied to k (stable step ∝ 1/k²)"),
            ("cost", "its cost is on the work-precision path (the step falls with k)"),
            (
                "benchmarks",
                "explicit: the spin-up problems at k = 32 need h ≈ 1.6e-5 s for 8 s (~100 s a run)",
            ),
        ),
        base="dttmm",
        spatial="reference_models.mujoco_spatial:simulate",
        spatial_check="reference_models.mujoco_spatial:check_case",
        spatial_max_step=_mujoco_spatial_step,
        label="MuJoCo hinge chain",
        style=Style("C5", "X", "-.", 6),
    ),
    # The assumed modes method (docs/assumed_modes.md): modes per link in the common argument. The
    # consistent variant (the default: the only one that passes the spin-up benchmarks) runs in
    # every study; the two others where the variants part ways.
    *(
        Method(
            name,
            "reference_models.assumed_modes",
            (("variant", variant),),
            role="peer",
            physics=Physics("modal", strain),
            discretisation="modes per link",
            libraries=_DTTMM_LIBS,
            capabilities=_ALL_CAPS - {"cut_loads"} - ({"modes"} if variant != "consistent" else set()),
            frequencies="reference_models.assumed_modes:modes" if variant == "consistent" else "",
            max_k=(("*", 16),),  # at most 30 modes per link; 16 is converged on every case (measured)
            skip=skip,
            label=label,
            style=style,
        )
        for name, variant, strain, label, style, skip in (
            (
                "amm",
                "consistent",
                "nonlinear",
                "assumed modes (consistent)",
                Style("C8", "h", "-", 6),
                _AMM_LARGE,
            ),
            (
                "amm-ruthless",
                "ruthless",
                "linear",
                "assumed modes (ruthless)",
                Style("C8", "d", ":", 5, hollow=True),
                (
                    *((s, _AMM_VARIANT) for s in ("convergence_k", "convergence_h", "cost", "control")),
                    *_AMM_LARGE,
                ),
            ),
            (
                "amm-premature",
                "premature",
                "linear",
                "assumed modes (premature)",
                Style("C8", "x", "--", 5),
                (
                    *((s, _AMM_VARIANT) for s in ("convergence_k", "convergence_h", "cost", "control")),
                    *_AMM_LARGE,
                ),
            ),
        )
    ),
    Method(
        "pinocchio-rigid",
        "reference_models.pinocchio_rigid",
        (("integrator", "rk4"),),
        rigid_links=True,
        role="baseline",
        physics=Physics("rigid", "rigid"),
        discretisation=None,
        libraries=("numpy", "pin"),
        capabilities=_ALL_CAPS - {"moment_feedback", "energy", "cut_loads", "modes", "damping"},
        skip=(
            ("convergence_k", "rigid links: nothing to refine in k"),
            ("convergence_h", "rigid links: its error is the floor of ignoring flexibility"),
            ("cost", "rigid links: no elements"),
            ("benchmarks:peak_tip_deflection", "rigid links: no tip deflection"),
            ("benchmarks:static_tip_displacement", "rigid links: no deflection"),
            ("benchmarks:tip_extrema", "rigid links: a locked-joint arm does not move"),
        ),
        scans=("elements",),
        spatial="reference_models.pinocchio_spatial:simulate",
        spatial_check="reference_models.pinocchio_spatial:check_case",
        label="Pinocchio rigid",
        style=Style("k", "*", ":", 9),
    ),
)

# Shown in figures and text but not run by the studies (the reference curve, benchmark variants).
_SHOWN = (
    Method("reference", None, label="reference", style=Style("0.3", "", "-", 0)),
    # the element scans' variants of DT-TMM (Newmark): converged, and one sweep per step
    *(
        Method(
            name,
            None,
            alias_of="dttmm",
            scans=("elements",),
            role="subject",
            physics=Physics("hermite-fe", "linear"),
            label=label,
            style=style,
        )
        for name, label, style in (
            ("dttmm-converged", "DT-TMM (Newmark), converged", Style("C0", "o")),
            ("dttmm-one-shot", "DT-TMM (Newmark), one sweep per step", Style("C9", "v")),
        )
    ),
)

METHODS: dict[str, Method] = {m.name: m for m in _BUILTIN}
_LOOKS: dict[str, Method] = {m.name: m for m in (*_BUILTIN, *_SHOWN)}
_FALLBACK_MARKERS = "osD^v<>ph*"
_EXTRA: dict[str, Method] = {}  # registered at run time (outside, user or test methods)


# ----------------------------------------------------------------------------- lookups
def is_spatial(case) -> bool:
    """Whether ``case`` is a spatial arm (a ``dttmm.spatial.SpatialCase``)."""
    from dttmm.spatial.case import SpatialCase

    return isinstance(case, SpatialCase)


@functools.lru_cache(maxsize=256)
def _spatial_refusal(check: str, case) -> str:
    """The message of the InputError ``check(case)`` raises ('' when it raises none)."""
    from dttmm.errors import InputError

    mod, fn = check.split(":")
    try:
        getattr(importlib.import_module(mod), fn)(case)
    except InputError as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - a check that cannot load or crashes: the method cannot run it
        return f"{check} failed: {type(exc).__name__}: {exc}"
    return ""


def runs_on(name: str, case, k: int | None = None) -> bool:
    """Whether method ``name`` runs ``case`` at k (a spatial case needs a ``spatial`` entry;
    see :meth:`Method.runs_on`). An unknown name runs nothing."""
    try:
        return get(name).runs_on(case, k)
    except MethodUnavailable:
        return False


def why_not_options(name: str, case, options=()) -> str:
    """Why method ``name`` refuses ``case`` with a study's extra ``options`` before the run
    starts ('' when it takes them): a DT-TMM method on a spatial arm with loop closures takes the
    Newmark family with every step run to the stop rule only (``dttmm.spatial``'s own rule, so a
    study option such as ``iterations="auto"`` is sat out, not run into its refusal)."""
    from dttmm.errors import InputError

    try:
        rec = get(name)
    except MethodUnavailable:
        return ""
    if not (is_spatial(case) and case.model.closures and rec.spatial == _DTTMM_SPATIAL):
        return ""
    opts = dict(rec.options if rec.spatial_options is None else rec.spatial_options)
    opts.update(dict(options))
    from dttmm.spatial.solver import _check_closures

    try:
        _check_closures(case, str(opts.get("integrator", "newmark")), opts.get("iterations"))
    except InputError as exc:
        given = ", ".join(f"{k}={v!r}" for k, v in sorted(dict(options).items()))
        return f"its runs here take {given}, which a closed loop refuses: {exc}" if given else str(exc)
    return ""


def get(name: str) -> Method:
    """The record of ``name`` (built-in, shown or registered); raises MethodUnavailable."""
    m = _EXTRA.get(name) or METHODS.get(name) or _LOOKS.get(name)
    if m is None:
        raise MethodUnavailable(f"unknown method {name!r} (known: {', '.join(names())})")
    return m


def names() -> list[str]:
    """Every method that runs: built-in first, then registered ones, in registration order."""
    return list(METHODS) + [n for n in _EXTRA if n not in METHODS]


def by_role(*roles: str) -> list[str]:
    """The runnable methods of the given roles, in registry order."""
    return [n for n in names() if get(n).role in roles]


def takes_part(
    study: str,
    *,
    kind: str | None = None,
    size: str | None = None,
    flexible: bool | None = None,
    implicit: bool | None = None,
    needs: tuple[str, ...] = (),
) -> list[str]:
    """The runnable methods that take part in ``study`` (no ``skip`` entry for it, its ``kind``
    or ``size``), optionally only the flexible ones (a discretisation parameter), only the
    implicit ones, or only those with every capability in ``needs``."""
    out = []
    for n in names():
        m = get(n)
        if m.why_not(study, kind, size) or not all(m.has(c) for c in needs):
            continue
        if flexible is not None and m.uses_k != flexible:
            continue
        if implicit is not None and m.explicit == implicit:
            continue
        out.append(n)
    return out


def sitting_out(study: str, kind: str | None = None, size: str | None = None) -> dict[str, str]:
    """method -> why it sits out ``study``, for the report's omissions."""
    return {n: w for n in names() if (w := get(n).why_not(study, kind, size))}


def reference_candidates() -> list[str]:
    """Methods that compute converged references, in the order they are tried."""
    ranked = [n for n in names() if get(n).reference_rank > 0]
    return sorted(ranked, key=lambda n: get(n).reference_rank)


def cross_checks() -> list[str]:
    """Methods that cross-check a reference, in order."""
    ranked = [n for n in names() if get(n).check_rank > 0]
    return sorted(ranked, key=lambda n: get(n).check_rank)


def frequencies_of(name: str) -> Callable | None:
    """The method's ``f(case, k, n) -> Hz`` natural-frequency function, or None."""
    try:
        m = get(name)
    except MethodUnavailable:
        return None
    if not m.has("modes") or not m.frequencies:
        return None
    mod, _, fn = m.frequencies.partition(":")
    return getattr(importlib.import_module(mod), fn)


def base_of(name: str) -> str:
    """The DT-TMM method ``name``'s costs are compared with: its record's ``base``, else the first
    subject of the same strain class ('' when there is none, or for the subject itself)."""
    try:
        m = get(name)
    except MethodUnavailable:
        return ""
    if m.base:
        return m.base if m.base != name else ""
    for n in (*names(), *(s.name for s in _SHOWN)):
        s = get(n)
        if s.role == "subject" and not s.explicit and s.physics.strain == m.physics.strain:
            return n if n != name else ""
    return ""


def shown_order() -> list[str]:
    """Every name in the order figures and tables list methods: each method followed by the
    variants shown for it (``alias_of``), then registered outside methods."""
    out = []
    for m in _BUILTIN:
        out += [s.name for s in _SHOWN if s.alias_of == m.name] + [m.name]
    return [*out, *(n for n in _EXTRA if n not in out)]


def in_scan(scan: str) -> list[str]:
    """The names timed in a pytest-benchmark scan ("elements", "links"), in :func:`shown_order`."""
    return [n for n in shown_order() if scan in (_EXTRA.get(n) or _LOOKS[n]).scans]


def ratio_pairs() -> list[tuple[str, tuple[str, ...]]]:
    """Like-for-like speed ratios: (method, the names of its DT-TMM partner, most specific first)
    for every reference and peer method with a partner of its strain class."""
    out = []
    for n in names():
        m = get(n)
        base = base_of(n)
        if m.role in ("reference", "peer") and base:
            out.append((n, (*[s.name for s in _SHOWN if s.alias_of == base][:1], base)))
    return out


def same_equations() -> list[tuple[str, str]]:
    """(DT-TMM method, reference method) pairs that solve the same discrete equations (same
    element and strain, both implicit): they must agree to round-off."""
    out = []
    for s in by_role("subject"):
        a = get(s)
        for r in by_role("reference"):
            b = get(r)
            if not a.explicit and not b.explicit and a.physics == b.physics:
                out.append((s, r))
    return out


def uses_k(name: str) -> bool:
    """Whether the method discretises the links (False: rigid baseline, k is ignored)."""
    try:
        return get(name).uses_k
    except MethodUnavailable:
        return True


def label(name: str, spatial: bool = False) -> str:
    """Human-readable name for legends, tables and sentences (the name itself if unknown); with
    ``spatial``, the label of the method's spatial engine (its ``spatial_label``, if it has one)."""
    m = _EXTRA.get(name) or _LOOKS.get(name)
    if spatial and m is not None and getattr(m, "spatial_label", ""):
        return m.spatial_label
    return m.label if m and m.label else name


def style(name: str, index: int = 0) -> Style:
    """Plot style of ``name``; an unknown name gets a colour and marker picked by ``index``."""
    m = _EXTRA.get(name) or _LOOKS.get(name)
    if m is not None and (m.name in _LOOKS or m.style != Style()):
        return m.style
    return Style(f"C{index % 10}", _FALLBACK_MARKERS[index % len(_FALLBACK_MARKERS)])


def source_of(name: str) -> tuple[tuple[str, ...], tuple]:
    """(modules whose code makes the method's runs, options it always gets), for cache keys;
    ((), ()) for an unknown name."""
    m = _EXTRA.get(name) or METHODS.get(name)
    if m is None:
        return (), ()
    if m.simulate is not None:
        return (m.simulate.__module__,), m.options
    return ((m.module,) if m.module else ()), m.options


def libraries() -> tuple[str, ...]:
    """Every library any registered method names (the cache key's library versions)."""
    out = {}
    for n in names():
        out.update(dict.fromkeys(get(n).libraries))
    return tuple(out)


# ----------------------------------------------------------------------------- outside methods
def register(
    name: str | Method,
    simulate: Callable | None = None,
    *,
    uses_k: bool = True,
    label: str = "",
    style: Style | None = None,
    **traits,
) -> Method:
    """Add a method and return its record.

    Either a :class:`Method` record (with ``module`` or ``simulate``), or a name and a function
    ``simulate(case, *, elements_per_link, h, **options) -> Result`` with the stated defaults
    (role "peer", physics unknown, elements per link, every capability assumed; the studies'
    runs show what it really supports), optionally with record fields as keywords.
    """
    if isinstance(name, Method):
        rec = name
    else:
        if simulate is None or not callable(simulate):
            from dttmm.errors import InputError

            raise InputError(
                f"method {name}", simulate, "needs a callable simulate(case, *, elements_per_link, h)"
            )
        if not uses_k:
            traits.setdefault("discretisation", None)
        rec = Method(name, None, label=label or name, style=style or Style(), simulate=simulate, **traits)
    _EXTRA[rec.name] = rec
    return rec


def unregister(name: str) -> None:
    """Remove a method added with :func:`register` (tests)."""
    _EXTRA.pop(name, None)


def _bad_spec(spec, why):
    from dttmm.errors import InputError

    return InputError("--method", spec, why)


def load_spec(spec: str) -> Method:
    """The method named by ``spec``, registered and returned.

    ``spec`` is a registered name, an entry point of the group ``dttmm.methods``, or
    ``module.path:function`` / ``path/to/file.py:function`` (function default ``simulate``). The
    object found may be a :class:`Method` record or a function; a function may carry its traits
    as a ``method`` attribute (a Method, or a dict of Method fields). Raises InputError with one
    line for a bad spec (no such module or file, no such function, not callable, bad traits).
    """
    spec = str(spec).strip()
    if spec in names():
        return get(spec)
    eps = entry_points()
    if spec in eps:
        return _from_object(spec, eps[spec].load, spec)
    target, _, attr = spec.partition(":")
    attr = attr or "simulate"
    if target.endswith(".py") or "/" in target or "\\" in target:
        path = Path(target)
        if not path.is_file():
            raise _bad_spec(spec, f"no such file: {path}")
        modname = f"dttmm_outside_{path.stem}"
        folder = str(path.resolve().parent)
        before = set(sys.modules)
        if folder not in sys.path:  # the file imports the modules beside it, as when run as a script
            sys.path.insert(0, folder)
        loader_spec = importlib.util.spec_from_file_location(modname, path.resolve())
        module = importlib.util.module_from_spec(loader_spec)
        sys.modules[modname] = module
        try:
            loader_spec.loader.exec_module(module)
        except Exception as exc:  # noqa: BLE001 - any failure to load the file is a bad spec
            sys.modules.pop(modname, None)
            raise _bad_spec(spec, f"cannot load {path}: {type(exc).__name__}: {exc}") from None
        _ship_by_value(module, folder, set(sys.modules) - before)
        default_name = path.stem.replace("_", "-")
    else:
        before = set(sys.modules)
        try:
            module = importlib.import_module(target)
        except ModuleNotFoundError as exc:
            names_ = ", ".join(names())
            near = difflib.get_close_matches(target, names(), n=1)
            if ":" not in spec and "." not in target:  # a bare word: meant as a method's name
                hint = f"; did you mean {near[0]!r}?" if near else ""
                raise _bad_spec(
                    spec,
                    f"no method of that name (built-in: {names_}){hint}; or module:function, file.py:function",
                ) from None
            raise _bad_spec(spec, f"no such module: {exc.name}") from None
        except Exception as exc:  # noqa: BLE001
            raise _bad_spec(spec, f"cannot import {target}: {type(exc).__name__}: {exc}") from None
        if _is_local_source(module):
            _ship_by_value(module, str(Path(module.__file__).resolve().parent), set(sys.modules) - before)
        default_name = target.rsplit(".", 1)[-1].replace("_", "-")
    if not hasattr(module, attr):
        raise _bad_spec(spec, f"{target} has no {attr!r}")
    return _from_object(
        default_name if attr == "simulate" else attr.replace("_", "-"), lambda: getattr(module, attr), spec
    )


def _from_object(name, get_obj, spec) -> Method:
    try:
        obj = get_obj()
    except Exception as exc:  # noqa: BLE001 - an entry point that fails to load
        raise _bad_spec(spec, f"cannot load: {type(exc).__name__}: {exc}") from None
    if isinstance(obj, Method):
        rec = obj
    elif callable(obj):
        traits = getattr(obj, "method", None)
        try:
            if isinstance(traits, Method):
                rec = replace(traits, simulate=obj, module=None)
            elif isinstance(traits, dict):
                t = dict(traits)
                for k in ("physics", "style"):
                    if isinstance(t.get(k), dict):
                        t[k] = (Physics if k == "physics" else Style)(**t[k])
                if "settings" in t:
                    t["settings"] = tuple(
                        Setting(*s) if not isinstance(s, Setting) else s for s in t["settings"]
                    )
                rec = Method(t.pop("name", name), None, simulate=obj, **{"label": name, **t})
            elif traits is None:
                rec = Method(name, None, simulate=obj, label=name)
            else:
                raise TypeError(f"its 'method' attribute is a {type(traits).__name__}, not a Method or dict")
        except TypeError as exc:
            raise _bad_spec(spec, f"bad traits: {exc}") from None
    else:
        raise _bad_spec(spec, f"{type(obj).__name__} object is not callable")
    if rec.module is None and rec.simulate is None:
        raise _bad_spec(spec, "the record names neither a module nor a function")
    if not math.isfinite(rec.timeout):
        rec = replace(rec, timeout=OUTSIDE_TIMEOUT)  # an outside method gets a stated time limit
    if rec.name in METHODS and METHODS[rec.name] is not rec:
        raise _bad_spec(spec, f"the name {rec.name!r} is a built-in method's")
    return register(rec)


#: s per call: an outside method's default time limit (``dttmm report --method-timeout``).
OUTSIDE_TIMEOUT = 600.0


def _is_local_source(module) -> bool:
    """Whether ``module`` is a source file of the user's (not of an installed distribution nor of
    this suite), so that workers elsewhere may not be able to import it."""
    f = getattr(module, "__file__", None)
    if not f:
        return False
    p = Path(f).resolve()
    here = Path(__file__).resolve().parents[1]
    installed = any(part in ("site-packages", "dist-packages") for part in p.parts)
    return not installed and here not in p.parents


_BY_VALUE: set[str] = set()  # modules whose functions are sent to the workers by value


def _ship_by_value(module, folder: str, imported) -> None:
    """Send ``module`` and the modules it imported from beside it (``folder``) to the workers by
    value (cloudpickle), so a worker that cannot import them (another machine, another
    working directory) still runs the method. By value rather than by upload: it works with any
    scheduler, needs no state on the workers, and every run carries the code version the cache
    key hashed."""
    import cloudpickle

    mods = [module] + [
        m
        for n in sorted(imported)
        if (m := sys.modules.get(n)) is not None
        and getattr(m, "__file__", None)
        and str(Path(m.__file__).resolve()).startswith(folder + "/")
    ]
    for m in mods:
        if m.__name__ not in _BY_VALUE:
            cloudpickle.register_pickle_by_value(m)
            _BY_VALUE.add(m.__name__)


class MethodShippingError(RuntimeError):
    """An outside method could not be sent to, or loaded on, a worker: not the method's verdict."""


class _Shipped:
    """An outside function carried by value (cloudpickle bytes), loaded at its first call.

    Dask pickles a task's arguments with the standard pickle first, which sends a function by
    reference; a worker that cannot import the user's file would then fail while deserializing
    the task, outside the run. Carried as bytes, the function is loaded inside the run, where a
    failure is reported as :class:`MethodShippingError` (an infrastructure failure, never
    stored) and leaves the worker and its other runs alone.
    """

    def __init__(self, fn, folder: str = ""):
        import cloudpickle

        self.name = f"{getattr(fn, '__module__', '?')}.{getattr(fn, '__qualname__', fn)}"
        self.folder = folder
        self.fn = fn
        try:
            self.blob = cloudpickle.dumps(fn)
        except Exception as exc:  # noqa: BLE001 - the reason it cannot go to the workers
            raise MethodUnavailable(
                f"{self.name} cannot be sent to the workers: {type(exc).__name__}: {exc}"
            ) from None

    def __getstate__(self):
        return {"name": self.name, "folder": self.folder, "blob": self.blob}

    def __setstate__(self, state):
        self.__dict__.update(state, fn=None)

    def __call__(self, *args, **kwargs):
        if self.fn is None:
            import cloudpickle

            if self.folder and os.path.isdir(self.folder) and self.folder not in sys.path:
                sys.path.append(self.folder)  # imports made at call time find the modules beside it
            try:
                self.fn = cloudpickle.loads(self.blob)
            except Exception as exc:  # noqa: BLE001
                raise MethodShippingError(
                    f"could not load {self.name} in this worker: {type(exc).__name__}: {exc}"
                ) from None
        return self.fn(*args, **kwargs)


def _shipped(fn):
    """``fn`` wrapped for the workers when its module goes by value, else ``fn`` itself."""
    mod = getattr(fn, "__module__", None) or ""
    if mod not in _BY_VALUE:
        return fn
    f = getattr(sys.modules.get(mod), "__file__", None)
    return _Shipped(fn, str(Path(f).resolve().parent) if f else "")


def entry_points() -> dict:
    """Entry points of the group ``dttmm.methods`` declared by installed packages: name -> EntryPoint."""
    try:
        return {ep.name: ep for ep in importlib.metadata.entry_points(group="dttmm.methods")}
    except Exception:  # noqa: BLE001 - a broken distribution must not break the suite
        return {}


# ----------------------------------------------------------------------------- running
def resolve(name: str) -> Callable:
    """The method as ``f(case, k, h, **options) -> Result``; raises MethodUnavailable."""
    m = get(name)
    spatial = (m.spatial, m.options if m.spatial_options is None else m.spatial_options)
    if m.simulate is not None:
        return _Bound(_shipped(m.simulate), m.options, m.uses_k, m.timeout, *spatial)
    if m.module is None:
        raise MethodUnavailable(f"{name!r} is shown in figures but not run")
    try:
        module = importlib.import_module(m.module)
    except Exception as exc:  # noqa: BLE001 - any import failure makes the method unavailable, with the reason
        raise MethodUnavailable(f"cannot import {m.module}: {type(exc).__name__}: {exc}") from None
    sim = getattr(module, m.entry, None)
    if sim is None:
        raise MethodUnavailable(f"{m.module} has no {m.entry}()")
    return _Bound(sim, m.options, m.uses_k, m.timeout, *spatial)


@dataclass(frozen=True)
class _Bound:
    """A resolved method; picklable when ``simulate`` is a module-level function. ``timeout``:
    seconds a call may take before the sweep records it as an omission (inf: no limit).
    ``spatial`` (``module:function``) and ``spatial_options`` run spatial cases (imported at
    the first spatial call)."""

    simulate: Callable
    options: tuple
    uses_k: bool
    timeout: float = math.inf
    spatial: str = ""
    spatial_options: tuple = ()

    def _target(self, case):
        if not is_spatial(case):
            return self.simulate, dict(self.options)
        if not self.spatial:
            raise MethodUnavailable("runs planar arms only (its record has no spatial entry)")
        mod, fn = self.spatial.split(":")
        try:
            sim = getattr(importlib.import_module(mod), fn)
        except Exception as exc:  # noqa: BLE001 - the reason it cannot run spatial arms here
            raise MethodUnavailable(f"cannot load {self.spatial}: {type(exc).__name__}: {exc}") from None
        return sim, dict(self.spatial_options)

    def __call__(self, case, k, h, **options):
        sim, opts = self._target(case)
        opts.update(options)
        if getattr(sim, "__module__", "").startswith("dttmm."):
            # runs of a sweep report through the sweep's own progress bar, not one bar each
            opts.setdefault("progress", False)
        kk = int(k) if self.uses_k else None
        try:
            return sim(case, elements_per_link=kk, h=float(h), **opts)
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


#: s a registered method's probe may take before it is given up (its runs have their own limit)
PROBE_TIMEOUT = 60.0


def _probe_one(name: str, case) -> str | None:
    """None when ``name`` resolves and runs two steps of ``case``, else the reason. A method
    registered at run time (outside code) is probed in a forked process of its own, so a probe
    that ends its process or never returns is a reason, not the end of the report."""
    if case is not None and name in _EXTRA and hasattr(os, "fork"):
        return _probe_forked(name, case, min(PROBE_TIMEOUT, get(name).timeout))
    return _probe_here(name, case)


def _probe_forked(name: str, case, limit: float) -> str | None:
    """:func:`_probe_here` in a forked child; its answer comes back through a pipe."""
    import pickle
    import select
    import signal

    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: answer, then leave without running this process's exit handlers
        code = 0
        try:
            os.close(r)
            data = pickle.dumps(_probe_here(name, case))
            view = memoryview(data)
            while view:
                view = view[os.write(w, view) :]
        except BaseException:  # noqa: BLE001 - nothing may escape the child
            code = 1
        finally:
            os._exit(code)
    os.close(w)
    chunks = []
    try:
        while select.select([r], [], [], limit)[0]:
            chunk = os.read(r, 1 << 16)
            if not chunk:
                break
            chunks.append(chunk)
        else:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            return f"its probe run (two steps of a one-link arm) did not return within {limit:g} s"
    finally:
        os.close(r)
    _, status = os.waitpid(pid, 0)
    if not chunks:
        return f"its probe run ended its process (exit code {os.waitstatus_to_exitcode(status)})"
    return pickle.loads(b"".join(chunks))


def _probe_here(name: str, case) -> str | None:
    try:
        f = resolve(name)
        if case is not None:
            f(case, 1, 0.002)
        return None
    except MethodUnavailable as exc:
        return str(exc)
    except Exception as exc:  # noqa: BLE001 - a crash on the probe is a reason too
        return f"probe run failed: {type(exc).__name__}: {exc}"


def _spatial_probe_case():
    """A one-link spatial arm for a few steps (compiles or loads the spatial kernel)."""
    from dttmm import Constant, Drive, Scenario
    from dttmm.spatial import SpatialCase, SpatialLink, SpatialManipulator, SpatialSection

    beam = SpatialSection(1.0, GJ=1.0, EIy=2.0, EIz=2.0, rhoA=0.3, rhoJ=1e-3, EA=7e6)
    sc = Scenario(0.004, 0.002, (Drive("torque", Constant(0.1)),))
    return SpatialCase(SpatialManipulator((SpatialLink(beam),)), sc, "probe")


_WARM_SPATIAL = "spatial kernel warm-up"  # the probe's job that compiles the spatial kernel


def _warm_spatial(names_) -> list[None]:
    """Run the first of ``names_`` (methods sharing one spatial engine) on the spatial probe
    case, so that a compiled spatial engine is compiled once here and its cache is on disk
    before the sweep's workers start; a failure is left to the runs (they report it)."""
    with contextlib.suppress(Exception):
        resolve(names_[0])(_spatial_probe_case(), 1, 0.002)
    return [None] * len(names_)


def _probe_group(names_, probe: bool) -> list[str | None]:
    """:func:`_probe_one` for methods that share one engine module, in order (the first call
    compiles or loads the engine, the rest reuse it)."""
    case = _probe_case() if probe else None
    return [_probe_one(n, case) for n in names_]


def _fork_pool(workers: int):
    """A process pool of ``workers`` forked from this process (which holds the registered
    outside methods), or None where fork is not offered."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    return ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"))


def available(methods=None, *, probe: bool = True, workers: int | None = 1) -> dict[str, str | None]:
    """Which methods run here: name -> None when available, else the reason.

    With ``probe`` each importable method is run for two steps of a one-link arm, so one that
    still raises ``NotImplementedError`` (or fails outright) is reported with the reason. The
    first probe of a compiled engine compiles it (minutes on a fresh checkout) and fills its
    on-disk cache, which later runs load from.

    ``workers`` > 1 (None: this machine's cores) probes the engines in that many processes at
    once: methods of one module go to one process, in order, so no engine is compiled twice;
    the modules that take longest to compile go first (the DT-TMM kernel, then the global
    solver and the assumed-modes engine).
    """

    wanted = list(names() if methods is None else methods)
    groups: dict[str, list[str]] = {}
    for name in wanted:
        m = _EXTRA.get(name) or METHODS.get(name)
        groups.setdefault(m.module if m is not None and m.module else name, []).append(name)
    n_proc = min(len(groups), os.cpu_count() or 1) if workers is None else min(len(groups), workers)
    pool = _fork_pool(n_proc) if probe and n_proc > 1 else None
    if pool is None:
        reasons = _probe_group(wanted, probe)
        return dict(zip(wanted, reasons, strict=True))
    # the compiled spatial kernel too, in a process of its own, so the sweep's workers load it
    warm = [n for n in wanted if (m := _EXTRA.get(n) or METHODS.get(n)) and m.spatial == _DTTMM_SPATIAL][:1]
    first = ("dttmm", _WARM_SPATIAL, "reference_models.global_newmark", "reference_models.assumed_modes")
    order = sorted(
        [*groups, *([_WARM_SPATIAL] if warm else [])], key=lambda g: first.index(g) if g in first else 9
    )
    with pool:
        futures = {
            g: pool.submit(_warm_spatial, warm)
            if g == _WARM_SPATIAL
            else pool.submit(_probe_group, groups[g], probe)
            for g in order
        }
        by_name = {}
        for g, f in futures.items():  # every job, the warm-up too, ends before the sweep starts
            reasons = f.result()
            if g != _WARM_SPATIAL:
                by_name.update(zip(groups[g], reasons, strict=True))
    return {n: by_name[n] for n in wanted}
