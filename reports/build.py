"""Assemble the report from stored study tables: figures, interpretation, omissions, footer.

Needs only the tables (``<out>/data/*.parquet``) and ``report_meta.json``: figures are
rebuilt from stored data without re-simulating.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from . import bench, figures, interpret, peers
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

    def per_case(t, stem, plot, caption, interp):
        """One figure and its sentences per case of table t."""
        return [(f"{stem}_{c}.png", plot(c), f"{c}: {caption}", interp(c)) for c in _cases(t)]

    t = tables.get("convergence_k")
    if t is not None and len(t):
        o = tables["convergence_k_orders"]
        items = per_case(t, "convergence_k", lambda c: figures.convergence_k(t, c, floor=_floor(meta, c)),
                         "end-effector error against elements per link",
                         lambda c: interpret.convergence_k(t, o, c, _floor(meta, c)))
        add("Convergence in elements per link", "convergence-k", items, ["convergence_k_orders"],
            f"Convergence in k ({_cases(t)[0]}): " + interpret.convergence_k(t, o, _cases(t)[0])[0])
    t = tables.get("convergence_h")
    if t is not None and len(t):
        o = tables["convergence_h_orders"]
        items = per_case(t, "convergence_h", lambda c: figures.convergence_h(t, c),
                         "end-effector error against step", lambda c: interpret.convergence_h(t, o, c))
        add("Convergence in the time step", "convergence-h", items, ["convergence_h_orders"],
            f"Convergence in h ({_cases(t)[0]}): " + interpret.convergence_h(t, o, _cases(t)[0])[0])
    t = tables.get("work_precision")
    if t is not None and len(t):
        s = tables["work_precision_summary"]
        eq = tables.get("work_precision_equal_accuracy", pd.DataFrame())
        items = per_case(t, "work_precision", lambda c: peers.work_precision_figure(t, c), "error against CPU time",
                         lambda c: peers.work_precision_text(s, eq, c))
        add("Work-precision", "work-precision", items, ["work_precision_summary", "work_precision_equal_accuracy"],
            f"Work-precision: {peers.equal_accuracy_text(eq, _cases(t)[-1])[0]}")
    t = tables.get("scheme")
    if t is not None and len(t):
        s = tables["scheme_summary"]
        items = per_case(t, "scheme", lambda c: figures.scheme(t, c),
                         "DT-TMM plain vs Riccati sweep, corrections per step", lambda c: interpret.scheme(s, c))
        add("The paper's scheme under test", "scheme", items, ["scheme_summary"],
            f"Paper's scheme ({_cases(t)[-1]}): " + interpret.scheme(s, _cases(t)[-1])[0])
    t = tables.get("paper_series")
    if t is not None and len(t):
        s = tables["paper_summary"]
        items = per_case(t, "paper", lambda c: figures.time_histories(t, c),
                         "joint angles and tip deflections", lambda c: interpret.paper(s, c))
        add("Paper figures: time histories", "paper", items, ["paper_summary"])
    t = tables.get("cost")
    if t is not None and len(t):
        e = tables["cost_exponents"]
        add(
            "CPU time against elements per link",
            "cost",
            [("cost.png", peers.cost_figure(t, e), "CPU time against k", peers.cost_text(t, e))],
            ["cost_exponents"],
            peers.cost_text(t, e)[0],
        )
    secs.append(peers.configuration_section())
    tables["peer_configuration"] = secs[-1].tables[0][1]
    sec, head = _bench_section(tables, fig_dir, bench_dir)
    secs.append(sec)
    if head:
        summary.append(head)
    return secs, summary


BENCH_TITLE = "Cost scaling (benchmarks)"
BENCH_TABLES = ("bench", "bench_exponents", "bench_element_step_us", "bench_ratios")


def _bench_provenance(info) -> str:
    cores = info.get("cores")
    dirty = " (uncommitted changes)" if info.get("dirty") else ""
    date, name = str(info["date"])[:19].replace("T", " "), Path(info["file"]).name
    return (
        f"Benchmark run {date} ({name}) on {info['machine'] or info['node']}"
        f"{f', {cores} cores' if cores else ''}, Python {info['python']}, "
        f"commit {info['commit'][:10]}{dirty}. "
        f"Timings are from one run on a shared {f'{cores}-core ' if cores else ''}machine, not repeated: "
        "read differences under about 20 % as noise."
    )


def _bench_section(tables, fig_dir, bench_dir):
    """The cost-scaling section from the newest pytest-benchmark JSON: (Section, summary line)."""
    latest = bench.latest(bench_dir)
    if latest is None:
        why = f"Skipped: no pytest-benchmark JSON in {bench_dir}/ (run `make bench` to produce one)."
        return Section(BENCH_TITLE, [], [why], [], "bench"), None
    try:
        rec, info = bench.read(latest)
    except (ValueError, TypeError, AttributeError, KeyError) as exc:  # not a pytest-benchmark JSON
        return Section(BENCH_TITLE, [], [f"Skipped: cannot read {latest}: {exc}."], [], "bench"), None
    if not bench.has_scans(rec):  # an older file: every group against its element count
        bt, _ = bench.load(latest)
        if bt.empty:
            return Section(
                BENCH_TITLE, [], [f"Skipped: {latest} has no benchmark with an element count."], [], "bench"
            ), None
        be = bench.exponents(bt)
        tables["bench"], tables["bench_exponents"] = bt, be
        figures.save(figures.bench_scaling(bt, be), fig_dir / "bench_scaling.png")
        text = interpret.bench(be) + [
            (
                f"No scaling-suite groups (elements:…, links:…) in {latest.name}: every group is shown "
                "against its element count."
            ),
            f"Benchmark run {info['date']} on {info['machine']}, commit {info['commit'][:10]}.",
        ]
        figs = [("figures/bench_scaling.png", f"time per step against elements ({latest.name})")]
        return Section(BENCH_TITLE, figs, text, [("bench_exponents", be)], "bench"), None
    ex = bench.scaling_exponents(rec)
    per_el = bench.element_step_table(rec, "three_link")
    ratios = bench.ratios(rec, tables.get("work_precision_equal_accuracy"))
    tables.update(bench=rec, bench_exponents=ex, bench_element_step_us=per_el, bench_ratios=ratios)
    figs = []
    if (rec.kind == "elements").any():
        figures.save(figures.bench_elements(rec, ex, bench.K_MIN), fig_dir / "bench_elements.png")
        figs.append(("figures/bench_elements.png", "time per step (solve only) against elements per link"))
    if (rec.kind == "links").any():
        figures.save(figures.bench_links(rec, ex, bench.N_MIN), fig_dir / "bench_links.png")
        figs.append(("figures/bench_links.png", "time per step (solve only) against the number of links"))
    text = bench.costs_text(ex, per_el, ratios, k_min=bench.K_MIN, n_min=bench.N_MIN)
    gone = bench.absent(rec)
    if gone:
        text.append("Absent from this benchmark file: " + ", ".join(gone) + ".")
    text += [
        (
            "Tables: exponents with their fit ranges (bench_exponents), cost per element-step in µs "
            "(bench_element_step_us, three_link), ratios of each method's time to DT-TMM's "
            "(bench_ratios: >1 means DT-TMM is faster); the benchmarks' tip errors are against a DT-TMM "
            "reference and are not used here for cross-method accuracy."
        ),
        *bench.provenance(info),
    ]
    tabs = [(n, tables[n]) for n in BENCH_TABLES[1:]]
    head = next((s for s in text if s.startswith("At equal model size")), None)
    return Section(BENCH_TITLE, figs, text, tabs, "bench"), head and f"Benchmarks: a{head[1:]}"


def build(tables: dict, meta: dict, out, *, bench_dir="data/bench", footer_extra=None):
    """Write figures, ``index.html`` and ``REPORT.md`` into ``out`` from the study tables."""
    from pathlib import Path

    out = Path(out)
    tables = dict(tables)
    secs, summary = _sections(tables, meta, out, bench_dir)
    om = omissions(tables)
    (out / "data").mkdir(parents=True, exist_ok=True)
    om.to_csv(out / "data" / "omissions.csv", index=False)
    for name in BENCH_TABLES:
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
