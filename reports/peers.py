"""Report parts about the fairness of the comparison: the peer configuration, CPU-time figures
built from repeated timings, and like-for-like equal-accuracy ratios (2 significant digits)."""

from __future__ import annotations

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.ticker import NullLocator

from .figures import _legend, _style
from .render import Section

__all__ = [
    "configuration_section",
    "cost_figure",
    "cost_text",
    "equal_accuracy_text",
    "peer_settings",
    "sig2",
    "work_precision_axes",
    "work_precision_figure",
    "work_precision_text",
]


def peer_settings() -> list[tuple]:
    """(peers, setting, value used, why — measured on three_link unless said, documentation
    source) of every method's documented settings (its registry record), a setting shared by
    several methods listed once with all their labels."""
    from experiments import methods

    rows: dict = {}
    for n in methods.names():
        for st in methods.get(n).settings:
            rows.setdefault(st, []).append(methods.label(n))
    return [(", ".join(who), st.setting, st.value, st.why, st.source) for st, who in rows.items()]


def configuration_section() -> Section:
    """The "Peer configuration" section: every setting of the Exudyn peers, why, and its source."""
    df = pd.DataFrame(
        peer_settings(), columns=["peer", "setting", "value", "why (measured)", "documentation"]
    )
    text = [
        (
            "The Exudyn models are run as Exudyn's documentation recommends for speed: drive values set "
            "once per step, one Jacobian per step, sparse solver, no file output, one thread. Each "
            "setting below names its documentation source; 'why' gives the measurement behind it."
        ),
        (
            "Ratios between methods are formed only between runs of the same element strain: DT-TMM "
            "with the linear element against the global solver with the linear element, and DT-TMM "
            "with the second-order element against the global solver with it and the Exudyn elements."
        ),
    ]
    return Section("Peer configuration", [], text, [("peer_configuration", df)], "peers")


def sig2(x) -> str:
    """A number with 2 significant digits, plainly written ("2800", "2.8", "0.028")."""
    if x is None or not np.isfinite(x):
        return "n/a"
    return f"{float(f'{x:.2g}'):g}" if 1e-4 <= abs(x) < 1e6 else f"{x:.1e}"


def _label(m, spatial=False):
    from experiments.methods import label

    return label(m, spatial)


def _timed(t: pd.DataFrame) -> pd.DataFrame:
    if "cpu_time" in t:
        return t
    from experiments.studies.cost import timing_columns

    return timing_columns(t)


def _cost_cases(t: pd.DataFrame) -> list[tuple[str, bool]]:
    """(case, spatial) of every case of a cost table, planar arms first (cost.case_order)."""
    from experiments.studies.cost import case_order, spatial_cases

    spatial = spatial_cases(t)
    return [(c, c in spatial) for c in case_order(t)]


def _case_title(case: str, spatial: bool) -> str:
    return f"{case} ({'spatial' if spatial else 'planar'})"


def _exponents_of(exponents: pd.DataFrame, case: str) -> dict:
    """method -> fitted exponent on ``case`` (a table without a case column: one case)."""
    if exponents is None or not len(exponents):
        return {}
    e = exponents[exponents.case == case] if "case" in exponents else exponents
    return dict(zip(e.method, e.exponent))


def cost_figure(table: pd.DataFrame, exponents: pd.DataFrame) -> Figure:
    """CPU time (least of the repeats; bar to the median) against k, one panel per case side by
    side (planar arms first, then spatial ones), each titled with its case, one line per method;
    noisy points (machine loaded or wide spread) drawn hollow."""
    t = _timed(table)
    cases = _cost_cases(t) or [("", False)]
    fig = Figure(figsize=(6.0 * len(cases), 5.0), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(1, len(cases), squeeze=False).ravel()
    t = t[(t.status == "ok") & (t.k > 0)]
    order = list(dict.fromkeys(t.method))  # one style per method in every panel
    for ax, (case, spatial) in zip(axes, cases):
        _cost_panel(ax, t[t.case == case], _exponents_of(exponents, case), order, spatial)
        n = int(t[t.case == case].repeats.min()) if (t.case == case).any() else 0
        ax.set(
            ylabel=f"CPU time (s), least of ≥ {n} runs",  # short runs are called more often (timing.MIN_CPU)
            title=f"{_case_title(case, spatial)}: CPU time against k (hollow: noisy)" if case else "",
        )
    return fig


def _cost_panel(ax, t: pd.DataFrame, ex: dict, order: list, spatial: bool = False) -> None:
    for m, g in t.groupby("method", sort=False):
        g = g.sort_values("k")
        p = ex.get(m, np.nan)
        st = _style(m, order.index(m))
        c = st.color
        ax.loglog(
            g.k,
            g.cpu_time,
            st.linestyle,
            color=c,
            label=f"{_label(m, spatial)}" + (f" (∝ k^{p:.2f})" if np.isfinite(p) else ""),
        )
        quiet, noisy = g[~g.noisy], g[g.noisy]
        ax.loglog(quiet.k, quiet.cpu_time, st.marker, color=c, ls="none")
        ax.loglog(noisy.k, noisy.cpu_time, st.marker, mfc="none", color=c, ls="none")
        med = g.cpu_time_median.where(np.isfinite(g.cpu_time_median), g.cpu_time)
        ax.vlines(g.k, g.cpu_time, med, color=c, lw=1)
    ks = sorted({int(k) for k in t.k})
    ax.set_xticks(ks, [str(k) for k in ks])
    ax.xaxis.set_minor_locator(NullLocator())  # the y axis keeps its minor ticks
    ax.set(xlabel="elements per link k")
    _legend(ax, ncol=1)


def cost_text(table: pd.DataFrame, exponents: pd.DataFrame) -> list[str]:
    """Sentences under the cost figure: exponents per case, the methods a spatial arm runs only
    in part, noise and the timing protocol, and where DT-TMM overtakes the global solver."""
    t = _timed(table)
    cases = _cost_cases(t)
    ex = exponents[np.isfinite(exponents.exponent)] if len(exponents) else exponents

    def fitted(case, spatial=False):
        e = ex[ex.case == case] if "case" in ex else ex
        return (
            ", ".join(f"{_label(r.method, spatial)} p = {r.exponent:.2f}" for r in e.itertuples()) or "none"
        )

    per_case = [f"on {_case_title(c, s)} {fitted(c, s)}" for c, s in cases] or [fitted("")]
    head = "Fitted exponents of CPU time ∝ k^p (k ≥ 2): " + "; ".join(per_case) + "."
    out = [head]
    ok = t[t.status == "ok"]
    out += _spatial_limits(ok, cases)
    n_noisy = int(ok.noisy.sum())
    reps = sorted({int(x) for x in ok.repeats}) if len(ok) else []
    n_runs = "?" if not reps else str(reps[0]) if len(reps) == 1 else f"{reps[0]}–{reps[-1]}"
    out.append(
        f"Each point is the least CPU time (time.process_time, whole simulate call, one BLAS thread) of "
        f"{n_runs} runs (short runs more often); the bar reaches the median. {n_noisy} of {len(ok)} points "
        "are noisy (hollow: load above the core count, or median more than 10 % above the least): "
        "read their differences under about 20 % as noise."
    )
    first_planar = next((c for c, s in cases if not s), None)  # the per-step scaling: once, after it
    for case, spatial in cases:
        out += crossover_text(
            ok[ok.case == case],
            SCALING_CSV if case == first_planar else None,
            case=case if len(cases) > 1 else "",
            spatial=spatial,
        )
    return out


def _spatial_limits(ok: pd.DataFrame, cases: list) -> list[str]:
    """For each spatial arm: the methods of the planar panels that sit it out, and those that
    run it only up to their spatial k limit (``Method.spatial_max_k``, set for their cost)."""
    from experiments import methods

    def limit(m):
        try:
            return methods.get(m).spatial_max_k
        except methods.MethodUnavailable:
            return float("inf")

    planar = list(dict.fromkeys(ok[ok.case.isin([c for c, s in cases if not s])].method))
    out = []
    for case in (c for c, s in cases if s):
        g = ok[ok.case == case]
        here = list(dict.fromkeys(g.method))
        k_lo, k_hi = (int(g.k.min()), int(g.k.max())) if len(g) else (0, 0)
        below = [m for m in planar if m not in here and limit(m) < k_lo]
        absent = [m for m in planar if m not in here and m not in below]
        parts = []
        if absent:
            verb = "sits" if len(absent) == 1 else "sit"
            parts.append(f"{', '.join(map(_label, absent))} {verb} it out (the Cases section says why)")
        parts += [
            f"{_label(m, True)} runs it up to k = {int(limit(m))} only (its spatial k limit, set for cost)"
            for m in [*here, *below]
            if limit(m) < k_hi
        ]
        if parts:
            out.append(f"On {_case_title(case, True)}: " + "; ".join(parts) + ".")
    return out


SCALING_CSV = "data/bench/global_scaling.csv"


def crossover_text(
    ok: pd.DataFrame, scaling_csv=SCALING_CSV, *, case: str = "", spatial: bool = False
) -> list[str]:
    """Where DT-TMM overtakes the global solver: in k from the cost table of one case (same
    linear element, same h; ``case`` names it in the sentence; nothing where the global solver
    has no point: a spatial arm's global solver runs small k only), and for a planar case in k
    and n from ``python -m experiments.global_scaling`` when ``scaling_csv`` is given and there
    (:func:`scaling_text`)."""
    from experiments.methods import same_equations

    out = []
    subject, glob = same_equations()[0]  # DT-TMM and the global solver, linear strain
    if {subject, glob} <= set(ok.method):
        ratio = (
            ok[ok.method == glob].set_index("k").cpu_time / ok[ok.method == subject].set_index("k").cpu_time
        )
        ratio = ratio.dropna().sort_index()
        if len(ratio):
            faster = ratio[ratio > 1]
            where = (
                f"at every k measured (k = {int(ratio.index[0])}…{int(ratio.index[-1])})"
                if len(faster) == len(ratio)
                else f"from k = {int(faster.index[0])} on"
                if len(faster)
                else "at no k measured"
            )
            solver = (
                "the spatial global solver (one dense system, compiled)"
                if spatial
                else "the compiled global solver"
            )
            prefix = f"{_case_title(case, spatial)}: " if case else ""
            out.append(
                f"{prefix}DT-TMM (Newmark) against {solver} (same element, same h): DT-TMM is "
                f"cheaper {where}; time ratio global / DT-TMM "
                + ", ".join(f"{sig2(v)} at k = {int(k)}" for k, v in ratio.items())
                + "."
            )
    if scaling_csv is not None and not spatial:
        out += scaling_text(scaling_csv)
    return out


def scaling_text(scaling_csv=SCALING_CSV) -> list[str]:
    """Where DT-TMM overtakes the compiled global solver per step, in k and n (planar arms), from
    ``python -m experiments.global_scaling`` when its table is there."""
    out = []
    try:
        sc = pd.read_csv(scaling_csv)
    except (OSError, ValueError):
        return out
    for study, name in (("k", "elements per link k (three_link)"), ("n", "links n (k = 8)")):
        r = sc[sc.study == study].sort_values("size")
        if len(r):
            below = r[r.ratio_global_over_dttmm <= 1]
            where = (
                "no crossover: DT-TMM is cheaper at every size"
                if not len(below)
                else (f"the global solver is cheaper up to {study} = {int(below['size'].max())}")
            )
            out.append(
                f"Per step over {name} ({scaling_csv}, `python -m experiments.global_scaling`): {where}; "
                f"ratio {sig2(r.ratio_global_over_dttmm.iloc[0])} at {study} = {int(r['size'].iloc[0])} to "
                f"{sig2(r.ratio_global_over_dttmm.iloc[-1])} at {study} = {int(r['size'].iloc[-1])}."
            )
    return out


def work_precision_axes(ax, table: pd.DataFrame, case: str, order: list | None = None) -> None:
    """Draw ``case``'s work-precision diagram on ``ax``: error against CPU time (least of the
    repeats), one curve per flexible method, hollow markers for noisy timings, the rigid baseline
    as a star; ``order``: the methods in the order their styles are picked."""
    from experiments.studies._common import MAIN_ERROR

    t = _timed(table)
    g = t[(t.case == case) & np.isfinite(t[MAIN_ERROR].astype(float))]
    order = list(order or dict.fromkeys(g.method))
    for m, gm in g[g.k > 0].groupby("method", sort=False):
        gm = gm.sort_values("cpu_time")
        st = _style(m, order.index(m) if m in order else len(order))
        c = st.color
        ax.loglog(gm.cpu_time, gm[MAIN_ERROR], st.linestyle, color=c, label=_label(m))
        quiet, noisy = gm[~gm.noisy], gm[gm.noisy]
        ax.loglog(quiet.cpu_time, quiet[MAIN_ERROR], st.marker, color=c, ms=4, ls="none")
        ax.loglog(noisy.cpu_time, noisy[MAIN_ERROR], st.marker, mfc="none", color=c, ms=4, ls="none")
    for m, r in g[g.k == 0].groupby("method"):
        ax.loglog(r.cpu_time, r[MAIN_ERROR], "*", ms=12, color="k", label=f"{_label(m)} (rigid-model floor)")
    ax.set(xlabel="CPU time (s), least of the repeats", ylabel="end-effector RMS error (m)")
    ax.grid(True, which="major", alpha=0.3)


def work_precision_figure(table: pd.DataFrame, case: str) -> Figure:
    """Error against CPU time (least of the repeats), one curve per flexible method, hollow
    markers for noisy timings, the rigid baseline as stars."""
    fig = Figure(figsize=(6.0, 5.6), layout="constrained")
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    g = table[table.case == case]
    work_precision_axes(ax, table, case, list(dict.fromkeys(g[np.isfinite(g.ee_l2.astype(float))].method)))
    ax.set_title(f"{case}: work-precision (lower left is better)")
    _legend(ax, ncol=2, fontsize=7)
    return fig


def work_precision_text(summary: pd.DataFrame, eq: pd.DataFrame, case: str) -> list[str]:
    """Sentences under a work-precision figure: CPU time of each method to reach the common error
    (no ratio across physics), the rigid floor, and the like-for-like ratios."""
    s = summary[summary.case == case] if len(summary) else summary
    if not len(s):
        return ["No run of this case produced an error value."]
    out = []
    col = "cpu_time_to_target" if "cpu_time_to_target" in s else "wall_time_to_target"
    flex = s[s.method != "pinocchio-rigid"].dropna(subset=[col])
    if len(flex):
        fast = flex.sort_values(col)
        parts = ", ".join(f"{_label(r.method)} {sig2(getattr(r, col))} s" for r in fast.itertuples())
        out.append(
            f"CPU time to reach the common error {flex.target_error.iloc[0]:.2g} m (least of the repeats): {parts}."
        )
    rigid = s[s.method == "pinocchio-rigid"]
    if len(rigid) and np.isfinite(rigid.best_error.iloc[0]):
        out.append(
            f"The rigid baseline's error, {rigid.best_error.iloc[0]:.2g} m, is what ignoring the links' "
            "flexibility costs; no step size removes it."
        )
    return out + equal_accuracy_text(eq, case)


def equal_accuracy_text(eq: pd.DataFrame, case: str) -> list[str]:
    """Like-for-like ratios at each target accuracy, 2 significant digits."""
    e = eq[(eq.case == case) & np.isfinite(eq.ratio.astype(float))] if len(eq) else eq
    if e is None or not len(e):
        return [
            f"{case}: no pair of the same element strain reached one of the target accuracies (1e-3, 1e-4, 1e-5 m) on this grid."
        ]
    parts = []
    for tgt, g in e.groupby("target_error", sort=False):
        bits = [f"{_label(r.method)} / {_label(r.against)} = {sig2(r.ratio)}" for r in g.itertuples()]
        parts.append(f"at {tgt:.0e} m: " + ", ".join(bits))
    return [
        f"{case}, CPU time at equal end-effector accuracy (same element strain only, read off each "
        "method's lower envelope; > 1 means DT-TMM is faster): " + "; ".join(parts) + "."
    ]
