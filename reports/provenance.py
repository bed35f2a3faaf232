"""Where and how a report was made: machine, Python and package versions, git commit."""

from __future__ import annotations

import datetime
import importlib.metadata as md
import os
import platform
import subprocess

__all__ = ["collect"]

PACKAGES = (
    "dttmm",
    "numpy",
    "scipy",
    "pandas",
    "pyarrow",
    "matplotlib",
    "dask",
    "distributed",
    "exudyn",
    "pin",
    "numba",
    "tqdm",
)


def _git(*args) -> str:
    try:
        return subprocess.run(
            ["git", *args], capture_output=True, text=True, timeout=10, check=False
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _cpu() -> str:
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def collect(command: str) -> dict:
    """Provenance of a report built now by ``command``."""
    versions = {}
    for p in PACKAGES:
        try:
            versions[p] = md.version(p)
        except md.PackageNotFoundError:
            versions[p] = "not installed"
    commit = _git("rev-parse", "HEAD")
    dirty = bool(_git("status", "--porcelain", "--untracked-files=no"))
    return {
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "machine": f"{platform.node()}: {_cpu()}, {os.cpu_count()} cores, "
        f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "versions": versions,
        "commit": (commit or "unknown") + (" (with uncommitted changes)" if dirty else ""),
        "command": command,
    }
