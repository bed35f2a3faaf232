"""The ``dttmm simulate`` command line."""

import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest
from conftest import CASES, case, shortened

import dttmm
from dttmm.cli import main


@pytest.fixture
def short_case(tmp_path):
    p = tmp_path / "three_link.toml"
    dttmm.save_case(shortened(case("three_link"), 0.05), p)
    return p


def test_simulate_writes_table_plot_and_meta(short_case, tmp_path):
    out = tmp_path / "out"
    assert main(["simulate", str(short_case), "--elements", "2", "--h", "1e-3", "--out", str(out)]) == 0
    df = pd.read_csv(out / "three_link.csv")
    assert len(df) == 51 and {"t", "joint_angle_3", "tip_deflection_2", "end_effector_y"} <= set(df.columns)
    png = (out / "three_link.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    meta = json.loads((out / "meta.json").read_text())
    assert meta["method"] == "dttmm" and meta["elements_per_link"] == 2 and meta["n_steps"] == 50


def test_simulate_parquet(short_case, tmp_path):
    out = tmp_path / "pq"
    assert (
        main(
            ["simulate", str(short_case), "-k", "1", "--h", "1e-3", "--format", "parquet", "--out", str(out)]
        )
        == 0
    )
    res = dttmm.Result.from_frame(pd.read_parquet(out / "three_link.parquet"))
    assert res.joint_angle.shape == (51, 3)


def test_bad_input_exit_code_and_message(short_case, tmp_path, capsys):
    assert main(["simulate", str(short_case), "--elements", "0", "--h", "1e-3", "--out", str(tmp_path)]) == 2
    assert "elements_per_link = 0" in capsys.readouterr().err


def test_console_script_runs(short_case, tmp_path):
    import os

    exe = Path(sys.executable).with_name("dttmm")
    # the script imports this checkout's code (not another one the environment's package points
    # to), so it loads the kernel from the on-disk cache the tests have filled, not compiling anew
    root = str(Path(__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    r = subprocess.run(
        [str(exe), "simulate", str(short_case), "-k", "1", "--h", "1e-3", "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
        env=env,
    )
    assert r.returncode == 0, r.stderr
    assert "wrote" in r.stdout


# --- errors are one line; exit codes 0 ok, 1 failed, 2 bad input, 3 not ok ------------------------
BLOW = """[model]
[[model.links]]
length = 1.0
EI = 2.0
rhoA = 0.3
[scenario]
duration = 0.1
output_step = 0.01
[[scenario.drives]]
kind = "torque"
law = "table"
times = [0.0, 0.05, 0.06]
values = [0.0, 0.0, 1e30]
"""


def _one_line(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, err
    return lines[0]


@pytest.mark.parametrize("what", ["missing", "directory", "binary", "misspelt key"])
def test_bad_case_file_is_one_line_exit_2(tmp_path, capsys, what):
    path = {
        "missing": tmp_path / "nope.toml",
        "directory": tmp_path,
        "binary": tmp_path / "b.toml",
        "misspelt key": tmp_path / "k.toml",
    }[what]
    if what == "binary":
        path.write_bytes(b"\x00\x01\x02\xff")
    if what == "misspelt key":
        path.write_text((CASES / "three_link.toml").read_text().replace("gravity =", "gravty ="))
    assert main(["simulate", str(path), "-k", "1", "--h", "1e-3", "--out", str(tmp_path / "o")]) == 2
    line = _one_line(capsys.readouterr().err)
    assert line.startswith("dttmm: bad input: ")
    assert ("did you mean 'gravity'" in line) if what == "misspelt key" else (str(path) in line)


def test_unwritable_out_is_refused_before_the_run(short_case, tmp_path, capsys, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setattr("dttmm.simulate_cli.simulate", lambda *a, **k: pytest.fail("ran"))
    assert main(["simulate", str(short_case), "-k", "1", "--h", "1e-3", "--out", str(blocker / "sub")]) == 2
    assert "--out" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--h", "abc"], "--h"),
        (["--h", "1e-12"], "h = 1e-12"),
        (["--h", "nan"], "h = nan"),
        (["--h", "1e-3", "--strain", "cubic"], "--strain"),
        (["--h", "1e-3", "--tol", "2"], "tol"),
    ],
)
def test_bad_options_are_one_line_exit_2(short_case, tmp_path, capsys, args, fragment):
    assert main(["simulate", str(short_case), "-k", "1", *args, "--out", str(tmp_path / "o")]) == 2
    assert fragment in _one_line(capsys.readouterr().err)


def test_failed_simulation_one_line_exit_1_partial_written(tmp_path, capsys):
    case_path = tmp_path / "blow.toml"
    case_path.write_text(BLOW)
    out = tmp_path / "out"
    assert main(["simulate", str(case_path), "-k", "1", "--h", "1e-3", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    lines = [ln for ln in err.split("\n") if ln.strip() and "step/s]" not in ln]  # minus the progress bar
    assert len(lines) == 1 and lines[0].startswith("dttmm: simulation failed:"), err
    assert "t = 0.051 s" in lines[0] and "partial result up to t = 0.05 s" in lines[0]
    df = pd.read_csv(out / "blow.csv")
    assert 2 <= len(df) < 11 and df["t"].iloc[-1] <= 0.05 + 1e-12
    assert json.loads((out / "meta.json").read_text())["status"] == "failed"


def test_not_ok_status_is_printed_and_exits_3(short_case, tmp_path, capsys, monkeypatch):
    import dataclasses as dc

    import dttmm.simulate_cli as sc

    real = sc.simulate
    monkeypatch.setattr(
        sc,
        "simulate",
        lambda *a, **k: dc.replace(
            real(*a, **k), status="unconverged", warnings=("3 steps hit max_iterations",)
        ),
    )
    assert main(["simulate", str(short_case), "-k", "1", "--h", "1e-3", "--out", str(tmp_path / "o")]) == 3
    out = capsys.readouterr().out
    assert "status: unconverged" in out and "warning: 3 steps hit max_iterations" in out


def test_solver_options_pass_through(short_case, tmp_path, monkeypatch):
    import dttmm.simulate_cli as sc

    seen, real = {}, sc.simulate
    monkeypatch.setattr(sc, "simulate", lambda *a, **k: seen.update(k) or real(*a, **k))
    out = tmp_path / "o"
    assert (
        main(
            [
                "simulate",
                str(short_case),
                "-k",
                "1",
                "--h",
                "1e-3",
                "--integrator",
                "generalized-alpha",
                "--rho-inf",
                "0.7",
                "--tol",
                "1e-8",
                "--strain",
                "linear",
                "--engine",
                "python",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    meta = json.loads((out / "meta.json").read_text())
    assert meta["tol"] == 1e-8 and meta["strain"] == "linear" and meta["engine"] == "python"
    assert meta["integrator"] == "generalized-alpha" and seen["rho_inf"] == 0.7


@pytest.mark.parametrize(
    "value, fragment", [("foo", "must be 'serial'"), ("tcp://127.0.0.1:1", "cannot reach")]
)
def test_report_bad_scheduler_one_line_exit_2(capsys, value, fragment):
    assert main(["report", "--scheduler", value]) == 2
    assert fragment in _one_line(capsys.readouterr().err)


def test_core_cli_does_not_import_the_report_harness():
    code = (
        "import sys, dttmm.cli; print(any(m == 'reports' or m.startswith('reports.') for m in sys.modules))"
    )
    r = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert r.stdout.strip() == "False", r.stderr
