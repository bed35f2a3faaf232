"""Tables written for people: method labels, column headers in words with units, numbers with
three significant digits, no raw index columns, and a missing value that says why in words.

``present(df)`` turns a study table into the strings a report page shows; the CSV beside the
page keeps the raw table (``data/<name>.csv``).
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd

__all__ = ["BAD_WORDS", "cell", "header", "present"]

#: words no cell of a report page may read (checked by the browser test)
BAD_WORDS = re.compile(r"\b(NaN|nan|None|inf|-inf)\b")

#: raw columns that are bookkeeping, not results: never shown (the CSV keeps them)
HIDDEN = {"key", "index", "level_0", "run_key", "cache_key", "code_hash", "fingerprint"}

#: headers in words with units, for the columns the studies write most
WORDS = {
    "case": "case",
    "method": "method",
    "against": "against",
    "k": "elements per link k",
    "h": "step h (s)",
    "status": "status",
    "reason": "why",
    "options": "settings",
    "study": "study",
    "ee_l2": "end-effector error, RMS (m)",
    "ee_linf": "end-effector error, max (m)",
    "ee_final": "end-effector error, final (m)",
    "best_error": "best error reached (m)",
    "target_error": "common error (m)",
    "cpu_time": "CPU time (s)",
    "cpu_time_median": "CPU time, median (s)",
    "cpu_time_to_target": "CPU time to the common error (s)",
    "wall_time": "wall time (s)",
    "wall_time_to_target": "wall time to the common error (s)",
    "ratio": "time ratio",
    "order": "observed order",
    "exponent": "exponent p (time ∝ size^p)",
    "quantity": "quantity",
    "repeats": "repeats",
    "noisy": "noisy timing",
    "role": "role",
    "problem": "problem",
    "target": "target",
    "value": "value",
    "error": "error",
    "rel_error": "relative error",
    "tolerance": "tolerance",
    "passed": "passed",
    "fit_from": "fit from",
    "fit_to": "fit to",
    "n_points": "points fitted",
    "moment1_l2": "root moment error, RMS (N·m)",
    "torque1_l2": "joint-1 torque error, RMS (N·m)",
    "energy_l2": "energy error, RMS (J)",
    "energy_reference": "energy reference",
}

_UNITS = {"_m": " (m)", "_s": " (s)", "_us": " (µs)", "_hz": " (Hz)", "_rad": " (rad)", "_nm": " (N·m)"}


def header(col) -> str:
    """The column header in words: the table above, else the name with its unit suffix as a
    unit ("tip_error_m" → "tip error (m)") and underscores as spaces."""
    col = str(col)
    if col in WORDS:
        return WORDS[col]
    m = re.fullmatch(r"tip(\d+)_(l2|linf)", col)
    if m:
        return f"tip {m[1]} deflection error, {'RMS' if m[2] == 'l2' else 'max'} (m)"
    m = re.fullmatch(r"angle(\d+)_(l2|linf)", col)
    if m:
        return f"joint {m[1]} angle error, {'RMS' if m[2] == 'l2' else 'max'} (rad)"
    for suffix, unit in _UNITS.items():
        if col.lower().endswith(suffix) and len(col) > len(suffix):
            return col[: -len(suffix)].replace("_", " ") + unit
    return col.replace("_", " ")


def _number(v: float) -> str:
    if np.isinf(v):
        return "unbounded" if v > 0 else "−unbounded"
    if v == int(v) and abs(v) < 1e6:
        return str(int(v))
    return f"{v:.3g}"


def _missing(col: str, status) -> str:
    """Why a cell has no value, in words."""
    if isinstance(status, str) and status not in ("ok", ""):
        return f"no value (run {status})"
    if "order" in col or "exponent" in col:
        return "not fitted"
    if "target" in col:
        return "not reached"
    return "not recorded"


def cell(v, col: str = "", status=None) -> str:
    """One cell as text: numbers with three significant digits, a missing value in words,
    method ids as their labels (``col == "method"``)."""
    if v is None or v is pd.NA or v is pd.NaT or (isinstance(v, (float, np.floating)) and np.isnan(v)):
        return _missing(col, status)
    if isinstance(v, (bool, np.bool_)):
        return "yes" if v else "no"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return _number(float(v))
    s = str(v)
    if col in ("method", "against") and s:
        return _label(s)
    if col == "study":
        return s.replace("_", " ")
    if s.strip() in ("nan", "NaN", "None", "inf", "-inf", "<NA>"):
        return _missing(col, status)
    return BAD_WORDS.sub(lambda m: {"inf": "unbounded", "-inf": "−unbounded"}.get(m[1], "no value"), s)


def _label(m: str) -> str:
    from experiments import methods

    try:
        return methods.label(m)
    except Exception:  # an outside method's id, or a free text: shown as it is
        return m


def present(df: pd.DataFrame) -> pd.DataFrame:
    """``df`` as the strings a page shows: hidden bookkeeping columns dropped, headers in words
    (kept as written when ``df.attrs["verbatim_headers"]``), every cell through :func:`cell` (a
    missing value says why, using the row's status)."""
    keep = [c for c in df.columns if str(c) not in HIDDEN and not str(c).startswith("Unnamed")]
    d = df[keep].reset_index(drop=True)
    status = d["status"] if "status" in d else pd.Series([None] * len(d))
    out = {}
    for c in keep:
        out[header(c)] = [cell(v, str(c), s) for v, s in zip(d[c], status)]
    if df.attrs.get("verbatim_headers"):  # e.g. case names as columns: shown as written
        out = dict(zip(keep, out.values()))
    res = pd.DataFrame(out, columns=list(out))
    res.columns = _unique(res.columns)
    return res


def _unique(cols) -> list:
    seen: dict = {}
    out = []
    for c in cols:
        n = seen.get(c, 0)
        out.append(c if n == 0 else f"{c} ({n + 1})")
        seen[c] = n + 1
    return out
