"""CPU time against the number of elements per link, with fitted exponents (t ∝ k^p).

The study times a planar arm (the plan's ``case`` at its ``ks``) and, where the plan names one,
a spatial arm (``spatial_case`` at ``spatial_ks``); a method runs the cases it can
(``Method.runs_on``, applied by :func:`experiments.study.run_studies`: on a spatial arm the
methods with a spatial engine, up to their ``spatial_max_k``). Exponents are fitted per case
and method.

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
    """Each flexible method at every k of each case of the plan (planar, then spatial), one step."""
    p = params(ctx, NAME)
    ms = study_methods(ctx, NAME, flexible=True)
    return [
        Task(c, m, k, p.h, ctx.cases[c].scenario.duration)
        for c, ks in p.case_ks()
        for m in ms
        for k in ks
        if k <= k_limit(m, NAME, ctx.plan.name)  # e.g. the global solver's cost grows fastest
    ]


def spatial_cases(table: pd.DataFrame) -> set[str]:
    """The cases of a run table that are spatial arms: one of their runs returned a spatial
    result (column ``space``)."""
    if table is None or not len(table) or "space" not in table:
        return set()
    return set(table.case[table.space == "spatial"])


def case_order(table: pd.DataFrame) -> list[str]:
    """The cases of a run table, planar arms first, then spatial ones (:func:`spatial_cases`),
    each group by name."""
    if table is None or not len(table) or "case" not in table:
        return []
    spatial, cases = spatial_cases(table), sorted(set(table.case))
    return [c for c in cases if c not in spatial] + [c for c in cases if c in spatial]


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
    the exponent p of CPU time ∝ k^p per case and method (cases in :func:`case_order`), fitted
    over k ≥ 2 (k = 1 is dominated by fixed costs), with the number of noisy points in the fit."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_exponents": table}
    table = timing_columns(table)
    table["time_per_step"] = table["cpu_time"] / table["n_steps"].where(table["n_steps"] > 0)
    rows = []
    for c in case_order(table):
        rows += _exponents(c, table[table.case == c])
    return {NAME: table, f"{NAME}_exponents": pd.DataFrame(rows)}


def _exponents(case: str, table: pd.DataFrame) -> list[dict]:
    rows = []
    for m, g in table.groupby("method"):
        g = g[(g.status == "ok") & (g.k >= 2)]
        p, n = slope(g.k, g.cpu_time)
        rows.append(
            {
                "case": case,
                "method": m,
                "exponent": p,
                "n_points": n,
                "noisy_points": int(g.noisy.sum()),
                "k_max": int(g.k.max()) if n else np.nan,
                "cpu_time_at_k_max": float(g.loc[g.k.idxmax(), "cpu_time"]) if n else np.nan,
            }
        )
    return rows


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
