"""What every study needs: the plan's cases, their reference solutions and the run store."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from .plan import Plan, load_cases
from .references import reference
from .runs import RunStore

__all__ = ["Context", "prepare"]


@dataclass
class Context:
    """plan; cases (name -> Case); references (name -> (Result or None, id)); provenance
    (name -> the reference's JSON provenance); store (RunStore); data (root folder)."""

    plan: Plan
    cases: dict
    references: dict
    provenance: dict
    store: RunStore
    data: Path


def prepare(plan: Plan, data="data", *, case_dir=None, recompute=False, log=print) -> Context:
    """Load the cases and compute (or load) their references.

    References go to ``<data>/references/<plan>/`` (small, worth keeping), run histories to
    ``<data>/cache/runs/<plan>_dt<output step>/`` (recomputable). Both are keyed by the cases'
    content and the code of the methods, and verified on read. ``recompute`` ignores every
    stored reference and run and writes them again.
    """
    data = Path(data)
    cases = load_cases(plan) if case_dir is None else load_cases(plan, case_dir)
    refs, prov = {}, {}
    for name, case in cases.items():
        res, p = reference(
            case,
            plan.reference[name],
            data / "references" / plan.name,
            check=plan.check.get(name, ()),
            size=plan.name,
            recompute=recompute,
        )
        refs[name], prov[name] = (res, p.get("id", "")), p
        if log:
            log(
                f"reference {name}: "
                + (
                    f"{p['method']} k={p['k']} h={p['h']:g}"
                    if res is not None
                    else "none (" + "; ".join(p["failures"]) + ")"
                )
            )
    grid = "_".join(sorted({f"dt{c.scenario.output_step:g}" for c in cases.values()}))
    store = RunStore(data / "cache" / "runs" / f"{plan.name}_{grid}", cases, recompute=recompute)
    return Context(plan, cases, refs, prov, store, data)
