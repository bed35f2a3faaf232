"""The examples/ gallery: every numbered script runs at its quick size (DTTMM_EXAMPLES_QUICK=1)
and writes what it promises into a temporary folder."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPTS = sorted((ROOT / "examples").glob("[0-9][0-9]_*.py"))
# what each script leaves in its output folder (besides what it prints)
WRITES = {
    "01": ["01_first_simulation.png"],
    "02": ["my_arm.toml", "02_my_arm.gif"],
    "03": ["03_compare_methods.png", "03_compare_methods.gif"],
    "04": ["04_convergence.png"],
    "05": ["05_user_law.gif"],
    "06": ["06_modes.gif"],
    "07": [],
    "08": ["three_link.urdf"],
    "09": ["09_robot_from_urdf.png"],
}
SLOW = {"07"}  # starts a Dask LocalCluster of two worker processes


def test_the_gallery_has_every_topic():
    assert [p.name[:2] for p in SCRIPTS] == sorted(WRITES)


@pytest.mark.parametrize(
    "script",
    [pytest.param(p, id=p.stem, marks=[pytest.mark.slow] if p.name[:2] in SLOW else []) for p in SCRIPTS],
)
def test_example_runs_at_its_quick_size(script, tmp_path):
    env = {
        **os.environ,
        "DTTMM_EXAMPLES_QUICK": "1",
        "DTTMM_EXAMPLES_OUT": str(tmp_path),
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
        "OPENBLAS_NUM_THREADS": "1",
        "MPLBACKEND": "Agg",
    }
    r = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.strip()
    for name in WRITES[script.name[:2]]:
        assert (tmp_path / name).stat().st_size > 0, name
