"""Sweep runner, run store, metrics and method registry (fast tier, test-only rotor method)."""

from __future__ import annotations

import os
from pathlib import Path

import _rotor_method as rotor
import numpy as np
import pandas as pd
import pytest
from conftest import case, shortened

from experiments import methods, metrics
from experiments.runs import RunStore, Task
from experiments.sweep import pending, run_sweep

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
TIMING = ["wall_time", "run_time", "worker"]


@pytest.fixture(autouse=True)
def _rotor():
    methods.register("rotor", rotor.simulate)
    rotor.CALLS["n"] = 0
    rotor.FAIL_AFTER["n"] = None
    yield
    rotor.FAIL_AFTER["n"] = None


def _cases():
    return {
        "single_link": shortened(case("single_link"), 0.2, 0.01),
        "three_link": shortened(case("three_link"), 0.2, 0.01),
    }


def _tasks(cases):
    return [
        Task(c, "rotor", k, h, cases[c].scenario.duration)
        for c in cases
        for k in (1, 2, 4)
        for h in (1e-2, 5e-3)
    ]


def _references(cases):
    return {c: (rotor.simulate(x, elements_per_link=1000, h=1e-5), "rotor-ref") for c, x in cases.items()}


def test_errors_of_a_result_against_itself_are_zero_and_offsets_are_measured():
    c = _cases()["three_link"]
    ref = rotor.simulate(c, elements_per_link=8, h=1e-3)
    assert all(v == 0.0 for v in metrics.errors(ref, ref).values())
    other = rotor.simulate(c, elements_per_link=8, h=2e-3)  # angles differ by (h² − h_ref²)·t
    e = metrics.errors(other, ref)
    expect = (2e-3**2 - 1e-3**2) * c.scenario.output_times
    assert e["angle2_linf"] == pytest.approx(expect.max(), rel=1e-9)
    assert e["angle2_l2"] == pytest.approx(np.sqrt(np.mean(expect**2)), rel=1e-9)
    assert set(e) == set(metrics.columns(3))


def test_reference_on_a_finer_grid_is_interpolated():
    c = _cases()["single_link"]
    fine = shortened(c, 0.2, 0.002)
    ref = rotor.simulate(fine, elements_per_link=8, h=1e-3)
    res = rotor.simulate(c, elements_per_link=8, h=1e-3)
    e = metrics.errors(res, ref)
    assert e["tip1_linf"] < 1e-6 and e["angle1_linf"] < 1e-4


def test_killed_sweep_resumes_and_recomputes_only_missing_runs(tmp_path):
    cases = _cases()
    tasks = _tasks(cases)
    refs = _references(cases)
    store = RunStore(tmp_path)
    rotor.CALLS["n"] = 0
    rotor.FAIL_AFTER["n"] = 5  # the 5th run "kills" the sweep
    with pytest.raises(KeyboardInterrupt):
        run_sweep(tasks, cases, store, references=refs, scheduler="serial", progress=False)
    assert len(pending(tasks, store)) == len(tasks) - 4
    done = [t for t in tasks if store.has(t)]  # the sweep starts the longest runs first
    first = store.table(done, refs)
    assert len(done) == 4 and len(first) == 4
    rotor.FAIL_AFTER["n"] = None
    rotor.CALLS["n"] = 0
    table = run_sweep(tasks, cases, store, references=refs, scheduler="serial", progress=False)
    assert rotor.CALLS["n"] == len(tasks) - 4
    assert len(table) == len(tasks) and (table.status == "ok").all()
    at = [tasks.index(t) for t in done]
    pd.testing.assert_frame_equal(table.iloc[at][first.columns].reset_index(drop=True), first)
    rotor.CALLS["n"] = 0
    run_sweep(tasks, cases, store, references=refs, scheduler="serial", progress=False)
    assert rotor.CALLS["n"] == 0
    # errors fall with k as the rotor is built to (1/k² in the deflection)
    t1 = table[(table.case == "single_link") & (table.h == 5e-3)].sort_values("k")
    assert np.all(np.diff(t1.tip1_l2) < 0)


def test_failures_are_rows_with_nan_and_a_reason(tmp_path):
    def not_yet(case, **kw):
        raise NotImplementedError

    methods.register("not-yet", not_yet)
    cases = _cases()
    T = 0.2
    tasks = [
        Task("single_link", "rotor", 2, 1e-2, T, (("fail", True),)),
        Task("single_link", "rotor", 2, 1e-2, T, (("nan", True),)),
        Task("single_link", "not-yet", 2, 1e-2, T),
        Task("single_link", "no-such-method", 2, 1e-2, T),
        Task("single_link", "rotor", 2, 1e-2, T),
    ]
    table = run_sweep(
        tasks, cases, RunStore(tmp_path), references=_references(cases), scheduler="serial", progress=False
    ).set_index("method")
    assert len(table) == len(tasks)
    assert list(table.status) == ["failed", "failed", "unavailable", "unavailable", "ok"]
    reasons = list(table.reason)
    assert "test failure on request" in reasons[0] and "non-finite" in reasons[1]
    assert "not implemented" in reasons[2] and "unknown method" in reasons[3]
    assert table.ee_l2.isna().tolist() == [True, True, True, True, False]


def test_available_reports_reasons_instead_of_crashing():
    def not_yet(case, **kw):
        raise NotImplementedError("soon")

    methods.register("not-yet", not_yet)
    av = methods.available(["rotor", "not-yet", "no-such-method"])
    assert av["rotor"] is None
    assert "not implemented" in av["not-yet"] and "soon" in av["not-yet"]
    assert "unknown method" in av["no-such-method"]


def test_available_in_parallel_processes_gives_the_serial_answer():
    """The probe in forked processes (one per engine module) sees the methods registered here
    and reports the same reasons, in the order asked."""

    def not_yet(case, **kw):
        raise NotImplementedError("soon")

    methods.register("not-yet", not_yet)
    asked = ["no-such-method", "rotor", "not-yet", "pinocchio-rigid"]
    serial = methods.available(asked, workers=1)
    parallel = methods.available(asked, workers=2)
    assert list(parallel) == asked
    assert parallel == serial
    assert parallel["rotor"] is None and "not implemented" in parallel["not-yet"]


def test_separate_cluster_gives_the_same_table_as_a_local_run(tmp_path, loopback_cluster):
    cases = _cases()
    tasks = _tasks(cases) + [Task("three_link", "rotor", 2, 1e-2, 0.2, (("fail", True),))]
    refs = _references(cases)
    local = run_sweep(tasks, cases, RunStore(tmp_path / "local"), references=refs, workers=2, progress=False)
    remote = run_sweep(
        tasks,
        cases,
        RunStore(tmp_path / "remote"),
        references=refs,
        scheduler=loopback_cluster,
        progress=False,
    )
    assert len(local) == len(tasks) and (local.status == "ok").sum() == len(tasks) - 1
    assert local.worker.nunique() >= 1 and not local.worker.str.contains(str(os.getpid())).any()
    timing = TIMING + [c for c in local.columns if c.startswith("timing_")]  # measured, differ per run
    pd.testing.assert_frame_equal(local.drop(columns=timing), remote.drop(columns=timing))
