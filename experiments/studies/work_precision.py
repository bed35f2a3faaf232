"""Work-precision: error against wall time, one curve per method (lower-left is better).

Each method is refined along a diagonal path of (k, h) pairs; the rigid baseline is a point
(or a few steps) whose error is the floor of ignoring flexibility.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..runs import Task
from ._common import MAIN_ERROR, with_task_columns

NAME = "work_precision"


def tasks(ctx) -> list[Task]:
    """Each flexible method along the (k, h) path, plus the rigid baseline at its steps."""
    p = ctx.plan.studies[NAME]
    out = []
    for c in p["cases"]:
        T = ctx.cases[c].scenario.duration
        out += [Task(c, m, k, h, T) for m in p["methods"] for k, h in p["path"]]
        out += [Task(c, "mujoco-chain", k, h, T) for k, h in p.get("mujoco_path", ())]  # own (k, h) path
        rigid = p.get("rigid")
        if rigid:
            out += [Task(c, rigid["method"], 0, h, T) for h in rigid["h"]]
    return out


def analyse(ctx, table):
    """Tables: the runs, and per (case, method) the best error reached and the wall time
    that took, and the wall time to reach a common error target (the worst of the best)."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_summary": table}
    rows = []
    ok = table[np.isfinite(table[MAIN_ERROR])]
    flex = ok[ok["k"] > 0]
    for case, g in ok.groupby("case"):
        best = flex[flex.case == case].groupby("method")[MAIN_ERROR].min()
        target = float(best.max()) if len(best) else np.nan
        for method, gm in g.groupby("method"):
            i = gm[MAIN_ERROR].idxmin()
            reach = gm[gm[MAIN_ERROR] <= target * (1 + 1e-12)]["wall_time"]
            rows.append(
                {
                    "case": case,
                    "method": method,
                    "best_error": gm.loc[i, MAIN_ERROR],
                    "wall_time_at_best": gm.loc[i, "wall_time"],
                    "target_error": target,
                    "wall_time_to_target": float(reach.min()) if len(reach) else np.nan,
                }
            )
    return {NAME: table, f"{NAME}_summary": pd.DataFrame(rows)}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
