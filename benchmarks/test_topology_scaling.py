"""Cost of the spatial DT-TMM on trees and closed loops over the elements per link k
(docs/spatial.md §11 "Cost"): Bauchau's four-bar (``topology/four_bar.toml``, one revolute
closure, 5 constraint equations), its cut-open tree (the same mechanism with ``closures=()``:
the links swing free of the cut joint) and the branched arm (a tree), Newmark to the stop rule,
h = 1e-3, 50 steps, outputs off.

extra_info: sweeps per step, CPU time of the time loop (``meta["cpu_time"]``, least over the
rounds) per step and per element-step. ``test_loop_to_tree_ratio`` measures the three cases for
k = 2 … 16 (alternating them so that all see the same machine load; least CPU time of 3
repeats) and reports µs per step, sweeps per step, the ratio four-bar / cut-open tree and the
fitted exponent p of cost ∝ (number of elements)^p per case. Targets (measured, not asserted):
ratio ≤ 1.5, p ≈ 1.

Run: ``OPENBLAS_NUM_THREADS=1 pytest benchmarks/test_topology_scaling.py --benchmark-enable -s``.
"""

from __future__ import annotations

import dataclasses as dc
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import QUICK, least_of_rounds

pytest.importorskip("numba")

from dttmm.spatial import simulate  # noqa: E402
from dttmm.spatial.case import load_case  # noqa: E402
from dttmm.threads import one_blas_thread  # noqa: E402

TOPO = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"
KS = [1, 2] if QUICK else [2, 4, 8, 16]
N_STEPS = 5 if QUICK else 50
H = 1e-3
ROUNDS = 1 if QUICK else 3
NAMES = ["four_bar", "four_bar_cut", "branched_arm"]


def _case(name):
    base = "four_bar" if name == "four_bar_cut" else name
    c = load_case(TOPO / f"{base}.toml")
    if name == "four_bar_cut":
        c = dc.replace(c, model=dc.replace(c.model, closures=()))
    sc = c.scenario
    return dc.replace(c, scenario=dc.replace(sc, duration=N_STEPS * H, output_step=N_STEPS * H / 2))


def _run(c, k):
    return simulate(c, elements_per_link=k, h=H, energy=False, cut_loads=False, progress=False)


def _per_step(res):
    """CPU time (s) of the time loop per step."""
    return res.meta["cpu_time"] / res.n_steps


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("k", KS)
def test_topology_step(benchmark, name, k):
    benchmark.group = f"topology:{name}"
    c = _case(name)
    with one_blas_thread():
        res, least = least_of_rounds(benchmark, lambda: _run(c, k), ROUNDS, cpu=_per_step)
    n_el = k * len(c.model.links)
    cpu = least["cpu"]
    benchmark.extra_info.update(
        case=name,
        elements_per_link=k,
        n_elements=n_el,
        n_steps=res.n_steps,
        sweeps_per_step=res.meta["sweeps_per_step"],
        cpu_us_per_step=cpu * 1e6,
        cpu_us_per_element_step=cpu / n_el * 1e6,
        load_average=os.getloadavg()[0],
    )


def _exponent(n_elements, us_per_step):
    """p of cost ∝ (number of elements)^p, least squares in log-log."""
    return float(np.polyfit(np.log(np.asarray(n_elements, float)), np.log(np.asarray(us_per_step)), 1)[0])


def test_loop_to_tree_ratio(benchmark):
    benchmark.group = "topology:summary"
    cases = {name: _case(name) for name in NAMES}
    rows = []

    def target():
        rows.clear()
        for k in KS:
            best = {name: np.inf for name in NAMES}
            sweeps = {}
            for name in NAMES:
                _run(cases[name], k)
            for _ in range(ROUNDS):  # alternate, so that every case sees the same load
                for name in NAMES:
                    res = _run(cases[name], k)
                    best[name] = min(best[name], _per_step(res))
                    sweeps[name] = res.meta["sweeps_per_step"]
            row = dict(k=k, load_average=os.getloadavg()[0])
            for name in NAMES:
                row[f"{name}_us"] = best[name] * 1e6
                row[f"{name}_sweeps"] = sweeps[name]
                row[f"{name}_elements"] = k * len(cases[name].model.links)
            row["ratio"] = row["four_bar_us"] / row["four_bar_cut_us"]
            rows.append(row)

    with one_blas_thread():
        benchmark.pedantic(target, rounds=1, iterations=1, warmup_rounds=0)
    for r in rows:
        print(
            f"k = {r['k']:2d}: four-bar {r['four_bar_us']:.0f} µs ({r['four_bar_sweeps']:.2f} sweeps), "
            f"cut open {r['four_bar_cut_us']:.0f} µs ({r['four_bar_cut_sweeps']:.2f}), branched arm "
            f"{r['branched_arm_us']:.0f} µs ({r['branched_arm_sweeps']:.2f}) per step; loop / tree "
            f"{r['ratio']:.2f}; load {r['load_average']:.1f}"
        )
    p = {
        name: _exponent([r[f"{name}_elements"] for r in rows], [r[f"{name}_us"] for r in rows])
        for name in NAMES
    }
    print("exponent in the number of elements: " + ", ".join(f"{n} {v:.3f}" for n, v in p.items()))
    benchmark.extra_info.update(rows=rows, exponents=p)
    assert all(np.isfinite(r[f"{n}_us"]) and r[f"{n}_us"] > 0 for r in rows for n in NAMES)
