"""The "Benchmark problems" report section: per problem a table (target, each method's value at
each k, error, pass/fail at the stated tolerance, observed order in k) and one figure (error
against k), plus the spin-up tip-deflection histories. Built from the tables of the
benchmark-problems study (:mod:`experiments.studies.problems`, study name ``benchmarks``, whose
table names and the section's anchor keep that name) only (no simulation)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from experiments.studies.problems import K_FINE

from . import figures
from .render import Section

__all__ = [
    "error_figure",
    "headline",
    "overview_table",
    "section",
    "sections",
    "sentences",
    "spin_up_figure",
    "summary_table",
]

TITLE = "Benchmark problems"
ANCHOR = "benchmarks"


def _g(x, digits: int = 3) -> str:
    """A number with ``digits`` significant digits ('n/a' when not finite)."""
    return f"{x:.{digits}g}" if x is not None and np.isfinite(x) else "n/a"


def _measure(d: pd.DataFrame) -> pd.Series:
    """The error the tolerance applies to: relative or absolute, row by row."""
    return d.rel_error.where(d.tolerance_kind == "relative", d.error)


def _groups(res: pd.DataFrame) -> pd.DataFrame:
    """The rows with a ``group`` column (the quantity itself where a table has none)."""
    if "group" not in res.columns:
        res = res.assign(group=res.quantity)
    return res.assign(group=res.group.where(res.group.astype(bool), res.quantity))


def grouped(res: pd.DataFrame, orders: pd.DataFrame | None = None) -> pd.DataFrame:
    """One row per (problem, group, method, k): the group's worst quantity there (largest error
    as the tolerance measures it), passed only when every quantity of the group passed, and the
    observed order of the quantity that is worst at the group's largest k. A group of one
    quantity is that quantity's rows. The spatial load sweeps (the Princeton beam's 28
    published values) are summarised and plotted by their groups (|u_y|, u_z)."""
    d = _groups(res)
    d = d.assign(_m=_measure(d).fillna(np.inf), _order=np.nan)
    if orders is not None and len(orders):
        key = orders.set_index(["problem", "quantity", "method"]).order
        d["_order"] = [key.get((r.problem, r.quantity, r.method), np.nan) for r in d.itertuples()]
    out = []
    for (_p, _g, _meth, _k), g in d.groupby(["problem", "group", "method", "k"], sort=False):
        worst = g.loc[g._m.idxmax()].copy()
        worst["passed"] = bool(g.passed.astype(bool).all())
        if (g.status != "ok").any():
            worst["status"] = g.status[g.status != "ok"].iloc[0]
        worst["quantity"] = worst["group"]
        worst["n_quantities"] = len(g)
        out.append(worst)
    if not out:
        return d.drop(columns=["_m", "_order"]).assign(n_quantities=1)
    g = pd.DataFrame(out).reset_index(drop=True)
    g.loc[g._m == np.inf, ["error", "rel_error", "order_error"]] = np.nan
    return g.drop(columns=["_m"]).rename(columns={"_order": "worst_order"})


def summary_table(res: pd.DataFrame, orders: pd.DataFrame, problem: str) -> pd.DataFrame:
    """One row per (quantity, method) of ``problem``: target, value at every k, the error
    (relative or absolute, as the tolerance) at the largest k, pass/fail there, the smallest k
    from which every larger k passes, and the observed order in k; numbers as text with 3 significant digits."""
    d = res[res.problem == problem]
    rows = []
    for (quantity, method), g in d.groupby(["quantity", "method"], sort=False):
        g = g.sort_values("k")
        last = g.iloc[-1]
        meas = _measure(g)
        passing = _passes_from(g)
        o = orders[(orders.problem == problem) & (orders.quantity == quantity) & (orders.method == method)]
        order = float(o.order.iloc[0]) if len(o) else np.nan
        row = {"quantity": quantity, "method": method, "target": _g(last.target, 5)}
        row.update({_kcol(r.k): _g(r.value) if r.status == "ok" else r.status for r in g.itertuples()})
        row.update(
            {
                f"{last.tolerance_kind} error": _g(meas.iloc[-1], 2),
                "tolerance": _g(last.tolerance, 2),
                "pass": "yes" if bool(last.passed) else "NO",
                "passes from k": passing,
                "order in k": _g(order, 2),
            }
        )
        rows.append(row)
    return pd.DataFrame(rows)


def overview_table(res: pd.DataFrame, orders: pd.DataFrame) -> pd.DataFrame:
    """One row per (problem, quantity), one column per flexible method: "error at the largest k
    (k from which it passes, observed order)", e.g. "5.7e-06 (k≥8, p=3.0)"; "fails" when the
    largest k is outside the tolerance. A group of quantities (a load sweep, the extrema of a
    run) is one row: its worst quantity (:func:`grouped`)."""
    rows = []
    flex = grouped(res[res.method != "pinocchio-rigid"], orders)
    for (problem, quantity), d in flex.groupby(["problem", "quantity"], sort=False):
        row = {"problem": problem, "quantity": quantity}
        for method, g in d.groupby("method", sort=False):
            g = g.sort_values("k")
            if int(g.n_quantities.iloc[-1]) > 1:  # a group: the order of its worst quantity
                p = _g(float(g.worst_order.iloc[-1]), 2)
                row["quantity"] = f"{quantity} (worst of {int(g.n_quantities.iloc[-1])})"
            else:
                o = orders[
                    (orders.problem == problem) & (orders.quantity == quantity) & (orders.method == method)
                ]
                p = _g(float(o.order.iloc[0]), 2) if len(o) else "n/a"
            start = _passes_from(g)
            where = f"k≥{start}" if start != "none" else "fails"
            row[method] = f"{_g(_measure(g).iloc[-1], 2)} ({where}, p={p})"
        rows.append(row)
    out = pd.DataFrame(rows)
    from experiments.methods import shown_order

    first = [m for m in shown_order() if m in out.columns]
    out = out[["problem", "quantity", *first, *[c for c in out.columns[2:] if c not in first]]]
    return out.fillna("not run")  # the method does not model the problem or records no such quantity


def _kcol(k) -> str:
    return "rigid" if int(k) == 0 else f"k={int(k)}"


def _passes_from(g: pd.DataFrame) -> str:
    """The smallest k from which every larger k passes too ('none' if the largest fails)."""
    g = g.sort_values("k")
    ok = g.passed.astype(bool).to_numpy()
    if not ok.size or not ok[-1]:
        return "none"
    i = ok.size - 1
    while i > 0 and ok[i - 1]:
        i -= 1
    return _kcol(g.k.iloc[i]).removeprefix("k=")


def error_figure(res: pd.DataFrame, problem: str):
    """Error (as the tolerance measures it) against k, one line per (method, quantity), with the
    tolerance as a dashed line. The frequencies show their difference to k = K_FINE instead, since
    the published values are rounded to 0.01 Hz."""
    d = res[(res.problem == problem) & (res.k > 0)].copy()
    freq = d.quantity.str.fullmatch(r"f\d+").all()
    if not freq:  # a group of quantities (a load sweep, extrema): its worst one at each k
        d = grouped(d)
    d["y"] = d.order_error if freq else _measure(d)
    quantities = list(dict.fromkeys(d.quantity))
    fig, axes = figures._figure(ncols=len(quantities), size=(5.2, 3.8))
    for ax, q in zip(axes, quantities):
        g = d[d.quantity == q]
        figures._loglog_groups(ax, g, "k", "y", "method")
        if not freq:
            ax.axhline(g.tolerance.iloc[0], ls="--", color="0.4", lw=1, label="tolerance")
        figures._integer_ticks(ax, g.k)
        ax.set_xlabel("elements per link k")
        kind = f"|f(k) − f({K_FINE})| (Hz)" if freq else f"{g.tolerance_kind.iloc[0]} error"
        if not freq and int(g.n_quantities.max()) > 1:
            kind += f" (worst of {int(g.n_quantities.max())})"
        ax.set_ylabel(kind)
        ax.set_title(f"{problem}: {q}", fontsize=9)
        _not_drawn(ax, g)
    figures._fig_legend(fig, axes, ncol=4)
    return fig


def _not_drawn(ax, g: pd.DataFrame) -> None:
    """Say in the panel which runs finished but have nothing to draw on a log axis (a difference
    of zero to round-off); a panel with nothing drawn shows only that sentence."""
    none = g[g.status.isin(figures.OK) & ~(np.isfinite(g.y.astype(float)) & (g.y > 0))]
    if not len(none):
        return
    ks = ", ".join(str(int(k)) for k in sorted(set(none.k)))
    msg = f"runs ok, not drawn (no difference left,\nround-off): k = {ks}"
    if not ax.lines:
        ax.set_yscale("linear")
        ax.set_yticks([])
        ax.text(0.5, 0.5, msg, ha="center", va="center", fontsize=8, transform=ax.transAxes)
    else:
        ax.text(0.97, 0.97, msg, ha="right", va="top", fontsize=7, transform=ax.transAxes)


def spin_up_figure(series: pd.DataFrame):
    """Tip deflection against time of every spin-up problem: DT-TMM (linear strain) at each k,
    the second-order element and Exudyn ANCF at the largest k."""
    probs = sorted(set(series.problem), key=lambda p: float(p.rsplit("w", 1)[-1]))
    fig, axes = figures._figure(ncols=len(probs), size=(4.6, 3.8))
    for ax, p in zip(axes, probs):
        s = series[series.problem == p]
        ks = sorted(set(s[s.method == "dttmm"].k))
        good = s[s.method != "dttmm"].tip_deflection
        # the y range of the converged curves: a run-away linear-element curve must not flatten them
        bottom = 1.6 * float(good.min()) if len(good) else None
        gone = []
        for i, k in enumerate(ks):
            c = s[(s.method == "dttmm") & (s.k == k)]
            off = bottom is not None and float(c.tip_deflection.min()) < bottom
            ax.plot(
                c.t,
                c.tip_deflection,
                color="C0",
                alpha=0.35 + 0.65 * (i + 1) / len(ks),
                lw=1,
                label=f"DT-TMM linear strain k={k}",
            )
            if off:
                gone.append(f"linear k={k} leaves the axes (min {c.tip_deflection.min():.3g} m)")
        for m, style in (("dttmm-2nd", "C9--"), ("exudyn-ancf", "C1:")):
            c = s[s.method == m]
            if len(c):
                ax.plot(
                    c.t, c.tip_deflection, style, lw=1.5, label=f"{figures._label(m)} k={int(c.k.iloc[0])}"
                )
        if bottom is not None:
            ax.set_ylim(bottom, -0.15 * bottom)
        if gone:
            ax.text(0.03, 0.03, "\n".join(gone), transform=ax.transAxes, fontsize=7, va="bottom")
        ax.set_xlabel("t (s)")
        ax.set_ylabel("tip deflection (m)")
        ax.set_title(p, fontsize=9)
        ax.grid(True, alpha=0.3)
    figures._fig_legend(fig, axes, ncol=3)
    return fig


def sentences(res: pd.DataFrame, orders: pd.DataFrame, problem: str) -> list:
    """What the table says, computed: which methods pass at the largest k, and their orders."""
    d = res[(res.problem == problem) & (res.method != "pinocchio-rigid")]
    if len(d) and not d.quantity.str.fullmatch(r"f\d+").all():
        d = grouped(d, orders)
    out = []
    for q, g in d.groupby("quantity", sort=False):
        kmax = g.k.max()
        last = g[g.k == kmax]
        ok = [figures._label(m) for m in last[last.passed.astype(bool)].method]
        bad = [figures._label(m) for m in last[~last.passed.astype(bool)].method]
        o = orders[(orders.problem == problem) & (orders.quantity == q) & np.isfinite(orders.order)]
        ords = ", ".join(f"{figures._label(r.method)} {r.order:.1f}" for r in o.itertuples())
        if "n_quantities" in g and int(g.n_quantities.max()) > 1:
            q = f"{q} (worst of {int(g.n_quantities.max())} values)"
            w = last[np.isfinite(last.worst_order.astype(float))]
            ords = ", ".join(f"{figures._label(r.method)} {r.worst_order:.1f}" for r in w.itertuples())
        out.append(
            f"{q} at k = {kmax}: within tolerance: {', '.join(ok) or 'none'}"
            f"{'; outside: ' + ', '.join(bad) if bad else ''}. Observed orders in k: {ords or 'none fitted'}."
        )
    return out


def section(inputs) -> Section | None:
    """Report-section builder (``reports.build.SECTION_BUILDERS``): reads ``inputs.tables``,
    writes its figures into ``inputs.fig_dir``; None when the study did not run."""
    secs = sections(inputs.tables, inputs.fig_dir)
    return secs[0] if secs else None


def sections(tables: dict, fig_dir) -> list:
    """The section (a one-element list), or [] when the study did not run. Its tables are
    written as CSV by the report builder."""
    res = tables.get("benchmarks")
    if res is None or res.empty:
        return []
    orders = tables.get("benchmarks_orders", pd.DataFrame(columns=["problem", "quantity", "method", "order"]))
    info = tables.get("benchmarks_problems", pd.DataFrame())
    fig_dir = Path(fig_dir)
    fig_dir.mkdir(parents=True, exist_ok=True)
    figs, text = [], [_intro()]
    tabs = [
        ("benchmarks_overview", overview_table(res, orders), "Overview: error at the largest k per method")
    ]
    if len(info):
        cols = ["problem", "compared", "target", "value_kind", "tolerance"]
        tabs.append(("benchmarks_problems", info[cols], "Problems, compared quantities and tolerances"))
    for problem in dict.fromkeys(res.problem):
        name = f"benchmarks_{problem}"
        tabs.append((name, summary_table(res, orders, problem), problem))
        figures.save(error_figure(res, problem), fig_dir / f"{name}.png")
        figs.append((f"figures/{name}.png", f"{problem}: error against elements per link"))
        text += [f"{problem}: {s}" for s in sentences(res, orders, problem)]
    series = tables.get("benchmarks_series")
    if series is not None and len(series):
        figures.save(spin_up_figure(series), fig_dir / "benchmarks_spin_up.png")
        figs.append(("figures/benchmarks_spin_up.png", "spin-up beam: tip deflection against time"))
    return [Section(TITLE, figs, text, tabs, ANCHOR, summary=headline(res))]


def headline(res: pd.DataFrame) -> str:
    """One summary sentence: how many compared quantities DT-TMM (either strain element) gets
    within tolerance at the largest k, and which it does not."""
    from experiments.methods import by_role

    d = res[res.method.isin(by_role("subject"))]
    if len(d):
        d = grouped(d)
    ok, bad = [], []
    for (problem, quantity), g in d.groupby(["problem", "quantity"], sort=False):
        last = g[g.k == g.k.max()]
        (ok if last.passed.astype(bool).any() else bad).append(f"{problem} {quantity}")
    return (
        f"Benchmark problems: DT-TMM is within tolerance at the largest k on {len(ok)} of "
        f"{len(ok) + len(bad)} compared quantities (a load sweep or a run's extrema counted as one)"
        + (f" (not on: {', '.join(bad)})." if bad else ".")
    )


def _intro() -> str:
    return (
        "Problems of the field with a published, closed-form or recorded value (sources and "
        "tolerances in each case file's [provenance] table and in docs/benchmarks.md). Each table "
        "gives the target, every method's value at each k, the error at the largest k as the "
        "tolerance measures it (relative or absolute), pass/fail there, the smallest k from which every larger k passes "
        "and the observed order in k (fitted before the error floor). Problems compared against a "
        "reference run (tip_path_rms, tip_deflection_rms) have target 0: the value is the "
        "normalised difference to an Exudyn run named in the case file (planar: ANCF at k = 32, "
        "h = 2.5e-4 s; the spatial bang-bang arm: the 3-D beam at k = 32, h = 5e-4 s). The overview "
        "gives, per method, the error at the largest k (k from which it passes, observed order p). The "
        "spatial problems (princeton_beam, bend_45deg, right_angle_cantilever, bang_bang_arm; "
        "experiments/cases/spatial/) run with every method that runs spatial arms; their static "
        "problems are solved by each method's own statics (DT-TMM: dttmm.spatial.statics; Exudyn: "
        "SolveStatic), the right-angle cantilever by a run compared with a recorded converged Exudyn "
        "value, the bang-bang arm by a run compared with an Exudyn run (at the settings its case "
        "file's peer_options give, with the reason). A load "
        "sweep (the Princeton beam's |u_y| and u_z at 14 load points) or a run's extrema is one "
        "line of the overview and one panel of the figure: its worst value at each k."
    )
