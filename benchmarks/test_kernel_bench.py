"""The compiled DT-TMM kernel (engine="numba", dttmm.kernel): cost per element-step vs mesh size.

three_link, fixed step count (200 steps of h = 1e-3), outputs off (cut loads, energy) so the
sweeps are measured; the case is built and the kernel compiled (or loaded from the cache)
outside the timed part. extra_info: n_dof, sweeps per step, time per element-step (µs) from the
solve-only wall time. Targets (measured, not asserted): ≤ 0.3 µs per element-step for k ≥ 64
at default accuracy, cost ∝ elements^p with p ≤ 1.05 over k = 8…1024, three_link at k = 16
more than 20× faster than real time.

Run: ``pytest benchmarks/test_kernel_bench.py --benchmark-enable``.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from conftest import CASES, QUICK, case

import dttmm

pytest.importorskip("numba")
from dttmm.kernel import driver

KS = [8, 64] if QUICK else [8, 16, 32, 64, 128, 256, 1024]
N_STEPS = 10 if QUICK else 200
H = 1e-3
VARIANTS = {"converged": {}, "auto": {"iterations": "auto"}}


def _info(benchmark, res, k, n_links, walls):
    """extra_info from the last result and the best solve-only wall time over the rounds."""
    n_el = k * n_links
    wall = min(walls)
    benchmark.extra_info.update(
        engine=res.meta["engine"],
        elements_per_link=k,
        n_elements=n_el,
        n_dof=res.meta["n_dof"],
        n_steps=res.n_steps,
        sweeps_per_step=res.meta["iterations_mean"],
        solve_time=wall,
        us_per_element_step=wall / res.n_steps / n_el * 1e6,
        ns_per_element_sweep=wall / res.n_steps / n_el / res.meta["iterations_mean"] * 1e9,
    )


@pytest.mark.parametrize("variant", sorted(VARIANTS))
@pytest.mark.parametrize("k", KS)
def test_kernel_element_step(benchmark, k, variant):
    benchmark.group = f"kernel:three_link:{variant}"
    holder = {"walls": []}

    def setup():
        driver.warmup()
        holder["case"] = case("three_link", n_steps=N_STEPS, h=H)
        return (), {}

    def target():
        holder["res"] = dttmm.simulate(
            holder["case"],
            elements_per_link=k,
            h=H,
            engine="numba",
            cut_loads=False,
            energy=False,
            **VARIANTS[variant],
        )
        holder["walls"].append(holder["res"].wall_time)

    benchmark.pedantic(
        target, setup=setup, rounds=1 if QUICK else 5, iterations=1, warmup_rounds=0 if QUICK else 1
    )
    _info(benchmark, holder["res"], k, 3, holder["walls"])


def test_kernel_real_time_factor(benchmark):
    """three_link, k = 16, the full 2 s with every output on (cut loads, energy), default accuracy."""
    benchmark.group = "kernel:real-time"
    holder = {"walls": []}
    c = dttmm.load_case(CASES / "three_link.toml")
    if QUICK:
        import dataclasses as dc

        c = dc.replace(c, scenario=dc.replace(c.scenario, duration=0.02))

    def setup():
        driver.warmup()
        return (), {}

    def target():
        holder["res"] = dttmm.simulate(c, elements_per_link=16, h=H, engine="numba")
        holder["walls"].append(holder["res"].wall_time)

    benchmark.pedantic(target, setup=setup, rounds=1 if QUICK else 3, iterations=1, warmup_rounds=0)
    res = holder["res"]
    _info(benchmark, res, 16, 3, holder["walls"])
    benchmark.extra_info["real_time_factor"] = c.scenario.duration / min(holder["walls"])


def test_kernel_cost_exponent(benchmark):
    """Fit cost ∝ (elements)^p over KS from the best of 3 runs each (solve-only wall time)."""
    benchmark.group = "kernel:exponent"
    driver.warmup()
    c = case("three_link", n_steps=N_STEPS, h=H)
    out = {}

    def target():
        for k in KS:
            best = np.inf
            for _ in range(1 if QUICK else 3):
                r = dttmm.simulate(
                    c, elements_per_link=k, h=H, engine="numba", cut_loads=False, energy=False, iterations=1
                )  # a fixed sweep count isolates the per-sweep cost
                best = min(best, r.wall_time)
            out[k] = best

    t0 = time.perf_counter()
    benchmark.pedantic(target, rounds=1, iterations=1)
    ks = np.array(sorted(out), float)
    t = np.array([out[k] for k in sorted(out)])
    p = np.polyfit(np.log(3 * ks), np.log(t), 1)[0]
    benchmark.extra_info.update(
        exponent=float(p),
        ks=[int(k) for k in ks],
        us_per_element_step=[float(x) for x in t / N_STEPS / (3 * ks) * 1e6],
        wall=time.perf_counter() - t0,
    )
