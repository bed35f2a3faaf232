"""Paper figures: time histories of the 1-DOF arm (hub angle, tip deflection) and of the
3-DOF arm (joint angles, tip deflections) for every method, with the reference."""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..runs import Task, task_from_row
from ._common import MAIN_ERROR, tip_col, with_task_columns

NAME = "paper"
MAX_POINTS = 1000  # time samples kept per curve in the stored series


def tasks(ctx) -> list[Task]:
    """Every method at the plan's k and h (or its own h) on every case."""
    p = ctx.plan.studies[NAME]
    hb = p.get("h_by_method", {})
    return [
        Task(c, m, p["k"], hb.get(m, p["h"]), ctx.cases[c].scenario.duration)
        for c in p["cases"]
        for m in p["methods"]
    ]


def _series(res, case, label) -> pd.DataFrame:
    df = res.to_frame()
    keep = ["t"] + [c for c in df.columns if c.startswith(("joint_angle_", "tip_deflection_"))]
    step = max(1, len(df) // MAX_POINTS)
    return df[keep].iloc[::step].assign(case=case, method=label)


def analyse(ctx, table):
    """Tables: the runs, a summary per (case, method) (peak tip deflection, error against the
    reference) and ``paper_series``: the sampled time histories, the reference included."""
    table = with_task_columns(table)
    series, rows = [], []
    for case in ctx.plan.studies[NAME]["cases"]:
        ref = ctx.references.get(case, (None, ""))[0]
        if ref is not None:
            series.append(_series(ref, case, "reference"))
            rows.append(
                {
                    "case": case,
                    "method": "reference",
                    "status": "ok",
                    "reason": "",
                    "peak_tip": float(np.max(np.abs(ref.tip_deflection[:, -1]))),
                    MAIN_ERROR: 0.0,
                }
            )
        for _, r in table[table.case == case].iterrows():
            res = ctx.store.history(task_from_row(r)) if r.status == "ok" else None
            if res is not None:
                series.append(_series(res, case, r.method))
            n = int(r.n_joints)
            rows.append(
                {
                    "case": case,
                    "method": r.method,
                    "status": r.status,
                    "reason": r.reason,
                    "k": r.k,
                    "h": r.h,
                    "peak_tip": float(np.max(np.abs(res.tip_deflection[:, -1])))
                    if res is not None
                    else np.nan,
                    MAIN_ERROR: r[MAIN_ERROR],
                    tip_col(n): r[tip_col(n)],
                }
            )
    s = pd.concat(series, ignore_index=True) if series else pd.DataFrame(columns=["t", "case", "method"])
    return {NAME: table, f"{NAME}_summary": pd.DataFrame(rows), f"{NAME}_series": s}


if __name__ == "__main__":  # python -m experiments.studies.<name> [--quick|--full] ...
    from experiments.study import study_main

    raise SystemExit(study_main(NAME))
