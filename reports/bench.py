"""Ingest pytest-benchmark JSON (``data/bench/*.json``) for the report's cost-scaling section."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

__all__ = ["latest", "load", "exponents"]

_K_KEYS = ("elements_per_link", "k", "elements", "n_elements")
_STEP_KEYS = ("n_steps", "steps")


def latest(folder="data/bench") -> Path | None:
    """The newest benchmark JSON in ``folder`` (by modification time), or None."""
    files = sorted(Path(folder).glob("*.json"), key=lambda p: p.stat().st_mtime)
    return files[-1] if files else None


def _first(d: dict, keys):
    for k in keys:
        if k in d and d[k] is not None:
            return d[k]
    return None


def load(path) -> tuple[pd.DataFrame, dict]:
    """(table, info): one row per benchmark with group, elements, mean time (s), steps and
    time per step (s); info = machine, commit and date of the run. Benchmarks without an
    element count are left out of the table (they do not scale with k)."""
    data = json.loads(Path(path).read_text())
    rows = []
    for b in data.get("benchmarks", []):
        params, extra = b.get("params") or {}, b.get("extra_info") or {}
        k = _first(params, _K_KEYS) or _first(extra, _K_KEYS)
        if k is None:
            continue
        steps = _first(extra, _STEP_KEYS) or _first(params, _STEP_KEYS)
        mean = b["stats"]["mean"]
        group = b.get("group") or params.get("method") or extra.get("method") or b["name"].split("[")[0]
        rows.append(
            {
                "group": str(group),
                "name": b["name"],
                "elements": int(k),
                "mean": mean,
                "n_steps": steps,
                "time_per_step": mean / steps if steps else mean,
                "n_dof": extra.get("n_dof"),
            }
        )
    m, c = data.get("machine_info", {}), data.get("commit_info", {})
    info = {
        "file": str(path),
        "date": data.get("datetime", ""),
        "machine": m.get("cpu", {}).get("brand_raw", m.get("node", "")),
        "commit": c.get("id", ""),
        "python": m.get("python_version", ""),
    }
    return pd.DataFrame(rows), info


def exponents(table: pd.DataFrame) -> pd.DataFrame:
    """Exponent p of time per step ∝ elements^p per group (elements ≥ 2)."""
    from experiments.fit import slope

    rows = []
    for g, d in table.groupby("group"):
        d = d[d.elements >= 2]
        p, n = slope(d.elements, d.time_per_step)
        rows.append({"group": g, "exponent": p, "n_points": n})
    return pd.DataFrame(rows, columns=["group", "exponent", "n_points"])
