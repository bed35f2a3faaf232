"""Assemble the report from stored study tables: scoreboard, sections, omissions, footer.

Needs only the tables (``<out>/data/*.parquet``) and ``report_meta.json``: figures are
rebuilt from stored data without re-simulating.

Sections come from ``SECTION_BUILDERS``, in order: each is ``builder(inputs) -> Section | None``
(None: nothing to show for this report). To add a section, write a builder and add it to the
list; it saves its figures with ``inputs.figure(name, fig)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import animations, bench, control, figures, interpret, peers, problems
from .front import front
from .render import Section, write
from .scoreboard import scoreboard

__all__ = ["SECTION_BUILDERS", "Inputs", "build", "omissions"]

TITLE = "dttmm: accuracy and cost of DT-TMM against reference methods"
CITATION = (
    'X. Zhang, R. Sørensen, M. R. Iversen, H. Li, "Computationally efficient dynamic modeling of robot '
    "manipulators with multiple flexible-links using acceleration-based discrete time transfer matrix "
    'method", Robotics and Computer-Integrated Manufacturing 49 (2018) 181–193'
)
PAPER_CASES = ("single_link", "three_link")  # the shipped cases that model the paper's arms


def lead(meta: dict) -> list[str]:
    """The paragraphs under the title: what is compared, the seed paper and what of it is shown."""
    cases = list(meta.get("cases") or {})
    shown = [c for c in PAPER_CASES if c in cases] if cases else list(PAPER_CASES)
    if shown:
        what = (
            "Reproduced, with the models and scenarios as defined in this project (the case tables below): its "
            "simulations of a 1-DOF arm with one flexible link (single_link) and of a 3-DOF arm with three "
            "flexible links (three_link), and its comparison of CPU time against the number of elements per link."
        )
    else:
        what = (
            "This report runs the same studies on the cases given on the command line; the paper's arms "
            "(single_link, three_link) and its CPU time against elements per link are in the default report "
            "(`dttmm report --quick`)."
        )
    return [
        (
            "DT-TMM (the acceleration-based discrete time transfer matrix method) against a global-equation "
            "solver of the same discretisation, Exudyn ANCF and geometrically exact beams, and a rigid Pinocchio "
            "model, on the same cases: accuracy against converged references and cost."
        ),
        (
            f"Seed paper: {CITATION}. {what} The paper's experimental data are not available, so no figure is "
            "compared with measurements; its numbers are not reused either: every curve here is computed by "
            "the methods above."
        ),
    ]


RUN_TABLES = ("convergence_k", "convergence_h", "work_precision", "scheme", "paper", "cost")


@dataclass
class Inputs:
    """What a section builder reads: the study tables, the report's metadata, the figure folder
    and the pytest-benchmark JSON folder."""

    tables: dict
    meta: dict
    fig_dir: Path
    bench_dir: Path

    def figure(self, name: str, fig) -> str:
        """Save ``fig`` as ``figures/<name>`` and return that relative path."""
        figures.save(fig, self.fig_dir / name)
        return f"figures/{name}"


def _floor(meta, case) -> float:
    cc = (meta.get("references", {}).get(case) or {}).get("cross_check") or {}
    return float((cc.get("errors") or {}).get("ee_l2", np.nan) or np.nan)


def _cases(df) -> list:
    return list(dict.fromkeys(df.case)) if df is not None and "case" in df and len(df) else []


#: the study tables of runs besides RUN_TABLES, whose rows carry a status: the benchmark problems
#: and the closed loop (a run of theirs that is not "ok" is an omission too)
STATUS_TABLES = ("benchmarks", "control")
OMISSION_COLUMNS = ["study", "case", "method", "k", "h", "options", "status", "reason"]


def _why(r) -> str:
    why = getattr(r, "reason", "") or getattr(r, "error_note", "")
    if not isinstance(why, str) or not why:
        return f"the run ended with status {r.status} and no value" if r.status != "ok" else "no error value"
    return why


def omissions(tables: dict) -> pd.DataFrame:
    """Every planned run of every study that is not ok or has no error value: study, case,
    method, k, h, options, status (failed, unavailable, or flagged unconverged /
    ill-conditioned), why."""
    rows = []
    for name in (*RUN_TABLES, *STATUS_TABLES):
        df = tables.get(name)
        if df is None or df.empty or "status" not in df or "method" not in df:
            continue
        bad = df.status != "ok"
        if name in RUN_TABLES and "ee_l2" in df:
            bad |= ~np.isfinite(df.ee_l2.astype(float))
        for r in df[bad].itertuples():
            rows.append(
                {
                    "study": name,
                    "case": getattr(r, "case", None) or getattr(r, "problem", ""),
                    "method": r.method,
                    "k": getattr(r, "k", np.nan),
                    "h": getattr(r, "h", np.nan),
                    "options": getattr(r, "options", ""),
                    "status": r.status,
                    "reason": _why(r),
                }
            )
    cols = OMISSION_COLUMNS
    df = pd.DataFrame(rows, columns=cols)
    key = df[cols[1:6]].astype(str)  # one line per run (a run shared by two studies: its first)
    return df[~key.duplicated()].reset_index(drop=True)


def _per_case(inp, table, stem, title, plot, caption, interp, tabs=(), summary=None):
    """A section of one figure (with its sentences) per case of ``table``; its anchor is ``stem``
    with hyphens."""
    anchor = stem.replace("_", "-")
    if table is None or not len(table):
        return None
    figs, text = [], []
    order = list(inp.meta.get("cases") or {})
    cases = sorted(_cases(table), key=lambda c: order.index(c) if c in order else len(order))
    for c in cases:
        figs.append((inp.figure(f"{stem}_{c}.png", plot(c)), f"{c}: {caption(c)}"))
        sentences = interp(c)
        text += [f"{c}: {sentences[0]}", *sentences[1:]] if len(cases) > 1 and sentences else sentences
    tables = [(n, inp.tables[n]) for n in tabs if n in inp.tables]
    return Section(title, figs, text, tables, anchor, summary(cases) if summary and cases else "")


def _h(table) -> str:
    return f"{table.h.iloc[0]:g} s" if len(table) else "?"


def _convergence_k(inp):
    t, o = inp.tables.get("convergence_k"), inp.tables.get("convergence_k_orders")
    return _per_case(
        inp,
        t,
        "convergence_k",
        "Convergence in elements per link",
        lambda c: figures.convergence_k(t, c, floor=_floor(inp.meta, c)),
        lambda c: (
            f"end-effector position error (RMS over time, against the reference) against the number "
            f"of elements per link k at h = {_h(t[t.case == c])}; dotted: the difference between the reference "
            "and its independent cross-check."
        ),
        lambda c: interpret.convergence_k(t, o, c, _floor(inp.meta, c)),
        ["convergence_k_orders"],
        lambda cs: f"Convergence in k ({cs[0]}): " + interpret.convergence_k(t, o, cs[0])[0],
    )


def _convergence_h(inp):
    t, o = inp.tables.get("convergence_h"), inp.tables.get("convergence_h_orders")
    return _per_case(
        inp,
        t,
        "convergence_h",
        "Convergence in the time step",
        lambda c: figures.convergence_h(t, c),
        lambda c: (
            "end-effector position error against the step h at fixed k; solid: against the reference, "
            "dashed: against the same method at h/2 (the time error alone)."
        ),
        lambda c: interpret.convergence_h(t, o, c),
        ["convergence_h_orders"],
        lambda cs: f"Convergence in h ({cs[0]}): " + interpret.convergence_h(t, o, cs[0])[0],
    )


def _work_precision(inp):
    t, s = inp.tables.get("work_precision"), inp.tables.get("work_precision_summary")
    eq = inp.tables.get("work_precision_equal_accuracy", pd.DataFrame())
    return _per_case(
        inp,
        t,
        "work_precision",
        "Work-precision",
        lambda c: peers.work_precision_figure(t, c),
        lambda c: (
            "end-effector error against the CPU time of the solve (minimum of repeats), each method "
            "refined along the same (k, h) path; lower left is better; hollow markers: timings taken on a "
            "loaded machine; the star is the rigid-link model."
        ),
        lambda c: peers.work_precision_text(s, eq, c),
        ["work_precision_summary", "work_precision_equal_accuracy"],
        lambda cs: "Work-precision: " + peers.equal_accuracy_text(eq, cs[-1])[0],
    )


def _scheme(inp):
    t, s = inp.tables.get("scheme"), inp.tables.get("scheme_summary")
    return _per_case(
        inp,
        t,
        "scheme",
        "The paper's scheme under test",
        lambda c: figures.scheme(t, c),
        lambda c: (
            "DT-TMM with the paper's plain transfer sweep or the Riccati sweep, and 0, 1 or converged "
            "corrections per step: error against k (left) and against h (right)."
        ),
        lambda c: interpret.scheme(s, c),
        ["scheme_summary"],
        lambda cs: f"Paper's scheme ({cs[-1]}): " + interpret.scheme(s, cs[-1])[0],
    )


def _paper(inp):
    t, s = inp.tables.get("paper_series"), inp.tables.get("paper_summary")
    return _per_case(
        inp,
        t,
        "paper",
        "Paper figures: time histories",
        lambda c: figures.time_histories(t, c),
        lambda c: (
            "joint angles and tip deflections of every method with the reference (wide grey), and "
            "below them Δ = method minus reference; the rigid model's Δ, far larger, is left out of the lower "
            "panels (its RMS is in the table)."
        ),
        lambda c: interpret.paper(s, c),
        ["paper_summary"],
    )


def _is_spatial(inp, case) -> bool:
    """Whether ``case`` is a spatial arm (the run's case records)."""
    return (inp.meta.get("cases") or {}).get(case, {}).get("kind") == "spatial"


def _loads(inp):
    t, s = inp.tables.get("paper_load_series"), inp.tables.get("paper_loads")
    if s is None:
        return None
    return _per_case(
        inp,
        t,
        "loads",
        "Loads and energy",
        lambda c: figures.loads(t, c),
        lambda c: (
            (
                "bending moment at the root of link 1 (the magnitude of the bending part of the root cut "
                "load, from the cut loads of the runs that record them)"
                if _is_spatial(inp, c)
                else "bending moment at the root of link 1 (from the hub balance M = τ₁ − J₁θ̈₁)"
            )
            + ", torques of motion-driven joints and total energy of every method with its reference (wide "
            "grey; for the energy, the energy reference named below), and below them Δ = method minus "
            "reference (rigid model left out of the lower panels)."
        ),
        lambda c: interpret.loads(s, c),
        ["paper_loads"],
    )


def _cost(inp):
    t, e = inp.tables.get("cost"), inp.tables.get("cost_exponents")
    if t is None or not len(t):
        return None
    text = peers.cost_text(t, e)
    fig = inp.figure("cost.png", peers.cost_figure(t, e))
    from experiments.studies.cost import case_order

    caption = (
        f"{' and '.join(case_order(t))}: CPU time of the solve (minimum of repeats) against elements per "
        f"link k at h = {_h(t)}, one panel per case; hollow markers: noisy points"
    )
    return Section(
        "CPU time against elements per link", [(fig, caption)], text, [("cost_exponents", e)], "cost", text[0]
    )


def _validation(inp):
    """Links to the methods' scorecards of ``dttmm validate`` (its folder: the report meta's
    ``validate_dir``, default ``out/validate``), or how to make them."""
    from .validate_page import links_section

    folder = Path(inp.meta.get("validate_dir") or "out/validate")
    sec = links_section(folder, inp.fig_dir.parent)
    if sec is not None:
        return sec
    return Section(
        "Validation scorecards",
        [],
        [
            f"No scorecards in {folder}: `dttmm validate --quick --out {folder}` checks every method against "
            "the published, closed-form and independent values (docs/validate.md); the report then links them."
        ],
        [],
        "validate",
    )


def _peer_configuration(inp):
    sec = peers.configuration_section()
    inp.tables["peer_configuration"] = sec.tables[0][1]
    return sec


def _cases_section(inp):
    from .cases import case_section

    return case_section(inp.meta)


BENCH_TITLE = "Cost scaling (pytest-benchmark)"
BENCH_TABLES = ("bench", "bench_exponents", "bench_element_step_us", "bench_ratios")


def _skipped(why: str) -> Section:
    return Section(BENCH_TITLE, [], [f"Skipped: {why}"], [], "bench")


def _bench_section(inp):
    """The cost-scaling section from the newest pytest-benchmark JSON of the scaling suites."""
    tables, latest = inp.tables, bench.latest(inp.bench_dir)
    if latest is None:
        return _skipped(f"no pytest-benchmark JSON in {inp.bench_dir}/ (run `make bench` to produce one).")
    try:
        rec, info = bench.read(latest)
    except (ValueError, TypeError, AttributeError, KeyError) as exc:  # not a pytest-benchmark JSON
        return _skipped(f"cannot read {latest}: {exc}.")
    if not bench.has_scans(rec):
        return _skipped(f"{latest.name} has no scaling-suite groups (elements:…, links:…); run `make bench`.")
    ex = bench.scaling_exponents(rec)
    per_el = bench.element_step_table(rec, "three_link")
    ratios = bench.ratios(rec, tables.get("work_precision_equal_accuracy"))
    tables.update(bench=rec, bench_exponents=ex, bench_element_step_us=per_el, bench_ratios=ratios)
    figs = []
    if (rec.kind == "elements").any():
        f = inp.figure("bench_elements.png", figures.bench_elements(rec, ex, bench.K_MIN))
        figs.append((f, "time per step (solve only) against elements per link"))
    if (rec.kind == "links").any():
        f = inp.figure("bench_links.png", figures.bench_links(rec, ex, bench.N_MIN))
        figs.append((f, "time per step (solve only) against the number of links"))
    text = bench.costs_text(ex, per_el, ratios, k_min=bench.K_MIN, n_min=bench.N_MIN)
    spatial = bench.spatial_table(latest)
    text += bench.spatial_text(spatial)
    gone = bench.absent(rec)
    if gone:
        text.append("Absent from this pytest-benchmark file: " + ", ".join(gone) + ".")
    text += [
        (
            "Tables: exponents with their fit ranges (bench_exponents), cost per element-step in µs "
            "(bench_element_step_us, three_link), ratios of each method's time to DT-TMM's "
            "(bench_ratios: >1 means DT-TMM is faster); the pytest-benchmark runs' tip errors are against a DT-TMM "
            "reference and are not used here for cross-method accuracy."
        ),
        *bench.provenance(info),
    ]
    tabs = [(n, tables[n]) for n in BENCH_TABLES[1:]]
    if len(spatial):
        tables["bench_spatial_us"] = spatial
        tabs.append(("bench_spatial_us", spatial))
    head = next((s for s in text if s.startswith("At equal model size")), None)
    return Section(BENCH_TITLE, figs, text, tabs, "bench", head and f"pytest-benchmark: a{head[1:]}")


SECTION_BUILDERS = [
    _cases_section,
    animations.section,  # the arm moving, per case (table motion)
    _convergence_k,
    _convergence_h,
    _work_precision,
    _scheme,
    _paper,
    _loads,
    _cost,
    problems.section,  # benchmark problems (published single-case checks)
    control.section,  # closed-loop drives: tracking, moment feedback, natural frequencies
    _validation,
    _peer_configuration,
    _bench_section,
]


def _head(meta, om) -> list[str]:
    avail = meta.get("availability", {})
    missing = {m: r for m, r in avail.items() if r}
    from experiments.methods import label

    note = meta.get("note", "")
    head = [
        note[:1].upper() + note[1:] if note else f"Size: {meta.get('plan', '?')}.",
        "Methods run: " + (", ".join(label(m) for m, r in avail.items() if not r) or "none") + ".",
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
                "errors for this case have no value."
            )
    return head


_FORKED: Inputs | None = None  # the inputs a forked section worker reads (see _sections)


def _section_in_worker(i: int):
    """Section builder i on the forked inputs: (its Section, the tables and meta entries it added
    or replaced), so that the parent can keep them as if it had run the builder itself."""
    inp = _FORKED
    tables, meta = dict(inp.tables), dict(inp.meta)
    sec = SECTION_BUILDERS[i](inp)
    new_tables = {k: v for k, v in inp.tables.items() if tables.get(k) is not v}
    new_meta = {k: v for k, v in inp.meta.items() if meta.get(k) is not v}
    return sec, new_tables, new_meta


def _sections(inp: Inputs, workers: int | None = None) -> list:
    """Every section builder's Section, in order. Drawing the figures is most of a report's
    build; the builders are independent, so they run in ``workers`` processes forked from this
    one (default: this machine's cores, at most 4), or here where fork is not offered."""
    import multiprocessing
    import os
    from concurrent.futures import ProcessPoolExecutor

    global _FORKED
    n = min(4, os.cpu_count() or 1) if workers is None else workers
    if n <= 1 or "fork" not in multiprocessing.get_all_start_methods():
        return [b(inp) for b in SECTION_BUILDERS]
    _FORKED = inp
    try:
        with ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork")) as pool:
            done = list(pool.map(_section_in_worker, range(len(SECTION_BUILDERS))))
    finally:
        _FORKED = None
    for _, new_tables, new_meta in done:
        inp.tables.update(new_tables)
        inp.meta.update(new_meta)
    return [sec for sec, _, _ in done]


def build(tables: dict, meta: dict, out, *, bench_dir="data/bench", footer_extra=None):
    """Write figures, the pages (``index.html`` and one per study) and ``REPORT.md`` into ``out``
    from the study tables."""
    out = Path(out)
    tables = dict(tables)
    inp = Inputs(tables, meta, out / "figures", Path(bench_dir))
    inp.fig_dir.mkdir(parents=True, exist_ok=True)
    secs = [s for s in _sections(inp) if s is not None]
    om = omissions(tables)
    board = scoreboard(tables, meta)
    board.title, board.anchor = "Scoreboard per case", "scoreboard-per-case"
    at = next((i for i, s in enumerate(secs) if s.anchor == "work-precision"), len(secs) - 1)
    secs.insert(at + 1, board)
    first = front(tables, meta, om, inp.figure)
    (out / "data").mkdir(parents=True, exist_ok=True)
    om.to_csv(out / "data" / "omissions.csv", index=False)
    if first.board is not None:
        first.board[1].to_csv(out / "data" / "scoreboard.csv", index=False)
    for name, df, *_ in [t for s in secs for t in s.tables]:
        df.to_csv(out / "data" / f"{name}.csv", index=False)
    head = _head(meta, om) + [s.summary for s in secs if s.summary]
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
    return write(out, TITLE, head, secs, om, footer, lead=lead(meta), front=first)
