"""The front page's scoreboard: per case, each method's error at the comparison point, cost at
equal accuracy, observed orders and status, gathered from the study tables."""

from __future__ import annotations

import numpy as np
import pandas as pd

from .render import Section

__all__ = ["case_board", "scoreboard", "verdict"]

#: the studies whose runs the "runs not ok" column counts: not the scheme study, whose variants of the
#: paper's scheme (plain sweep, one-shot linearisation) are run to show where they break
RUN_TABLES = ("convergence_k", "convergence_h", "work_precision", "paper", "cost")


def _by_method(df, case, col, **where) -> dict:
    if df is None or df.empty or col not in df:
        return {}
    g = df[df.case == case]
    for k, v in where.items():
        g = g[g[k] == v]
    return dict(zip(g.method, g[col]))


def _not_ok(tables, case) -> dict:
    """method -> (runs not ok, runs) over every study of the case, each run counted once."""
    frames = [
        t[["case", "method", "key", "status"]]
        for n in RUN_TABLES
        if (t := tables.get(n)) is not None and len(t) and "key" in t
    ]
    if not frames:
        return {}
    runs = pd.concat(frames).drop_duplicates(["case", "key"])  # a key names a run within its case
    runs = runs[runs.case == case]
    return {m: (int((g.status != "ok").sum()), len(g)) for m, g in runs.groupby("method")}


def _why_not(method: str, study: str) -> str:
    """Why ``method`` has no value from ``study``: its registry record's reason, else ''."""
    from experiments import methods

    try:
        return methods.get(method).why_not(study)
    except methods.MethodUnavailable:
        return ""


def _cell(value, method, study, *, reached=None) -> object:
    """A number, or the words that say why there is none: "not reached (best …)", "not run: …"."""
    if isinstance(value, (float, np.floating)) and np.isfinite(value):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, bool):
        return value
    if reached is not None and np.isfinite(reached):
        return f"not reached (best {reached:.2g} m)"
    why = _why_not(method, study)
    return f"not run: {why}" if why else "not run"


def case_board(tables: dict, case: str) -> pd.DataFrame:
    """One row per method of ``case``: the scoreboard columns; where a study has no number for a
    method the cell says why ("not reached", "not run" with the reason, "too few points")."""
    from experiments.methods import label

    paper = tables.get("paper_summary")
    err = _by_method(paper, case, "ee_l2")
    status = _by_method(paper, case, "status")
    k = _by_method(paper, case, "k")
    h = _by_method(paper, case, "h")
    # CPU time, least of the repeats: the quantity every cost figure uses (a first call's wall
    # time carries JIT compilation and the machine's other work)
    wp = _by_method(tables.get("work_precision_summary"), case, "cpu_time_to_target")
    best = _by_method(tables.get("work_precision_summary"), case, "best_error")
    ok_ = _by_method(tables.get("convergence_k_orders"), case, "order", quantity="ee_l2")
    oh = _by_method(tables.get("convergence_h_orders"), case, "order", quantity="selfdiff_ee_l2")
    bad = _not_ok(tables, case)
    methods = [m for m in dict.fromkeys([*err, *wp, *ok_, *bad]) if m != "reference"]
    rows = []
    for m in methods:
        n_bad, n = bad.get(m, (0, 0))
        kk, hh = k.get(m, np.nan), h.get(m, np.nan)
        at = "–" if pd.isna(hh) else f"{int(kk) if pd.notna(kk) and kk else '–'}, {hh:g}"
        rows.append(
            {
                "method": label(m),
                "end-effector error (m)": _cell(err.get(m, np.nan), m, "paper"),
                "at k, h (s)": at,
                "CPU time to target (s)": _cell(wp.get(m, np.nan), m, "work_precision", reached=best.get(m)),
                "order in k": _order_cell(ok_, m, "convergence_k"),
                "order in h": _order_cell(oh, m, "convergence_h"),
                "status": status.get(m, "not run"),
                "runs not ok": f"{n_bad} of {n}" if n else "–",
            }
        )
    return pd.DataFrame(rows)


def _order_cell(orders: dict, m: str, study: str):
    if m in orders:
        v = orders[m]
        return v if np.isfinite(v) else "too few points before the error floor"
    return _cell(np.nan, m, study)


def verdict(tables: dict, case: str) -> str:
    """One sentence, computed from the work-precision summary: which method reaches the case's
    common error cheapest, by what factor over each other method, and which did not reach it or
    did not run (and why)."""
    from experiments import methods
    from experiments.methods import label

    s = tables.get("work_precision_summary")
    if s is None or not len(s) or case not in set(s.case):
        return f"{case}: no work-precision study, no verdict."
    g = s[s.case == case]
    target = float(g.target_error.iloc[0])
    reached = g[np.isfinite(g.cpu_time_to_target)].sort_values("cpu_time_to_target")
    missed = g[~np.isfinite(g.cpu_time_to_target)]
    if reached.empty:
        return f"{case}: no method reached the common error {target:.2g} m."
    win = reached.iloc[0]
    t0 = float(win.cpu_time_to_target)
    others = [f"{label(r.method)} {r.cpu_time_to_target / t0:.2g}×" for r in reached.iloc[1:].itertuples()]
    out = (
        f"{case}: {label(win.method)} reaches the common end-effector error {target:.2g} m cheapest "
        f"({t0:.2g} s CPU)" + (f"; the others need: {', '.join(others)}" if others else "")
    )
    notes = [f"{label(r.method)} did not reach it (best {r.best_error:.2g} m)" for r in missed.itertuples()]
    ran = set(g.method)
    for m in methods.names():
        why = methods.get(m).why_not("work_precision")
        if m not in ran and why:
            notes.append(f"{label(m)} did not run ({why})")
    wp = tables.get("work_precision")
    if wp is not None and len(wp):
        for m, gm in wp[(wp.case == case) & (wp.status != "ok")].groupby("method"):
            if m not in ran:
                reason = next((r for r in gm.reason if isinstance(r, str) and r), gm.status.iloc[0])
                notes.append(f"{label(m)} did not run ({reason})")
    return out + ("; " + "; ".join(notes) if notes else "") + "."


def scoreboard(tables: dict, meta: dict) -> Section:
    """The scoreboard section: one table per case and a sentence on how to read it."""
    cases = [c for c in dict.fromkeys(tables["paper_summary"].case)] if "paper_summary" in tables else []
    tabs = [(f"scoreboard_{c}", case_board(tables, c), f"Scoreboard of {c}") for c in cases]
    wp = tables.get("work_precision_summary")
    targets = (
        "; ".join(f"{c} {t:.2g} m" for c, t in dict(zip(wp.case, wp.target_error)).items() if np.isfinite(t))
        if wp is not None and len(wp) and "target_error" in wp
        else "n/a"
    )
    text = [
        (
            "Per case, one row per method: the end-effector position error (RMS over time, against the "
            "case's reference) at the comparison point of the paper figures (at k, h); the CPU time (least "
            "of the repeated runs) the method needs to reach the target error, the common error of the "
            "work-precision study "
            f"({targets}; 'not reached' with the method's best error when it does not get there); "
            "the observed orders of convergence in k (against the reference) "
            "and in h (against h/2); the status of the run at the comparison point, and how many of the "
            "method's runs over the studies with the method's default settings did not finish 'ok' (listed "
            "under Omissions; the scheme study's variants of the paper's scheme, run to show where they "
            "break, are counted in its own section)."
        )
    ]
    if not tabs:
        text = ["No paper-figure study in this report: nothing to score."]
    else:
        text = [*(verdict(tables, c) for c in cases), *text]
    return Section("Scoreboard", [], text, tabs, "scoreboard", bullets=True)
