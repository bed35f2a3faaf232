"""The ``dttmm simulate`` command line."""
import json
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import dttmm
from dttmm.cli import main

from conftest import CASES, shortened, case


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
    assert main(["simulate", str(short_case), "-k", "1", "--h", "1e-3", "--format", "parquet", "--out", str(out)]) == 0
    res = dttmm.Result.from_frame(pd.read_parquet(out / "three_link.parquet"))
    assert res.joint_angle.shape == (51, 3)


def test_bad_input_exit_code_and_message(short_case, tmp_path, capsys):
    assert main(["simulate", str(short_case), "--elements", "0", "--h", "1e-3", "--out", str(tmp_path)]) == 2
    assert "elements_per_link = 0" in capsys.readouterr().err


def test_console_script_runs(short_case, tmp_path):
    exe = Path(sys.executable).with_name("dttmm")
    r = subprocess.run([str(exe), "simulate", str(short_case), "-k", "1", "--h", "1e-3", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "wrote" in r.stdout
