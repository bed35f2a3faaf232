"""CPU time against the number of elements per link, with fitted exponents (t ∝ k^p).

Every run is timed with :data:`REPEATS` calls (see :mod:`experiments.timing`): the figure and the
exponents use the least CPU time of the calls (``cpu_time``), the median is kept beside it, and
runs measured under load or with a wide spread are marked ``noisy``.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..fit import slope
from ..runs import Task
from ..timing import COST_REPEATS
from ._common import k_limit, params, study_methods, with_task_columns

NAME = "cost"
REPEATS = COST_REPEATS  # timed calls per run (the sweep gives every run of this study that many)


def tasks(ctx) -> list[Task]:
    """Each method at every k of the plan, one case, one step."""
    p = params(ctx, NAME)
    T = ctx.cases[p.case].scenario.duration
    return [
        Task(p.case, m, k, p.h, T)
        for m in study_methods(ctx, NAME, flexible=True)
        for k in p.ks
        if k <= k_limit(m, NAME, ctx.plan.name)  # e.g. the global solver's cost grows fastest
    ]


def timing_columns(table: pd.DataFrame) -> pd.DataFrame:
    """The run table with ``cpu_time``/``cpu_time_median`` (s, whole call), ``wall_time_min``
    (s, least wall time of the whole call over the repeats), ``repeats`` and ``noisy``; runs
    stored without a timing fall back to their wall time, marked noisy.

    ``wall_time_min`` is the wall time to quote: the ``wall_time`` column is the first call's
    solve-only time alone, which includes one-off costs (JIT compilation in a fresh worker) and
    whatever else ran on the machine at that moment."""
    t = table.copy()
    has = "timing_cpu_min" in t
    t["cpu_time"] = t["timing_cpu_min"].astype(float) if has else np.nan
    t["wall_time_min"] = t["timing_wall_min"].astype(float) if has else np.nan
    t["cpu_time_median"] = t["timing_cpu_median"].astype(float) if has else np.nan
    t["repeats"] = t["timing_repeats"].fillna(0).astype(int) if has else 0
    t["noisy"] = t["timing_noisy"].fillna(True).astype(bool) if has else True
    t["noise"] = t["timing_noise"].fillna("not timed with repeats") if has else "not timed with repeats"
    old = ~np.isfinite(t["cpu_time"])
    t.loc[old, "cpu_time"] = t.loc[old, "wall_time"]
    untimed = ~np.isfinite(t["wall_time_min"])
    t.loc[untimed, "wall_time_min"] = t.loc[untimed, "wall_time"]
    t.loc[old, "noise"] = "not timed with repeats (one wall time)"
    t.loc[old, "noisy"] = True
    return t


def analyse(ctx, table):
    """Tables: runs with ``cpu_time`` (s, least of the repeats) and ``time_per_step`` (s), and
    the exponent p of CPU time ∝ k^p per method, fitted over k ≥ 2 (k = 1 is dominated by
    fixed costs), with the number of noisy points in the fit."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_exponents": table}
    table = timing_columns(table)
    table["time_per_step"] = table["cpu_time"] / table["n_steps"].where(table["n_steps"] > 0)
    rows = []
    for m, g in table.groupby("method"):
        g = g[(g.status == "ok") & (g.k >= 2)]
        p, n = slope(g.k, g.cpu_time)
        rows.append(
            {
                "method": m,
                "exponent": p,
                "n_points": n,
                "noisy_points": int(g.noisy.sum()),
                "k_max": int(g.k.max()) if n else np.nan,
                "cpu_time_at_k_max": float(g.loc[g.k.idxmax(), "cpu_time"]) if n else np.nan,
            }
        )
    return {NAME: table, f"{NAME}_exponents": pd.DataFrame(rows)}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
