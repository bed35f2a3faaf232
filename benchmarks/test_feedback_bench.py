"""Cost of closed-loop (pd) joints in the compiled DT-TMM kernel.

experiments/cases/control/closed_loop_three_link.toml at k = 8, h = 1e-3, outputs off: the pd
laws with moment feedback as shipped (g_M = 0.5) and without it (g_M = 0), against the same
arm open loop with the torques of the closed-loop run replayed from a table (the torque at every
step end is the same, so the two runs take the same path). extra_info: CPU time of the time
loop per step (``meta["loop_cpu_time"]``, least of the rounds), sweeps per step, and the ratio
closed/open of the per-step cost. Target (measured, not asserted): g_M = 0 at most 5 % more per
step than open loop.

Run: ``pytest benchmarks/test_feedback_bench.py --benchmark-enable``.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pytest
from conftest import QUICK, case

import dttmm
from dttmm.drives import Drive, Table

pytest.importorskip("numba")
from dttmm.kernel import driver

K = 8
H = 1e-3
N_STEPS = 10 if QUICK else 1000
ROUNDS = 1 if QUICK else 5


def closed_case(moment_gain: float) -> dttmm.Case:
    c = case("control/closed_loop_three_link", n_steps=N_STEPS, h=H)
    drives = tuple(Drive("torque", dc.replace(d.law, moment_gain=moment_gain)) for d in c.scenario.drives)
    return dc.replace(c, scenario=dc.replace(c.scenario, drives=drives))


def replay(closed: dttmm.Case, res: dttmm.Result) -> dttmm.Case:
    """The arm open loop, each joint driven by the closed-loop run's torques (a table through
    the torque at every step end)."""
    drives = tuple(
        Drive("torque", Table(tuple(res.t), tuple(res.joint_torque[:, i])))
        for i in range(res.joint_torque.shape[1])
    )
    return dc.replace(closed, scenario=dc.replace(closed.scenario, drives=drives))


def _run(c):
    return dttmm.simulate(c, elements_per_link=K, h=H, engine="numba", cut_loads=False, energy=False)


@pytest.mark.parametrize("moment_gain", [0.0, 0.5])
def test_feedback_cost_per_step(benchmark, moment_gain):
    benchmark.group = "kernel:feedback"
    driver.warmup()
    closed = closed_case(moment_gain)
    first = _run(closed)
    opened = replay(closed, first)
    cpu = {"closed": [], "open": []}
    out = {}

    def target():
        for name, c in (("closed", closed), ("open", opened)):
            out[name] = _run(c)
            cpu[name].append(out[name].meta["loop_cpu_time"])

    benchmark.pedantic(target, rounds=ROUNDS, iterations=1, warmup_rounds=0 if QUICK else 1)
    # the replay follows the closed-loop run (same torques at every step end)
    assert np.abs(out["open"].joint_angle - out["closed"].joint_angle).max() <= 1e-8
    per_step = {name: min(v) / N_STEPS for name, v in cpu.items()}
    benchmark.extra_info.update(
        moment_gain=moment_gain,
        elements_per_link=K,
        n_steps=N_STEPS,
        cpu_per_step_closed=per_step["closed"],
        cpu_per_step_open=per_step["open"],
        sweeps_per_step_closed=out["closed"].meta["iterations_mean"],
        sweeps_per_step_open=out["open"].meta["iterations_mean"],
        cost_ratio=per_step["closed"] / per_step["open"],
    )
