"""The front page: three answers computed from the tables (is DT-TMM right? is it fast? where
does it break?), one summary figure (the work-precision diagrams, one panel per case) and one
compact scoreboard (methods × cases, each cell the CPU time to the case's common error relative
to the cheapest method, or a short mark whose footnote holds the reason)."""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from .render import Front

__all__ = ["answers", "board", "front", "summary_figure"]


def _label(m: str) -> str:
    from experiments.methods import label

    return label(m)


def _role(m: str) -> str:
    from experiments import methods

    try:
        return methods.get(m).role
    except methods.MethodUnavailable:
        return "peer"


def _sig(x: float) -> str:
    from .peers import sig2

    return sig2(x)


def _span(v) -> str:
    """ "a–b" of the smallest and largest of ``v`` (2 significant digits), "a" when they read alike."""
    lo, hi = _sig(float(min(v))), _sig(float(max(v)))
    return lo if lo == hi else f"{lo}–{hi}"


def _cases(meta: dict, *tables) -> list[str]:
    order = list(meta.get("cases") or {})
    seen = []
    for t in tables:
        if t is not None and len(t) and "case" in t:
            seen += list(dict.fromkeys(t.case))
    seen = list(dict.fromkeys(seen))
    return sorted(seen, key=lambda c: order.index(c) if c in order else len(order))


def _order(methods) -> list[str]:
    from experiments.methods import shown_order

    known = shown_order()
    return sorted(dict.fromkeys(methods), key=lambda m: known.index(m) if m in known else len(known))


# --- the compact scoreboard -------------------------------------------------------------------


def _why_not_run(method: str, case: str, tables: dict, meta: dict) -> str:
    """Why ``method`` has no work-precision value on ``case``: its failed runs' reason, the case's
    sitting-out record, the registry's reason, or that it was not planned."""
    wp = tables.get("work_precision")
    if wp is not None and len(wp):
        g = wp[(wp.case == case) & (wp.method == method)]
        if len(g):
            r = next((x for x in g.get("reason", []) if isinstance(x, str) and x), "")
            return f"every run {g.status.iloc[0]}" + (f": {r}" if r else "")
    why = (meta.get("sitting_out") or {}).get(case, {}).get(method)
    why = why or ((meta.get("sitting_out_runs") or {}).get("work_precision") or {}).get(case, {}).get(method)
    if why:
        return why
    from experiments import methods

    try:
        why = methods.get(method).why_not("work_precision")
    except methods.MethodUnavailable as exc:
        why = str(exc)
    avail = (meta.get("availability") or {}).get(method)
    return why or avail or "not in this report's work-precision plan"


def board(tables: dict, meta: dict) -> tuple[pd.DataFrame, list[str]]:
    """(table, footnotes): one row per method, one column per case, each cell the CPU time to
    the case's common error over the cheapest method's ("1×" for the cheapest), "not reached N"
    or "not run N" where footnote N gives the reason."""
    s = tables.get("work_precision_summary")
    if s is None or not len(s):
        return pd.DataFrame(), []
    cases = _cases(meta, s)
    methods = _order([*s.method, *_planned(tables)])
    notes: list[str] = []

    def note(text: str) -> int:
        if text not in notes:
            notes.append(text)
        return notes.index(text) + 1

    missed: dict = {}  # method -> ["case best vs target"], one footnote per method
    absent: dict = {}  # (method, reason) -> [cases]
    cells: dict = {}
    for m in methods:
        for c in cases:
            g = s[s.case == c]
            r = g[g.method == m]
            if len(r) and np.isfinite(r.cpu_time_to_target.iloc[0]):
                cells[m, c] = f"{_sig(float(r.cpu_time_to_target.iloc[0] / g.cpu_time_to_target.min()))}×"
            elif len(r):
                best, target = float(r.best_error.iloc[0]), float(r.target_error.iloc[0])
                missed.setdefault(m, []).append(f"{c} {_sig(best)} m (common error {_sig(target)} m)")
                cells[m, c] = ("not reached", m)
            else:
                why = _why_not_run(m, c, tables, meta)
                absent.setdefault((m, why), []).append(c)
                cells[m, c] = ("not run", (m, why))
    for m, where in missed.items():
        floor = " (the rigid model's floor: no step removes it)" if _role(m) == "baseline" else ""
        note(f"{_label(m)}: its smallest error stays above the common error{floor}: {'; '.join(where)}.")
    for (m, why), where in absent.items():
        note(f"{_label(m)} on {', '.join(where)}: {why}.")
    rows = []
    for m in methods:
        row = {"method": _label(m)}
        for c in cases:
            v = cells[m, c]
            if isinstance(v, tuple):
                kind, key = v
                text = (
                    f"{_label(key)}: its smallest error"
                    if kind == "not reached"
                    else f"{_label(key[0])} on {', '.join(absent[key])}: {key[1]}."
                )
                n = next(i for i, x in enumerate(notes, 1) if x.startswith(text))
                v = f"{kind} [{n}]"
            row[c] = v
        rows.append(row)
    df = pd.DataFrame(rows)
    df.attrs["verbatim_headers"] = True
    times = ", ".join(f"{c} {_sig(float(s[s.case == c].cpu_time_to_target.min()))} s" for c in cases)
    targets = ", ".join(f"{c} {_sig(float(s[s.case == c].target_error.iloc[0]))} m" for c in cases)
    notes = [
        f"Cells: CPU time (least of repeats) to reach the case's common end-effector error ({targets}), "
        f"divided by the cheapest method's ({times}). Lower is better.",
        *[f"[{i}] {n}" for i, n in enumerate(notes, 1)],
    ]
    return df, notes


def _planned(tables: dict) -> list[str]:
    wp = tables.get("work_precision")
    return list(dict.fromkeys(wp.method)) if wp is not None and len(wp) else []


# --- the summary figure -----------------------------------------------------------------------


def summary_figure(table: pd.DataFrame, cases: list[str]) -> Figure:
    """The work-precision diagrams of every case side by side (two per row), one legend below."""
    from .peers import work_precision_axes

    n = len(cases)
    cols = min(n, 2)
    rows = -(-n // cols)
    fig = Figure(figsize=(5.0 * cols, 3.3 * rows + 0.9), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    order = _order(table.method)
    for ax, c in zip(axes, cases):
        work_precision_axes(ax, table, c, order)
        ax.set_title(c, fontsize=10)
    for ax in axes[n:]:
        ax.set_visible(False)
    seen: dict = {}
    for ax in axes[:n]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    if seen:
        fig.legend(
            list(seen.values()), list(seen), loc="outside lower center", ncol=3, fontsize=8, frameon=False
        )
    return fig


# --- the three answers ------------------------------------------------------------------------


def _right(tables: dict, meta: dict) -> str:
    """Is DT-TMM right? Agreement with the global solver (same discretisation), with the
    independent reference engines at the comparison point, and the published values."""
    out = []
    ps = tables.get("paper_summary")
    if ps is not None and len(ps):
        dt = ps[np.array([_role(m) == "subject" for m in ps.method], bool) & (ps.status == "ok").to_numpy()]
        errs = dt.groupby("case").ee_l2.min()
        refs = {c: (meta.get("references", {}).get(c) or {}).get("method", "") for c in errs.index}
        indep = [c for c in errs.index if refs[c] and _role(refs[c]) != "subject"]
        own = [c for c in errs.index if c not in indep]
        names = sorted({_label(refs[c]) for c in indep})
        if indep:
            out.append(
                f"Against converged {' and '.join(names)} references its end-effector error is "
                f"{_span(errs[indep])} m RMS on {len(indep)} case(s)"
                + (f" ({', '.join(own)}: against its own converged run, cross-checked)" if own else "")
                + "."
            )
    agree = _global_agreement(tables)
    if agree:
        out.append(agree)
    res = tables.get("benchmarks")
    if res is not None and len(res):
        ok, total, bad = _problems_passed(res)
        probs = list(dict.fromkeys(b.split(" ")[0] for b in bad))
        out.append(
            f"Published values: {ok} of {total} benchmark quantities within tolerance"
            + (f" (not: {', '.join(probs)})." if bad else ".")
        )
    return " ".join(out) or "No study in this report compares DT-TMM with a reference."


def _global_agreement(tables: dict) -> str:
    """DT-TMM against the global solver of the same discretisation: the largest difference of
    their end-effector errors (convergence in k, same k and h), relative."""
    from experiments.methods import same_equations

    t = tables.get("convergence_k")
    if t is None or not len(t):
        return ""
    worst, n = 0.0, 0
    for sub, glob in same_equations():
        a = t[(t.method == sub) & (t.status == "ok")].set_index(["case", "k", "h"]).ee_l2
        b = t[(t.method == glob) & (t.status == "ok")].set_index(["case", "k", "h"]).ee_l2
        both = pd.concat([a, b], axis=1, join="inner").dropna()
        if len(both):
            rel = (both.iloc[:, 0] - both.iloc[:, 1]).abs() / both.abs().max(axis=1)
            worst, n = max(worst, float(rel.max())), n + len(both)
    if not n:
        return ""
    within = "to round-off" if worst < 1e-6 else f"within {_sig(100 * worst)} %"
    return f"The global solver of the same discretisation gives the same errors {within} ({n} runs)."


def _problems_passed(res: pd.DataFrame) -> tuple[int, int, list]:
    from experiments.methods import by_role

    from .problems import grouped

    d = res[res.method.isin(by_role("subject"))]
    if not len(d):
        return 0, 0, []
    d = grouped(d)
    ok, bad = 0, []
    for (p, q), g in d.groupby(["problem", "quantity"], sort=False):
        last = g[g.k == g.k.max()]
        if last.passed.astype(bool).any():
            ok += 1
        else:
            bad.append(f"{p} {q}")
    return ok, ok + len(bad), bad


def _fast(tables: dict, meta: dict) -> str:
    """Is it fast? Per peer, the range over cases of its CPU time to the common error over
    DT-TMM's (the cheaper of its variants)."""
    s = tables.get("work_precision_summary")
    if s is None or not len(s):
        return "No work-precision study in this report."
    ratios: dict = {}
    wins = []
    for c, g in s.groupby("case", sort=False):
        g = g[np.isfinite(g.cpu_time_to_target)]
        sub = g[[_role(m) == "subject" for m in g.method]]
        if not len(sub):
            continue
        t0 = float(sub.cpu_time_to_target.min())
        if t0 <= float(g.cpu_time_to_target.min()) * (1 + 1e-12):
            wins.append(c)
        for r in g[[_role(m) != "subject" for m in g.method]].itertuples():
            ratios.setdefault(r.method, []).append(r.cpu_time_to_target / t0)
    if not ratios:
        return "No peer reached the common error of any case, so no cost ratio can be formed."
    parts = [f"{_label(m)} {_span(ratios[m])}×" for m in _order(ratios)]
    n_cases = len(_cases(meta, s))
    return (
        f"DT-TMM is the cheapest at equal accuracy on {len(wins)} of {n_cases} cases. CPU time to each case's "
        f"common error over DT-TMM's (range over cases): {'; '.join(parts)}."
    )


def _breaks(tables: dict, meta: dict, om: pd.DataFrame) -> str:
    """Where does it break? DT-TMM's runs without a value (per variant: how many, where, why),
    and per peer the cases where it does not reach the common error and its runs without a value."""
    out = []
    subj = om[[_role(m) == "subject" for m in om.method]] if len(om) else om
    main = subj[subj.study != "scheme"] if len(subj) else subj
    bits = []
    for m, g in main.groupby("method", sort=False) if len(main) else []:
        where = ", ".join(dict.fromkeys(g.case))
        bits.append(f"{_label(m)} {len(g)} on {where} ({_short(g.reason.iloc[0], 50)})")
    out.append(
        ("DT-TMM runs without a value: " + "; ".join(bits) + ".")
        if bits
        else "Every planned DT-TMM run of its default settings produced a value."
    )
    s = tables.get("work_precision_summary")
    miss: dict = {}
    n_cases = 0
    if s is not None and len(s):
        n_cases = s.case.nunique()
        for r in s[~np.isfinite(s.cpu_time_to_target)].itertuples():
            miss.setdefault(r.method, []).append(r.case)
    peers = om[[_role(m) != "subject" for m in om.method]] if len(om) else om
    bad = peers.groupby("method").size().to_dict() if len(peers) else {}
    if miss:
        out.append(
            "Peers missing the common error: "
            + ", ".join(f"{_label(m)} on {len(miss[m])} of {n_cases} cases" for m in _order(miss))
            + "."
        )
    if bad:
        out.append(
            "Peer runs without a value: " + ", ".join(f"{_label(m)} {bad[m]}" for m in _order(bad)) + "."
        )
    return " ".join(out)


def _short(reason: str, n: int = 90) -> str:
    """The head of a reason: up to its first parenthesis or ``n`` characters."""
    head = re.sub(r"^\w+(Error|Exception): ", "", str(reason)).split(" (")[0].rstrip(".;:, ")
    return head if len(head) <= n else head[: n - 1].rstrip() + "…"


def answers(tables: dict, meta: dict, om: pd.DataFrame) -> list[tuple[str, str, str]]:
    """[(question, answer, page with the evidence)] of the front page."""
    right_page = "problems.html" if "benchmarks" in tables else "convergence.html"
    return [
        ("Is DT-TMM right?", _right(tables, meta), right_page),
        ("Is it fast?", _fast(tables, meta), "work-precision.html"),
        ("Where does it break?", _breaks(tables, meta, om), "omissions.html"),
    ]


def front(tables: dict, meta: dict, om: pd.DataFrame, figure) -> Front:
    """The front page; ``figure(name, fig) -> path`` saves the summary figure."""
    fig, brd = None, None
    wp = tables.get("work_precision")
    if wp is not None and len(wp):
        cases = _cases(meta, wp)
        path = figure("summary_work_precision.png", summary_figure(wp, cases))
        fig = (
            path,
            "Work-precision, one panel per case: end-effector error (RMS, against the case's reference) against "
            "CPU time (least of the repeats); lower left is better; each method refined along the same (k, h) "
            "path; the star is the rigid-link model. Details: the Work-precision page.",
        )
    df, notes = board(tables, meta)
    if len(df):
        brd = ("scoreboard", df, notes)
    return Front(answers(tables, meta, om), fig, brd)
