"""Assemble the report from stored study tables: figures, interpretation, omissions, footer.

Needs only the tables (``<out>/data/*.parquet``) and ``report_meta.json``: figures are
rebuilt from stored data without re-simulating.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from . import bench, figures, interpret
from .render import Section, write

__all__ = ["build", "omissions"]


def _floor(meta, case) -> float:
    cc = (meta.get("references", {}).get(case) or {}).get("cross_check") or {}
    return float((cc.get("errors") or {}).get("ee_l2", np.nan) or np.nan)


def _cases(df) -> list:
    return list(dict.fromkeys(df.case)) if "case" in df and len(df) else []


def omissions(tables: dict) -> pd.DataFrame:
    """Every planned run without an error value: study, case, method, k, h, options, status, why."""
    rows = []
    for name in ("convergence_k", "convergence_h", "work_precision", "scheme", "paper", "cost"):
        df = tables.get(name)
        if df is None or df.empty:
            continue
        bad = df[(df.status != "ok") | ~np.isfinite(df.ee_l2.astype(float))]
        for r in bad.itertuples():
            why = r.reason or getattr(r, "error_note", "")
            rows.append(
                {
                    "study": name,
                    "case": r.case,
                    "method": r.method,
                    "k": r.k,
                    "h": r.h,
                    "options": r.options,
                    "status": r.status,
                    "reason": why,
                }
            )
    cols = ["study", "case", "method", "k", "h", "options", "status", "reason"]
    return pd.DataFrame(rows, columns=cols).drop_duplicates(subset=cols[1:])


def _sections(tables, meta, out, bench_dir):
    fig_dir = out / "figures"
    fig_dir.mkdir(parents=True, exist_ok=True)
    secs, summary = [], []

    def add(sec_title, anchor, items, tabs, head=None):
        figs, text = [], []
        for fname, fig, caption, sentences in items:
            figures.save(fig, fig_dir / fname)
            figs.append((f"figures/{fname}", caption))
            who = caption.split(":")[0] if len(items) > 1 else ""
            text += [f"{who}: {sentences[0]}" if who else sentences[0], *sentences[1:]] if sentences else []
        secs.append(Section(sec_title, figs, text, [(n, tables[n]) for n in tabs if n in tables], anchor))
        if head:
            summary.append(head)

    t = tables.get("convergence_k")
    if t is not None and len(t):
        o = tables["convergence_k_orders"]
        items = [
            (
                f"convergence_k_{c}.png",
                figures.convergence_k(t, c, floor=_floor(meta, c)),
                f"{c}: end-effector error against elements per link",
                interpret.convergence_k(t, o, c, _floor(meta, c)),
            )
            for c in _cases(t)
        ]
        add(
            "Convergence in elements per link",
            "convergence-k",
            items,
            ["convergence_k_orders"],
            f"Convergence in k ({_cases(t)[0]}): " + interpret.convergence_k(t, o, _cases(t)[0])[0],
        )
    t = tables.get("convergence_h")
    if t is not None and len(t):
        o = tables["convergence_h_orders"]
        items = [
            (
                f"convergence_h_{c}.png",
                figures.convergence_h(t, c),
                f"{c}: end-effector error against step",
                interpret.convergence_h(t, o, c),
            )
            for c in _cases(t)
        ]
        add(
            "Convergence in the time step",
            "convergence-h",
            items,
            ["convergence_h_orders"],
            f"Convergence in h ({_cases(t)[0]}): " + interpret.convergence_h(t, o, _cases(t)[0])[0],
        )
    t = tables.get("work_precision")
    if t is not None and len(t):
        s = tables["work_precision_summary"]
        items = [
            (
                f"work_precision_{c}.png",
                figures.work_precision(t, c),
                f"{c}: error against wall time",
                interpret.work_precision(s, c),
            )
            for c in _cases(t)
        ]
        add(
            "Work-precision",
            "work-precision",
            items,
            ["work_precision_summary"],
            f"Work-precision ({_cases(t)[-1]}): " + " ".join(interpret.work_precision(s, _cases(t)[-1])[:2]),
        )
    t = tables.get("scheme")
    if t is not None and len(t):
        s = tables["scheme_summary"]
        items = [
            (
                f"scheme_{c}.png",
                figures.scheme(t, c),
                f"{c}: DT-TMM plain vs Riccati sweep, corrections per step",
                interpret.scheme(s, c),
            )
            for c in _cases(t)
        ]
        add(
            "The paper's scheme under test",
            "scheme",
            items,
            ["scheme_summary"],
            f"Paper's scheme ({_cases(t)[-1]}): " + interpret.scheme(s, _cases(t)[-1])[0],
        )
    t = tables.get("paper_series")
    if t is not None and len(t):
        s = tables["paper_summary"]
        items = [
            (
                f"paper_{c}.png",
                figures.time_histories(t, c),
                f"{c}: joint angles and tip deflections",
                interpret.paper(s, c),
            )
            for c in _cases(t)
        ]
        add("Paper figures: time histories", "paper", items, ["paper_summary"])
    t = tables.get("cost")
    if t is not None and len(t):
        e = tables["cost_exponents"]
        add(
            "CPU time against elements per link",
            "cost",
            [("cost.png", figures.cost(t, e), "wall time of the solve against k", interpret.cost(t, e))],
            ["cost_exponents"],
            interpret.cost(t, e)[0],
        )
    latest = bench.latest(bench_dir)
    if latest is None:
        secs.append(
            Section(
                "Cost scaling (benchmarks)",
                [],
                [f"Skipped: no pytest-benchmark JSON in {bench_dir}/ (run `make bench` to produce one)."],
                [],
                "bench",
            )
        )
    else:
        bt, info = bench.load(latest)
        if bt.empty:
            secs.append(
                Section(
                    "Cost scaling (benchmarks)",
                    [],
                    [f"Skipped: {latest} has no benchmark with an element count."],
                    [],
                    "bench",
                )
            )
        else:
            be = bench.exponents(bt)
            tables["bench"], tables["bench_exponents"] = bt, be
            add(
                "Cost scaling (benchmarks)",
                "bench",
                [
                    (
                        "bench_scaling.png",
                        figures.bench_scaling(bt, be),
                        f"time per step against elements ({latest.name})",
                        interpret.bench(be)
                        + [
                            f"Benchmark run {info['date']} on {info['machine']}, "
                            f"commit {info['commit'][:10]}."
                        ],
                    )
                ],
                ["bench_exponents"],
            )
    return secs, summary


def build(tables: dict, meta: dict, out, *, bench_dir="data/bench", footer_extra=None):
    """Write figures, ``index.html`` and ``REPORT.md`` into ``out`` from the study tables."""
    from pathlib import Path

    out = Path(out)
    tables = dict(tables)
    secs, summary = _sections(tables, meta, out, bench_dir)
    om = omissions(tables)
    (out / "data").mkdir(parents=True, exist_ok=True)
    om.to_csv(out / "data" / "omissions.csv", index=False)
    for name in ("bench", "bench_exponents"):
        if name in tables:
            tables[name].to_csv(out / "data" / f"{name}.csv", index=False)
    avail = meta.get("availability", {})
    missing = {m: r for m, r in avail.items() if r}
    head = [
        f"Size: {meta.get('plan', '?')}. {meta.get('note', '')}",
        "Methods run: " + (", ".join(m for m, r in avail.items() if not r) or "none") + ".",
    ]
    if missing:
        head.append("Unavailable: " + "; ".join(f"{m} ({r})" for m, r in missing.items()) + ".")
    for case, p in meta.get("references", {}).items():
        if p.get("status") == "ok":
            cc = p.get("cross_check") or {}
            e = (cc.get("errors") or {}).get("ee_l2")
            chk = (
                f"; cross-check {cc['method']} k={cc['k']} h={cc['h']:g} differs by {e:.2g} m "
                "(end-effector RMS)"
                if cc.get("method") and e is not None
                else "; no cross-check ran"
            )
            head.append(f"Reference {case}: {p['method']} k={p['k']} h={p['h']:g}{chk}.")
        else:
            head.append(
                f"Reference {case}: none could be computed ({'; '.join(p.get('failures', []))}); "
                "errors for this case are NaN."
            )
    head += summary
    head.append(f"{len(om)} planned run(s) without an error value (see Omissions).")
    footer = {
        "built": meta.get("date", ""),
        "machine": meta.get("machine", ""),
        "python": meta.get("python", ""),
        "packages": meta.get("versions", {}),
        "git commit": meta.get("commit", ""),
        "studies computed in": f"{meta['elapsed']:.0f} s" if "elapsed" in meta else "n/a",
        "rebuild": meta.get("command", ""),
        **(footer_extra or {}),
    }
    return write(out, "dttmm: accuracy and cost of DT-TMM against reference methods", head, secs, om, footer)
