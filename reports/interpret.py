"""Two or three sentences under each figure, computed from the tables (never typed in)."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = [
    "bench_costs",
    "convergence_h",
    "convergence_k",
    "cost",
    "loads",
    "paper",
    "scheme",
    "work_precision",
]


def _l(m):
    from experiments.methods import label

    return label(m)


def _sig(x, n: int = 3) -> str:
    """``x`` rounded to ``n`` significant digits, without exponent notation for ordinary sizes."""
    return "n/a" if x is None or not np.isfinite(x) else f"{float(f'{x:.{n}g}'):g}"


def _e(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{x:.2g}"


def _orders_text(orders: pd.DataFrame, quantity: str) -> str:
    o = orders[(orders.quantity == quantity) & np.isfinite(orders.order)]
    return ", ".join(f"{_l(r.method)} {r.order:.1f}" for r in o.itertuples()) or "none could be fitted"


FLAGGED = ("unconverged", "ill-conditioned")  # ran to the end, but the method does not vouch for it


def not_ok(rows: pd.DataFrame) -> list[str]:
    """Sentences on the runs of ``rows`` that are not "ok": failed ones, and flagged ones
    (unconverged, ill-conditioned), whose errors are measured but left out of every fit."""
    out = []
    failed = rows[~rows.status.isin(("ok", *FLAGGED))]
    if len(failed):
        r = failed.iloc[0]
        out.append(
            f"{len(failed)} run(s) failed, e.g. {_l(r.method)} at k = {r.k}, h = {r.h:g} s: {r.reason}."
        )
    flagged = rows[rows.status.isin(FLAGGED)]
    if len(flagged):
        r = flagged.iloc[0]
        out.append(
            f"{len(flagged)} run(s) finished but were flagged by the method ({', '.join(sorted(set(flagged.status)))}), "
            f"e.g. {_l(r.method)} at k = {r.k}, h = {r.h:g} s: {r.reason}; "
            "their errors are not counted as converged results."
        )
    return out


def convergence_k(table, orders, case, floor=None) -> list[str]:
    g = table[(table.case == case) & (table.k > 0) & (table.status == "ok")]
    out = [
        (
            "Observed orders in k of the end-effector error (fitted before each curve's floor): "
            f"{_orders_text(orders[orders.case == case], 'ee_l2')}."
        )
    ]
    best = g[np.isfinite(g.ee_l2)].groupby("method").ee_l2.min()
    if len(best):
        lo, hi = best.idxmin(), best.idxmax()
        out.append(
            f"The smallest error reached is {_e(best[lo])} m ({_l(lo)}), the largest best error "
            f"{_e(best[hi])} m ({_l(hi)}); curves level off where the time error at "
            f"h = {g.h.iloc[0]:g} s or the reference's own accuracy takes over."
        )
    if floor is not None and np.isfinite(floor):
        out.append(
            f"The reference and its independent cross-check differ by {_e(floor)} m (dotted line): "
            "errors below it are not resolved."
        )
    return out + not_ok(table[table.case == case])


def convergence_h(table, orders, case) -> list[str]:
    o = orders[orders.case == case]
    out = [
        (
            "Observed orders in h from the self-differences (h against h/2, time error alone): "
            f"{_orders_text(o, 'selfdiff_ee_l2')}."
        ),
        (
            f"Against the reference: {_orders_text(o, 'ee_l2')}; a low value there means the spatial error "
            f"of k = {table[table.case == case].k.max()} dominates at small h."
        ),
    ]
    return out + not_ok(table[table.case == case])


def work_precision(summary, case) -> list[str]:
    s = summary[summary.case == case]
    if s.empty:
        return ["No run of this case produced an error value."]
    flex = s[s.method != "pinocchio-rigid"].dropna(subset=["wall_time_to_target"])
    out = []
    if len(flex):
        target = flex.target_error.iloc[0]
        fast = flex.sort_values("wall_time_to_target")
        parts = ", ".join(f"{_l(r.method)} {r.wall_time_to_target:.3g} s" for r in fast.itertuples())
        out.append(f"Wall time to reach the common error {_e(target)} m: {parts}.")
        if len(fast) > 1:
            a, b = fast.iloc[0], fast.iloc[-1]
            out.append(
                f"{_l(a.method)} is {_sig(b.wall_time_to_target / a.wall_time_to_target)}x faster than "
                f"{_l(b.method)} at that accuracy."
            )
    rigid = s[s.method == "pinocchio-rigid"]
    if len(rigid) and np.isfinite(rigid.best_error.iloc[0]):
        out.append(
            f"The rigid baseline's error, {_e(rigid.best_error.iloc[0])} m, is what ignoring the links' "
            "flexibility costs; no step size removes it."
        )
    return out


def scheme(summary, case) -> list[str]:
    s = summary[summary.case == case]
    out = []
    for r in s.itertuples():
        if np.isfinite(r.breaks_at_k):
            why = f" ({r.first_reason})" if r.first_reason else ""
            out.append(
                f"{r.variant}: breaks at k = {int(r.breaks_at_k)} (error > 10x the converged Riccati "
                f"error, or a run not ok; {r.failed} of {r.runs} runs not ok"
                f"{f', {r.flagged} of them flagged unconverged or ill-conditioned' if getattr(r, 'flagged', 0) else ''}"
                f"{why})."
            )
    ok = [r.variant for r in s.itertuples() if not np.isfinite(r.breaks_at_k)]
    if ok:
        out.append(f"Within 10x of the converged Riccati sweep at every k: {', '.join(ok)}.")
    return out or ["No variant ran for this case."]


def paper(summary, case) -> list[str]:
    s = summary[summary.case == case]
    ref = s[s.method == "reference"]
    others = s[(s.method != "reference") & np.isfinite(s.ee_l2) & (s.status == "ok")]
    out = []
    if len(ref):
        out.append(
            f"Peak tip deflection of the last link: {ref.peak_tip.iloc[0] * 1e3:.3g} mm in the reference."
        )
    if len(others):
        flex = others[others.method != "pinocchio-rigid"]
        if len(flex):
            worst = flex.loc[flex.ee_l2.idxmax()]
            best = flex.loc[flex.ee_l2.idxmin()]
            out.append(
                f"Flexible methods agree with it to an end-effector RMS of {_e(best.ee_l2)} m "
                f"({_l(best.method)}) … {_e(worst.ee_l2)} m ({_l(worst.method)}) "
                f"at k = {int(flex.k.iloc[0])}."
            )
        rigid = others[others.method == "pinocchio-rigid"]
        if len(rigid):
            out.append(
                f"The rigid arm misses the deflection: end-effector RMS error {_e(rigid.ee_l2.iloc[0])} m."
            )
    missing = s[~s.status.isin(["ok"])]
    if len(missing):
        out.append(
            "Not shown: "
            + "; ".join(f"{_l(r.method)} ({r.status}: {r.reason})" for r in missing.itertuples())
            + "."
        )
    return out


def loads(table, case) -> list[str]:
    """Sentences under the loads figure: RMS errors of root moment, motion-driven joint
    torques and energy, relative to the largest reference value."""
    from .figures import load_label

    g = table[table.case == case] if len(table) else table
    if g.empty:
        return ["No run of this case has load histories to compare."]
    out = []
    qs = [c[:-3] for c in g.columns if c.endswith("_l2")]
    for q in qs:
        ok = g[np.isfinite(g[f"{q}_l2"])]
        if ok.empty:
            continue
        parts = ", ".join(
            f"{_l(r.method)} {_e(getattr(r, f'{q}_l2'))} ({_pct(getattr(r, f'{q}_rel'))})" for r in ok.itertuples()
        )
        out.append(f"{load_label(q).split(' (')[0]}, RMS of method − reference (relative to the peak): {parts}.")
    missing = g[~np.isfinite(g["energy_l2"])].method.tolist() if "energy_l2" in g else g.method.tolist()
    eref = g.energy_reference.iloc[0] if "energy_reference" in g else "none"
    out.append(
        f"Energies are compared against {eref}"
        + (f"; not recorded by {', '.join(_l(m) for m in missing)}." if missing else ".")
    )
    return out


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:.2g} %"


def cost(table, exponents) -> list[str]:
    ex = exponents[np.isfinite(exponents.exponent)]
    out = [
        "Fitted exponents of wall time ∝ k^p (k ≥ 2): "
        + (", ".join(f"{_l(r.method)} p = {r.exponent:.2g}" for r in ex.itertuples()) or "none")
        + "."
    ]
    if len(ex) > 1:
        kmax = int(ex.k_max.min())
        at = table[(table.k == kmax) & (table.status == "ok")].set_index("method").wall_time
        if "dttmm" in at and "global" in at:
            out.append(
                f"At k = {kmax}, DT-TMM takes {at['dttmm']:.3g} s and the global solver "
                f"{at['global']:.3g} s (ratio {at['global'] / at['dttmm']:.2f})."
            )
    out.append("Timings come from one run per worker process on a shared machine; read them as ±20 %.")
    return out


def _x(v) -> str:
    return "n/a" if v is None or not np.isfinite(v) else (f"{v:.0f}" if v >= 100 else f"{v:.3g}")


def bench_costs(exponents, per_element, ratios, *, k_min=8, n_min=2, case="three_link") -> list[str]:
    """Sentences under the benchmark figures: fitted exponents, cost per element-step at the
    largest k of each method, and speed ratios against DT-TMM at equal size and equal accuracy."""
    out = []
    el = exponents[(exponents.scan == "elements per link") & (exponents.case == case)]
    el = el[np.isfinite(el.exponent)]
    ln = exponents[exponents.scan.str.startswith("links") & np.isfinite(exponents.exponent)]
    if len(el) or len(ln):
        parts = []
        if len(el):
            parts.append(
                f"over k ≥ {k_min} ({case}, the asymptotic regime: below it fixed per-step costs dominate) "
                + ", ".join(f"{_l(r.method)} {r.exponent:.2g}" for r in el.itertuples())
            )
        if len(ln):
            parts.append(
                f"over n ≥ {n_min} links at k = 8: "
                + ", ".join(f"{_l(r.method)} {r.exponent:.2g}" for r in ln.itertuples())
            )
        out.append("Fitted exponents p of time per step ∝ N^p: " + "; ".join(parts) + ".")
    if len(per_element) and len(per_element.columns) > 1:
        bits = []
        for m in per_element.columns[1:]:
            v = per_element[["k", m]].dropna()
            if len(v):
                bits.append(f"{_l(m)} {v[m].iloc[-1]:.3g} µs (k = {v.k.iloc[-1]})")
        out.append(
            f"Cost per element-step at each method's largest k ({case}, solve only): " + ", ".join(bits) + "."
        )
    cols = [c for c in ratios.columns if c.endswith("/dttmm")]
    names = " : ".join(["DT-TMM"] + [_l(c.split("/")[0]) for c in cols])
    size = ratios[ratios.basis.str.startswith("equal size") & (ratios.case == case) & ratios.k.notna()]
    if len(size):
        kmax = size.k.max()
        parts = [
            f"{r.basis.split('(')[-1].rstrip(')')} 1 : " + " : ".join(_x(r[c]) for c in cols)
            for _, r in size[size.k == kmax].iterrows()
        ]
        out.append(
            f"At equal model size ({case}, k = {_x(kmax)}, time per step) {names} = " + "; ".join(parts) + "."
        )
    acc = ratios[ratios.basis.str.startswith("equal accuracy")]
    if len(acc):
        parts = [
            f"{r.case} (error {_e(r.target_error_m)} m) 1 : " + " : ".join(_x(r[c]) for c in cols)
            for _, r in acc.iterrows()
        ]
        out.append(
            "At equal accuracy (this report's work-precision study, wall time to reach the common error) "
            f"{names} = "
            + "; ".join(parts)
            + (" (n/a: did not reach it)." if acc[cols].isna().any().any() else ".")
        )
    else:
        out.append(
            "No equal-accuracy ratio: the work-precision summary (wall_time_to_target) is absent from "
            "the report data."
        )
    return out
