"""The "Closed loop" report section: tracking and residual vibration of every method on the
closed-loop case, moment feedback against its gain, natural frequencies of the arm. Built from
the ``control`` study tables only (no simulation)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from . import figures
from .render import Section

__all__ = [
    "gain_figure",
    "gain_table",
    "gain_text",
    "method_table",
    "modes_display",
    "section",
    "tracking_figure",
]

TITLE = "Closed loop"
ANCHOR = "control"
SAME = 0.05  # relative change of the decay rate below which moment feedback "has little effect"


def _g(x, digits: int = 3) -> str:
    return f"{x:.{digits}g}" if x is not None and np.isfinite(x) else "n/a"


def _mm(x) -> float:
    return 1e3 * float(x) if x is not None and np.isfinite(x) else math.nan


def _name(r) -> str:
    return figures._label(r.method) + (f" (moment_gain {r.moment_gain:g})" if r.variant else "")


def _rows(t: pd.DataFrame, g0: float) -> pd.DataFrame:
    t = t.copy()
    t["variant"] = ~np.isclose(t.moment_gain.astype(float), g0)
    return t


def method_table(t: pd.DataFrame, n_links: int, g0: float) -> pd.DataFrame:
    """One row per run: status (with the refusal's text), tracking errors (rad), peak and
    residual |tip deflection| of each link (mm), decay rate of link 1 (1/s), largest
    tip-position difference to the reference (m), CPU time (s)."""
    rows = []
    for r in _rows(t, g0).itertuples():
        row = {"method": _name(r), "k": int(r.k) if r.k else "rigid", "h (s)": f"{r.h:g}", "status": r.status}
        get = r._asdict().get
        row["max |α−α_ref| in move (rad)"] = get("track_move_max", math.nan)
        row["|α−α_ref| at end (rad)"] = get("track_final", math.nan)
        row.update({f"peak |w{i}| (mm)": _mm(get(f"peak_w{i}")) for i in range(1, n_links + 1)})
        row.update({f"residual |w{i}| (mm)": _mm(get(f"residual_w{i}")) for i in range(1, n_links + 1)})
        row["decay rate link 1 (1/s)"] = get("decay_rate1", math.nan)
        row["max tip-position diff to ref (m)"] = get("ee_diff_max", math.nan)
        row["CPU (s)"] = get("cpu_time", math.nan)
        row["note"] = r.reason if r.status != "ok" and isinstance(r.reason, str) else ""
        rows.append(row)
    return pd.DataFrame(rows)


def gain_table(g: pd.DataFrame) -> pd.DataFrame:
    """One row per (method, moment gain): status, peak |w₁| (mm), decay rate of link 1 (1/s),
    largest final joint error (rad), peak |τ₁| (N·m)."""
    rows = []
    for r in g.itertuples():
        get = r._asdict().get
        rows.append(
            {
                "method": figures._label(r.method),
                "moment_gain": r.moment_gain,
                "status": r.status,
                "peak |w1| (mm)": _mm(get("peak_w1")),
                "decay rate link 1 (1/s)": get("decay_rate1", math.nan),
                "final error (rad)": get("track_final", math.nan),
                "peak |τ1| (N·m)": get("peak_tau1", math.nan),
                "note": r.reason if r.status != "ok" and isinstance(r.reason, str) else "",
            }
        )
    return pd.DataFrame(rows)


def primary(g: pd.DataFrame, order) -> str | None:
    """The method the gain finding is stated for: the first of ``order`` with every gain ok."""
    for m in order:
        d = g[g.method == m]
        if len(d) and (d.status == "ok").all():
            return m
    return None


def verdict(g: pd.DataFrame, method: str) -> tuple[str, pd.Series, pd.Series]:
    """(what moment feedback does to the residual vibration, in words; the row of the smallest
    gain; the row of the largest) for ``method``'s runs of the gain sweep."""
    d = g[g.method == method].sort_values("moment_gain")
    lo, hi = d.iloc[0], d.iloc[-1]
    r0, r1 = float(lo.decay_rate1), float(hi.decay_rate1)
    change = (r1 - r0) / abs(r0) if r0 else math.nan
    rates = d.decay_rate1.to_numpy(float)
    steady = "steadily " if np.all(np.diff(rates) > 0) or np.all(np.diff(rates) < 0) else ""
    span = f"from {_g(r0)} to {_g(r1)} 1/s between moment_gain {lo.moment_gain:g} and {hi.moment_gain:g}"
    if not np.isfinite(change):
        words = "the decay rate could not be measured"
    elif abs(change) < SAME:
        words = f"it has little effect on the decay rate of the residual vibration ({span})"
    elif change > 0:
        words = f"it damps the residual vibration: the decay rate {steady}rises {span}"
    else:
        words = f"it does not damp the residual vibration: the decay rate {steady}falls {span}"
    return words, lo, hi


def gain_text(g: pd.DataFrame, method: str | None) -> list[str]:
    """The finding of the gain sweep in words, computed from the numbers of ``method``."""
    if method is None:
        return ["Moment feedback against its gain: no method ran every gain of the sweep."]
    words, lo, hi = verdict(g, method)
    w0, w1 = float(lo.peak_w1), float(hi.peak_w1)
    less = f"{_g(w0 / w1, 2)}× less" if w1 < w0 else f"{_g(w1 / w0, 2)}× more"
    return [
        f"Moment feedback against its gain ({figures._label(method)}): from moment_gain {lo.moment_gain:g} "
        f"to {hi.moment_gain:g} the peak tip deflection of link 1 goes from {_g(_mm(w0))} to {_g(_mm(w1))} mm "
        f"({less}) and the peak torque of joint 1 from {_g(lo.peak_tau1)} to {_g(hi.peak_tau1)} N·m, while "
        f"the largest final joint error goes from {_g(lo.track_final, 2)} to {_g(hi.track_final, 2)} rad; "
        f"{words}."
    ]


def agreement(g: pd.DataFrame) -> list[str]:
    """Where two or more methods ran the same gain: their largest relative spread in peak |w₁|
    and in the decay rate, over the gains."""
    ok = g[g.status == "ok"]
    both = ok.groupby("moment_gain").filter(lambda d: len(d) > 1)
    if both.empty:
        return []

    def spread(col):
        return max(
            float((d[col].max() - d[col].min()) / abs(d[col].mean())) for _, d in both.groupby("moment_gain")
        )

    names = ", ".join(figures._label(m) for m in dict.fromkeys(both.method))
    gains = ", ".join(f"{x:g}" for x in sorted(set(both.moment_gain)))
    return [
        f"{names} agree at moment_gain {gains} within {_g(100 * spread('peak_w1'), 2)} % in the peak deflection "
        f"of link 1 and {_g(100 * spread('decay_rate1'), 2)} % in its decay rate."
    ]


def pairs_text(pairs: pd.DataFrame | None) -> list[str]:
    """How far DT-TMM is from the global solver of the same discrete equations, closed loop."""
    if pairs is None or not len(pairs):
        return []
    parts = []
    for (a, b), d in pairs.groupby(["a", "b"], sort=False):
        parts.append(
            f"{figures._label(a)} against {figures._label(b)}: {_g(d.ee_max.max(), 2)} m and "
            f"{_g(d.angle_max.max(), 2)} rad over {len(d)} run(s)"
        )
    return [
        "DT-TMM solves the same discrete closed-loop equations as the global solver; largest end-effector "
        "distance and joint-angle difference between the two: " + "; ".join(parts) + "."
    ]


def modes_display(m: pd.DataFrame) -> pd.DataFrame:
    """Frequencies per system and mode: DT-TMM, Exudyn (Hz), relative difference."""
    d = m[np.isfinite(m.dttmm_hz.astype(float))]
    return pd.DataFrame(
        {
            "system": d.system,
            "mode": d["mode"].astype(int),
            "DT-TMM (Hz)": [f"{x:.6g}" for x in d.dttmm_hz],
            "Exudyn (Hz)": [f"{x:.6g}" if np.isfinite(x) else "n/a" for x in d.exudyn_hz],
            "relative difference": d.rel_diff,
            "k (DT-TMM / Exudyn)": [f"{int(a)} / {int(b)}" for a, b in zip(d.k, d.exudyn_k)],
        }
    )


def modes_text(m: pd.DataFrame | None) -> list[str]:
    """What the frequency table shows, or why it is absent."""
    if m is None or not len(m):
        return ["Natural frequencies: not computed in this report."]
    ok = m[np.isfinite(m.dttmm_hz.astype(float))]
    notes = sorted({n for n in m.note if isinstance(n, str) and n})
    if not len(ok):
        return [f"Natural frequencies: skipped ({'; '.join(notes)})."]
    both = ok[np.isfinite(ok.rel_diff.astype(float))]
    out = [
        "Natural frequencies of the arm (torque-driven joints free, motion-driven joints held; rigid-body "
        "modes at 0 Hz left out) and of the clamped De Luca links, from the DT-TMM linearisation "
        "(dttmm.modes) and from Exudyn's eigenvalue computation of an ANCF model."
    ]
    if len(both):
        worst = both.loc[both.rel_diff.astype(float).idxmax()]
        out.append(
            f"Largest relative difference: {_g(worst.rel_diff, 2)} ({worst.system}, mode {int(worst['mode'])}; "
            f"DT-TMM at k = {int(worst.k)}, Exudyn at k = {int(worst.exudyn_k)})."
        )
    if notes:
        out.append("Not compared: " + "; ".join(notes) + ".")
    return out


def tracking_figure(s: pd.DataFrame):
    """Against time, every finished run: tip deflection of link 1 with the reference (left), the
    largest joint tracking error (middle) and the end effector's distance to the reference
    (right, log scale; runs of the case itself only)."""
    fig, axes = figures._figure(ncols=3, size=(4.4, 4.0))
    for i, (key, d) in enumerate(s.groupby(["method", "case"], sort=False)):
        m, own = key[0], d.case.iloc[0] == s.case.iloc[0]
        st = figures._style(m, i)
        ref = m == "reference"
        kw = {"color": st.color, "ls": st.linestyle, "lw": 3 if ref else 1.2, "alpha": 0.5 if ref else 1.0}
        kw["label"] = "reference" if ref else figures._label(m) + ("" if own else " (moment_gain 0)")
        axes[0].plot(d.t, 1e3 * d.w1, **kw)
        if not ref:
            axes[1].plot(d.t, d.track_error, **kw)
        if not ref and own and np.isfinite(d.ee_diff).any():
            axes[2].semilogy(d.t, np.maximum(d.ee_diff, 1e-12), **kw)
    axes[0].set_ylabel("tip deflection of link 1 (mm)")
    axes[1].set_ylabel("max joint |α − α_ref| (rad)")
    axes[2].set_ylabel("end-effector error (m)")
    if axes[2].lines:  # four decades below the largest distance: the start from zero is not of interest
        top = max(float(np.nanmax(ln.get_ydata())) for ln in axes[2].lines)
        axes[2].set_ylim(bottom=max(1e-12, 1e-4 * top))
    else:
        axes[2].text(0.5, 0.5, "no reference run", transform=axes[2].transAxes, ha="center")
    for ax in axes:
        ax.set_xlabel("t (s)")
        ax.grid(True, alpha=0.3)
        figures._legend(ax, ncol=1)
    return fig


def gain_figure(g: pd.DataFrame):
    """Decay rate of link 1's residual vibration (left) and peak |w₁| (right) against the gain."""
    fig, axes = figures._figure(ncols=2, size=(4.6, 3.8))
    for i, (m, d) in enumerate(g[g.status == "ok"].groupby("method", sort=False)):
        d = d.sort_values("moment_gain")
        st = figures._style(m, i)
        kw = {"color": st.color, "marker": st.marker, "ls": st.linestyle, "label": figures._label(m)}
        axes[0].plot(d.moment_gain, d.decay_rate1, **kw)
        axes[1].plot(d.moment_gain, 1e3 * d.peak_w1, **kw)
    axes[0].set_ylabel("decay rate of link 1 (1/s)")
    axes[1].set_ylabel("peak |w1| (mm)")
    for ax in axes:
        ax.set_xlabel("moment_gain g_M")
        ax.grid(True, alpha=0.3)
        figures._legend(ax, ncol=1)
    return fig


def _intro(info: dict, n_links: int) -> str:
    ref = info.get("reference") or ""
    ref_text = (
        f"the largest distance between the end effector and that of the reference run ({ref})"
        if ref
        else f"not measured: {info.get('reference_note') or 'no reference run'}"
    )
    return (
        f"The closed-loop case {info['case']}: {n_links} flexible links moved rest to rest in "
        f"{info['move_end']:g} s by PD laws with feedback of each link's root bending moment "
        f"(moment_gain {info['moment_gain']:g}), {info['duration']:g} s simulated (case file and gains in "
        "docs/control.md). Every method is tried on it; one that refuses closed-loop drives, or one of "
        'their settings, is listed as "not supported" with its message. The rigid baseline has no '
        "bending moment to feed back and also runs the case with moment_gain 0. Residual vibration: the "
        "largest |w| on the last window; decay rate ln(A_early/A_late)/Δt with A the largest peak of |w| "
        f"in {info['early_window']} and in {info['late_window']} and Δt the time between the two peaks. "
        f"Tip-position difference: {ref_text}. CPU time: the least of three or more calls, one BLAS thread, on a "
        "machine shared with other runs (build and solve; the work-precision section compares costs properly)."
    )


def _status_text(t: pd.DataFrame, g0: float) -> list[str]:
    t = _rows(t, g0)
    by = {s: [_name(r) for r in t[t.status == s].itertuples()] for s in dict.fromkeys(t.status)}
    out = ["Status: " + "; ".join(f"{s}: {', '.join(ms)}" for s, ms in by.items()) + "."]
    diff = t[(t.status == "ok") & np.isfinite(t.get("ee_diff_max", pd.Series(np.nan, t.index)).astype(float))]
    if len(diff):
        parts = [f"{_name(r)} {_g(r.ee_diff_max, 2)} m" for r in diff.itertuples()]
        out.append("Largest tip-position difference to the reference: " + ", ".join(parts) + ".")
    return out


def section(inputs) -> Section | None:
    """Report-section builder (``reports.build.SECTION_BUILDERS``); None when the study did not run."""
    t, g = inputs.tables.get("control"), inputs.tables.get("control_gains")
    info_t = inputs.tables.get("control_info")
    if t is None or info_t is None or not len(info_t):
        return None
    info = info_t.iloc[0].to_dict()
    g0 = float(info["moment_gain"])
    n_links = sum(c.startswith("peak_w") for c in t.columns) or 1
    figs, tabs = [], [("control_methods", method_table(t, n_links, g0), "Tracking and residual vibration")]
    text = [_intro(info, n_links), *_status_text(t, g0)] if len(t) else [_intro(info, n_links)]
    text += pairs_text(inputs.tables.get("control_pairs"))
    s = inputs.tables.get("control_series")
    if s is not None and len(s):
        f = inputs.figure("control_tracking.png", tracking_figure(s))
        figs.append(
            (f, "tip deflection of link 1 (left) and the largest joint tracking error (right) against time")
        )
    who = None
    if g is not None and len(g):
        who = primary(g, list(dict.fromkeys(g.method)))
        tabs.append(("control_gain_sweep", gain_table(g), "Moment feedback against its gain"))
        if (g.status == "ok").any():
            f = inputs.figure("control_gains.png", gain_figure(g))
            figs.append(
                (
                    f,
                    "decay rate of link 1's residual vibration (left) and its peak deflection (right) against moment_gain",
                )
            )
        text += gain_text(g, who) + agreement(g)
    m = inputs.tables.get("control_modes")
    text += modes_text(m)
    if m is not None and np.isfinite(m.dttmm_hz.astype(float)).any():
        tabs.append(("control_frequencies", modes_display(m), "Natural frequencies"))
    n_ok = int((t.status == "ok").sum()) if len(t) else 0
    summary = f"Closed loop: {n_ok} of {len(t)} runs finish on the closed-loop case"
    summary += f"; moment feedback ({figures._label(who)}): {verdict(g, who)[0]}." if who else "."
    return Section(TITLE, figs, text, tabs, ANCHOR, summary)
