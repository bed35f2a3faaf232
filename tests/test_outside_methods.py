"""Methods from outside the package: a file path spec, a module spec, an entry point; bad specs
are one-line errors; a method that raises, returns NaN, returns wrong shapes or hangs is an
omission with its reason, and the report still completes."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from conftest import case, shortened

from dttmm.errors import InputError
from experiments import methods
from experiments.plan import Plan
from experiments.references import RefSpec
from experiments.runs import RunStore, Task
from experiments.sweep import run_sweep

ROOT = Path(__file__).resolve().parents[1]

COARSE = '''
"""A deliberately coarse model: DT-TMM with one element per link, whatever k is asked."""
import math
import time

import numpy as np
from dataclasses import replace

import dttmm


def simulate(case, *, elements_per_link, h, **options):
    return dttmm.simulate(case, elements_per_link=1, h=h)


def raises(case, *, elements_per_link, h, **options):
    raise RuntimeError("the solver blew up")


def nan(case, *, elements_per_link, h, **options):
    res = dttmm.simulate(case, elements_per_link=1, h=h)
    return replace(res, end_effector=np.full_like(res.end_effector, math.nan))


def shapes(case, *, elements_per_link, h, **options):
    res = dttmm.simulate(case, elements_per_link=1, h=h)
    return replace(res, joint_angle=res.joint_angle[:, :1].repeat(3, axis=1)[:-1])


def milliseconds(case, *, elements_per_link, h, **options):
    res = dttmm.simulate(case, elements_per_link=1, h=h)
    return replace(res, t=res.t * 1e3)


def hangs(case, *, elements_per_link, h, **options):
    time.sleep(60)


not_callable = 3
'''


@pytest.fixture
def solver_file(tmp_path):
    path = tmp_path / "coarse_solver.py"
    path.write_text(COARSE)
    yield path
    for n in [n for n in methods.names() if n not in methods.METHODS]:
        methods.unregister(n)


def test_a_file_spec_is_registered_with_the_stated_defaults(solver_file):
    rec = methods.load_spec(f"{solver_file}:simulate")
    assert rec.name == "coarse-solver" and rec.role == "peer" and rec.uses_k
    assert rec.capabilities == frozenset(methods.CAPABILITIES) and rec.timeout == methods.OUTSIDE_TIMEOUT
    assert rec.name in methods.names() and rec.name in methods.takes_part("work_precision")
    c = shortened(case("single_link"), 0.02, 4e-3)
    res = methods.run(rec.name, c, 8, 2e-3)
    assert res.meta["elements_per_link"] == 1  # it is what it says: coarse
    # its cache key hashes its own source file
    from experiments import fingerprint

    sources = fingerprint.code_version(rec.name)["sources"]
    assert any(v == fingerprint.tree_hash(solver_file) for v in sources.values())


@pytest.mark.parametrize(
    "spec, why",
    [
        ("no/such/file.py:simulate", "no such file"),
        ("no_such_module_xyz:simulate", "no such module"),
        ("json:no_such_function", "has no 'no_such_function'"),
        ("{file}:not_callable", "not callable"),
    ],
)
def test_a_bad_spec_is_one_line_naming_it(solver_file, spec, why):
    spec = spec.format(file=solver_file)
    with pytest.raises(InputError, match=why) as exc:
        methods.load_spec(spec)
    assert "--method" in str(exc.value) and "\n" not in str(exc.value)


def test_bad_traits_are_refused(solver_file):
    solver_file.write_text(COARSE + "\nsimulate.method = {'role': 'oracle'}\n")
    with pytest.raises(InputError, match="role"):
        methods.load_spec(f"{solver_file}:simulate")


def test_dttmm_report_refuses_a_bad_method_with_exit_2():
    r = subprocess.run(
        [sys.executable, "-m", "dttmm.cli", "report", "--method", "no_such_module_xyz:simulate"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert r.returncode == 2 and "no such module" in r.stderr
    assert len([x for x in r.stderr.strip().splitlines() if "no such module" in x]) == 1


def test_failing_methods_are_omissions_with_their_reason(solver_file, tmp_path, monkeypatch):
    monkeypatch.setattr(methods, "OUTSIDE_TIMEOUT", 1.0)
    c = shortened(case("three_link"), 0.02, 4e-3)
    want = {
        "raises": "RuntimeError: the solver blew up",
        "nan": "non-finite output",
        "shapes": "malformed result",
        "milliseconds": "is not the case's output grid",
        "hangs": "ran past its time limit of 1 s",
    }
    tasks = []
    for fn in want:
        rec = methods.load_spec(f"{solver_file}:{fn}")
        tasks.append(Task("three_link", rec.name, 2, 2e-3, 0.02))
    table = run_sweep(
        tasks, {"three_link": c}, RunStore(tmp_path / "runs"), scheduler="serial", progress=False
    )
    got = dict(zip(table.method, zip(table.status, table.reason)))
    for fn, why in want.items():
        status, reason = got[fn]
        assert status == "failed" and why in reason, (fn, reason)


@pytest.fixture
def tiny_plan(tmp_path):
    cases = ["three_link"]
    ref, chk = [RefSpec("dttmm", 4, 1e-3)], [RefSpec("global", 4, 1e-3)]
    return Plan(
        "tiny",
        dict.fromkeys(cases, 0.04),
        dict.fromkeys(cases, ref),
        dict.fromkeys(cases, chk),
        {
            "work_precision": {
                "cases": cases,
                "methods": ["dttmm", "coarse-solver"],
                "path": [(1, 4e-3), (2, 2e-3)],
            },
            "paper": {"cases": cases, "methods": ["dttmm", "coarse-solver"], "k": 2, "h": 2e-3},
            "benchmarks": {
                "ks": [1, 2],
                "problems": ["cantilever_self_weight"],
                "methods": ["dttmm", "coarse-solver"],
            },
        },
        "tiny test size",
        output_step=4e-3,
    )


def test_an_outside_method_appears_in_every_table_of_the_report(solver_file, tiny_plan, tmp_path):
    from reports import cli

    assert cli.add_methods([f"{solver_file}:simulate"]) == ["coarse-solver"]
    html, md = cli.run_report(
        tiny_plan,
        tmp_path / "report",
        data=tmp_path / "data",
        scheduler="serial",
        progress=False,
        log=lambda *a: None,
    )
    data = tmp_path / "report" / "data"
    wp = pd.read_parquet(data / "work_precision.parquet")
    assert {"dttmm", "coarse-solver"} <= set(wp.method) and (wp.status == "ok").all()
    bench = pd.read_parquet(data / "benchmarks.parquet")
    assert "coarse-solver" in set(bench.method)
    text = Path(md).read_text()
    board = text[text.index("## Scoreboard") : text.index("## About this report")]
    assert "| coarse-solver |" in board  # in the scoreboard, under its name (no label declared)
    assert json.loads((data / "report_meta.json").read_text())["availability"]["coarse-solver"] is None


def test_an_entry_point_of_an_installed_package_is_found(tmp_path):
    """A package in a temporary venv declares ``dttmm.methods``; the suite finds it by name."""
    pkg = tmp_path / "pkg"
    (pkg / "my_methods").mkdir(parents=True)
    (pkg / "my_methods" / "__init__.py").write_text(
        "import dttmm\n\n\ndef simulate(case, *, elements_per_link, h, **options):\n"
        "    return dttmm.simulate(case, elements_per_link=elements_per_link, h=h)\n"
    )
    (pkg / "pyproject.toml").write_text(
        textwrap.dedent(
            """
            [build-system]
            requires = ["setuptools"]
            build-backend = "setuptools.build_meta"
            [project]
            name = "my-methods"
            version = "1.2.3"
            [project.entry-points."dttmm.methods"]
            my-entry = "my_methods:simulate"
            """
        )
    )
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    site = subprocess.run(
        [py, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    # the suite's own environment is visible from the new venv (a .pth line), the package is
    # installed into the new venv by this environment's pip
    import sysconfig

    Path(site, "suite.pth").write_text(sysconfig.get_paths()["purelib"] + "\n" + str(ROOT) + "\n")
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "-q",
            "--no-deps",
            "--target",
            site,
            str(pkg),
        ],
        check=True,
        capture_output=True,
    )
    code = (
        "from experiments import methods, fingerprint\n"
        "rec = methods.load_spec('my-entry')\n"
        "print(rec.name, fingerprint.code_version(rec.name)['libraries'].get('my-methods'))\n"
    )
    r = subprocess.run([py, "-c", code], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split() == ["my-entry", "1.2.3"]  # found, and its version is in the cache key
