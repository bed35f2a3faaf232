"""Two or three sentences under each figure, computed from the tables (never typed in)."""

from __future__ import annotations

import numpy as np
import pandas as pd

__all__ = [
    "convergence_h",
    "convergence_k",
    "loads",
    "paper",
    "scheme",
]


def _l(m):
    from experiments.methods import label

    return label(m)


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
            f"{_l(r.method)} {_e(getattr(r, f'{q}_l2'))} ({_pct(getattr(r, f'{q}_rel'))})"
            for r in ok.itertuples()
        )
        out.append(
            f"{load_label(q).split(' (')[0]}, RMS of method − reference (relative to the peak): {parts}."
        )
    out += _spatial_moment(g)
    missing = g[~np.isfinite(g["energy_l2"])].method.tolist() if "energy_l2" in g else g.method.tolist()
    eref = g.energy_reference.iloc[0] if "energy_reference" in g else "none"
    out.append(
        f"Energies are compared against {eref}"
        + (f"; not recorded by {', '.join(_l(m) for m in missing)}." if missing else ".")
    )
    return out


SPATIAL_MOMENT = (
    "On this spatial arm the root moment of link 1 is the magnitude of the bending part of the moment "
    "that the base, joint 1 and link 1's hub exert on link 1's beam about its root point (the cut load "
    "at the link's root: its components along the y and z axes of link 1's frame, the torsion about the "
    "link's axis left out), taken from the runs' cut loads"
)


def _spatial_moment(g) -> list[str]:
    """The sentence on a spatial arm's root bending moment: what it is, and for which methods
    it is not compared, with the reason (the ``moment1_note`` column of ``paper_loads``)."""
    if "moment1_note" not in g or not g.moment1_note.notna().any():
        return []  # a planar arm: the hub balance, described in the caption
    rows = g[g.moment1_note.notna()]
    left = rows[rows.moment1_note != ""]
    if left.empty:
        return [SPATIAL_MOMENT + "."]
    notes = list(dict.fromkeys(left.moment1_note))
    if len(left) == len(rows) and len(notes) == 1:
        return [f"{SPATIAL_MOMENT}; it is compared for no method here: {notes[0]}."]
    why = "; ".join(f"{', '.join(_l(m) for m in left.method[left.moment1_note == n])} ({n})" for n in notes)
    return [f"{SPATIAL_MOMENT}; not compared for {why}."]


def _pct(x) -> str:
    return "n/a" if x is None or not np.isfinite(x) else f"{100 * x:.2g} %"


def _x(v) -> str:
    return "n/a" if v is None or not np.isfinite(v) else (f"{v:.0f}" if v >= 100 else f"{v:.3g}")
