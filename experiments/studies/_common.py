"""Helpers shared by the study modules."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..fit import decreasing_prefix, slope

MAIN_ERROR = "ee_l2"  # end-effector position, RMS over time (m): the headline error of every study


def tip_col(n_joints: int, kind: str = "l2") -> str:
    """Error column of the last link's tip deflection."""
    return f"tip{n_joints}_{kind}"


def fit_orders(table: pd.DataFrame, x: str, y: str, by: list, *, refine_descending: bool) -> pd.DataFrame:
    """Observed order per group: slope of log y against log x over the points before the
    error floor (see fit.decreasing_prefix). ``refine_descending``: True when refining means
    a smaller x (h), False when a larger x (k). The order is reported positive for convergence."""
    rows = []
    if table.empty:
        return pd.DataFrame(columns=[*by, "order", "n_points", "x_min", "x_max", "quantity"])
    for key, g in table.groupby(by, dropna=False, sort=False):
        g = g.sort_values(x, ascending=not refine_descending)
        if "status" in g:
            g = g.assign(**{y: g[y].where(g.status == "ok")})
        m = decreasing_prefix(g[x], g[y])
        s, n = slope(g[x][m], g[y][m])
        order = s if refine_descending else -s
        xs = g[x][m]
        rows.append(
            {
                **dict(zip(by, key if isinstance(key, tuple) else (key,))),
                "quantity": y,
                "order": order,
                "n_points": n,
                "x_min": float(xs.min()) if n else np.nan,
                "x_max": float(xs.max()) if n else np.nan,
            }
        )
    return pd.DataFrame(rows)


def params(ctx, study: str):
    """The plan's parameter record of ``study`` (:mod:`experiments.params`; a plan written as
    plain dicts, as tests do, gets its record built here)."""
    from ..params import study_params

    return study_params(study, ctx.plan.studies[study])


def with_task_columns(table: pd.DataFrame) -> pd.DataFrame:
    """The run table with a stable column order and sorted rows."""
    if table.empty:
        return table
    return table.sort_values(["case", "method", "options", "k", "h"]).reset_index(drop=True)


def study_methods(ctx, study: str, **filters) -> list[str]:
    """The methods a study runs: the plan's ``methods`` when it names some (tests), else every
    registered method that takes part (``experiments.methods.takes_part``, at the plan's size)."""
    from .. import methods

    chosen = params(ctx, study).methods
    if chosen is None:
        return methods.takes_part(study, size=ctx.plan.name, **filters)
    flexible = filters.get("flexible")
    return [m for m in chosen if flexible is None or methods.uses_k(m) == flexible]


def step_for(method: str, k: int, h: float, case=None) -> float:
    """The step a method runs at in place of ``h``: at most its record's ``max_step(k)``
    (``spatial_max_step(k)`` on a spatial ``case``, where the record has one)."""
    from .. import methods

    try:
        rec = methods.get(method)
    except methods.MethodUnavailable:
        return h
    rule = methods.step_rule(rec, case)
    return min(h, rule(k)) if rule is not None else h


def k_limit(method: str, study: str, size: str) -> float:
    """Largest k a method runs in ``study`` at the plan ``size`` (inf: no limit)."""
    from .. import methods

    try:
        return methods.get(method).k_limit(study, size)
    except methods.MethodUnavailable:
        return float("inf")
