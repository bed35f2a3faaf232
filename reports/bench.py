"""Ingest pytest-benchmark JSON (``data/bench/*.json``) for the report's cost-scaling section."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = [
    "absent",
    "code_commit",
    "costs_text",
    "element_step_table",
    "exponents",
    "has_scans",
    "info_of",
    "latest",
    "load",
    "provenance",
    "ratios",
    "read",
    "scaling_exponents",
]

_K_KEYS = ("elements_per_link", "k", "elements", "n_elements")
_STEP_KEYS = ("n_steps", "steps")


def latest(folder="data/bench") -> Path | None:
    """The newest pytest-benchmark JSON in ``folder`` (by modification time), or None."""
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


# --- The scaling suites (benchmarks/): groups "elements:<case>:<method>", "links:<method>",
# "one-step:k=<k>". Times are the solve-only time per step from extra_info (model build and
# the benchmark's own overhead excluded), not the pytest-benchmark mean.


# Which names each scan times, and the like-for-like ratio pairs (same element strain: a method
# over its DT-TMM partner), come from the method registry (experiments/methods.py: ``scans``,
# ``physics.strain``, ``base``).
def _element_methods() -> list[str]:
    from experiments import methods

    return methods.in_scan("elements")


def _link_methods() -> list[str]:
    from experiments import methods

    return methods.in_scan("links")


def _ratio_pairs() -> list:
    from experiments import methods

    return methods.ratio_pairs()


def _ratio_columns() -> list[str]:
    return [f"{m}/{bases[-1]}" for m, bases in _ratio_pairs()]


K_MIN = 8  # exponents in k are fitted over k ≥ K_MIN: below it per-step overhead dominates
N_MIN = 2  # exponents in the number of links: n ≥ N_MIN
_RECORD_COLS = [
    "group",
    "name",
    "kind",
    "case",
    "method",
    "k",
    "n_links",
    "n_steps",
    "n_dof",
    "h",
    "time_per_step",
    "time_per_element_step",
    "mean",
    "tip_error_l2",
    "cpu_per_step",
    "cpu_per_step_median",
    "rounds",
    "noisy",
]


def _num(v) -> float:
    try:
        return float(v)
    except (TypeError, ValueError):
        return np.nan


def info_of(data: dict, path) -> dict:
    """Machine, commit and date of a pytest-benchmark run (from its JSON)."""
    m, c = data.get("machine_info") or {}, data.get("commit_info") or {}
    cpu = m.get("cpu") or {}
    return {
        "file": str(path),
        "date": data.get("datetime", ""),
        "machine": cpu.get("brand_raw", m.get("node", "")),
        "cores": cpu.get("count"),
        "node": m.get("node", ""),
        "commit": c.get("id", "") or "",
        "dirty": c.get("dirty"),
        "python": m.get("python_version", ""),
    }


def _record(b: dict) -> dict:
    group = str(b.get("group") or "")
    parts = group.split(":")
    kind = parts[0] if len(parts) > 1 else ""
    params, e = b.get("params") or {}, b.get("extra_info") or {}
    method, case = e.get("method"), e.get("case")
    if kind == "elements" and len(parts) >= 3:
        case, method = parts[1], ":".join(parts[2:])
    elif kind == "links":
        method = parts[1]
    k = _num(_first(e, _K_KEYS) if _first(e, _K_KEYS) is not None else _first(params, _K_KEYS))
    n_links = _num(e.get("n_links"))
    steps = _num(_first(e, _STEP_KEYS) or _first(params, _STEP_KEYS))
    mean = _num((b.get("stats") or {}).get("mean"))
    tps = _num(e.get("time_per_step"))
    if not np.isfinite(tps):  # older files: the solve time, else the whole benchmark mean
        tps = _num(e.get("solve_time")) / steps if np.isfinite(_num(e.get("solve_time"))) else mean / steps
    tpe = _num(e.get("time_per_element_step"))
    if not np.isfinite(tpe) and k > 0 and n_links > 0:
        tpe = tps / (k * n_links)
    return {
        "group": group,
        "name": b.get("name", ""),
        "kind": kind,
        "case": case,
        "method": method,
        "k": k,
        "n_links": n_links,
        "n_steps": steps,
        "n_dof": _num(e.get("n_dof")),
        "h": _num(e.get("h")),
        "time_per_step": tps,
        "time_per_element_step": tpe,
        "mean": mean,
        "tip_error_l2": _num(e.get("tip_error_l2")),
        "cpu_per_step": _num(e.get("cpu_per_step")),
        "cpu_per_step_median": _num(e.get("cpu_per_step_median")),
        "rounds": _num(e.get("rounds")),
        "noisy": bool(e.get("noisy", True)),  # files without the timing protocol count as noisy
    }


def read(path) -> tuple[pd.DataFrame, dict]:
    """(records, info): one row per benchmark of the file, every group, with kind ("elements",
    "links", "one-step", "kernel", … or "" for ungrouped), case, method, k (elements per link,
    NaN where none), n_links, time per step (s, solve only) and per element-step (s)."""
    data = json.loads(Path(path).read_text())
    rows = [_record(b) for b in data.get("benchmarks", [])]
    return pd.DataFrame(rows, columns=_RECORD_COLS), info_of(data, path)


def has_scans(records: pd.DataFrame) -> bool:
    """Whether the file holds the scaling suites' groups (else the report falls back to ``load``)."""
    return bool(len(records)) and records.kind.isin(["elements", "links"]).any()


def scaling_exponents(records: pd.DataFrame, k_min: int = K_MIN, n_min: int = N_MIN) -> pd.DataFrame:
    """Exponent p of time per step ∝ x^p: x = elements per link per (case, method) of the
    "elements" scans, fitted over k ≥ k_min; x = number of links per method of the "links" scan
    (k = 8), over n ≥ n_min. One row per curve: scan, case, method, exponent, fit_from, fit_to,
    n_points (NaN exponent with fewer than two points in range)."""
    from experiments.fit import slope

    rows = []
    scans = (("elements", "k", k_min, ["case", "method"]), ("links", "n_links", n_min, ["method"]))
    for kind, x, lo, by in scans:
        d = records[(records.kind == kind) & (records[x] > 0)]
        for key, g in d.groupby(by, sort=False):
            key = key if isinstance(key, tuple) else (key,)
            fit = g[g[x] >= lo]
            p, n = slope(fit[x], fit.time_per_step)
            rows.append(
                {
                    "scan": "elements per link" if kind == "elements" else "links (k = 8)",
                    "case": key[0] if kind == "elements" else "chain",
                    "method": key[-1],
                    "exponent": p,
                    "fit_from": fit[x].min() if len(fit) else np.nan,
                    "fit_to": fit[x].max() if len(fit) else np.nan,
                    "n_points": n,
                }
            )
    return pd.DataFrame(
        rows, columns=["scan", "case", "method", "exponent", "fit_from", "fit_to", "n_points"]
    )


def element_step_table(records: pd.DataFrame, case: str = "three_link") -> pd.DataFrame:
    """Cost per element-step (µs, solve only) of the "elements" scan of ``case``: one row per k,
    one column per method (NaN where a method did not run at that k)."""
    d = records[(records.kind == "elements") & (records.case == case) & (records.k > 0)]
    if d.empty:
        return pd.DataFrame(columns=["k"])
    w = d.pivot_table(index="k", columns="method", values="time_per_element_step", aggfunc="first") * 1e6
    known = _element_methods()
    order = [m for m in known if m in w] + [m for m in w if m not in known]
    w = w[order].reset_index()
    w["k"] = w.k.astype(int)
    w.columns.name = None
    return w


def _ratio_row(basis, case, k, times, target=np.nan) -> dict:
    """One ratio row: each like-for-like pair's time over its DT-TMM partner's (NaN if absent)."""
    row = {"basis": basis, "case": case, "k": k, "target_error_m": target}
    for (m, bases), col in zip(_ratio_pairs(), _ratio_columns()):
        base = next((b for b in bases if b in times), None)
        t0 = times.get(base, np.nan) if base else np.nan
        row[col] = times.get(m, np.nan) / t0 if np.isfinite(t0) and t0 > 0 else np.nan
    return row


def ratios(records: pd.DataFrame, equal_accuracy=None, ks=(4, 16, 64)) -> pd.DataFrame:
    """Speed ratios between runs of the same element strain (the registry's ``ratio_pairs``): each column
    ``<method>/<dttmm run>`` is that method's time over DT-TMM's, > 1 when DT-TMM is faster.
    Rows: equal model size (time per step at the same k) from the "elements" scans (k in
    ``ks``) and the "one-step" groups; equal accuracy (CPU time to reach each target error on
    the method's lower envelope) from the work-precision ``equal_accuracy`` table when given."""
    rows = []
    el = records[records.kind == "elements"]
    for case in dict.fromkeys(el.case):
        for k in ks:
            d = el[(el.case == case) & (el.k == k)]
            if len(d):
                rows.append(
                    _ratio_row(
                        "equal size: time per step (elements scan)",
                        case,
                        k,
                        dict(zip(d.method, d.time_per_step)),
                    )
                )
    one = records[records.kind == "one-step"]
    for (case, k), d in one.groupby(["case", "k"], sort=True):
        rows.append(
            _ratio_row(
                "equal size: time per step (one-step)", case, int(k), dict(zip(d.method, d.time_per_step))
            )
        )
    if equal_accuracy is not None and len(equal_accuracy):
        for (case, tgt), d in equal_accuracy.groupby(["case", "target_error"], sort=False):
            times = dict(zip(d.method, d.cpu_time.astype(float)))
            rows.append(
                _ratio_row("equal accuracy: CPU time to target (work-precision)", case, np.nan, times, tgt)
            )
    cols = ["basis", "case", "k", "target_error_m", *_ratio_columns()]
    return pd.DataFrame(rows, columns=cols)


def _sig2(v) -> str:
    from .peers import sig2

    return sig2(v)


def costs_text(exponents, per_element, ratios, *, k_min=K_MIN, n_min=N_MIN, case="three_link") -> list[str]:
    """Sentences under the pytest-benchmark figures: fitted exponents, cost per element-step at each
    method's largest k, and the like-for-like ratios (2 significant digits)."""
    out = []
    el = exponents[(exponents.scan == "elements per link") & (exponents.case == case)]
    el = el[np.isfinite(el.exponent)]
    ln = exponents[exponents.scan.str.startswith("links") & np.isfinite(exponents.exponent)]
    parts = []
    if len(el):
        parts.append(
            f"over k ≥ {k_min} ({case}; below it fixed per-step costs dominate) "
            + ", ".join(f"{r.method} {r.exponent:.2f}" for r in el.itertuples())
        )
    if len(ln):
        parts.append(
            f"over n ≥ {n_min} links at k = 8: "
            + ", ".join(f"{r.method} {r.exponent:.2f}" for r in ln.itertuples())
        )
    if parts:
        out.append("Fitted exponents p of time per step ∝ N^p: " + "; ".join(parts) + ".")
    if len(per_element) and len(per_element.columns) > 1:
        bits = []
        for m in per_element.columns[1:]:
            v = per_element[["k", m]].dropna()
            if len(v):
                bits.append(f"{m} {_sig2(v[m].iloc[-1])} µs (k = {v.k.iloc[-1]})")
        out.append(
            f"Cost per element-step at each method's largest k ({case}, solve only): " + ", ".join(bits) + "."
        )
    pairs = " ; ".join(_ratio_columns())
    size = ratios[ratios.basis.str.startswith("equal size") & (ratios.case == case) & ratios.k.notna()]
    if len(size):
        kmax = size.k.max()
        for _, r in size[size.k == kmax].iterrows():
            shown = [f"{c} = {_sig2(r[c])}" for c in _ratio_columns() if np.isfinite(r[c])]
            out.append(
                f"At equal model size ({case}, k = {int(kmax)}, time per step, {r.basis.split('(')[-1].rstrip(')')}; "
                f"same element strain only): "
                + (", ".join(shown) or "no like-for-like pair in this file")
                + "."
            )
    acc = ratios[ratios.basis.str.startswith("equal accuracy")]
    if len(acc):
        parts = []
        for _, r in acc.iterrows():
            shown = [f"{c} = {_sig2(r[c])}" for c in _ratio_columns() if np.isfinite(r[c])]
            parts.append(f"{r['case']} at {r['target_error_m']:.0e} m: " + (", ".join(shown) or "n/a"))
        out.append(
            "At equal accuracy (work-precision study, CPU time to reach the error): " + "; ".join(parts) + "."
        )
    else:
        out.append(
            "No equal-accuracy ratio: the work-precision equal-accuracy table is absent from the report data."
        )
    out.append(f"Ratio columns ({pairs}): > 1 means DT-TMM is faster.")
    return out


def code_commit(root=None) -> str:
    """The git commit of the code the report describes ('' when not a git checkout)."""
    import subprocess

    root = Path(root) if root else Path(__file__).resolve().parents[1]
    try:
        r = subprocess.run(
            ["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True, check=False
        )
    except OSError:
        return ""
    return r.stdout.strip() if r.returncode == 0 else ""


#: the folders whose code the cost benchmarks time: a pytest-benchmark file made at another commit still
#: describes the code when none of them changed in between
TIMED_CODE = ("dttmm", "reference_models", "benchmarks")


def code_changed(since: str, commit: str, root=None) -> bool:
    """Whether the timed code (:data:`TIMED_CODE`) differs between the two commits (True when
    git cannot tell, e.g. a commit unknown to this checkout)."""
    import subprocess

    root = Path(root) if root else Path(__file__).resolve().parents[1]
    try:
        r = subprocess.run(
            ["git", "diff", "--quiet", since, commit, "--", *TIMED_CODE],
            cwd=root,
            capture_output=True,
            check=False,
        )
    except OSError:
        return True
    return r.returncode != 0


def provenance(info, commit: str | None = None) -> list[str]:
    """Where the pytest-benchmark numbers come from, how they were timed, and a warning when the file
    was made at another commit than the code (``commit``; found with git when None) and the
    timed code changed in between."""
    commit = code_commit() if commit is None else commit
    cores = info.get("cores")
    dirty = " (uncommitted changes)" if info.get("dirty") else ""
    date, name = str(info["date"])[:19].replace("T", " "), Path(info["file"]).name
    out = [
        (
            f"pytest-benchmark run {date} ({name}) on {info['machine'] or info['node']}"
            f"{f', {cores} cores' if cores else ''}, Python {info['python']}, commit {info['commit'][:10]}{dirty}. "
            f"Times per step are the least solve-only time of the rounds (CPU time beside it where recorded) "
            f"on a shared {f'{cores}-core ' if cores else ''}machine: read differences under about 20 % as noise."
        )
    ]
    bc = str(info.get("commit") or "")
    other = commit and bc and not (commit.startswith(bc) or bc.startswith(commit))
    if other and not code_changed(bc, commit):
        out.append(
            f"The file was made at commit {bc[:10]}; the timed code ({', '.join(TIMED_CODE)}) is the same "
            f"at the code's commit {commit[:10]}."
        )
    elif other:
        out.append(
            f"Warning: this pytest-benchmark file was made at commit {bc[:10]}, not at the code's commit "
            f"{commit[:10]}; its timings may not describe this code (rerun `make bench`)."
        )
    elif info.get("dirty"):
        out.append("Warning: this pytest-benchmark file was made with uncommitted changes.")
    return out


def absent(records: pd.DataFrame) -> list[str]:
    """The expected scaling curves this file lacks, as "<method> (<case>)" strings."""
    el, ln = records[records.kind == "elements"], records[records.kind == "links"]
    out = [
        f"{m} ({c})"
        for c in dict.fromkeys(list(el.case) or ["three_link", "single_link"])
        for m in _element_methods()
        if el[(el.case == c) & (el.method == m)].empty
    ]
    return out + [f"{m} (links scan)" for m in _link_methods() if ln[ln.method == m].empty]


# --- The spatial kernel next to the planar one (benchmarks/test_bench_spatial.py) --------------
SPATIAL_GROUP = "spatial-vs-planar:three_link"


def spatial_table(path) -> pd.DataFrame:
    """CPU µs per element-step of both kernels on three_link (the spatial kernel on the same arm
    in a tilted plane), from the ``spatial-vs-planar`` group of a pytest-benchmark file: one row
    per k with planar, spatial and their ratio (empty when the file has no such group)."""
    data = json.loads(Path(path).read_text())
    rows = {}
    for b in data.get("benchmarks", []):
        e = b.get("extra_info") or {}
        if b.get("group") != SPATIAL_GROUP or e.get("kernel") not in ("planar", "spatial"):
            continue
        k = int(e["elements_per_link"])
        rows.setdefault(k, {"k": k})[f"{e['kernel']} (µs)"] = _num(e.get("cpu_us_per_element_step"))
        if e["kernel"] == "spatial":
            rows[k]["sweeps per step"] = _num(e.get("sweeps_per_step"))
    cols = ["k", "planar (µs)", "spatial (µs)", "spatial / planar", "sweeps per step"]
    if not rows:
        return pd.DataFrame(columns=cols)
    t = pd.DataFrame(sorted(rows.values(), key=lambda r: r["k"]))
    for c in cols:
        if c not in t:
            t[c] = np.nan
    t["spatial / planar"] = t["spatial (µs)"] / t["planar (µs)"]
    return t[cols]


def spatial_text(table: pd.DataFrame, n_links: int = 3) -> list[str]:
    """One sentence on the spatial kernel's cost against the planar one's (none without data)."""
    d = table.dropna(subset=["planar (µs)", "spatial (µs)"])
    if d.empty:
        return []
    n = n_links * d.k.to_numpy(float)
    p = {
        c: float(np.polyfit(np.log(n), np.log(d[c].to_numpy() * n), 1)[0])
        for c in ("planar (µs)", "spatial (µs)")
    }
    r = d["spatial / planar"]
    return [
        f"Spatial kernel (three_link in a tilted plane, the same tolerance-driven iteration) against the planar "
        f"kernel, CPU time per element-step: {_sig2(r.min())}–{_sig2(r.max())}× over k = {int(d.k.min())}…"
        f"{int(d.k.max())} (table bench_spatial_us); cost ∝ elements^p with p = {p['spatial (µs)']:.2f} "
        f"(planar {p['planar (µs)']:.2f}). The 6×6 articulated-inertia work alone costs about 4× the planar "
        "element-step (docs/spatial.md §7)."
    ]
