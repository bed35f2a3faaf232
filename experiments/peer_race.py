"""The peer race on three_link: Exudyn before/after tuning, and speed at equal accuracy.

``python -m experiments.peer_race [--out data/peers] [--repeats 3] [--duration 2.0]`` writes
``race.json`` (every measurement with its timing, load and configuration) and ``race.md``
(the tables). Every time is the CPU time of the whole ``simulate`` call (model build and
solve, ``time.process_time``), minimum and median of the repeats, one BLAS thread
(:mod:`experiments.timing`).

Parts:

1. Cost per element-step and per simulated second at k = 16 and 64 (h = 1e-3) for each Exudyn
   peer as the adapter ran it before (drive torques in load user functions, Jacobian reused
   across steps, GE rotary inertia 1e-5 kg·m) and tuned (the adapters' defaults now).
2. Work-precision: end-effector RMS error against a fine reference (Exudyn ANCF k = 32,
   h = 1.25e-4, cross-checked by DT-TMM with the second-order element at k = 32, h = 2.5e-4)
   over a grid of (k, h, solver option) per method. The cost of reaching an accuracy is read
   off each method's lower envelope (the cheapest run reaching at most that error, linear
   interpolation in log-log between envelope points), the same rule for every method.
"""

from __future__ import annotations

import argparse
import dataclasses as dc
import json
import math
import platform
from pathlib import Path

import numpy as np

from . import methods, metrics
from .plan import CASE_DIR
from .studies.work_precision import cost_at
from .studies.work_precision import envelope as _envelope
from .timing import measure

TARGETS = (1e-3, 1e-4, 1e-5)
OUTPUT_STEP = 4e-3  # a multiple of every step of the grid (the Exudyn adapters sample on it)
HS = (4e-3, 2e-3, 1e-3, 5e-4, 2.5e-4)
KS = (2, 4, 8, 16)
BEFORE = {"drive_input": "user-function", "jacobian_per_step": False}
GE_BEFORE = {**BEFORE, "cross_section_inertia": 1e-5}
#: (configuration, method, label, options) of the work-precision grid. A configuration's
#: envelope spans its labels: Newton tolerance and DT-TMM's iteration count are grid dimensions,
#: so each envelope picks whichever is cheapest at a given accuracy.
VARIANTS = (
    ("exudyn-ancf tuned", "exudyn-ancf", "tuned", {}),
    ("exudyn-ancf tuned", "exudyn-ancf", "tuned, relaxed Newton tolerance", {"newton_rel_tol": 1e-5}),
    ("dttmm-2nd", "dttmm-2nd", "converged", {}),
    ("dttmm-2nd", "dttmm-2nd", "iterations=auto", {"iterations": "auto"}),
    ("exudyn-ancf tuned", "exudyn-ancf", "tuned, Jacobian reused across steps", {"jacobian_per_step": False}),
    ("exudyn-ancf before", "exudyn-ancf", "before", BEFORE),
    ("exudyn-beam before", "exudyn-beam", "before", GE_BEFORE),
    ("exudyn-beam tuned", "exudyn-beam", "tuned", {"cross_section_inertia": "physical"}),
    (
        "exudyn-beam tuned",
        "exudyn-beam",
        "tuned, Jacobian reused across steps",
        {"jacobian_per_step": False, "cross_section_inertia": "physical"},
    ),
)
BASE = "dttmm-2nd"  # the like-for-like DT-TMM configuration (second-order element)


def _case(duration: float):
    import dttmm

    c = dttmm.load_case(CASE_DIR / "three_link.toml")
    return dc.replace(c, scenario=dc.replace(c.scenario, duration=duration, output_step=OUTPUT_STEP))


def _timed(method, case, k, h, repeats, **options):
    res, t = measure(lambda: methods.run(method, case, k, h, **options), repeats)
    return res, {
        "method": method,
        "k": k,
        "h": h,
        "options": {a: str(b) for a, b in options.items()},
        "n_steps": int(res.n_steps),
        "cpu_solve": res.meta.get("cpu_time_solve"),
        **t.columns(),
    }


def cost_rows(case, repeats, ks=(16, 64), h=1e-3) -> list[dict]:
    """Part 1: each peer before/after tuning (and DT-TMM for scale) at the given k."""
    runs = [
        ("exudyn-ancf", "before", BEFORE),
        ("exudyn-ancf", "tuned", {}),
        ("exudyn-beam", "before", GE_BEFORE),
        ("exudyn-beam", "tuned", {}),
        ("dttmm-2nd", "converged", {}),
        ("dttmm-2nd", "iterations=auto", {"iterations": "auto"}),
        ("dttmm", "linear strain, converged", {}),
    ]
    rows = []
    n_links = case.model.n_links
    for k in ks:
        for method, label, opts in runs:
            _, row = _timed(method, case, k, h, repeats, **opts)
            cpu = row["timing_cpu_min"]
            row.update(
                label=label,
                us_per_element_step=1e6 * cpu / (row["n_steps"] * k * n_links),
                s_per_simulated_s=cpu / case.scenario.duration,
            )
            rows.append(row)
            print(
                f"cost {method:12s} {label:26s} k={k:3d} cpu={cpu:.3f}s "
                f"{row['us_per_element_step']:.2f} us/el-step noisy={row['timing_noisy']}",
                flush=True,
            )
    return rows


def reference(case):
    """(reference Result, its description, cross-check error in m)."""
    ref = methods.run("exudyn-ancf", case, 32, 1.25e-4)
    chk = methods.run("dttmm-2nd", case, 32, 2.5e-4)
    e = metrics.errors(chk, ref)["ee_l2"]
    return ref, "exudyn-ancf k=32 h=1.25e-4", {"method": "dttmm-2nd", "k": 32, "h": 2.5e-4, "ee_l2": e}


def grid_rows(case, ref, repeats, ks=KS, hs=HS, configs=None, labels=None) -> list[dict]:
    """Part 2: every (configuration, variant, k, h) of the grid with its error and timing."""
    rows = []
    for config, method, label, opts in VARIANTS:
        if (configs and config not in configs) or (labels and label not in labels):
            continue
        for k in ks:
            for h in hs:
                try:
                    res, row = _timed(method, case, k, h, repeats, **opts)
                    row["ee_l2"] = metrics.errors(res, ref)["ee_l2"]
                    row["status"] = "ok"
                except Exception as exc:  # noqa: BLE001 - a failing run is recorded, not dropped
                    row = {
                        "method": method,
                        "k": k,
                        "h": h,
                        "status": f"failed: {type(exc).__name__}: {exc}"[:200],
                        "ee_l2": math.nan,
                        "timing_cpu_min": math.nan,
                    }
                row["label"], row["config"] = label, config
                rows.append(row)
                print(
                    f"grid {method:12s} {label:30s} k={k:2d} h={h:g} err={row['ee_l2']:.3g} "
                    f"cpu={row['timing_cpu_min']:.3f}",
                    flush=True,
                )
    return rows


def envelope(rows) -> list[tuple[float, float]]:
    """Lower envelope (error, cpu) of the finished runs (see work_precision.envelope)."""
    ok = [r for r in rows if r.get("status") == "ok"]
    return _envelope([r["timing_cpu_min"] for r in ok], [r["ee_l2"] for r in ok])


def equal_accuracy(rows, targets=TARGETS) -> list[dict]:
    """Per target and configuration: CPU time to reach it on the configuration's envelope, and
    its ratio to DT-TMM's (:data:`BASE`)."""
    by = {}
    for r in rows:
        by.setdefault(r.get("config", r["method"]), []).append(r)
    envs = {m: envelope(rs) for m, rs in by.items()}
    out = []
    for tgt in targets:
        c = {m: cost_at(e, tgt) for m, e in envs.items()}
        base = c.get(BASE, math.nan)
        for m, v in c.items():
            out.append(
                {
                    "target_m": tgt,
                    "config": m,
                    "cpu": v,
                    "ratio_to_dttmm": v / base if m != BASE else math.nan,
                }
            )
    return out


def _sig2(x) -> str:
    return "n/a" if not np.isfinite(x) else f"{float(f'{x:.2g}'):g}"


def markdown(doc) -> str:
    lines = [
        "| peer | configuration | k | µs per element-step (min / median) | s per simulated s | noisy |",
        "|---|---|---|---|---|---|",
    ]
    for r in doc["cost"]:
        n = r["n_steps"] * r["k"] * 3
        lines.append(
            f"| {r['method']} | {r['label']} | {r['k']} | {_sig2(r['us_per_element_step'])} / "
            f"{_sig2(1e6 * r['timing_cpu_median'] / n)} | {_sig2(r['s_per_simulated_s'])} | "
            f"{r['timing_noise'] or 'no'} |"
        )
    lines += [
        "",
        f"Reference: {doc['reference']}; cross-check {doc['cross_check']}.",
        "",
        "| configuration | " + " | ".join(f"CPU (s) to {t:g} m | ratio" for t in TARGETS) + " |",
        "|---|" + "---|---|" * len(TARGETS),
    ]
    confs = list(dict.fromkeys(r["config"] for r in doc["equal_accuracy"]))
    for cname in confs:
        cells = []
        for t in TARGETS:
            r = next(x for x in doc["equal_accuracy"] if x["config"] == cname and x["target_m"] == t)
            cells.append(f"{_sig2(r['cpu'])} | {_sig2(r['ratio_to_dttmm'])}")
        lines.append(f"| {cname} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m experiments.peer_race")
    ap.add_argument("--out", default="data/peers")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--duration", type=float, default=2.0)
    ap.add_argument("--skip-cost", action="store_true")
    ap.add_argument("--configs", nargs="*", default=None, help="grid configurations to run (default all)")
    ap.add_argument("--labels", nargs="*", default=None, help="grid variants (labels) to run (default all)")
    ap.add_argument(
        "--merge", action="store_true", help="add to the cost and grid rows of an existing race.json"
    )
    a = ap.parse_args(argv)
    import os
    import subprocess

    case = _case(a.duration)
    ref, ref_name, chk = reference(case)
    print(f"reference {ref_name}; cross-check {chk}", flush=True)
    doc = {
        "case": "three_link",
        "duration": a.duration,
        "repeats": a.repeats,
        "reference": ref_name,
        "cross_check": chk,
        "machine": platform.platform(),
        "load_at_start": os.getloadavg()[0],
        "commit": subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=False
        ).stdout.strip(),
    }
    out = Path(a.out)
    old = json.loads((out / "race.json").read_text()) if a.merge and (out / "race.json").exists() else {}
    doc["cost"] = old.get("cost", []) + ([] if a.skip_cost else cost_rows(case, a.repeats))
    doc["grid"] = old.get("grid", []) + grid_rows(case, ref, a.repeats, configs=a.configs, labels=a.labels)
    if old:
        doc["runs"] = [
            *old.get("runs", [{k: old[k] for k in ("commit", "load_at_start")}]),
            {k: doc[k] for k in ("commit", "load_at_start")},
        ]
    doc["equal_accuracy"] = equal_accuracy(doc["grid"])
    out.mkdir(parents=True, exist_ok=True)
    (out / "race.json").write_text(json.dumps(doc, indent=1, default=str))
    (out / "race.md").write_text(markdown(doc))
    print(markdown(doc))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
