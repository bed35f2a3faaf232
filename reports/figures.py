"""Pure plotting functions: study tables in, matplotlib Figures out (Agg canvas, no pyplot).

Failed runs (a status other than ok or flagged) are drawn as grey crosses on the bottom edge of
the axes, so a missing point is visible rather than silently absent; a run that finished is
never drawn as failed.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

__all__ = [
    "bench_elements",
    "bench_links",
    "clipped",
    "unlabelled_axes",
    "convergence_h",
    "convergence_k",
    "load_label",
    "loads",
    "save",
    "scheme",
    "time_histories",
]

ERROR_LABEL = "end-effector position error, RMS (m)"


def _figure(ncols=1, nrows=1, size=(6.0, 4.2)):
    fig = Figure(figsize=(size[0] * ncols, size[1] * nrows), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes.ravel()


def _label(method: str) -> str:
    from experiments.methods import label

    return label(method)


def _uses_k(method: str) -> bool:
    from experiments.methods import uses_k

    return uses_k(method)


def _style(name: str, index: int = 0):
    from experiments.methods import style

    return style(name, index)


def _legend(ax, ncol: int = 2, fontsize: float = 8) -> None:
    """Legend below the axes, outside the plotting area, so it never hides a curve."""
    if ax.get_legend_handles_labels()[0]:
        ax.legend(
            fontsize=fontsize, loc="upper center", bbox_to_anchor=(0.5, -0.16), ncol=ncol, frameon=False
        )


def _fig_legend(fig, axes, ncol: int = 4) -> None:
    """One legend for the whole figure, below every panel (labels merged over ``axes``)."""
    seen = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    if seen:
        fig.legend(
            list(seen.values()), list(seen), loc="outside lower center", ncol=ncol, fontsize=8, frameon=False
        )


def _integer_ticks(ax, values):
    """Label a log axis of element counts with the counts themselves."""
    v = sorted({int(x) for x in values if x > 0})
    if v:
        ax.set_xticks(v, [str(x) for x in v])
        ax.xaxis.set_minor_locator(NullLocator())  # the y axis keeps its minor ticks


FAILED_LABEL = "failed (listed in Omissions)"
OK = ("ok", "unconverged", "ill-conditioned")  # ran to the end: a value, maybe flagged


def failed_rows(table: pd.DataFrame) -> pd.DataFrame:
    """The runs of ``table`` a figure draws as failed: those whose status says the run did not
    finish (failed, unavailable, …); a run that finished is never drawn as failed, even when
    it has no positive value to draw."""
    if "status" not in table:
        return table[:0]
    return table[~table.status.isin(OK)]


def _loglog_groups(ax, table, x, y, group, *, style=None, labels=None, lw=1.5):
    """One log-log line per group; failed runs as crosses at the bottom edge (recorded on the
    axes as ``ax.failed_runs``, the rows drawn), flagged ones (unconverged, ill-conditioned)
    ringed."""
    for i, (name, g) in enumerate(table.groupby(group, sort=False)):
        g = g.sort_values(x)
        ok = np.isfinite(g[y]) & (g[y] > 0)
        if "status" in g:
            ok &= g.status.isin(OK)
        lab = (labels or {}).get(name, _label(name) if group == "method" else str(name))
        st = _style(name, i) if group == "method" else _style(f"{group}:{name}", i)
        if ok.any():
            ax.loglog(
                g[x][ok],
                g[y][ok],
                style or st.linestyle,
                color=st.color,
                marker=st.marker,
                ms=st.size,
                lw=lw,
                label=lab,
                mfc="none" if st.hollow else st.color,
            )
    # runs the method flagged (unconverged, ill-conditioned): their value, ringed
    flagged = table[table.status.isin(("unconverged", "ill-conditioned"))] if "status" in table else table[:0]
    flagged = flagged[np.isfinite(flagged[y]) & (flagged[y] > 0)]
    if len(flagged):
        ax.loglog(
            flagged[x],
            flagged[y],
            "o",
            ms=11,
            mfc="none",
            mec="red",
            mew=1.2,
            ls="none",
            label="flagged by the method (unconverged / ill-conditioned)",
        )
    fails = failed_rows(table)
    ax.failed_runs = getattr(ax, "failed_runs", []) + fails.to_dict("records")
    if len(fails):
        ax.plot(
            list(fails[x]),
            np.full(len(fails), 0.0),
            "x",
            color="0.5",
            transform=ax.get_xaxis_transform(),
            clip_on=False,
            label=FAILED_LABEL,
        )
    ax.grid(True, which="both", alpha=0.3)


def convergence_k(table: pd.DataFrame, case: str, *, floor: float | None = None, y="ee_l2") -> Figure:
    """Error against elements per link k at fixed h, one line per method (case ``case``)."""
    fig, (ax,) = _figure()
    g = table[(table.case == case) & (table.k > 0)]
    _loglog_groups(ax, g, "k", y, "method")
    if floor is not None and np.isfinite(floor) and floor > 0:
        ax.axhline(floor, color="k", ls=":", lw=1, label="reference cross-check difference")
    _integer_ticks(ax, g.k)
    h = g.h.iloc[0] if len(g) else np.nan
    ax.set(xlabel="elements per link k", ylabel=ERROR_LABEL, title=f"{case}: convergence in k (h = {h:g} s)")
    _legend(ax)
    return fig


def convergence_h(table: pd.DataFrame, case: str) -> Figure:
    """Error against step h at fixed k: against the reference (solid) and against the next
    finer h of the same method (dashed, time error alone)."""
    fig, (ax,) = _figure()
    g = table[table.case == case]
    _loglog_groups(ax, g, "h", "ee_l2", "method")
    if "selfdiff_ee_l2" in g and np.isfinite(g["selfdiff_ee_l2"]).any():
        sd = g[np.isfinite(g["selfdiff_ee_l2"])]
        _loglog_groups(
            ax,
            sd,
            "h",
            "selfdiff_ee_l2",
            "method",
            style="--",
            lw=1,
            labels={m: f"{_label(m)}: h vs h/2" for m in sd.method.unique()},
        )
    k = g.k.iloc[0] if len(g) else np.nan
    ax.set(xlabel="step h (s)", ylabel=ERROR_LABEL, title=f"{case}: convergence in h (k = {k})")
    _legend(ax)
    return fig


def scheme(table: pd.DataFrame, case: str) -> Figure:
    """DT-TMM variants (sweep form × corrections per step): error against k and against h."""
    fig, axes = _figure(ncols=2)
    g = table[table.case == case]
    for ax, series, x, xl in ((axes[0], "k", "k", "elements per link k"), (axes[1], "h", "h", "step h (s)")):
        s = g[g.series == series]
        _loglog_groups(ax, s, x, "ee_l2", "variant")
        if series == "k":
            _integer_ticks(ax, s.k)
        fixed = (
            f"h = {s.h.iloc[0]:g} s" if series == "k" and len(s) else (f"k = {s.k.iloc[0]}" if len(s) else "")
        )
        ax.set(xlabel=xl, ylabel=ERROR_LABEL, title=f"{case}: DT-TMM variants ({fixed})")
        _legend(ax)
    return fig


def _line_kw(method: str) -> dict:
    """Line style of a time history: the reference wide and pale underneath, methods thin."""
    if method == "reference":
        return {"color": "k", "lw": 2.5, "alpha": 0.35, "zorder": 0}
    st = _style(method)
    return {"lw": 1, "color": st.color, "ls": st.linestyle}


def _history_grid(s, rows, case, title):
    """Panels rows × columns of time histories; ``rows`` = [(column stem per panel list,
    y label per panel list, scale, difference?)]; one legend below all panels."""
    ncols = max(len(r[0]) for r in rows)
    fig, axes = _figure(ncols=ncols, nrows=len(rows), size=(4.6, 2.7))
    axes = axes.reshape(len(rows), ncols)
    for m, g in s.groupby("method", sort=False):
        for i, (cols, _, scale, diff) in enumerate(rows):
            if diff and (m == "reference" or not _uses_k(m)):
                continue  # the rigid model's differences would set the scale: they are in the tables
            for j, c in enumerate(cols):
                if c in g and g[c].notna().any():
                    axes[i, j].plot(g.t, g[c] * scale, label=_label(m), **_line_kw(m))
    for i, (cols, ylabels, _, diff) in enumerate(rows):
        for j in range(ncols):
            ax = axes[i, j]
            if j >= len(cols):
                ax.set_visible(False)
                continue
            ax.set(xlabel="t (s)", ylabel=ylabels[j])
            ax.grid(True, alpha=0.3)
            if diff:
                _mark_round_off(ax)
                ax.axhline(0, color="k", lw=0.6)
    _fig_legend(fig, axes.ravel())
    fig.suptitle(f"{case}: {title}")
    return fig


def _mark_round_off(ax, tiny: float = 1e-12) -> None:
    """Say so on a difference panel whose every curve is at round-off (a prescribed motion)."""
    ys = [np.nanmax(np.abs(ln.get_ydata())) for ln in ax.get_lines() if len(ln.get_ydata())]
    if ys and max(ys) < tiny:
        ax.text(
            0.5, 0.85, "Δ at round-off (prescribed motion)", transform=ax.transAxes, ha="center", fontsize=8
        )


def time_histories(series: pd.DataFrame, case: str) -> Figure:
    """Joint angles and tip deflections of every method with the reference (top rows), and
    each method minus the reference (bottom rows), against time."""
    s = series[series.case == case]
    n = sum(1 for c in s.columns if c.startswith("joint_angle_") and s[c].notna().any())
    joint = ["hub angle"] if n == 1 else [f"joint {j} angle" for j in range(1, n + 1)]
    ang = [f"joint_angle_{j}" for j in range(1, n + 1)]
    tip = [f"tip_deflection_{j}" for j in range(1, n + 1)]
    tipl = [f"link {j} tip deflection" for j in range(1, n + 1)]
    rows = [
        (ang, [f"{a} (rad)" for a in joint], 1.0, False),
        (tip, [f"{a} (mm)" for a in tipl], 1e3, False),
        ([f"d_{c}" for c in ang], [f"Δ {a} (rad)" for a in joint], 1.0, True),
        ([f"d_{c}" for c in tip], [f"Δ link {j} tip (mm)" for j in range(1, n + 1)], 1e3, True),
    ]
    return _history_grid(s, rows, case, "time histories (top) and Δ = method − reference (bottom)")


LOAD_LABELS = {"moment1": "root moment, link 1 (N·m)", "energy": "total energy (J)"}


def load_label(q: str) -> str:
    """Axis label of a load quantity (``moment1``, ``torque{i}``, ``energy``)."""
    return LOAD_LABELS.get(q, f"joint {q[6:]} torque (N·m)" if q.startswith("torque") else q)


def loads(series: pd.DataFrame, case: str) -> Figure:
    """Root bending moment, torques of motion-driven joints and energy of every method with the
    reference (top row), and each method minus its reference (bottom row), against time."""
    s = series[series.case == case]
    qs = [q for q in s.columns if (q in LOAD_LABELS or q.startswith("torque")) and s[q].notna().any()]
    rows = [
        (qs, [load_label(q) for q in qs], 1.0, False),
        ([f"d_{q}" for q in qs], [f"Δ {load_label(q)}" for q in qs], 1.0, True),
    ]
    return _history_grid(s, rows, case, "loads and energy (top) and Δ = method − reference (bottom)")


DPI = 110


def _texts(fig) -> list:
    """(name, artist) of every text a reader must see: titles, axis labels, the tick labels
    drawn (those within the view), offset texts, texts and legends of each axes, and the
    figure's suptitle, texts and legends."""
    out = []
    for ax in fig.axes:
        if not ax.get_visible():
            continue
        out += [("title", t) for t in (ax.title, ax._left_title, ax._right_title)]
        for axis in (ax.xaxis, ax.yaxis):
            if not axis.get_visible():
                continue
            out += [("axis label", axis.label), ("offset text", axis.get_offset_text())]
            for tick in axis._update_ticks():  # the ticks drawn: those within the view
                out += [("tick label", tick.label1), ("tick label", tick.label2)]
        out += [("text", t) for t in ax.texts if not t.get_clip_on()]
        if ax.get_legend() is not None:
            out.append(("legend", ax.get_legend()))
    out += [("figure legend", lg) for lg in fig.legends]
    out += [("figure text", t) for t in fig.texts]
    out += [("suptitle", t) for t in (getattr(fig, "_suptitle", None), getattr(fig, "_supxlabel", None)) if t]
    return out


def clipped(fig, tol: float = 1.0) -> list[str]:
    """The texts of ``fig`` (:func:`_texts`) whose window extent leaves the canvas, as
    "kind 'text'" strings (empty: everything is inside)."""
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    w, h = fig.bbox.width, fig.bbox.height
    bad = []
    for kind, t in _texts(fig):
        if not t.get_visible() or (hasattr(t, "get_text") and not t.get_text().strip()):
            continue
        bb = t.get_window_extent(r)
        if bb.x0 < -tol or bb.y0 < -tol or bb.x1 > w + tol or bb.y1 > h + tol:
            what = t.get_text() if hasattr(t, "get_text") else ", ".join(x.get_text() for x in t.get_texts())
            bad.append(f"{kind} {what[:60]!r}")
    return bad


def fit_canvas(fig, tries: int = 4) -> None:
    """Grow the figure until every text of :func:`_texts` is inside the canvas: where a title,
    label or legend sticks out, the figure gets that much more room on that side and the
    layout is drawn again (constrained layout then places the axes inside)."""
    for _ in range(tries):
        if not clipped(fig):
            return
        r = fig.canvas.get_renderer()
        w, h = fig.bbox.width, fig.bbox.height
        x0 = y0 = 0.0
        x1, y1 = w, h
        for _, t in _texts(fig):
            if t.get_visible() and (not hasattr(t, "get_text") or t.get_text().strip()):
                bb = t.get_window_extent(r)
                x0, y0, x1, y1 = min(x0, bb.x0), min(y0, bb.y0), max(x1, bb.x1), max(y1, bb.y1)
        dpi = fig.dpi
        grow_w, grow_h = (x1 - x0 - w) / dpi + 0.1, (y1 - y0 - h) / dpi + 0.1
        fw, fh = fig.get_size_inches()
        fig.set_size_inches(fw + max(grow_w, 0), fh + max(grow_h, 0))


def _labelled_ticks(axis) -> int:
    return sum(bool(t.label1.get_visible() and t.label1.get_text().strip()) for t in axis._update_ticks())


def unlabelled_axes(fig) -> list[str]:
    """The visible axes of ``fig`` that draw something but whose x or y axis shows fewer than
    two tick labels (a log axis spanning less than a decade, say), by title."""
    fig.canvas.draw()
    bad = []
    for ax in fig.axes:
        if not ax.get_visible() or not (ax.lines or ax.collections):
            continue
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            if axis.get_visible() and _labelled_ticks(axis) < 2:
                bad.append(f"{ax.get_title() or '(untitled)'}: {name} axis")
    return bad


def label_log_axes(fig) -> None:
    """A log axis that would show fewer than two tick labels (less than a decade in view) gets
    labels at 1, 2 and 5 of each decade."""
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator

    fig.canvas.draw()
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() == "log" and axis.get_visible() and _labelled_ticks(axis) < 2:
                axis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
                axis.set_major_formatter(LogFormatterSciNotation(labelOnlyBase=False))
                axis.set_minor_locator(NullLocator())


def save(fig: Figure, path) -> None:
    """Write a figure as PNG: every log axis labelled (:func:`label_log_axes`), every title,
    label and legend inside the canvas (:func:`fit_canvas`)."""
    fig.set_dpi(DPI)
    label_log_axes(fig)
    fit_canvas(fig)
    fig.savefig(path, dpi=DPI)


# --- Cost scaling (pytest-benchmark groups "elements:<case>:<method>", "links:<method>") ---


def _bench_curves(ax, d, x, exps, fit_note):
    """One log-log curve of time per step per method, the fitted exponent in its label."""
    from experiments.methods import shown_order

    order = shown_order()
    names = [m for m in order if m in set(d.method)] + sorted(set(d.method) - set(order))
    for i, m in enumerate(names):
        g = d[(d.method == m) & (d[x] > 0) & np.isfinite(d.time_per_step)].sort_values(x)
        if g.empty:
            continue
        st, p = _style(m, i), exps.get(m, np.nan)
        lab = _label(m) + (f", p = {p:.2f}" if np.isfinite(p) else ", p: too few points")
        ax.loglog(g[x], g.time_per_step, "-", color=st.color, marker=st.marker, ms=5, lw=1.5, label=lab)
    ax.plot([], [], " ", label=fit_note)


def _guides(ax, xs, ys, x0):
    """Dashed O(N) and O(N³) guides from x0, through the lowest and the highest curve there."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    if xs.size == 0:
        return
    lo, hi = ys.min(), ys.max()
    at = ys[xs == x0] if (xs == x0).any() else ys[xs == xs.min()]
    x = np.geomspace(x0 if (xs == x0).any() else xs.min(), xs.max(), 50)
    top = hi * 2
    for p, y0, lab in ((1, at.min(), "O(N)"), (3, at.max(), "O(N³)")):
        y = y0 * (x / x[0]) ** p
        ax.loglog(x, y, "--", color="0.5", lw=1.2, label="guides O(N), O(N³)" if p == 1 else None)
        end = np.flatnonzero(y <= top)[-1]  # label the guide where it leaves the plot
        ax.annotate(
            lab,
            (x[end], y[end]),
            xytext=(-3, -6),
            textcoords="offset points",
            color="0.3",
            fontsize=9,
            ha="right",
            va="top",
        )
    ax.set_ylim(lo / 2, top)  # the O(N³) guide would otherwise set the scale


def bench_elements(records: pd.DataFrame, exponents: pd.DataFrame, k_min: int = 8) -> Figure:
    """Time per step (solve only) against elements per link, one panel per case, one curve per
    method, fitted exponents (k ≥ ``k_min``) in the legend, O(N) and O(N³) guides dashed; the
    rigid baseline (no elements) as a dotted horizontal line."""
    el = records[records.kind == "elements"]
    cases = [c for c in ("three_link", "single_link") if c in set(el.case)]
    cases += [c for c in dict.fromkeys(el.case) if c not in cases]
    fig, axes = _figure(ncols=max(len(cases), 1), size=(6.4, 5.6))
    for ax, case in zip(axes, cases):
        d = el[el.case == case]
        ex = exponents[(exponents.scan == "elements per link") & (exponents.case == case)]
        _bench_curves(ax, d, "k", dict(zip(ex.method, ex.exponent)), f"p: fitted over k ≥ {k_min}")
        ok = d[(d.k > 0) & np.isfinite(d.time_per_step) & (d.time_per_step > 0)]
        for m, r in d[~(d.k > 0) & np.isfinite(d.time_per_step)].groupby("method"):
            ax.axhline(r.time_per_step.iloc[0], color="k", ls=":", lw=1, label=f"{_label(m)} (no elements)")
        _guides(ax, ok.k, ok.time_per_step, k_min)
        _integer_ticks(ax, ok.k)
        ax.grid(True, which="both", alpha=0.3)
        ax.set(xlabel="elements per link k", ylabel="time per step, solve only (s)", title=f"{case}")
        ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    fig.suptitle("pytest-benchmark: cost per step against elements per link (N = elements)")
    return fig


def bench_links(records: pd.DataFrame, exponents: pd.DataFrame, n_min: int = 2) -> Figure:
    """Time per step (solve only) against the number of links at k = 8 per link, one curve per
    method, fitted exponents (n ≥ ``n_min``) in the legend, O(N) and O(N³) guides dashed."""
    d = records[records.kind == "links"]
    fig, (ax,) = _figure(size=(6.4, 5.4))
    ex = exponents[exponents.scan.str.startswith("links")]
    _bench_curves(ax, d, "n_links", dict(zip(ex.method, ex.exponent)), f"p: fitted over n ≥ {n_min}")
    ok = d[(d.n_links > 0) & np.isfinite(d.time_per_step) & (d.time_per_step > 0)]
    _guides(ax, ok.n_links, ok.time_per_step, n_min)
    _integer_ticks(ax, ok.n_links)
    k = d.k.dropna()
    ax.grid(True, which="both", alpha=0.3)
    ax.set(
        xlabel="number of links n",
        ylabel="time per step, solve only (s)",
        title=f"pytest-benchmark: cost per step against links (k = {int(k.iloc[0]) if len(k) else '?'} per link)",
    )
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.13), ncol=2, frameon=False)
    return fig
