"""The spatial DT-TMM kernel (dttmm.spatial, engine "numba") against the planar kernel on the
same arm: three_link embedded in a tilted plane (``embed_planar``, base rpy = (0.3, −0.5, 0.7)),
200 steps of h = 1e-3, default tolerance, outputs off.

extra_info: sweeps per step, solve-only wall time (``Result.wall_time``, least over the rounds),
µs per element-step; for the spatial kernel also its solve-only CPU time (``meta["cpu_time"]``).
``test_spatial_to_planar_ratio`` measures both kernels for k = 4, 8, 16, 32 (least of 3 repeats,
one BLAS thread) and reports the ratio of their costs per element-step and the fitted exponent
p of cost ∝ (number of elements)^p (also from the spatial kernel's CPU time, which a loaded
machine disturbs less than the wall time). Targets (measured, not asserted): ratio ≤ 4,
p ≤ 1.05.

Run: ``OPENBLAS_NUM_THREADS=1 pytest benchmarks/test_bench_spatial.py --benchmark-enable -s``.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import QUICK, case

import dttmm

pytest.importorskip("numba")
from dttmm.spatial import SpatialCase, embed_planar, simulate  # noqa: E402

KS = [4, 8] if QUICK else [4, 8, 16, 32]
N_STEPS = 10 if QUICK else 200
H = 1e-3
RPY = (0.3, -0.5, 0.7)
ROUNDS = 1 if QUICK else 3


def _cases():
    planar = case("three_link", n_steps=N_STEPS, h=H)
    sc = planar.scenario
    import dataclasses as dc

    planar = dc.replace(planar, scenario=dc.replace(sc, output_step=sc.duration / 2))
    return planar, SpatialCase(embed_planar(planar.model, RPY), planar.scenario)


def _run(kind, c, k):
    if kind == "spatial":
        return simulate(c, elements_per_link=k, h=H, energy=False, cut_loads=False)
    return dttmm.simulate(c, elements_per_link=k, h=H, cut_loads=False, energy=False)


def _measure(kind, c, k, rounds=ROUNDS):
    """(least solve-only wall time, least solve CPU time or NaN, the last result)."""
    walls, cpus = [], []
    for _ in range(rounds):
        r = _run(kind, c, k)
        walls.append(r.wall_time)
        cpus.append(r.meta.get("cpu_time", np.nan))
    return min(walls), min(cpus), r


@pytest.mark.parametrize("kind", ["planar", "spatial"])
@pytest.mark.parametrize("k", KS)
def test_element_step(benchmark, kind, k):
    benchmark.group = "spatial-vs-planar:three_link"
    planar, spatial = _cases()
    c = spatial if kind == "spatial" else planar
    _run(kind, c, k)  # compile or load the kernel outside the timed part
    holder = {}

    def target():
        holder["res"] = _run(kind, c, k)
        holder.setdefault("walls", []).append(holder["res"].wall_time)

    benchmark.pedantic(target, rounds=ROUNDS, iterations=1, warmup_rounds=0)
    res = holder["res"]
    n_el = 3 * k
    wall = min(holder["walls"])
    sweeps = res.meta.get("sweeps_per_step", res.meta.get("iterations_mean"))
    benchmark.extra_info.update(
        kernel=kind,
        elements_per_link=k,
        n_elements=n_el,
        n_steps=res.n_steps,
        sweeps_per_step=sweeps,
        solve_time=wall,
        us_per_element_step=wall / res.n_steps / n_el * 1e6,
    )


def test_spatial_to_planar_ratio(benchmark):
    benchmark.group = "spatial-vs-planar:summary"
    planar, spatial = _cases()
    rows = []

    def target():
        rows.clear()
        for k in KS:
            _run("planar", planar, k)
            _run("spatial", spatial, k)
            wp, _, rp = _measure("planar", planar, k)
            ws, cs, rs = _measure("spatial", spatial, k)
            n = 3 * k * rp.n_steps
            rows.append((k, wp / n * 1e6, ws / n * 1e6, cs / n * 1e6))

    benchmark.pedantic(target, rounds=1, iterations=1, warmup_rounds=0)
    ks = np.array([r[0] for r in rows], float)
    tp = np.array([r[1] for r in rows])
    tsp = np.array([r[2] for r in rows])
    tsc = np.array([r[3] for r in rows])
    p_s = np.polyfit(np.log(3 * ks), np.log(tsp * 3 * ks), 1)[0]
    p_c = np.polyfit(np.log(3 * ks), np.log(tsc * 3 * ks), 1)[0]
    p_p = np.polyfit(np.log(3 * ks), np.log(tp * 3 * ks), 1)[0]
    for k, a, b, c in rows:
        print(
            f"k = {int(k):3d}: planar {a:.3f} µs, spatial {b:.3f} µs (CPU {c:.3f}) per element-step, ratio {b / a:.1f}"
        )
    print(f"exponent in the number of elements: spatial {p_s:.3f} (CPU {p_c:.3f}), planar {p_p:.3f}")
    benchmark.extra_info.update(
        rows=[
            dict(k=int(k), planar_us=a, spatial_us=b, spatial_cpu_us=c, ratio=b / a) for k, a, b, c in rows
        ],
        exponent_spatial=float(p_s),
        exponent_spatial_cpu=float(p_c),
        exponent_planar=float(p_p),
    )
    assert np.all(np.isfinite(tsp)) and np.all(tsp > 0)
