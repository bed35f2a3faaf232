"""Timing protocol: repeats, CPU/wall time, load and noise marks, one BLAS thread, repeats in
the sweep (only where a study reports cost), and the equal-accuracy read-off of work-precision."""

from __future__ import annotations

import math
import time

import _rotor_method as rotor
import numpy as np
import pandas as pd
import pytest
from conftest import case, shortened

from dttmm import InputError
from dttmm.threads import blas_threads, one_blas_thread
from experiments import methods, runs, timing
from experiments.runs import RunStore, Task, execute
from experiments.studies import work_precision as wp
from experiments.sweep import pending, run_sweep

_REAL_WARM_UP = runs._warm_up


def _burn(seconds):
    t0 = time.process_time()
    while time.process_time() - t0 < seconds:
        pass
    return seconds


def test_measure_keeps_the_first_value_and_min_median_of_cpu_time():
    calls = []
    durations = iter([0.03, 0.01, 0.02])

    def f():
        calls.append(1)
        return _burn(next(durations))

    value, t = timing.measure(f, 3)
    assert value == 0.03 and len(calls) == 3 and t.repeats == 3
    assert 0.01 <= t.cpu_min < 0.015 and 0.02 <= t.cpu_median < 0.03  # min 0.01 s, median 0.02 s
    assert t.wall_min > 0 and np.isnan(t.solve_min)  # a float is no Result: no solve time
    assert t.noisy and "above the minimum" in t.noise  # median twice the minimum
    assert t.columns()["timing_repeats"] == 3


def test_load_above_the_core_count_marks_noise(monkeypatch):
    monkeypatch.setattr(timing, "load_average", lambda: 99.0)
    _, t = timing.measure(lambda: _burn(0.001), 1)
    assert t.noisy and t.load_max == 99.0 and f"> {timing.cores()} cores" in t.noise
    monkeypatch.setattr(timing, "load_average", lambda: 0.0)
    _, t = timing.measure(lambda: None, 1)
    assert not t.noisy and t.noise == "" and t.spread == 0.0


def test_short_calls_are_repeated_until_their_cpu_time_adds_up():
    _, t = timing.measure(lambda: _burn(0.004), 3, min_cpu=0.04)
    assert 10 <= t.repeats <= 11 and t.cpu_min >= 0.004  # 10 calls of 4 ms reach 40 ms
    _, t = timing.measure(lambda: _burn(0.004), 3, min_cpu=1e3)
    assert t.repeats == timing.MAX_REPEATS
    _, t = timing.measure(lambda: _burn(0.03), 3, min_cpu=0.04)
    assert t.repeats == 3  # long calls: the repeats asked for, no more
    first = iter([0.2])  # a first call that compiles does not stand for the short ones after it
    _, t = timing.measure(lambda: _burn(next(first, 0.004)), 3, min_cpu=0.04)
    assert 10 <= t.repeats <= 11


def test_repeats_must_be_a_positive_integer():
    for bad in (0, -1, 1.5, True):
        with pytest.raises(InputError, match="repeats"):
            timing.measure(lambda: None, bad)


def test_one_blas_thread_inside_the_block():
    np.dot(np.ones((50, 50)), np.ones((50, 50)))  # BLAS loaded
    with one_blas_thread() as n:
        assert n in (0, 1) and blas_threads() in (0, 1)


@pytest.fixture
def _rotor(monkeypatch):
    monkeypatch.setattr(timing, "MIN_CPU", 0.0)  # these tests count the calls a study asks for
    monkeypatch.setattr(runs, "_WARM", set())
    monkeypatch.setattr(runs, "_warm_up", lambda *a: None)  # counted in its own test below
    methods.register("rotor", rotor.simulate)
    rotor.CALLS["n"] = 0
    rotor.FAIL_AFTER["n"] = None
    yield
    rotor.FAIL_AFTER["n"] = None


def test_execute_repeats_and_records_the_timing(_rotor, monkeypatch):
    monkeypatch.setattr(runs, "_warm_up", _REAL_WARM_UP)
    c = shortened(case("single_link"), 0.1, 0.01)
    task = Task("single_link", "rotor", 1, 1e-2, 0.1)
    out = execute(methods.resolve("rotor"), c, task, repeats=3)
    # one untimed warm-up call on the case's first steps (the first time this process times it), then 3
    assert out.status == "ok" and rotor.CALLS["n"] == 4
    execute(methods.resolve("rotor"), c, task, repeats=3)
    assert rotor.CALLS["n"] == 7  # warmed up already: the 3 timed calls only
    assert (
        out.timing["timing_repeats"] == 3 and out.timing["timing_cpu_min"] <= out.timing["timing_cpu_median"]
    )
    assert out.timing["timing_solve_min"] == pytest.approx(out.result.wall_time, rel=1.0)
    assert execute(methods.resolve("rotor"), c, task).timing["timing_repeats"] == 1


def test_sweep_repeats_only_what_a_cost_study_asks_for(tmp_path, _rotor):
    c = {"single_link": shortened(case("single_link"), 0.1, 0.01)}
    a, b = (Task("single_link", "rotor", k, 1e-2, 0.1) for k in (1, 2))
    store = RunStore(tmp_path)
    run_sweep([a, b], c, store, scheduler="serial", progress=False)
    assert rotor.CALLS["n"] == 2  # accuracy only: one call each
    assert pending([a, b], store) == [] and pending([a, b], store, {a: 3}) == [a]
    table = run_sweep([a, b], c, store, scheduler="serial", progress=False, repeats={a: 3})
    assert rotor.CALLS["n"] == 5  # a rerun with 3 timed calls, b reused
    assert dict(zip(table.k, table.timing_repeats)) == {1: 3, 2: 1}
    assert pending([a, b], store, {a: 3}) == []


def test_envelope_interpolates_a_power_law_exactly():
    cost = np.array([1.0, 2.0, 4.0, 8.0, 3.0])
    err = cost**-2.0
    err[-1] = 1.0  # a dominated run: dearer than one with a smaller error
    env = wp.envelope(cost, err)
    assert env == [(1.0, 1.0), (0.25, 2.0), (0.0625, 4.0), (0.015625, 8.0)]
    assert wp.cost_at(env, 0.1) == pytest.approx(0.1**-0.5)  # between envelope points
    assert wp.cost_at(env, 2.0) == 1.0  # the cheapest run is already better
    assert math.isnan(wp.cost_at(env, 1e-3))  # never reached


def test_equal_accuracy_ratios_only_within_the_same_strain():
    rows = []
    for m, scale in (("dttmm", 1.0), ("global", 10.0), ("dttmm-2nd", 2.0), ("exudyn-ancf", 6.0)):
        for c in (1.0, 2.0, 4.0, 8.0):
            rows.append(
                {"case": "x", "method": m, "k": 4, "status": "ok", "cpu_time": scale * c, "ee_l2": c**-2.0}
            )
    eq = wp.equal_accuracy(pd.DataFrame(rows), targets=(0.1,))
    r = eq.set_index("method")
    assert r.loc["global", "against"] == "dttmm" and r.loc["global", "ratio"] == pytest.approx(10.0)
    assert r.loc["exudyn-ancf", "against"] == "dttmm-2nd" and r.loc["exudyn-ancf", "ratio"] == pytest.approx(
        3.0
    )
    assert np.isnan(r.loc["dttmm", "ratio"]) and np.isnan(r.loc["dttmm-2nd", "ratio"])


def test_work_precision_summary_quotes_the_least_times_of_the_repeats():
    # the first call's solve time (``wall_time``) carries one-off costs such as JIT compilation:
    # the summary must quote the least wall and CPU times over the repeats instead
    rows = []
    for m, first_call in (("dttmm", 5.0), ("global", 0.2)):
        for k, err in ((2, 1e-3), (4, 1e-4)):
            rows.append(
                {
                    "case": "x",
                    "method": m,
                    "options": "",
                    "k": k,
                    "h": 1e-3,
                    "status": "ok",
                    "ee_l2": err,
                    "wall_time": first_call,
                    "timing_wall_min": 0.01 * k,
                    "timing_cpu_min": 0.009 * k,
                    "timing_cpu_median": 0.009 * k,
                    "timing_repeats": 3,
                    "timing_noisy": False,
                    "timing_noise": "",
                }
            )
    s = wp.analyse(None, pd.DataFrame(rows))["work_precision_summary"].set_index("method")
    assert s.loc["dttmm", "wall_time_to_target"] == pytest.approx(0.04)
    assert s.loc["global", "wall_time_at_best"] == pytest.approx(0.04)
    assert s.loc["dttmm", "cpu_time_to_target"] == pytest.approx(0.036)


def test_execute_asks_for_min_cpu_only_where_cost_is_reported(_rotor, monkeypatch):
    monkeypatch.setattr(timing, "MIN_CPU", 1e3)  # never reached: the cap decides
    monkeypatch.setattr(timing, "MAX_REPEATS", 5)
    c = shortened(case("single_link"), 0.1, 0.01)
    task = Task("single_link", "rotor", 1, 1e-2, 0.1)
    assert execute(methods.resolve("rotor"), c, task, repeats=3).timing["timing_repeats"] == 5
    assert execute(methods.resolve("rotor"), c, task, repeats=1).timing["timing_repeats"] == 1
    assert rotor.CALLS["n"] == 6


def test_a_long_call_is_timed_once_and_says_so():
    calls = []

    def f():
        calls.append(1)
        return _burn(0.06)

    _, t = timing.measure(f, 3, min_cpu=0.1, long_cpu=0.05)
    assert len(calls) == 1 and t.repeats == 1 and "timed once" in t.noise
    calls.clear()
    _, t = timing.measure(f, 3, min_cpu=0.1, long_cpu=1.0)  # not long: the repeats asked for (and min_cpu)
    assert len(calls) == 3 and "timed once" not in t.noise
    calls.clear()
    _, t = timing.measure(f, 1, long_cpu=0.05)  # one call asked for: no note
    assert len(calls) == 1 and t.noise == "" or "load" in t.noise


def test_short_calls_with_a_wide_spread_are_called_again():
    durations = iter([0.03, 0.01, 0.02, 0.02] + [0.01] * 60)
    _, t = timing.measure(lambda: _burn(next(durations)), 3, min_cpu=0.03)
    # after 3 calls the median lies 100 % above the least: called until it is within SPREAD_MAX
    assert t.repeats > 3 and t.spread <= timing.SPREAD_MAX


def test_the_estimate_counts_the_calls_of_the_timing_rule():
    from experiments import estimate

    assert estimate.calls(5.0, 3) == 1  # long: once
    assert estimate.calls(0.05, 3) == 3
    assert estimate.calls(0.004, 3) == 25  # 25 × 4 ms reach MIN_CPU = 0.1 s
    assert estimate.calls(0.05, 1) == 1
    rows = [
        {
            "method": "m",
            "status": "ok",
            "k": k,
            "h": 1e-3,
            "duration": 1.0,
            "n_joints": 1,
            "timing_cpu_min": c,
        }
        for k, c in [(1, 0.1), (3, 0.2), (7, 0.4), (15, 0.8), (15, 30.0)]  # the last one compiled
    ]
    fit = estimate.fit(rows)["m"]
    assert fit["p"] == pytest.approx(1.0, abs=1e-6) and fit["left_out"] == 1  # cpu ∝ k + 1
    task = Task("c", "m", 31, 1e-3, 1.0)
    assert estimate.one_call(task, case("single_link"), {"m": fit}) == pytest.approx(1.6, rel=1e-6)
