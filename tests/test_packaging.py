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
