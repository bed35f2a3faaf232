"""CPU time against the number of elements per link, with fitted exponents (t ∝ k^p)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..fit import slope
from ..runs import Task
from ._common import with_task_columns

NAME = "cost"


def tasks(ctx) -> list[Task]:
    """Each method at every k of the plan, one case, one step."""
    p = ctx.plan.studies[NAME]
    T = ctx.cases[p["case"]].scenario.duration
    cap = p.get("max_k", {})  # per-method largest k (the global solver's cost grows fastest)
    return [Task(p["case"], m, k, p["h"], T) for m in p["methods"] for k in p["ks"] if k <= cap.get(m, k)]


def analyse(ctx, table):
    """Tables: runs with ``time_per_step`` (s), and the exponent p of wall time ∝ k^p per
    method, fitted over k ≥ 2 (k = 1 is dominated by fixed costs)."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_exponents": table}
    table["time_per_step"] = table["wall_time"] / table["n_steps"].where(table["n_steps"] > 0)
    rows = []
    for m, g in table.groupby("method"):
        g = g[(g.status == "ok") & (g.k >= 2)]
        p, n = slope(g.k, g.wall_time)
        rows.append(
            {
                "method": m,
                "exponent": p,
                "n_points": n,
                "k_max": int(g.k.max()) if n else np.nan,
                "wall_time_at_k_max": float(g.loc[g.k.idxmax(), "wall_time"]) if n else np.nan,
            }
        )
    return {NAME: table, f"{NAME}_exponents": pd.DataFrame(rows)}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
