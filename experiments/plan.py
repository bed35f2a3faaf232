"""Study sizes: which cases, durations, references and (method, k, h) grids each study uses.

``PLANS["quick"]`` is what ``make report`` runs (under ten minutes on two cores: shortened
durations, cheaper references); ``PLANS["full"]`` the paper-size studies. ``plan_for(size,
case_files)`` gives the same sizes on any case files (``dttmm report --case PATH``). Tests build
their own tiny :class:`Plan`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass, field, replace
from pathlib import Path

from .params import (
    ControlModes,
    ControlParams,
    ConvergenceHParams,
    ConvergenceKParams,
    CostParams,
    PaperParams,
    ProblemsParams,
    SchemeParams,
    WorkPrecisionParams,
    study_params,
)
from .references import RefSpec

__all__ = ["CASE_DIR", "PLANS", "SHIPPED", "Plan", "case_fingerprint", "load_cases", "plan_for"]

CASE_DIR = Path(__file__).resolve().parent / "cases"
SHIPPED = ("single_link", "three_link", "spin_up")  # the cases of the default report, in order
#: the trees and closed loops of the default report (``CASE_DIR/spatial/topology``, docs/spatial.md §11)
TOPOLOGY_SHIPPED = ("four_bar", "five_bar", "branched_arm")
#: the spatial arms of the default report: the shipped arm (``CASE_DIR/spatial``), the robots
#: from their URDF (``CASE_DIR/spatial/robots``, docs/urdf.md) and the trees and loops
SPATIAL_SHIPPED = ("three_joint_arm", "ur5", "panda", *TOPOLOGY_SHIPPED)
#: the folder (under ``CASE_DIR``) of each shipped case outside it
_FOLDERS = {
    "three_joint_arm": "spatial",
    "ur5": "spatial/robots",
    "panda": "spatial/robots",
    **dict.fromkeys(TOPOLOGY_SHIPPED, "spatial/topology"),
}
QUICK_MAX_DURATION = 6.0  # s: the quick size shortens longer cases to this
#: s: the quick size runs the robots' first 0.1 s (the arm released under gravity rings, the move
#: starts); the spatial global solver costs 1.5 ms a step on them at k = 4, 5.7 ms at k = 16 (measured)
ROBOT_QUICK_DURATION = 0.1
#: s: the quick size runs the trees and loops' first 0.2 s (the four-bar's and the five-bar's
#: whole run: the crank's spin-up and 0.1 s at its rate, the five-bar's move; the branched arm
#: through its fingers' torque pulses into the arm's)
TOPOLOGY_QUICK_DURATION = 0.2


@dataclass(frozen=True)
class Plan:
    """Everything that sizes a report.

    durations : case name -> simulated duration (s); None keeps the TOML value
    reference, check : case name -> RefSpec candidates (reference) / cross-check methods
    studies : study name -> its parameter record (:mod:`experiments.params`; a dict of the
        record's fields is turned into the record here, an unknown name or bad value raises
        InputError)
    output_step : common output grid (s) of every run, or None to keep each TOML's value. The
        Exudyn adapters sample on their step grid, so it must be a multiple of every h studied.
    case_files : case name -> TOML path; a case not listed is read from ``CASE_DIR/<name>.toml``
        (the shipped spatial arms from their folders under it, ``_FOLDERS``)
    """

    name: str
    durations: dict
    reference: dict
    check: dict
    studies: dict = field(default_factory=dict)
    note: str = ""
    output_step: float | None = None
    case_files: dict = field(default_factory=dict)

    def __post_init__(self):
        object.__setattr__(self, "studies", {n: study_params(n, p) for n, p in self.studies.items()})


def case_fingerprint(case) -> str:
    """Eight hex digits that change with any parameter of the case (its TOML content).

    A case from outside the repository carries it in its name, so cached references and runs
    of an edited file are never mistaken for those of the earlier version.
    """
    from dttmm import case_to_dict

    d = case_to_dict(case)
    d.pop("name", None)
    return hashlib.sha256(json.dumps(d, sort_keys=True, default=str).encode()).hexdigest()[:8]


def _case_path(plan: Plan, name: str, case_dir) -> Path:
    if name in plan.case_files:
        return Path(plan.case_files[name])
    return Path(case_dir) / _FOLDERS.get(name, "") / f"{name}.toml"


def load_cases(plan: Plan, case_dir=CASE_DIR) -> dict:
    """Case name -> dttmm.Case, each shortened to the plan's duration (dataclasses.replace)."""
    import dttmm

    out = {}
    for name, duration in plan.durations.items():
        case = replace(dttmm.load_case(_case_path(plan, name, case_dir)), name=name)
        changes = {}
        if duration is not None and duration != case.scenario.duration:
            changes["duration"] = float(duration)
        if plan.output_step is not None and plan.output_step != case.scenario.output_step:
            changes["output_step"] = float(plan.output_step)
        if changes:
            case = replace(case, scenario=replace(case.scenario, **changes))
        out[name] = case
    return out


def plan_for(size: str, case_files=()) -> Plan:
    """The plan ``size`` ("quick" or "full") over the given case TOML files instead of the
    shipped cases (none given: ``PLANS[size]`` itself).

    A file inside ``CASE_DIR`` keeps its name; any other case is named ``<name>-<fingerprint>``
    (see :func:`case_fingerprint`). Durations are those of the files, except that the quick size
    shortens a case longer than ``QUICK_MAX_DURATION``. Raises InputError for a missing file or
    two files of the same name.
    """
    import dttmm
    from dttmm.errors import InputError

    from . import methods

    base = PLANS[size]
    if not case_files:
        return base
    files, durations, spatial = {}, {}, set()
    for p in map(Path, case_files):
        if not p.is_file():
            raise InputError("--case", str(p), "is not a file")
        try:
            case = dttmm.load_case(p)
        except InputError as exc:  # name the file as well as the field
            raise InputError(f"{p}: {exc.field}", exc.value, exc.reason) from None
        shipped = p.resolve().parent == CASE_DIR or p.resolve() == _case_path(base, p.stem, CASE_DIR)
        name = case.name if shipped else f"{case.name}-{case_fingerprint(case)}"
        if name in files:
            raise InputError("--case", str(p), f"names the same case as {files[name]} ({name})")
        files[name] = str(p.resolve())
        if methods.is_spatial(case):
            spatial.add(name)
        T = case.scenario.duration
        durations[name] = min(T, QUICK_MAX_DURATION) if size == "quick" and T > QUICK_MAX_DURATION else None
    return _retarget(base, files, durations, spatial)


def _durations_text(durations: dict) -> str:
    return ", ".join(
        f"{n}: {'as written' if T is None else f'its first {T:g} s'}" for n, T in durations.items()
    )


def _retarget(base: Plan, files: dict, durations: dict, spatial=frozenset()) -> Plan:
    """``base`` with every study and reference moved onto the cases ``files``; the cases named in
    ``spatial`` (spatial arms) get the references and cross-checks of the shipped spatial arm."""
    names = list(files)
    ref, chk = next(iter(base.reference.values())), next(iter(base.check.values()))
    arm = next((c for c in SPATIAL_SHIPPED if c in base.reference), None)
    sref, schk = (base.reference[arm], base.check[arm]) if arm else (ref, chk)
    studies = {}
    for s, p in base.studies.items():
        if hasattr(p, "cases"):
            p = replace(p, cases=names)
        if hasattr(p, "case"):  # the cost study times the last case given, alone
            p = replace(
                p,
                case=names[-1],
                **({"spatial_case": "", "spatial_ks": ()} if hasattr(p, "spatial_case") else {}),
            )
        studies[s] = p
    return replace(
        base,
        durations=durations,
        reference={n: sref if n in spatial else ref for n in names},
        check={n: schk if n in spatial else chk for n in names},
        studies=studies,
        case_files=files,
        note=f"{base.name} size on the cases given on the command line ({_durations_text(durations)}); "
        + _GRID_NOTE.get(base.name, ""),
    )


# The plain sweep with iterations=None spends up to max_iterations sweeps per step once it has
# lost its digits, so the quick size runs it with 0 and 1 corrections only.
_VARIANTS_QUICK = [
    {"sweep": "riccati", "iterations": None},
    {"sweep": "riccati", "iterations": 1},
    {"sweep": "riccati", "iterations": 0},
    {"sweep": "plain", "iterations": 1},
    {"sweep": "plain", "iterations": 0},
]
_VARIANTS_FULL = _VARIANTS_QUICK + [{"sweep": "plain", "iterations": None}]


def _refs(k, h):
    """Reference candidates and cross-checks at (k, h), in the registry's order."""
    from . import methods

    ref = [RefSpec(m, k, h) for m in methods.reference_candidates()]
    chk = [RefSpec(m, k * methods.get(m).check_refine, h) for m in methods.cross_checks()]
    return ref, chk


def _spatial_refs(k, h):
    """Reference candidates of a spatial arm: the registry's, those whose spatial runs record cut
    loads asked for them (the root bending moment the loads comparison needs)."""
    from . import methods

    return [
        RefSpec(m, k, h, (("cut_loads", True),) if methods.get(m).spatial_cut_loads else ())
        for m in methods.reference_candidates()
    ]


def _spatial_check(k, h):
    """Cross-checks of a spatial arm's reference: the registry's, at the reference's own k (the
    3-D geometrically exact beam at twice the k, 64 elements per link, fails Newton on
    three_joint_arm at h = 2.5e-4; at 32 it runs, measured)."""
    from . import methods

    return [RefSpec(m, k, h) for m in methods.cross_checks()]


def _plan(
    name,
    durations,
    ref_kh,
    ks,
    hs,
    k_h,
    path,
    rk4_h,
    cost_ks,
    scheme_ks,
    note,
    variants,
    bench,
    control,
    cost_case="three_link",
    cost_spatial_case="three_joint_arm",
    cost_spatial_ks=(),
):
    ref, chk = _refs(*ref_kh)
    cases = list(durations)
    planar = [c for c in cases if c not in SPATIAL_SHIPPED]  # the scheme variants are planar-kernel options
    return Plan(
        name,
        durations,
        {c: ref if c in planar else _spatial_refs(*ref_kh) for c in cases},
        {c: chk if c in planar else _spatial_check(*ref_kh) for c in cases},
        {
            # methods: every registered method that takes part (experiments/methods.py); explicit
            # methods use the explicit steps, or their record's max_step along the path
            "convergence_k": ConvergenceKParams(cases=cases, ks=ks, h=1e-3),
            "convergence_h": ConvergenceHParams(cases=cases, hs=hs, k=k_h, explicit_hs=rk4_h),
            "work_precision": WorkPrecisionParams(cases=cases, path=path, rigid_h=[1e-3]),
            "scheme": SchemeParams(cases=planar, variants=variants, ks=scheme_ks, h=1e-3, hs=hs, k=k_h),
            "paper": PaperParams(
                cases=cases,
                k=8,
                h=1e-3,
                explicit_h=rk4_h[-1],
                # Exudyn records no energy: the energy errors are taken against DT-TMM at the
                # reference's k and h (also the reference's cross-check)
                energy_reference={"k": ref_kh[0], "h": ref_kh[1]},
            ),
            # the spatial arm (when the plan has it) at convergence_k's h: its runs up to the
            # largest k of convergence_k are shared with that study, timed here with repeats
            "cost": CostParams(
                case=cost_case,
                ks=cost_ks,
                h=1e-3,
                **(
                    {"spatial_case": cost_spatial_case, "spatial_ks": cost_spatial_ks}
                    if cost_spatial_case in durations and cost_spatial_ks
                    else {}
                ),
            ),
            "benchmarks": bench,
            "control": control,
        },
        note,
        output_step=max(max(hs), max(h for _, h in path)),
    )


# Benchmark problems (study "benchmarks", experiments/studies/problems.py). Quick: spin-up runs end after the peak
# (8 s); methods that sit a size out say why in their registry record.
# the very flexible pendulum needs k = 64 (measured: 2nd-order element). The spatial problems
# (experiments/cases/spatial/): the quick size runs short ladders, about 16 s of CPU in all
# (measured: the Princeton sweep is 14 equilibria per k, 4 s at k = 4 for its three methods;
# the 45° bend's 8 links cost 4 s of statics at k = 1; the right-angle cantilever 8 s at k = 4
# and 8, most of it the ANCF cable; the bang-bang arm 3 s at k = 4 and 8, most of it Exudyn's
# beam), the full size the ladders to k = 32 (the bend to k = 8:
# 8 links of k elements each)
_KS_BY_PROBLEM = {"pendulum_berzeri": [2, 4, 8, 16, 32, 64]}
_SPATIAL_KS = {
    # Princeton at k = 8: at k = 4 the element's error reaches 2.2 % in |u_y| at large β (docs/spatial.md)
    "quick": {
        "princeton_beam": [8],
        "bend_45deg": [1],
        "right_angle_cantilever": [4, 8],
        "bang_bang_arm": [4, 8],
    },
    "full": {
        "princeton_beam": [2, 4, 8, 16, 32],
        "bend_45deg": [1, 2, 4, 8],
        "right_angle_cantilever": [2, 4, 8, 16, 32],
        "bang_bang_arm": [2, 4, 8, 16, 32],
    },
}
_BENCH = {
    "quick": ProblemsParams(
        ks=[2, 4, 8, 16, 32],
        durations=dict.fromkeys(["spin_up_w4", "spin_up_w6", "spin_up_w10"], 8.0),
        ks_by_problem={**_KS_BY_PROBLEM, **_SPATIAL_KS["quick"]},
    ),
    "full": ProblemsParams(ks=[2, 4, 8, 16, 32], ks_by_problem={**_KS_BY_PROBLEM, **_SPATIAL_KS["full"]}),
}

# Closed loop (experiments/studies/control.py) on its own case: every method that takes part at
# the report's k = 8, h = 1 ms (an explicit method at its record's max_step), the rigid baseline
# on the variant without moment feedback, a moment-gain sweep, references at k = 32, h = 2.5e-4.
_CONTROL = ControlParams(
    k=8,
    h=1e-3,
    rigid_h=1e-3,
    reference=(32, 2.5e-4),
    gains=[0.0, 0.5, 1.0, 2.0],
    # equal k for both: DT-TMM's frequencies agree with Exudyn's to 1e-7 at k = 16 (measured)
    modes=ControlModes(k=16, exudyn_k=16, n=4),
)
_CONTROL_SIZES = {"quick": _CONTROL, "full": replace(_CONTROL, modes=ControlModes(k=32, exudyn_k=32, n=4))}

_GRID_NOTE = {
    "quick": "references at h = 2.5e-4 instead of 1e-4; h down to 5e-4 and k up to 16 (32 for cost); errors "
    "on a 4 ms output grid (a multiple of every step studied); the global solver's cost curve stops at k = 16; "
    "the explicit MuJoCo chain follows the work-precision path to k = 16 only (its k = 32 points, 2.5 min of "
    "CPU with spin_up's 1.9 min, are in --full); RK4 steps down to h = 1e-5 (its h = 5e-6 points, 27 s of CPU, are "
    "in --full); runs of 2 s CPU or more are timed once.",
    "full": "errors on a 4 ms output grid.",
}

PLANS = {
    "quick": _plan(
        "quick",
        durations={
            "single_link": None,
            "three_link": None,
            "spin_up": QUICK_MAX_DURATION,
            "three_joint_arm": 0.6,
            "ur5": ROBOT_QUICK_DURATION,
            "panda": ROBOT_QUICK_DURATION,
            **dict.fromkeys(TOPOLOGY_SHIPPED, TOPOLOGY_QUICK_DURATION),
        },
        ref_kh=(32, 2.5e-4),
        ks=[1, 2, 4, 8, 16],
        hs=[4e-3, 2e-3, 1e-3, 5e-4],
        k_h=4,
        path=[(2, 4e-3), (4, 2e-3), (8, 1e-3), (16, 5e-4)],
        rk4_h=[1e-4, 2e-5, 1e-5],
        cost_ks=[1, 2, 4, 8, 16, 32],
        cost_spatial_ks=[1, 2, 4, 8, 16, 32],
        scheme_ks=[1, 2, 4, 8, 16],
        note="quick size: the cases as written (2 s), spin_up shortened to its first 6 s, the spatial "
        "three_joint_arm to its first 0.6 s (the torque pulses and 0.1 s of free motion), the robots ur5 and "
        f"panda to their first {ROBOT_QUICK_DURATION:g} s (released under gravity, the move starting), the trees "
        f"and loops four_bar, five_bar and branched_arm to their first {TOPOLOGY_QUICK_DURATION:g} s; "
        + _GRID_NOTE["quick"],
        variants=_VARIANTS_QUICK,
        bench=_BENCH["quick"],
        control=_CONTROL_SIZES["quick"],
    ),
    "full": _plan(
        "full",
        durations={
            "single_link": None,
            "three_link": None,
            "spin_up": None,
            "three_joint_arm": None,
            "ur5": None,
            "panda": None,
            **dict.fromkeys(TOPOLOGY_SHIPPED),
        },
        ref_kh=(32, 1e-4),
        ks=[1, 2, 4, 8, 16, 32],
        hs=[4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4],
        k_h=8,
        path=[(2, 4e-3), (4, 2e-3), (8, 1e-3), (16, 5e-4), (32, 2.5e-4)],
        rk4_h=[1e-4, 2e-5, 1e-5, 5e-6, 2.5e-6],
        cost_ks=[1, 2, 4, 8, 16, 32, 64],
        cost_spatial_ks=[1, 2, 4, 8, 16, 32, 64],
        scheme_ks=[1, 2, 4, 8, 16, 32],
        note="full size: the cases as written; " + _GRID_NOTE["full"],
        variants=_VARIANTS_FULL,
        bench=_BENCH["full"],
        control=_CONTROL_SIZES["full"],
    ),
}
