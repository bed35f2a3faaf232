"""The distribution's metadata: every case file is package data, and the description is true."""

from __future__ import annotations

import glob
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def test_every_case_file_is_package_data():
    """The package-data globs of ``experiments`` (setuptools expands them recursively) match
    every ``experiments/cases/**/*.toml``: planar, benchmark, control and spatial cases."""
    pkg = ROOT / "experiments"
    patterns = PYPROJECT["tool"]["setuptools"]["package-data"]["experiments"]
    listed = {p for pat in patterns for p in glob.glob(pat, root_dir=pkg, recursive=True)}
    files = {str(p.relative_to(pkg)) for p in (pkg / "cases").rglob("*.toml")}
    assert any(f.startswith("cases/spatial/") for f in files)
    assert files <= listed, sorted(files - listed)


def test_description_names_both_kinds_of_arm():
    text = PYPROJECT["project"]["description"]
    assert "planar" in text and "spatial" in text


def test_build_copies_every_case_file(tmp_path):
    """setuptools' build_py (the step that fills the wheel) puts every case file into the built
    ``experiments`` package (its metadata written to tmp_path, the checkout left untouched)."""
    import subprocess
    import sys

    lib, egg = tmp_path / "lib", tmp_path / "egg"
    egg.mkdir()
    r = subprocess.run(
        [sys.executable, "-c", "from setuptools import setup; setup()", "-q", "egg_info", "-e", str(egg)]
        + ["build_py", "--build-lib", str(lib)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert r.returncode == 0, r.stderr[-2000:]
    built = {str(p.relative_to(lib / "experiments")) for p in (lib / "experiments" / "cases").rglob("*.toml")}
    files = {
        str(p.relative_to(ROOT / "experiments")) for p in (ROOT / "experiments" / "cases").rglob("*.toml")
    }
    assert built == files
