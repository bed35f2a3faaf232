"""Study sizes: which cases, durations, references and (method, k, h) grids each study uses.

``PLANS["quick"]`` is what ``make report`` runs (under ten minutes on two cores: shortened
durations, cheaper references); ``PLANS["full"]`` the paper-size studies. Tests build their
own tiny :class:`Plan`.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from .references import RefSpec

__all__ = ["Plan", "PLANS", "CASE_DIR", "load_cases"]

CASE_DIR = Path(__file__).resolve().parent / "cases"


@dataclass(frozen=True)
class Plan:
    """Everything that sizes a report.

    durations : case name -> simulated duration (s); None keeps the TOML value
    reference, check : case name -> RefSpec candidates (reference) / cross-check methods
    studies : study name -> its parameters (see each study module's ``tasks``)
    output_step : common output grid (s) of every run, or None to keep each TOML's value. The
        Exudyn adapters sample on their step grid, so it must be a multiple of every h studied.
    """

    name: str
    durations: dict
    reference: dict
    check: dict
    studies: dict = field(default_factory=dict)
    note: str = ""
    output_step: float | None = None

    def with_studies(self, **studies) -> "Plan":
        return replace(self, studies={**self.studies, **studies})


def load_cases(plan: Plan, case_dir=CASE_DIR) -> dict:
    """Case name -> dttmm.Case, each shortened to the plan's duration (dataclasses.replace)."""
    import dttmm

    out = {}
    for name, duration in plan.durations.items():
        case = dttmm.load_case(Path(case_dir) / f"{name}.toml")
        changes = {}
        if duration is not None and duration != case.scenario.duration:
            changes["duration"] = float(duration)
        if plan.output_step is not None and plan.output_step != case.scenario.output_step:
            changes["output_step"] = float(plan.output_step)
        if changes:
            case = replace(case, scenario=replace(case.scenario, **changes))
        out[name] = case
    return out


_FLEX = ["dttmm", "dttmm-2nd", "global", "exudyn-ancf", "exudyn-beam"]
_ALL = ["dttmm", "dttmm-2nd", "dttmm-rk4", "global", "exudyn-ancf", "exudyn-beam", "pinocchio-rigid"]
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


def _refs(k, h, check):
    ref = [RefSpec("exudyn-ancf", k, h), RefSpec("dttmm", k, h), RefSpec("global", k, h)]
    return ref, [RefSpec(m, kc, hc) for m, kc, hc in check]


def _plan(
    name,
    durations,
    ref_kh,
    check,
    ks,
    hs,
    k_h,
    path,
    rk4_h,
    cost_ks,
    scheme_ks,
    note,
    variants,
    cost_cap=None,
):
    ref, chk = _refs(*ref_kh, check)
    cases = list(durations)
    return Plan(
        name,
        durations,
        dict.fromkeys(cases, ref),
        dict.fromkeys(cases, chk),
        {
            "convergence_k": {"cases": cases, "methods": _FLEX, "ks": ks, "h": 1e-3},
            "convergence_h": {
                "cases": cases,
                "methods": ["dttmm", "global", "exudyn-ancf"],
                "hs": hs,
                "k": k_h,
                "hs_by_method": {"dttmm-rk4": rk4_h},
            },
            "work_precision": {
                "cases": cases,
                "methods": _FLEX + ["global-2nd"],  # like-for-like partner of dttmm-2nd
                "path": path,
                "rigid": {"method": "pinocchio-rigid", "h": [1e-3]},
            },
            "scheme": {"cases": cases, "variants": variants, "ks": scheme_ks, "h": 1e-3, "hs": hs, "k": k_h},
            "paper": {
                "cases": cases,
                "methods": _ALL,
                "k": 8,
                "h": 1e-3,
                "h_by_method": {"dttmm-rk4": rk4_h[-1]},
            },
            "cost": {"case": cases[-1], "methods": _FLEX, "ks": cost_ks, "h": 1e-3, "max_k": cost_cap or {}},
        },
        note,
        output_step=max(max(hs), max(h for _, h in path)),
    )


PLANS = {
    "quick": _plan(
        "quick",
        durations={"single_link": None, "three_link": None},
        ref_kh=(32, 2.5e-4),
        check=[("dttmm", 32, 2.5e-4), ("exudyn-beam", 64, 2.5e-4)],
        ks=[1, 2, 4, 8, 16],
        hs=[4e-3, 2e-3, 1e-3, 5e-4],
        k_h=4,
        path=[(2, 4e-3), (4, 2e-3), (8, 1e-3), (16, 5e-4)],
        rk4_h=[1e-4, 2e-5, 1e-5, 5e-6],
        cost_ks=[1, 2, 4, 8, 16, 32],
        scheme_ks=[1, 2, 4, 8, 16],
        note="quick size: the cases as written (2 s); references at h = 2.5e-4 instead of 1e-4; "
        "h down to 5e-4 and k up to 16 (32 for cost); errors on a 4 ms output grid "
        "(a multiple of every step studied); the global solver's cost curve stops at k = 16.",
        variants=_VARIANTS_QUICK,
        cost_cap={"global": 16},
    ),
    "full": _plan(
        "full",
        durations={"single_link": None, "three_link": None},
        ref_kh=(32, 1e-4),
        check=[("dttmm", 32, 1e-4), ("exudyn-beam", 64, 1e-4)],
        ks=[1, 2, 4, 8, 16, 32],
        hs=[4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4],
        k_h=8,
        path=[(2, 4e-3), (4, 2e-3), (8, 1e-3), (16, 5e-4), (32, 2.5e-4)],
        rk4_h=[1e-4, 2e-5, 1e-5, 5e-6, 2.5e-6],
        cost_ks=[1, 2, 4, 8, 16, 32, 64],
        scheme_ks=[1, 2, 4, 8, 16, 32],
        note="full size: the cases as written, errors on a 4 ms output grid.",
        variants=_VARIANTS_FULL,
    ),
}
