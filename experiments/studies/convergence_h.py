"""Convergence in the step h at a fixed number of elements per link k.

Errors are taken against the case's reference (which also carries the spatial error of k)
and, to isolate the time error, against the same method at the next finer h
("self-differences"); observed orders are fitted to both.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from .. import methods, metrics
from ..runs import Task, task_from_row
from ._common import MAIN_ERROR, fit_orders, params, study_methods, with_task_columns

NAME = "convergence_h"


def tasks(ctx) -> list[Task]:
    """One run per (case, method, h) at the plan's k; some methods have their own h list."""
    p = params(ctx, NAME)
    out = []
    for c in p.cases:
        T = ctx.cases[c].scenario.duration
        for m in study_methods(ctx, NAME, flexible=True):
            hs = p.explicit_hs if methods.get(m).explicit and p.explicit_hs is not None else p.hs
            out += [Task(c, m, p.k, h, T) for h in hs]
    return out


def _self_differences(ctx, table: pd.DataFrame) -> pd.Series:
    """ee_l2 difference of each run to the run of the same method at the next finer h."""
    out = pd.Series(np.nan, index=table.index)
    for _, g in table.groupby(["case", "method", "k", "options"]):
        g = g.sort_values("h")
        for fine, coarse in zip(g.index[:-1], g.index[1:]):
            a, b = (ctx.store.history(task_from_row(table.loc[i])) for i in (coarse, fine))
            if (
                a is None
                or b is None
                or "ok" != table.loc[coarse, "status"]
                or "ok" != table.loc[fine, "status"]
            ):
                continue
            out[coarse] = metrics.errors(a, b)[MAIN_ERROR]
    return out


def analyse(ctx, table):
    """Tables: runs (with ``selfdiff_ee_l2``) and orders fitted against the reference and the
    self-differences."""
    table = with_task_columns(table)
    if table.empty:
        return {NAME: table, f"{NAME}_orders": table}
    table["selfdiff_ee_l2"] = _self_differences(ctx, table)
    by = ["case", "method"]
    orders = pd.concat(
        [
            fit_orders(table, "h", MAIN_ERROR, by, refine_descending=True),
            fit_orders(table, "h", "selfdiff_ee_l2", by, refine_descending=True),
        ],
        ignore_index=True,
    )
    return {NAME: table, f"{NAME}_orders": orders}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
