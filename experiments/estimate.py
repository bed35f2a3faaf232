"""Estimated CPU time of planned runs, from measured per-method costs.

Each method's cost of one call is modelled as ``a · steps · size^p`` CPU seconds, with
``steps = duration / h`` and ``size = joints · (k + 1)`` (``joints`` for a rigid method), and
``a``, ``p`` fitted by least squares on log CPU time over the runs a report has timed (the
cached run rows). A method's runs of spatial arms are fitted on their own, under the key
``<method>@spatial`` (the spatial kernel's element costs several times the planar one's).
The fit is stored in ``data/run_costs.json`` (committed, with its provenance) and refreshed
by ``python -m experiments.estimate --fit``. A method with no fit gets the median ``a`` with
``p = 1``. A run's estimate counts the calls the timing rule will make
(:mod:`experiments.timing`): one for a run of at least ``LONG_CPU``, else enough to reach
``MIN_CPU``, at least the repeats asked for.

The sweep uses the estimates to print the plan's size and time before it starts, to start the
longest runs first, and to drive its progress bar in estimated seconds of work (so its time to
go stays honest when the longest runs come first).
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
from pathlib import Path

import numpy as np

from . import timing

__all__ = ["COSTS_FILE", "calls", "estimate", "fit", "load_costs", "plan_text"]

COSTS_FILE = Path(__file__).resolve().parents[1] / "data" / "run_costs.json"
MIN_FIT_CPU = 0.02  # s: runs shorter than this are dominated by per-call overhead, left out of the fit


def cost_key(method: str, spatial: bool) -> str:
    """The key of a method's fitted cost: ``method``, or ``method@spatial`` for spatial arms."""
    return f"{method}@spatial" if spatial else method


def work(task, case) -> tuple[float, float]:
    """(steps, size) of a task: steps = duration / h, size = joints · (k + 1)."""
    n = max(case.n_joints, 1)  # an arm whose joints are all locked still has its links
    return task.duration / task.h, n * (task.k + 1) if task.k else n


def fit(rows) -> dict:
    """method -> {"a", "p", "runs", "rms_log"} from run rows (dicts with ``method``, ``k``, ``h``,
    ``duration``, ``n_joints``, ``timing_cpu_min``), each method fitted on its own rows."""
    by: dict = {}
    for r in rows:
        cpu = float(r.get("timing_cpu_min") or math.nan)
        if r.get("status") != "ok" or not cpu >= MIN_FIT_CPU:
            continue
        n, k = max(int(r["n_joints"]), 1), int(r["k"])
        steps, size = float(r["duration"]) / float(r["h"]), n * (k + 1) if k else n
        by.setdefault(cost_key(r["method"], r.get("space") == "spatial"), []).append(
            (math.log(steps), math.log(size), math.log(cpu))
        )
    out = {}
    for m, pts in sorted(by.items()):
        x = np.array(pts)
        keep = np.ones(len(x), bool)
        for _ in range(5):  # refit without the slow outliers (a first call that compiled, a loaded moment)
            la, p = _line(x[keep, 1], x[keep, 2] - x[keep, 0])
            res = x[:, 2] - x[:, 0] - (la + p * x[:, 1])
            keep = res <= 0.7  # at most 2× slower than the fit
        out[m] = {
            "a": math.exp(la),
            "p": float(p),
            "runs": int(keep.sum()),
            "left_out": int((~keep).sum()),
            "rms_log": float(np.sqrt(np.mean(res[keep] ** 2))) if keep.any() else math.nan,
        }
    return out


def _line(logsize, y) -> tuple[float, float]:
    """(intercept, slope) of y against log size; slope 1 with too few sizes to fit one."""
    if len(y) >= 3 and np.ptp(logsize) > 0:
        p, la = np.polyfit(logsize, y, 1)
        return float(la), float(p)
    return float(np.mean(y - logsize)) if len(y) else 0.0, 1.0


def load_costs(path=COSTS_FILE) -> dict:
    """The stored fit (method -> coefficients); {} when there is none."""
    try:
        return json.loads(Path(path).read_text())["methods"]
    except (OSError, ValueError, KeyError):
        return {}


def one_call(task, case, costs: dict) -> float:
    """Estimated CPU seconds of one call of ``task``."""
    from .methods import is_spatial

    steps, size = work(task, case)
    c = costs.get(cost_key(task.method, is_spatial(case)))
    if c is None:
        a = statistics.median([v["a"] for v in costs.values()]) if costs else 1e-6
        c = {"a": a, "p": 1.0}
    return float(c["a"] * steps * size ** c["p"])


def calls(one: float, repeats: int) -> int:
    """Calls the timing rule makes for a run of ``one`` CPU seconds asked ``repeats`` times."""
    if repeats <= 1:
        return 1
    if one >= timing.LONG_CPU:
        return 1
    need = math.ceil(timing.MIN_CPU / one) if one > 0 else timing.MAX_REPEATS
    return int(min(max(repeats, need), max(repeats, timing.MAX_REPEATS)))


def estimate(task, case, costs: dict, repeats: int = 1) -> float:
    """Estimated CPU seconds of a run with the calls the timing rule makes."""
    one = one_call(task, case, costs)
    return one * calls(one, repeats)


def plan_text(n_tasks: int, n_todo: int, seconds: float, workers: int, by_method: dict) -> str:
    """One line: the plan's size and its estimated time."""
    top = sorted(by_method.items(), key=lambda kv: -kv[1])[:3]
    share = ", ".join(f"{m} {s:.0f} s" for m, s in top)
    return (
        f"plan: {n_tasks} runs, {n_todo} to compute ({n_tasks - n_todo} cached); estimated "
        f"{seconds:.0f} s of CPU, about {seconds / max(workers, 1) / 60:.1f} min on {workers} workers"
        + (f" (most: {share})" if share else "")
    )


def _rows(folder) -> list:
    rows = []
    for p in Path(folder).rglob("*.json"):
        try:
            r = json.loads(p.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(r, dict) and "method" in r and "timing_cpu_min" in r:
            rows.append(r)
    return rows


def main(argv=None) -> int:
    """``python -m experiments.estimate --fit RUNS_DIR [--out data/run_costs.json]``."""
    import datetime
    import platform

    ap = argparse.ArgumentParser(prog="python -m experiments.estimate")
    ap.add_argument("--fit", required=True, metavar="RUNS_DIR", help="cached runs, e.g. data/cache/runs")
    ap.add_argument("--out", default=str(COSTS_FILE))
    a = ap.parse_args(argv)
    rows = _rows(a.fit)
    costs = fit(rows)
    doc = {
        "about": "per-method CPU cost of one call: a · steps · (joints·(k+1))^p s (experiments/estimate.py)",
        "fitted_from": f"{len(rows)} cached run rows under {a.fit}",
        "date": datetime.date.today().isoformat(),
        "machine": f"{platform.machine()}, {timing.cores()} cores",
        "methods": costs,
    }
    Path(a.out).write_text(json.dumps(doc, indent=1) + "\n")
    for m, c in costs.items():
        print(
            f"{m:18s} a = {c['a']:.3g} s, p = {c['p']:.2f}, {c['runs']} runs, rms log error {c['rms_log']:.2f}"
        )
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
