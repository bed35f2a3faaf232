"""Outside methods under every scheduler, and runs isolated from each other's accidents.

A method from a file (importing a module beside it) or from a module path runs on the default
LocalCluster, on a separately started scheduler and serially; a method that kills its worker
process or hangs is an omission with its reason and takes no other run down; the run store
keeps only the methods' own verdicts (an infrastructure failure is shown, never stored, and one
stored by an earlier version is dropped and computed again); the console noise of a run goes
into its record.
"""

from __future__ import annotations

import json
import os
import pickle
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from conftest import case, shortened

from experiments import methods
from experiments.runs import INFRASTRUCTURE, Outcome, RunStore, Task, execute
from experiments.sweep import _advance, run_sweep

ROOT = Path(__file__).resolve().parents[1]

HELPER = '''
"""A helper module beside the solver file."""


def coarse(k):
    return max(1, k // 2)
'''

SOLVER = '''
"""An outside solver: DT-TMM at half the elements asked, through a helper module beside it."""
import os
import time

from my_helpers import coarse

import dttmm


def simulate(case, *, elements_per_link, h, **options):
    return dttmm.simulate(case, elements_per_link=coarse(elements_per_link), h=h)


def crashes(case, *, elements_per_link, h, **options):
    os._exit(3)  # ends its worker process, as a segfault or the OOM killer would


def hangs(case, *, elements_per_link, h, **options):
    time.sleep(600)


def noisy(case, *, elements_per_link, h, **options):
    os.write(1, b"STATIC SOLVER FAILED: use showHints=True\\n")  # past sys.stdout, as C++ does
    print("a Python-level message")
    return dttmm.simulate(case, elements_per_link=1, h=h)
'''


@pytest.fixture
def solver_dir(tmp_path):
    """A folder outside the package holding the solver file and its helper module."""
    d = tmp_path / "elsewhere"
    d.mkdir()
    (d / "my_helpers.py").write_text(HELPER)
    (d / "my_solver.py").write_text(SOLVER)
    yield d
    for n in [n for n in methods.names() if n not in methods.METHODS]:
        methods.unregister(n)
    sys.modules.pop("my_helpers", None)
    if str(d) in sys.path:
        sys.path.remove(str(d))


def _case():
    return {"three_link": shortened(case("three_link"), 0.02, 4e-3)}


def _infra_rows(frame):
    return frame[frame.reason.fillna("").str.startswith(INFRASTRUCTURE)]


def _stored(store_root: Path) -> dict:
    """Stored rows by task name."""
    rows = {}
    for p in store_root.rglob("*.json"):
        row = json.loads(p.read_text())
        rows[row["task"]] = row
    return rows


# --------------------------------------------------------------------------- every scheduler
@pytest.mark.parametrize("scheduler", ["serial", None])
def test_a_file_method_importing_its_neighbour_runs_under_the_scheduler(solver_dir, tmp_path, scheduler):
    name = methods.load_spec(f"{solver_dir / 'my_solver.py'}:simulate").name
    cases = _case()
    tasks = [Task("three_link", m, k, 2e-3, 0.02) for m in (name, "dttmm") for k in (2, 4)]
    table = run_sweep(
        tasks, cases, RunStore(tmp_path / "runs"), scheduler=scheduler, workers=2, progress=False
    )
    assert len(table) == 4 and (table.status == "ok").all(), table[["method", "k", "status", "reason"]]
    mine = table[table.method == name]
    assert (mine.n_dof < table[table.method == "dttmm"].n_dof.to_numpy()).all()  # it ran at k // 2
    if scheduler is None:
        assert not table.worker.str.endswith(f":{os.getpid()}").any()  # in the cluster's workers


def test_outside_methods_run_on_a_separately_started_scheduler(solver_dir, tmp_path, loopback_cluster):
    """The workers are started elsewhere (another folder, without the solver's folder on their
    path): a file method and a module-path method reach them by value."""
    mod_dir = tmp_path / "modpath"
    mod_dir.mkdir()
    (mod_dir / "their_solver.py").write_text(
        "import dttmm\n\n\ndef simulate(case, *, elements_per_link, h, **options):\n"
        "    return dttmm.simulate(case, elements_per_link=1, h=h)\n"
    )
    sys.path.insert(0, str(mod_dir))
    try:
        a = methods.load_spec(f"{solver_dir / 'my_solver.py'}:simulate").name
        b = methods.load_spec("their_solver:simulate").name
        tasks = [Task("three_link", m, 2, 2e-3, 0.02) for m in (a, b, "dttmm")]
        table = run_sweep(
            tasks, _case(), RunStore(tmp_path / "runs"), scheduler=loopback_cluster, progress=False
        )
    finally:
        sys.path.remove(str(mod_dir))
        sys.modules.pop("their_solver", None)
    assert (table.status == "ok").all(), table[["method", "status", "reason"]]


def test_the_report_runs_a_file_method_through_the_default_local_cluster(solver_dir, tmp_path):
    """`dttmm report --quick --case … --method FILE:fn` as a user types it (default scheduler, a
    LocalCluster of two worker processes, the file in a folder outside the package importing a
    helper beside it): its rows are ok in the scoreboard, and no run of the report was lost."""
    case_file = tmp_path / "tiny_arm.toml"
    case_file.write_text(TINY_CASE)
    out = tmp_path / "report"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "dttmm.cli",
            "report",
            "--quick",
            "--case",
            str(case_file),
            "--method",
            f"{solver_dir / 'my_solver.py'}:simulate",
            "--out",
            str(out),
            "--data",
            str(tmp_path / "data"),
            "--workers",
            "2",
            "--no-progress",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1", "PYTHONPATH": str(ROOT)},
    )
    assert r.returncode == 0, r.stderr[-3000:]
    data = out / "data"
    runs = pd.concat(
        [pd.read_parquet(p) for p in data.glob("*.parquet") if {"method", "status", "reason"} <= _columns(p)],
        ignore_index=True,
    )
    assert _infra_rows(runs).empty, _infra_rows(runs)[["method", "reason"]]
    wp = pd.read_parquet(data / "work_precision.parquet")
    mine = wp[wp.method == "my-solver"]
    assert len(mine) > 0 and (mine.status == "ok").all()
    builtin = wp[wp.method.isin(methods.METHODS)]
    assert (builtin.status == "ok").all(), builtin[builtin.status != "ok"][["method", "k", "h", "reason"]]
    board = (out / "REPORT.md").read_text()
    assert "my-solver" in board
    assert "worker error" not in board and "Failed to deserialize" not in r.stderr


def _columns(path) -> set:
    import pyarrow.parquet as pq

    return set(pq.read_schema(path).names)


TINY_CASE = textwrap.dedent(
    """
    name = "tiny_arm"
    [model]
    gravity = [0.0, 0.0]
    [[model.links]]
    length = 1.0
    EI = 2.0
    rhoA = 0.3
    EA = 7.0e6
    hub = { mass = 0.0, inertia = 0.01 }
    payload = { mass = 0.1, inertia = 0.0 }
    [scenario]
    duration = 0.1
    output_step = 5e-3
    [[scenario.drives]]
    kind = "torque"
    law = "sine"
    amplitude = 0.5
    frequency = 2.0
    """
)


# --------------------------------------------------------------------------- isolation
def test_a_crash_and_a_hang_take_no_other_run_down_and_nothing_infrastructural_is_stored(
    solver_dir, tmp_path, monkeypatch
):
    """On the default LocalCluster: the crashing method is an omission (its worker died, twice),
    the hanging one is an omission (past its time limit: its own verdict, stored), every other
    run is ok; the store holds no infrastructure failure; a second sweep recomputes nothing that
    was ok and runs the crashed runs again."""
    spec = f"{solver_dir / 'my_solver.py'}"
    good = methods.load_spec(f"{spec}:simulate").name  # the default limit (600 s)
    monkeypatch.setattr(methods, "OUTSIDE_TIMEOUT", 3.0)
    crash, hang = (methods.load_spec(f"{spec}:{fn}").name for fn in ("crashes", "hangs"))
    cases = _case()
    tasks = [Task("three_link", m, k, 2e-3, 0.02) for m in (good, "dttmm", "global") for k in (1, 2, 4)]
    tasks += [Task("three_link", crash, 2, 2e-3, 0.02), Task("three_link", hang, 2, 2e-3, 0.02)]
    root = tmp_path / "runs"
    first = run_sweep(tasks, cases, RunStore(root), scheduler=None, workers=2, progress=False)
    by = first.set_index("method")
    assert len(first) == len(tasks)
    assert by.loc[crash, "status"] == "failed" and by.loc[crash, "reason"].startswith(INFRASTRUCTURE)
    assert "worker process died" in by.loc[crash, "reason"]
    assert by.loc[hang, "status"] == "failed" and "ran past its time limit of 3 s" in by.loc[hang, "reason"]
    others = first[~first.method.isin([crash, hang])]
    assert (others.status == "ok").all(), others[others.status != "ok"][["method", "k", "reason"]]
    stored = _stored(root)
    assert len(stored) == len(tasks) - 1  # every run but the crashed one
    assert not any(r["reason"].startswith(INFRASTRUCTURE) for r in stored.values())
    # the second sweep: the ok runs come from the store, untouched; the crash is tried again
    before = {p: p.read_bytes() for p in root.rglob("*.json")}
    second = run_sweep(tasks, cases, RunStore(root), scheduler=None, workers=2, progress=False)
    assert {p: p.read_bytes() for p in before} == before
    assert second.set_index("method").loc[crash, "reason"].startswith(INFRASTRUCTURE)


def test_an_infrastructure_failure_stored_by_an_earlier_version_is_computed_again(tmp_path, capsys):
    """A store written by the sweep of 508f6e1 holds "worker error: …" rows for runs whose worker
    was lost; the next sweep does not trust them: it drops them and computes the runs."""
    cases = _case()
    task = Task("three_link", "dttmm", 2, 2e-3, 0.02)
    store = RunStore(tmp_path / "runs", cases)
    lost = Outcome("failed", "worker error: FutureCancelledError: run-three_link lost dependencies")
    store.write(task, lost, 3)
    assert len(list((tmp_path / "runs").rglob("*.json"))) == 1
    table = run_sweep([task], cases, RunStore(tmp_path / "runs"), scheduler="serial", progress=True)
    assert list(table.status) == ["ok"]
    assert _stored(tmp_path / "runs")[task.key]["status"] == "ok"
    assert "1 stored infrastructure failure(s) of an earlier sweep dropped" in capsys.readouterr().out


def test_a_method_that_cannot_be_loaded_on_the_worker_is_an_unstored_infrastructure_failure(tmp_path):
    """The function reaches the run as bytes; one that cannot be loaded there (here: bytes of a
    module the worker lacks) fails inside the run, as an infrastructure failure."""
    shipped = methods._Shipped.__new__(methods._Shipped)
    shipped.__setstate__({"name": "gone.simulate", "folder": "", "blob": _bytes_of_a_missing_module()})
    bound = methods._Bound(shipped, (), True, 5.0)
    task = Task("three_link", "dttmm", 2, 2e-3, 0.02)
    out = execute(bound, _case()["three_link"], task)
    assert out.infrastructure and out.reason.startswith(INFRASTRUCTURE) and "could not load" in out.reason
    store = RunStore(tmp_path / "runs", _case())
    with pytest.raises(ValueError, match="not a verdict to store"):
        store.write(task, out, 3)
    assert not list((tmp_path / "runs").rglob("*.json"))


def _bytes_of_a_missing_module() -> bytes:
    class _Ref:
        def __reduce__(self):
            return (__import__, ("no_module_on_this_worker_xyz",))

    return pickle.dumps(_Ref())


# --------------------------------------------------------------------------- console, progress
def test_what_an_engine_prints_during_a_run_goes_into_its_record(solver_dir, tmp_path, capfd):
    name = methods.load_spec(f"{solver_dir / 'my_solver.py'}:noisy").name
    table = run_sweep(
        [Task("three_link", name, 2, 2e-3, 0.02)],
        _case(),
        RunStore(tmp_path / "runs"),
        scheduler="serial",
        progress=False,
    )
    printed = capfd.readouterr()
    assert "STATIC SOLVER FAILED" not in printed.out + printed.err
    assert "a Python-level message" not in printed.out + printed.err
    assert (
        "STATIC SOLVER FAILED" in table.console.iloc[0] and "a Python-level message" in table.console.iloc[0]
    )


def test_a_failed_run_names_what_it_printed_in_its_reason():
    def prints_and_fails(case, **kw):
        os.write(2, b"Newton: no convergence at t = 0.01\n")
        raise RuntimeError("solver gave up")

    bound = methods._Bound(prints_and_fails, (), True)
    out = execute(bound, _case()["three_link"], Task("three_link", "dttmm", 2, 2e-3, 0.02))
    assert out.status == "failed" and "solver gave up" in out.reason
    assert "it printed: Newton: no convergence at t = 0.01" in out.reason


class _Bar:
    def __init__(self, total):
        self.total, self.n = total, 0.0

    def update(self, d):
        self.n += d


@pytest.mark.parametrize("total", [0.4, 6.2, 217.0, 5000.0])
def test_the_progress_bar_reaches_its_end_only_with_the_last_run(total):
    bar = _Bar(total)
    _advance(bar, total, last=False)  # the estimates of the finished runs already add up
    assert f"{bar.n:.0f}" != f"{bar.total:.0f}" or bar.n == 0.0
    assert f"{100 * bar.n / bar.total:3.0f}" != "100"
    _advance(bar, total, last=True)
    assert bar.n == bar.total


# --------------------------------------------------------------------------- the command line
def _report(*args, cwd=None):
    return subprocess.run(
        [sys.executable, "-m", "dttmm.cli", "report", *args], capture_output=True, text=True, cwd=cwd or ROOT
    )


def test_a_bad_report_option_is_one_line_with_exit_2():
    for args in (["--bogus"], ["--quick", "--full"], ["--workers", "two"]):
        r = _report(*args)
        assert r.returncode == 2, args
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and "usage:" not in r.stderr, (args, r.stderr)


def test_a_mistyped_method_name_lists_the_built_in_names_and_the_nearest():
    r = _report("--method", "dtmm")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "did you mean 'dttmm'?" in r.stderr and "global" in r.stderr and "exudyn-ancf" in r.stderr


@pytest.mark.parametrize("command", ["modes", "simulate"])
def test_nothing_is_written_before_the_input_is_accepted(tmp_path, command):
    out = tmp_path / "X"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "dttmm.cli",
            command,
            str(tmp_path / "missing.toml"),
            "-k",
            "2",
            "--out",
            str(out),
        ]
        + (["--h", "1e-3"] if command == "simulate" else []),
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert r.returncode == 2 and "missing.toml" in r.stderr
    assert not out.exists()
