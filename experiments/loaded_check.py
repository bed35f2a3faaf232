"""Do the report's timing headlines survive a loaded machine? Run them twice and compare.

``python -m experiments.loaded_check [--burner | --no-burner] [--runs N] [--out DIR] [--tag NAME]``

Builds the quick plan (:func:`experiments.plan.plan_for`), keeps only the studies whose
headlines are timings (``work_precision`` and ``cost``) on ``three_link``, and runs them
``--runs`` times (default 2) through the report's own runner
(:func:`experiments.study.run_studies`, a LocalCluster as ``dttmm report`` uses), each time
into a fresh run store so that every run is computed again. With ``--burner`` one CPU-bound
process (``while True: pass``) runs beside each sweep. The cached reference of the quick
plan is reused (it is an accuracy reference, not a timing).

Headlines compared between the runs:

- ``equal_accuracy``: the work-precision ratios at equal end-effector accuracy (CPU time of
  each method over the DT-TMM method of the same element strain, at 1e-3, 1e-4, 1e-5 m);
- ``to_target_cpu`` / ``to_target_wall``: each method's CPU time (the scoreboard's "CPU time
  to target") and wall time to reach the common error of the work-precision study, as a ratio
  to DT-TMM's (linear element);
- ``cost_ratio``: CPU time over DT-TMM's at equal k and h (cost study, every common k);
- ``cost_exponent``: the fitted exponent p of CPU time ∝ k^p.

Writes ``<out>/<tag>.csv`` (one row per headline and run) and ``<out>/<tag>.md`` (side by side,
with the relative difference ``max/min - 1`` of the ratios and the loads).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from .timing import load_average

__all__ = ["compare", "headlines", "main", "reanalyse", "reduced_plan", "run_once"]

CASE = "three_link"
STUDIES = ("work_precision", "cost")
BASE = "dttmm"  # the denominator of the to-target and equal-size ratios (linear element)


def reduced_plan(size: str = "quick"):
    """The ``size`` plan with only the timing studies, on :data:`CASE` alone."""
    from .plan import plan_for

    base = plan_for(size)
    studies = {}
    for name in STUDIES:
        p = base.studies[name]
        if hasattr(p, "cases"):
            p = replace(p, cases=[CASE])
        if hasattr(p, "case"):  # the cost study on CASE alone (no spatial arm)
            p = replace(p, case=CASE, spatial_case="", spatial_ks=())
        studies[name] = p
    return replace(
        base,
        durations={CASE: base.durations[CASE]},
        reference={CASE: base.reference[CASE]},
        check={CASE: base.check[CASE]},
        studies=studies,
        note=base.note + f" Timing studies only ({', '.join(STUDIES)}) on {CASE}.",
    )


def _burner():
    """One CPU-bound Python process (the caller terminates it)."""
    return subprocess.Popen([sys.executable, "-c", "while True: pass"])


def run_once(ctx, folder: Path, *, burner: bool, scheduler=None, workers=None) -> dict:
    """Run the timing studies into a fresh store under ``folder``; return tables and loads."""
    from .runs import RunStore
    from .study import run_studies, save_tables

    ctx.store = RunStore(folder / "cache", ctx.cases, recompute=True)
    proc = _burner() if burner else None
    t0, load0 = time.perf_counter(), load_average()
    try:
        tables = run_studies(ctx, list(STUDIES), scheduler=scheduler, workers=workers, progress=False)
    finally:
        if proc is not None:
            proc.terminate()
            proc.wait()
    info = {
        "wall_s": time.perf_counter() - t0,
        "load_start": load0,
        "load_end": load_average(),
        "burner": burner,
    }
    save_tables(tables, folder / "data")
    (folder / "info.json").write_text(json.dumps(info))
    return {"tables": tables, "info": info}


def reanalyse(folder: Path) -> dict:
    """Tables and loads of a stored run (``run_once``'s folder), the studies' analysis applied
    again to the stored run rows with the current code."""
    from .studies import cost, work_precision
    from .study import load_tables

    tables = load_tables(folder / "data")
    tables.update(work_precision.analyse(None, tables["work_precision"]))
    tables.update(cost.analyse(None, tables["cost"]))
    return {"tables": tables, "info": json.loads((folder / "info.json").read_text())}


def _ratio_rows(values: dict, kind: str, where: str) -> list[dict]:
    base = values.get(BASE, math.nan)
    return [
        {"kind": kind, "where": where, "method": m, "value": v / base} for m, v in values.items() if m != BASE
    ]


def headlines(tables: dict, case: str = CASE) -> pd.DataFrame:
    """The timing headlines of one run as rows (kind, where, method, value)."""
    rows = []
    eq = tables["work_precision_equal_accuracy"]
    eq = eq[(eq.case == case) & eq.against.astype(bool)]
    for r in eq.itertuples():
        if r.method != r.against:
            rows.append(
                {
                    "kind": "equal_accuracy",
                    "where": f"{r.target_error:.0e} m vs {r.against}",
                    "method": r.method,
                    "value": r.ratio,
                }
            )
    s = tables["work_precision_summary"]
    s = s[(s.case == case) & (s.method != "pinocchio-rigid")]
    for col, kind in (("cpu_time_to_target", "to_target_cpu"), ("wall_time_to_target", "to_target_wall")):
        rows += _ratio_rows(dict(zip(s.method, s[col])), kind, f"common error vs {BASE}")
    cost = tables["cost"]
    cost = cost[(cost.case == case) & (cost.status == "ok")]
    for k, g in cost.groupby("k"):
        rows += _ratio_rows(dict(zip(g.method, g.cpu_time)), "cost_ratio", f"k = {int(k)} vs {BASE}")
    ex = tables["cost_exponents"]
    for r in ex[ex.case == case].itertuples():
        rows.append({"kind": "cost_exponent", "where": "k >= 2", "method": r.method, "value": r.exponent})
    return pd.DataFrame(rows, columns=["kind", "where", "method", "value"])


def noise_summary(tables: dict) -> dict:
    """Loads seen by the timed runs and how many were marked noisy."""
    t = pd.concat([tables["work_precision"], tables["cost"]]).drop_duplicates("key")
    t = t[t.status == "ok"]
    load = t["timing_load_max"].astype(float)
    spread = t["timing_cpu_median"].astype(float) / t["timing_cpu_min"].astype(float) - 1
    return {
        "runs": len(t),
        "noisy": int(t["noisy"].sum()),
        "load_min": float(load.min()),
        "load_median": float(load.median()),
        "load_max": float(load.max()),
        "spread_median": float(spread.median()),
        "spread_max": float(spread.max()),
    }


def compare(runs: list[pd.DataFrame]) -> pd.DataFrame:
    """Headlines side by side (``run1``, ``run2``, ...) with ``rel_diff`` = max/min − 1 over
    the runs (NaN where a run has no value)."""
    keys = ["kind", "where", "method"]
    out = runs[0].rename(columns={"value": "run1"})
    for i, r in enumerate(runs[1:], start=2):
        out = out.merge(r.rename(columns={"value": f"run{i}"}), on=keys, how="outer")
    vals = out[[f"run{i}" for i in range(1, len(runs) + 1)]].astype(float)
    pos = vals.where(vals > 0)
    out["rel_diff"] = pos.max(axis=1, skipna=False) / pos.min(axis=1, skipna=False) - 1
    return out


def _fmt(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.3g}"


def write(table: pd.DataFrame, infos: list[dict], out: Path, tag: str, header: str) -> None:
    """``<out>/<tag>.csv`` and ``<out>/<tag>.md``."""
    out.mkdir(parents=True, exist_ok=True)
    table.to_csv(out / f"{tag}.csv", index=False)
    runs = [c for c in table.columns if c.startswith("run")]
    head = (
        "| run | wall (s) | load at start / end | timed runs | noisy | load seen by the runs "
        "(min / median / max) | CPU spread median/least − 1 (median / max) |"
    )
    lines = [header, "", head, "|---|---|---|---|---|---|---|"]
    for i, f in enumerate(infos, start=1):
        lines.append(
            f"| {i} | {f['wall_s']:.0f} | {f['load_start']:.2f} / {f['load_end']:.2f} | {f['runs']} | "
            f"{f['noisy']} | {f['load_min']:.2f} / {f['load_median']:.2f} / {f['load_max']:.2f} | "
            f"{100 * f['spread_median']:.1f} % / {100 * f['spread_max']:.1f} % |"
        )
    lines += [
        "",
        "| headline | at | method | " + " | ".join(runs) + " | difference |",
        "|---|---|---|" + "---|" * (len(runs) + 1),
    ]
    for r in table.itertuples():
        vals = " | ".join(_fmt(getattr(r, c)) for c in runs)
        diff = "n/a" if not np.isfinite(r.rel_diff) else f"{100 * r.rel_diff:.1f} %"
        lines.append(f"| {r.kind} | {r.where} | {r.method} | {vals} | {diff} |")
    by_kind = table.groupby("kind").rel_diff.max()
    lines += [
        "",
        "Largest difference per headline: "
        + ", ".join(f"{k} {100 * v:.1f} %" for k, v in by_kind.items())
        + ".",
    ]
    (out / f"{tag}.md").write_text("\n".join(lines) + "\n")


def main(argv=None) -> int:
    """Command line (see the module docstring)."""
    from .context import prepare

    ap = argparse.ArgumentParser(
        prog="python -m experiments.loaded_check", description=__doc__.splitlines()[0]
    )
    ap.add_argument(
        "--burner",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run one CPU-bound process beside each sweep (default on)",
    )
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--data", default="data", help="folder of the cached references (default data)")
    ap.add_argument("--work", default="out/loaded_check", help="folder of the runs' stores and tables")
    ap.add_argument("--out", default="data/peers", help="folder of the CSV and markdown summary")
    ap.add_argument("--tag", default=None, help="file stem (default loaded_check or loaded_check_baseline)")
    ap.add_argument("--scheduler", default=None, help="as dttmm report (default: a LocalCluster)")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument(
        "--from-data",
        action="store_true",
        help="only redo the analysis and comparison of the runs under --work",
    )
    a = ap.parse_args(argv)
    tag = a.tag or ("loaded_check" if a.burner else "loaded_check_baseline")
    ctx = None if a.from_data else prepare(reduced_plan(), a.data)
    heads, infos = [], []
    for i in range(1, a.runs + 1):
        folder = Path(a.work) / tag / f"run{i}"
        if a.from_data:
            got = reanalyse(folder)
        else:
            got = run_once(ctx, folder, burner=a.burner, scheduler=a.scheduler, workers=a.workers)
        info = {**got["info"], **noise_summary(got["tables"])}
        print(f"{tag} run {i}: {info}", flush=True)
        heads.append(headlines(got["tables"]))
        infos.append(info)
    table = compare(heads)
    header = (
        f"# {tag}: timing headlines of the quick plan ({', '.join(STUDIES)} on {CASE}), "
        f"{a.runs} runs, {'one CPU burner beside each' if a.burner else 'no burner'}; "
        f"{os.cpu_count()} cores; the machine is shared with other work (loads below)"
    )
    write(table, infos, Path(a.out), tag, header)
    print((Path(a.out) / f"{tag}.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
