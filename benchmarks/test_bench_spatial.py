"""The spatial DT-TMM kernel (dttmm.spatial, engine "numba") against the planar kernel on the
same arm: three_link embedded in a tilted plane (``embed_planar``, base rpy = (0.3, −0.5, 0.7)),
200 steps of h = 1e-3, default tolerance (the same sweeps per step in both kernels), outputs off.

extra_info: sweeps per step, solve-only wall time (``Result.wall_time``, least over the rounds),
µs per element-step; CPU time of the time loop (spatial ``meta["cpu_time"]``, planar
``meta["loop_cpu_time"]``). ``test_spatial_to_planar_ratio`` measures both kernels for k = 4 … 64
(alternating planar and spatial runs so that both see the same machine load; least CPU time of
3 repeats) and reports each kernel's µs per element-step, their ratio, the fitted exponent p of
cost ∝ (number of elements)^p and the load average. ``test_spatial_6x6_bound`` times the
articulated-inertia work of an element alone (the rotation of P into the element frame, the
rigid transfer across the element and the Schur complement of the 6×6 elastic block, the
kernel's own helpers): a floor under the spatial element step (docs/spatial.md §7). Targets
(measured, not asserted): ratio ≤ 4, p ≤ 1.05.

Run: ``OPENBLAS_NUM_THREADS=1 pytest benchmarks/test_bench_spatial.py --benchmark-enable -s``.
"""

from __future__ import annotations

import dataclasses as dc
import os
import time

import numpy as np
import pytest
from conftest import QUICK, case, least_of_rounds

import dttmm

pytest.importorskip("numba")
import numba  # noqa: E402

from dttmm.spatial import SpatialCase, embed_planar, simulate  # noqa: E402
from dttmm.spatial.kernel import core  # noqa: E402

KS = [4, 8] if QUICK else [4, 8, 16, 32, 64]
N_STEPS = 10 if QUICK else 200
H = 1e-3
RPY = (0.3, -0.5, 0.7)
ROUNDS = 1 if QUICK else 3


def _cases():
    planar = case("three_link", n_steps=N_STEPS, h=H)
    sc = planar.scenario
    planar = dc.replace(planar, scenario=dc.replace(sc, output_step=sc.duration / 2))
    return planar, SpatialCase(embed_planar(planar.model, RPY), planar.scenario)


def _run(kind, c, k):
    if kind == "spatial":
        return simulate(c, elements_per_link=k, h=H, energy=False, cut_loads=False)
    return dttmm.simulate(c, elements_per_link=k, h=H, cut_loads=False, energy=False)


def _cpu(res):
    """CPU time (s) of the time loop of either kernel."""
    return res.meta.get("cpu_time", res.meta.get("loop_cpu_time", np.nan))


def _sweeps(res):
    return res.meta.get("sweeps_per_step", res.meta.get("iterations_mean"))


@pytest.mark.parametrize("kind", ["planar", "spatial"])
@pytest.mark.parametrize("k", KS)
def test_element_step(benchmark, kind, k):
    benchmark.group = "spatial-vs-planar:three_link"
    planar, spatial = _cases()
    c = spatial if kind == "spatial" else planar
    res, least = least_of_rounds(
        benchmark, lambda: _run(kind, c, k), ROUNDS, wall=lambda r: r.wall_time, cpu=_cpu
    )
    n_el = 3 * k
    wall, cpu = least["wall"], least["cpu"]
    benchmark.extra_info.update(
        kernel=kind,
        elements_per_link=k,
        n_elements=n_el,
        n_steps=res.n_steps,
        sweeps_per_step=_sweeps(res),
        solve_time=wall,
        cpu_time=cpu,
        us_per_element_step=wall / res.n_steps / n_el * 1e6,
        cpu_us_per_element_step=cpu / res.n_steps / n_el * 1e6,
        load_average=os.getloadavg()[0],
    )


def _exponent(ks, us_per_element_step):
    """p of cost ∝ (number of elements)^p, least squares in log-log."""
    n = 3 * np.asarray(ks, float)
    return float(np.polyfit(np.log(n), np.log(np.asarray(us_per_element_step) * n), 1)[0])


def test_spatial_to_planar_ratio(benchmark):
    benchmark.group = "spatial-vs-planar:summary"
    planar, spatial = _cases()
    rows = []

    def target():
        rows.clear()
        for k in KS:
            _run("planar", planar, k)
            _run("spatial", spatial, k)
            cp, cs = [], []
            for _ in range(ROUNDS):  # alternate, so that both kernels see the same load
                rp = _run("planar", planar, k)
                cp.append(_cpu(rp))
                rs = _run("spatial", spatial, k)
                cs.append(_cpu(rs))
            n = 3 * k * rp.n_steps
            rows.append(
                dict(
                    k=k,
                    planar_us=min(cp) / n * 1e6,
                    spatial_us=min(cs) / n * 1e6,
                    sweeps_planar=_sweeps(rp),
                    sweeps_spatial=_sweeps(rs),
                    load_average=os.getloadavg()[0],
                )
            )

    benchmark.pedantic(target, rounds=1, iterations=1, warmup_rounds=0)
    for r in rows:
        r["ratio"] = r["spatial_us"] / r["planar_us"]
        print(
            f"k = {r['k']:3d}: planar {r['planar_us']:.3f} µs, spatial {r['spatial_us']:.3f} µs per "
            f"element-step (CPU), ratio {r['ratio']:.1f}, sweeps/step {r['sweeps_spatial']:.2f}, "
            f"load {r['load_average']:.1f}"
        )
    ks = [r["k"] for r in rows]
    p_s = _exponent(ks, [r["spatial_us"] for r in rows])
    p_p = _exponent(ks, [r["planar_us"] for r in rows])
    print(f"exponent in the number of elements: spatial {p_s:.3f}, planar {p_p:.3f}")
    benchmark.extra_info.update(rows=rows, exponent_spatial=p_s, exponent_planar=p_p)
    assert all(np.isfinite(r["spatial_us"]) and r["spatial_us"] > 0 for r in rows)


@numba.njit(_nrt=False, boundscheck=False)
def _articulated_inertia_only(E, s, M0, r0, M, r, L, Y, P, c, T, N):
    """Per element, tip → root: P, c into the element frame (rotate_pc), across its rigid offset
    (shift_pc), added to a fixed element matrix M0, then the Schur complement of its 6×6 elastic
    block (schur_into) — the kernel's own helpers, nothing of the Gauss bodies."""
    ok = True
    for el in range(E.shape[0] - 1, -1, -1):
        core.rotate_pc(E[el], False, P, c, T)
        core.shift_pc(P, c, s[el, 0], s[el, 1], s[el, 2], N)
        for a in range(12):
            r[a] = r0[el, a] + (c[a] if a < 6 else 0.0)
            for b in range(a, 12):
                M[a, b] = M0[a, b] + (P[a, b] if b < 6 else 0.0)
        ok = core.schur_into(M, r, L, Y, P, c) and ok
        for a in range(6):  # keep the chain bounded (the fixed M0 stands in for the bodies)
            for b in range(6):
                P[a, b] *= 0.5
    return ok


def test_spatial_6x6_bound(benchmark):
    """ns per element-sweep of the articulated-inertia products alone, and what they alone cost
    per element-step at the spatial kernel's sweeps per step (k = 32)."""
    benchmark.group = "spatial-vs-planar:bound"
    nel = 96 if QUICK else 768
    rng = np.random.default_rng(0)
    q, _ = np.linalg.qr(rng.normal(size=(nel, 3, 3)))
    E = np.ascontiguousarray(q)
    s = rng.normal(size=(nel, 3)) * 0.1
    A = rng.normal(size=(12, 12))
    M0 = A @ A.T + 12.0 * np.eye(12)
    r0 = rng.normal(size=(nel, 12))
    z = np.zeros
    args = (E, s, M0, r0, z((12, 12)), z(12), z((6, 6)), z((6, 7)), z((6, 6)), z(6), z((3, 3)), z((3, 3)))
    assert _articulated_inertia_only(*args)
    reps = 5 if QUICK else 100
    best = []

    def target():
        t0 = time.process_time()
        for _ in range(reps):
            _articulated_inertia_only(*args)
        best.append((time.process_time() - t0) / reps / nel)

    benchmark.pedantic(target, rounds=ROUNDS + 2, iterations=1, warmup_rounds=0)
    ns = min(best) * 1e9
    planar, spatial = _cases()
    k = 8 if QUICK else 32
    rs = _run("spatial", spatial, k)
    rp = _run("planar", planar, k)
    n = 3 * k * rp.n_steps
    planar_us = _cpu(rp) / n * 1e6
    floor_us = ns * 1e-3 * _sweeps(rs)
    print(
        f"6×6 articulated-inertia work alone: {ns:.0f} ns per element-sweep, {floor_us:.2f} µs per "
        f"element-step at {_sweeps(rs):.2f} sweeps/step = {floor_us / planar_us:.1f}× the planar "
        f"kernel's whole element-step ({planar_us:.3f} µs, k = {k})"
    )
    benchmark.extra_info.update(
        ns_per_element_sweep=ns,
        floor_us_per_element_step=floor_us,
        planar_us_per_element_step=planar_us,
        floor_to_planar=floor_us / planar_us,
        load_average=os.getloadavg()[0],
    )
    assert ns > 0
