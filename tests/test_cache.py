"""The run and reference caches cannot lie: damaged entries are recomputed with a warning,
changed physics or code never finds an old entry, concurrent sweeps leave a readable store,
and runs a method flags (unconverged, ill-conditioned) are marked as such."""

from __future__ import annotations

import dataclasses as dc
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import _rotor_method as rotor
import numpy as np
import pandas as pd
import pytest
from conftest import case, shortened

from experiments import fingerprint, methods
from experiments.cachefiles import CacheWarning
from experiments.references import RefSpec, reference
from experiments.runs import RunStore, Task
from experiments.studies import _common, scheme
from experiments.sweep import run_sweep

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
TIMING = ["wall_time", "run_time", "worker"]


def _untimed(df):
    """The table without its measured timings (they differ per run)."""
    return df.drop(columns=[c for c in df.columns if c in TIMING or c.startswith("timing_")])


@pytest.fixture(autouse=True)
def _rotor():
    methods.register("rotor", rotor.simulate)
    rotor.CALLS["n"] = 0
    rotor.FAIL_AFTER["n"] = None
    yield


def _cases():
    return {"three_link": shortened(case("three_link"), 0.2, 0.01)}


def _tasks(cases, method="rotor"):
    return [Task(c, method, k, h, 0.2) for c in cases for k in (1, 2, 4) for h in (1e-2, 5e-3)]


def _refs(cases):
    n = rotor.CALLS["n"]  # the reference runs are not counted as runs of the sweep
    out = {c: (rotor.simulate(x, elements_per_link=1000, h=1e-5), "rotor-ref") for c, x in cases.items()}
    rotor.CALLS["n"] = n
    return out


def _sweep(tasks, cases, store):
    return run_sweep(tasks, cases, store, references=_refs(cases), scheduler="serial", progress=False)


def _entry(store, task):
    jpath, ppath, _ = store._paths(task)
    return jpath, ppath


def _truncate(path):
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])


def _edit_error(jpath, ppath):
    row = json.loads(jpath.read_text())
    row["ee_l2"] = 1e-9  # a plausible, wrong number
    jpath.write_text(json.dumps(row, indent=1))


DAMAGE = {
    "truncated history": lambda j, p, other: _truncate(p),
    "truncated row": lambda j, p, other: _truncate(j),
    "swapped entry": lambda j, p, other: (
        j.write_bytes(other[0].read_bytes()),
        p.write_bytes(other[1].read_bytes()),
    ),
    "swapped history": lambda j, p, other: p.write_bytes(other[1].read_bytes()),
    "edited row": lambda j, p, other: _edit_error(j, p),
    "deleted history": lambda j, p, other: p.unlink(),
    "empty row": lambda j, p, other: j.write_text(""),
    "row not a dict": lambda j, p, other: j.write_text("[1, 2]"),
}


# each damage runs three sweeps; the default tier keeps a damaged history and a plausible wrong
# row (the one a checksum-free cache would serve), the other kinds run in the slow tier
DAMAGE_DEFAULT = ("truncated history", "edited row")


@pytest.mark.parametrize(
    "damage", [pytest.param(d, marks=[] if d in DAMAGE_DEFAULT else [pytest.mark.slow]) for d in DAMAGE]
)
def test_damaged_entry_is_recomputed_with_a_warning_and_equals_a_fresh_run(tmp_path, damage):
    cases = _cases()
    tasks = _tasks(cases)
    store = RunStore(tmp_path / "a")
    first = _sweep(tasks, cases, store)
    victim, other = tasks[2], tasks[3]
    DAMAGE[damage](*_entry(store, victim), _entry(store, other))
    rotor.CALLS["n"] = 0
    with pytest.warns(CacheWarning, match="discarded"):
        again = _sweep(tasks, cases, RunStore(tmp_path / "a"))
    assert rotor.CALLS["n"] == 1  # the damaged run alone
    fresh = _sweep(tasks, cases, RunStore(tmp_path / "fresh"))
    pd.testing.assert_frame_equal(_untimed(again), _untimed(fresh))
    pd.testing.assert_frame_equal(_untimed(again), _untimed(first))
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)  # repaired: read back without complaint
        assert all(RunStore(tmp_path / "a", cases).has(t) for t in tasks)


def test_deleted_row_is_simply_missing_and_recomputed(tmp_path):
    cases = _cases()
    tasks = _tasks(cases)
    store = RunStore(tmp_path)
    _sweep(tasks, cases, store)
    _entry(store, tasks[0])[0].unlink()
    rotor.CALLS["n"] = 0
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)
        table = _sweep(tasks, cases, RunStore(tmp_path))
    assert rotor.CALLS["n"] == 1 and len(table) == len(tasks)


def test_history_of_a_damaged_entry_is_not_returned(tmp_path):
    cases = _cases()
    tasks = _tasks(cases)
    store = RunStore(tmp_path)
    _sweep(tasks, cases, store)
    assert store.history(tasks[0]) is not None
    _truncate(_entry(store, tasks[0])[1])
    with pytest.warns(CacheWarning):
        assert store.history(tasks[0]) is None
    with pytest.raises(KeyError):
        store.row(tasks[0])


def _heavier_payload(c, mass):
    links = list(c.model.links)
    links[-1] = dc.replace(links[-1], payload=dc.replace(links[-1].payload, mass=mass))
    return dc.replace(c, model=dc.replace(c.model, links=tuple(links)))


def test_case_edit_changes_the_key_and_the_results(tmp_path):
    cases = _cases()
    assert cases["three_link"].model.links[-1].payload.mass == 0.1  # the case file as written
    tasks = _tasks(cases)
    light = _sweep(tasks, cases, RunStore(tmp_path))
    heavy_cases = {"three_link": _heavier_payload(cases["three_link"], 1.0)}
    rotor.CALLS["n"] = 0
    _sweep(tasks, heavy_cases, RunStore(tmp_path))
    assert rotor.CALLS["n"] == len(tasks)  # nothing reused from the 0.1 kg case
    # the rotor's last joint turns slower under the heavier payload
    for t in tasks:
        a = RunStore(tmp_path, cases).history(t).joint_angle[-1, 2]
        b = RunStore(tmp_path, heavy_cases).history(t).joint_angle[-1, 2]
        assert abs(b) < 0.9 * abs(a)
    rotor.CALLS["n"] = 0
    back = _sweep(tasks, cases, RunStore(tmp_path))  # the original case finds its own entries
    assert rotor.CALLS["n"] == 0
    pd.testing.assert_frame_equal(_untimed(back), _untimed(light))


def test_reformatting_a_case_file_keeps_the_key(tmp_path):
    import dttmm

    c = case("three_link")
    path = dttmm.save_case(c, tmp_path / "three_link.toml")  # same content, other bytes
    again = dttmm.load_case(path)
    assert path.read_bytes() != (ROOT / "experiments/cases/three_link.toml").read_bytes()
    assert fingerprint.case_digest(again) == fingerprint.case_digest(c)
    assert fingerprint.case_digest(_heavier_payload(c, 1.0)) != fingerprint.case_digest(c)


def test_code_version_follows_every_source_file_of_the_tree(tmp_path):
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "kernel.py").write_text("A = 1\n")
    h0 = fingerprint.tree_hash(pkg)
    (pkg / "sub" / "kernel.py").write_text("A = 2\n")
    h1 = fingerprint.tree_hash(pkg)
    (pkg / "sub" / "new.py").write_text("")
    h2 = fingerprint.tree_hash(pkg)
    (pkg / "sub" / "new.py").rename(pkg / "moved.py")
    h3 = fingerprint.tree_hash(pkg)
    assert len({h0, h1, h2, h3}) == 4
    v = fingerprint.code_version("exudyn-ancf")
    assert v["sources"]["dttmm"] and v["sources"]["reference_models"]
    assert fingerprint.code_version("dttmm")["sources"].keys() == {"dttmm"}
    assert fingerprint.code_version("rotor")["sources"].keys() == {"dttmm", "_rotor_method"}
    assert (
        fingerprint.code_version("dttmm-2nd")["method_options"]
        != fingerprint.code_version("dttmm")["method_options"]
    )


def test_recompute_ignores_and_rewrites_every_entry(tmp_path):
    cases = _cases()
    tasks = _tasks(cases)
    first = _sweep(tasks, cases, RunStore(tmp_path))
    rotor.CALLS["n"] = 0
    again = _sweep(tasks, cases, RunStore(tmp_path, recompute=True))
    assert rotor.CALLS["n"] == len(tasks)
    pd.testing.assert_frame_equal(_untimed(again), _untimed(first))


_SLOW_METHOD = """
import time
import _rotor_method as rotor

def simulate(case, **kw):
    time.sleep(0.02)  # long enough for the two sweeps to overlap
    return rotor.simulate(case, **kw)
"""

_CONCURRENT = """
import sys, time
from pathlib import Path
me, root = sys.argv[1], Path(sys.argv[2])
sys.path[:0] = [{tests!r}, {root!r}, str(root)]
import slow_rotor
from conftest import case, shortened
from experiments import methods
from experiments.runs import RunStore, Task
from experiments.sweep import run_sweep

methods.register("slow-rotor", slow_rotor.simulate)
(root / f"ready-{{me}}").touch()
while not all((root / f"ready-{{i}}").exists() for i in "ab"):
    time.sleep(0.01)
cases = {{"three_link": shortened(case("three_link"), 0.2, 0.01)}}
tasks = [Task("three_link", "slow-rotor", k, h, 0.2) for k in range(1, 9) for h in (1e-2, 5e-3, 2e-3)]
table = run_sweep(tasks, cases, RunStore(root / "store"), scheduler="serial", progress=False)
assert len(table) == len(tasks) and (table.status == "ok").all(), table
print("done", len(table))
"""


def test_two_concurrent_sweeps_on_one_store_leave_it_complete_and_readable(tmp_path, monkeypatch):
    (tmp_path / "slow_rotor.py").write_text(_SLOW_METHOD)
    script = tmp_path / "sweep_once.py"
    script.write_text(_CONCURRENT.format(tests=str(TESTS), root=str(ROOT)))
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    procs = [
        subprocess.Popen(
            [sys.executable, str(script), me, str(tmp_path)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )
        for me in "ab"
    ]
    outs = [p.communicate(timeout=300) for p in procs]
    for p, (out, err) in zip(procs, outs):
        assert p.returncode == 0, err.decode()[-2000:]
        assert b"done 24" in out

    monkeypatch.syspath_prepend(str(tmp_path))  # the same method, to read the store back
    import slow_rotor

    methods.register("slow-rotor", slow_rotor.simulate)
    cases = _cases()
    tasks = [Task("three_link", "slow-rotor", k, h, 0.2) for k in range(1, 9) for h in (1e-2, 5e-3, 2e-3)]
    store = RunStore(tmp_path / "store", cases)
    with warnings.catch_warnings():
        warnings.simplefilter("error", CacheWarning)
        table = store.table(tasks)
        assert all(store.history(t) is not None for t in tasks)
    assert len(table) == len(tasks) and (table.status == "ok").all()
    files = [p.name for p in (tmp_path / "store").rglob("*") if p.is_file()]
    assert sorted(p.rsplit(".", 1)[1] for p in files if p != ".lock") == ["json"] * 24 + ["parquet"] * 24


def test_reference_cache_is_keyed_by_content_and_verified(tmp_path):
    c = _cases()["three_link"]
    spec = [RefSpec("rotor", 64, 1e-4)]
    res, prov = reference(c, spec, tmp_path)
    assert rotor.CALLS["n"] == 1 and prov["status"] == "ok"
    again, prov2 = reference(c, spec, tmp_path)
    assert rotor.CALLS["n"] == 1 and prov2["key"] == prov["key"]
    np.testing.assert_array_equal(again.joint_angle, res.joint_angle)
    # an edited provenance, a truncated history, a changed case: each computed again
    jpath = next(tmp_path.glob("*.json"))
    ppath = next(tmp_path.glob("*.parquet"))
    p = json.loads(jpath.read_text())
    p["method"] = "exudyn-ancf"
    jpath.write_text(json.dumps(p))
    with pytest.warns(CacheWarning, match="edited"):
        reference(c, spec, tmp_path)
    assert rotor.CALLS["n"] == 2
    _truncate(ppath)
    with pytest.warns(CacheWarning, match="sha256"):
        reference(c, spec, tmp_path)
    assert rotor.CALLS["n"] == 3
    with pytest.warns(CacheWarning, match="another case content"):  # same file name, other content
        heavy, hprov = reference(_heavier_payload(c, 1.0), spec, tmp_path)
    assert rotor.CALLS["n"] == 4 and hprov["key"] != prov["key"]
    assert not np.array_equal(heavy.joint_angle, res.joint_angle)
    with pytest.warns(CacheWarning, match="another case content"):  # the file now holds the 1 kg case
        reference(c, spec, tmp_path)
    assert rotor.CALLS["n"] == 5
    reference(c, spec, tmp_path, recompute=True)
    assert rotor.CALLS["n"] == 6


def test_committed_references_verify_and_match_their_files():
    """Every stored reference in data/references reads back (keys may be stale after a code
    change: the report then regenerates them, so only the integrity is checked here)."""
    from experiments.cachefiles import read_entry

    for jpath in sorted((ROOT / "data" / "references").rglob("*.json")):
        key = json.loads(jpath.read_text()).get("key")
        assert key, f"{jpath} has no key (made before references were keyed)"
        record, data = read_entry(jpath, jpath.with_suffix(".parquet"), key)
        assert record["status"] != "ok" or data is not None


def _flaky(case, *, elements_per_link, h, **options):
    """The rotor, flagged unconverged from k = 4 on and failed at k = 8."""
    res = rotor.simulate(case, elements_per_link=elements_per_link, h=h)
    if elements_per_link >= 8:
        return dc.replace(res, status="failed", warnings=("singular matrix at t = 0.1 s",))
    if elements_per_link >= 4:
        return dc.replace(
            res, status="unconverged", warnings=("no convergence after 10 iterations at t = 0.05 s",)
        )
    return res


def test_flagged_runs_are_marked_scored_and_left_out_of_fits(tmp_path):
    methods.register("flaky", _flaky)
    cases = _cases()
    tasks = [Task("three_link", "flaky", k, 1e-2, 0.2) for k in (1, 2, 4, 8)]
    table = _sweep(tasks, cases, RunStore(tmp_path)).set_index("k")
    assert list(table.status) == ["ok", "ok", "unconverged", "failed"]
    assert "no convergence after 10 iterations" in table.reason[4] and table.warnings[4]
    assert "singular matrix" in table.reason[8]
    assert np.isfinite(table.ee_l2[4]) and np.isnan(table.ee_l2[8])  # measured, but flagged
    t = table.reset_index()
    orders = _common.fit_orders(t, "k", "ee_l2", ["case", "method"], refine_descending=False)
    assert orders.n_points.iloc[0] == 2  # k = 1, 2 only


def test_scheme_counts_flagged_runs_as_broken(tmp_path):
    from types import SimpleNamespace

    methods.register("flaky", _flaky)
    methods.register("rotor", rotor.simulate)
    cases = _cases()
    ks = (1, 2, 4)
    tasks = [Task("three_link", m, k, 1e-2, 0.2) for m in ("flaky",) for k in ks]
    table = _sweep(tasks, cases, RunStore(tmp_path))
    plan = SimpleNamespace(studies={"scheme": {"h": 1e-2, "k": 2}})
    summary = scheme.analyse(SimpleNamespace(plan=plan), table)["scheme_summary"].iloc[0]
    assert summary.breaks_at_k == 4 and summary.failed == 1 and summary.flagged == 1
    assert summary.first_reason.startswith("unconverged: no convergence")


def test_payload_edit_in_the_case_file_changes_the_study_tables(tmp_path):
    """End to end with the real solver: the study of a case file whose payload goes from
    0.1 to 1.0 kg is computed again (reference and runs) and its numbers change."""
    from experiments.context import prepare
    from experiments.plan import Plan
    from experiments.study import run_studies

    case_dir = tmp_path / "cases"
    case_dir.mkdir()
    text = (ROOT / "experiments/cases/three_link.toml").read_text()
    assert "payload = { mass = 0.1," in text
    (case_dir / "three_link.toml").write_text(text)
    plan = Plan(
        "tiny",
        {"three_link": 0.04},
        {"three_link": [RefSpec("dttmm", 4, 5e-4)]},
        {"three_link": []},
        {"convergence_k": {"cases": ["three_link"], "methods": ["dttmm"], "ks": [1, 2], "h": 2e-3}},
        output_step=4e-3,
    )

    def study():
        ctx = prepare(plan, tmp_path / "data", case_dir=case_dir, log=None)
        return ctx, run_studies(ctx, scheduler="serial", progress=False)["convergence_k"]

    ctx1, light = study()
    _, again = study()
    pd.testing.assert_frame_equal(_untimed(again), _untimed(light))
    (case_dir / "three_link.toml").write_text(
        text.replace("payload = { mass = 0.1,", "payload = { mass = 1.0,")
    )
    with pytest.warns(CacheWarning, match="another case content"):  # the reference file is stale
        ctx2, heavy = study()
    assert ctx2.provenance["three_link"]["key"] != ctx1.provenance["three_link"]["key"]
    assert not np.array_equal(
        ctx2.references["three_link"][0].joint_angle, ctx1.references["three_link"][0].joint_angle
    )
    assert (heavy.key.to_numpy() != light.key.to_numpy()).all()  # new entries, none reused
    assert not np.allclose(heavy.ee_l2, light.ee_l2, rtol=1e-6, atol=0)
    assert len(list((tmp_path / "data/cache/runs").rglob("*.json"))) == 4


def test_rows_scored_by_other_metrics_code_are_scored_again(tmp_path, monkeypatch):
    from experiments import runs

    cases = _cases()
    tasks = _tasks(cases)
    refs = _refs(cases)
    store = RunStore(tmp_path)
    first = run_sweep(tasks, cases, store, references=refs, scheduler="serial", progress=False)
    calls = []
    real = runs.score
    monkeypatch.setattr(runs, "score", lambda *a: calls.append(1) or real(*a))
    store.table(tasks, refs)
    assert calls == []  # same reference, same metrics code: stored errors used
    monkeypatch.setattr(runs, "_metrics_version", lambda: "other metrics code")
    again = store.table(tasks, refs)
    assert len(calls) == len(tasks)
    pd.testing.assert_frame_equal(again, first)


def test_flagged_runs_are_ringed_in_the_figures_and_named_in_the_text(tmp_path):
    from reports import figures, interpret

    methods.register("flaky", _flaky)
    cases = _cases()
    tasks = [Task("three_link", "flaky", k, 1e-2, 0.2) for k in (1, 2, 4, 8)]
    table = _sweep(tasks, cases, RunStore(tmp_path))
    fig = figures.convergence_k(table, "three_link")
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert any("flagged" in x for x in labels) and any("failed" in x for x in labels)
    text = " ".join(interpret.not_ok(table))
    assert "1 run(s) failed" in text and "1 run(s) finished but were flagged" in text
    assert "unconverged" in text


def test_a_flagged_reference_candidate_is_skipped_like_a_failed_one(tmp_path):
    methods.register("flaky", _flaky)
    c = _cases()["three_link"]
    res, prov = reference(c, [RefSpec("flaky", 4, 1e-4), RefSpec("rotor", 64, 1e-4)], tmp_path)
    assert prov["method"] == "rotor" and res.status == "ok"
    assert len(prov["failures"]) == 1 and "status unconverged: no convergence" in prov["failures"][0]


def test_prune_deletes_the_entries_a_report_did_not_use(tmp_path):
    """Entries read or written after the mark stay; the others (stale code, other plans) go."""
    import os
    import time

    cases = _cases()
    tasks = _tasks(cases)
    _sweep(tasks, cases, RunStore(tmp_path))
    old = time.time() - 3600
    for p in tmp_path.rglob("*"):
        if p.is_file():
            os.utime(p, (old, old))
    mark = time.time() - 1.0
    used = tasks[:2]
    store = RunStore(tmp_path, cases)
    assert all(store.has(t) for t in used)  # a read marks the entry as used
    n_files, n_bytes = store.prune(mark)
    assert n_files == 2 * (len(tasks) - len(used)) and n_bytes > 0  # a record and a history each
    again = RunStore(tmp_path, cases)
    assert [again.has(t) for t in tasks] == [t in used for t in tasks]
    # nothing used at all: the folders go too
    assert again.prune(time.time() + 10.0)[0] == 2 * len(used)
    assert not any(tmp_path.iterdir())
