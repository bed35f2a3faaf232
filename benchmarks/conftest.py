"""Shared set-up of the cost benchmarks (the pytest-benchmark scaling suites of benchmarks/).

Every benchmark runs a method on the same case for a fixed number of steps; the timed call is
the whole ``simulate`` (model build included, it is small), and ``extra_info`` carries the
least solve-only time per step over the rounds (``Result.wall_time``), the least CPU time per
step of the whole call, sizes, iterations, load and the error against the case's reference,
so that timing and accuracy join in the report.

``DTTMM_BENCH_QUICK=1`` (CI) shrinks the parameter lists so the suites run once, untimed, in
seconds: they are checked to work, not measured.
"""

from __future__ import annotations

import dataclasses as dc
import math
import os
import time
from functools import cache
from pathlib import Path

import numpy as np
import pytest

import dttmm
from experiments.methods import MethodUnavailable, resolve

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
QUICK = os.environ.get("DTTMM_BENCH_QUICK", "") not in ("", "0")
H = 1e-3
N_STEPS = 10 if QUICK else 100


def case(name: str, n_steps: int = N_STEPS, h: float = H) -> dttmm.Case:
    c = dttmm.load_case(CASES / f"{name}.toml")
    return dc.replace(c, scenario=dc.replace(c.scenario, duration=n_steps * h, output_step=h))


def chain(n_links: int, n_steps: int = N_STEPS, h: float = H) -> dttmm.Case:
    """n equal links of the three_link strip (hubs, payload at the end, gravity, sine torques)."""
    base = dttmm.load_case(CASES / "three_link.toml")
    mid = base.model.links[1]
    links = (
        [base.model.links[0]] + [mid] * (n_links - 2) + [base.model.links[2]]
        if n_links > 1
        else [dc.replace(base.model.links[0], payload=base.model.links[2].payload)]
    )
    drives = tuple(dttmm.Drive("torque", dttmm.Sine(1.0 / (i + 1), 1.0, until=1.0)) for i in range(n_links))
    return dttmm.Case(
        dc.replace(base.model, links=tuple(links)), dttmm.Scenario(n_steps * h, h, drives), f"chain{n_links}"
    )


@cache
def reference(name: str, n_steps: int = N_STEPS) -> dttmm.Result:
    """DT-TMM at k = 64, h/4, converged: the benchmark window's reference (tip deflections)."""
    c = case(name, n_steps) if not name.startswith("chain") else chain(int(name[5:]), n_steps)
    return dttmm.simulate(c, elements_per_link=8 if QUICK else 64, h=H / 4, cut_loads=False, energy=False)


def tip_error(res: dttmm.Result, ref: dttmm.Result) -> float:
    """RMS over time of the tip deflections' difference (m), on the reference's grid."""
    n = min(len(res.t), len(ref.t))
    return float(np.sqrt(np.mean((res.tip_deflection[:n] - ref.tip_deflection[:n]) ** 2)))


def least_of_rounds(benchmark, run, rounds: int, **measures):
    """``run()`` once untimed (numba compiles or loads the kernel), then timed by
    ``benchmark.pedantic`` over ``rounds`` rounds of one call each: (the last round's Result,
    {name: the least over the rounds of ``measure(Result)``} for each of ``measures``)."""
    run()
    holder = {name: [] for name in measures}

    def target():
        holder["res"] = res = run()
        for name, measure in measures.items():
            holder[name].append(measure(res))

    benchmark.pedantic(target, rounds=rounds, iterations=1, warmup_rounds=0)
    return holder["res"], {name: min(holder[name]) for name in measures}


def run_benchmark(benchmark, method: str, c: dttmm.Case, k, h: float, ref_name: str | None, **options):
    """Time ``method`` on ``c`` (one warm-up round: numba compiles, caches fill) and fill extra_info.

    Timing protocol (:mod:`experiments.timing`): one BLAS thread; per round the CPU time of the
    whole call and the method's solve-only wall time; extra_info keeps the least (and median)
    of the rounds per step, the largest load average seen and whether the point is noisy.
    """
    import statistics

    from dttmm.threads import one_blas_thread
    from experiments.timing import SPREAD_MAX, cores, load_average

    try:
        f = resolve(method)
    except MethodUnavailable as exc:
        pytest.skip(str(exc))
    holder = {"cpu": [], "solve": [], "load": [load_average()]}

    def target():
        c0 = time.process_time()
        holder["res"] = f(c, k, h, **options)
        holder["cpu"].append(time.process_time() - c0)
        holder["solve"].append(holder["res"].wall_time)
        holder["load"].append(load_average())

    with one_blas_thread():
        benchmark.pedantic(target, rounds=1 if QUICK else 3, iterations=1, warmup_rounds=0 if QUICK else 1)
    res = holder["res"]
    rounds = 1 if QUICK else 3
    cpu, solve = holder["cpu"][-rounds:], holder["solve"][-rounds:]  # the warm-up round is not kept
    n_el = (k or 0) * len(c.model.links)
    load = max((x for x in holder["load"] if math.isfinite(x)), default=math.nan)
    spread = statistics.median(cpu) / min(cpu) - 1 if min(cpu) > 0 else 0.0
    info = benchmark.extra_info
    info.update(
        method=method,
        case=c.name,
        elements_per_link=k,
        n_links=len(c.model.links),
        h=h,
        n_steps=res.n_steps,
        n_dof=res.meta.get("n_dof"),
        final_system_size=res.meta.get("final_system_size"),
        iterations=res.meta.get("iterations_mean", res.meta.get("newton_iterations_per_step")),
        solve_time=min(solve),
        time_per_step=min(solve) / res.n_steps,
        time_per_step_median=statistics.median(solve) / res.n_steps,
        time_per_element_step=min(solve) / res.n_steps / n_el if n_el else None,
        cpu_per_step=min(cpu) / res.n_steps,
        cpu_per_step_median=statistics.median(cpu) / res.n_steps,
        rounds=len(cpu),
        load_max=load,
        noisy=bool(load > cores() or spread > SPREAD_MAX),
        options={k_: str(v) for k_, v in options.items()},
    )
    if ref_name is not None:
        info["tip_error_l2"] = tip_error(res, reference(ref_name, res.n_steps))
    return res
