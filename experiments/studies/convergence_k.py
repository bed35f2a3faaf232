"""Convergence in the number of elements per link k at a fixed step h."""

from __future__ import annotations

from ..runs import Task
from ._common import MAIN_ERROR, fit_orders, k_limit, params, study_methods, with_task_columns

NAME = "convergence_k"


def tasks(ctx) -> list[Task]:
    """One run per (case, method, k) at the plan's h."""
    p = params(ctx, NAME)
    return [
        Task(c, m, k, p.h, ctx.cases[c].scenario.duration)
        for c in p.cases
        for m in study_methods(ctx, NAME, flexible=True)
        for k in p.ks
        if k <= k_limit(m, NAME, ctx.plan.name)
    ]


def analyse(ctx, table):
    """Tables: the runs, and the observed order in k of the end-effector error per method."""
    table = with_task_columns(table)
    orders = fit_orders(table, "k", MAIN_ERROR, ["case", "method"], refine_descending=False)
    return {NAME: table, f"{NAME}_orders": orders}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
