"""Work-precision: error against CPU time, one curve per method (lower-left is better).

Each method is refined along a diagonal path of (k, h) pairs; the rigid baseline is a point
(or a few steps) whose error is the floor of ignoring flexibility. Every run is timed with
:data:`REPEATS` calls (least CPU time used, see :mod:`experiments.timing`). Costs at equal
accuracy are read off each method's lower envelope (:func:`cost_at`), and ratios are formed
only between methods of the same strain physics (each method's registry record, ``physics.strain``;
its DT-TMM partner is ``methods.base_of``).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .. import methods
from ..runs import Task
from ..timing import COST_REPEATS
from ._common import MAIN_ERROR, k_limit, params, step_for, study_methods, with_task_columns
from .cost import timing_columns

NAME = "work_precision"
REPEATS = COST_REPEATS
TARGETS = (1e-3, 1e-4, 1e-5)  # end-effector RMS accuracies (m) at which costs are compared


def tasks(ctx) -> list[Task]:
    """Each flexible method along the (k, h) path (an explicit one at its record's ``max_step`` at
    each k), plus every rigid method at the plan's ``rigid_h`` steps."""
    p = params(ctx, NAME)
    out = []
    flex = study_methods(ctx, NAME, flexible=True)
    rigid = study_methods(ctx, NAME, flexible=False)
    for c in p.cases:
        T = ctx.cases[c].scenario.duration
        for m in flex:
            out += [
                Task(c, m, k, step_for(m, k, h, ctx.cases[c]), T, methods.get(m).options_for(NAME))
                for k, h in p.path
                if k <= k_limit(m, NAME, ctx.plan.name)
            ]
        out += [Task(c, m, 0, h, T) for m in rigid for h in p.rigid_h]
    return out


def _converges(name: str) -> bool:
    """Whether the method is a DT-TMM or reference method (registry role), or unregistered."""
    try:
        return methods.get(name).role in ("subject", "reference")
    except methods.MethodUnavailable:
        return True


def _strain(name: str) -> str:
    """The method's strain class (its registry record), 'unknown' for an unregistered name."""
    try:
        return methods.get(name).physics.strain
    except methods.MethodUnavailable:
        return "unknown"


def envelope(cost, error) -> list[tuple[float, float]]:
    """Lower envelope of (error, cost) points: the cheapest run reaching each error, as
    (error, cost) pairs with error decreasing and cost increasing."""
    pts = sorted((c, e) for c, e in zip(cost, error) if np.isfinite(c) and np.isfinite(e) and e > 0 and c > 0)
    out, best = [], math.inf
    for c, e in pts:
        if e < best:
            out.append((e, c))
            best = e
    return out


def cost_at(env, target: float) -> float:
    """Cost to reach ``target`` on an envelope: log-log interpolation between the last point
    above and the first at or below it; NaN when the envelope never reaches it."""
    for i, (err, c) in enumerate(env):
        if err <= target:
            if i == 0:
                return c
            e0, c0 = env[i - 1]
            w = math.log(target / e0) / math.log(err / e0)
            return math.exp(math.log(c0) + w * (math.log(c) - math.log(c0)))
    return math.nan


def equal_accuracy(table: pd.DataFrame, targets=TARGETS) -> pd.DataFrame:
    """Per (case, target, method): CPU time to reach the target and its ratio to the DT-TMM
    method of the same physics (``ratio``: > 1 means DT-TMM is faster; NaN when either did
    not reach the target or the method has no like-for-like DT-TMM run)."""
    rows = []
    flex = table[(table.k > 0) & (table.status == "ok")]
    for case, g in flex.groupby("case", sort=False):
        cost = {
            m: [cost_at(envelope(gm.cpu_time, gm[MAIN_ERROR]), t) for t in targets]
            for m, gm in g.groupby("method", sort=False)
        }
        for i, t in enumerate(targets):
            for m, c in cost.items():
                phys = _strain(m)
                base = methods.base_of(m) or (m if _strain(m) != "unknown" else "")
                b = cost.get(base, [math.nan] * len(targets))[i] if base else math.nan
                rows.append(
                    {
                        "case": case,
                        "target_error": t,
                        "method": m,
                        "physics": phys,
                        "cpu_time": c[i],
                        "against": base if base in cost else "",
                        "ratio": c[i] / b if base in cost and m != base else math.nan,
                    }
                )
    cols = ["case", "target_error", "method", "physics", "cpu_time", "against", "ratio"]
    return pd.DataFrame(rows, columns=cols)


def analyse(ctx, table):
    """Tables: the runs (with ``cpu_time``), per (case, method) the best error and the CPU and
    wall time that took and to reach the common target (the worst of the best errors of the DT-TMM and reference methods; both
    times the least over the repeats of the whole call), and the like-for-like equal-accuracy
    costs at :data:`TARGETS`."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_summary": table, f"{NAME}_equal_accuracy": equal_accuracy(table)}
    table = timing_columns(table)
    rows = []
    ok = table[np.isfinite(table[MAIN_ERROR])]
    flex = ok[ok["k"] > 0]
    for case, g in ok.groupby("case"):
        best = flex[flex.case == case].groupby("method")[MAIN_ERROR].min()
        # the common error: the worst of the best errors of the methods that converge to the
        # reference by construction (DT-TMM and the reference methods); a peer or a variant with a
        # model error above it is "not reached", which is the finding
        conv = best[[_converges(m) for m in best.index]]
        target = float((conv if len(conv) else best).max()) if len(best) else np.nan
        for method, gm in g.groupby("method"):
            i = gm[MAIN_ERROR].idxmin()
            reach = gm[gm[MAIN_ERROR] <= target * (1 + 1e-12)]
            rows.append(
                {
                    "case": case,
                    "method": method,
                    "best_error": gm.loc[i, MAIN_ERROR],
                    "cpu_time_at_best": gm.loc[i, "cpu_time"],
                    "wall_time_at_best": gm.loc[i, "wall_time_min"],
                    "target_error": target,
                    "cpu_time_to_target": float(reach.cpu_time.min()) if len(reach) else np.nan,
                    "wall_time_to_target": float(reach.wall_time_min.min()) if len(reach) else np.nan,
                }
            )
    return {
        NAME: table,
        f"{NAME}_summary": pd.DataFrame(rows),
        f"{NAME}_equal_accuracy": equal_accuracy(table),
    }


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
