"""HTML pages of ``dttmm validate``: ``index.html`` (one line per method) and one scorecard per method.

The pages use the report's stylesheet (``report.css``, copied beside them) and its number format
(:func:`reports.render.fmt`).
"""

from __future__ import annotations

import html
import re
import shutil
from pathlib import Path

from .render import CSS, fmt

__all__ = ["links_section", "page_name", "write"]

COLUMNS = (
    ("check", "check"),
    ("problem", "problem"),
    ("quantity", "quantity"),
    ("value", "value"),
    ("reference", "reference"),
    ("tolerance", "tolerance"),
    ("passed", "verdict"),
    ("order", "observed order"),
    ("k", "k"),
    ("h", "h (s)"),
    ("cpu_time", "CPU time (s)"),
    ("reason", "reason"),
    ("source", "reference source"),
)


def page_name(method: str) -> str:
    """The scorecard page of a method, relative to the output folder."""
    return re.sub(r"[^A-Za-z0-9_.+-]", "_", method) + ".html"


def _cell(key, v) -> str:
    if key == "passed":
        return {True: "pass", False: "<b>FAIL</b>", None: "not run"}[v]
    if v is None:
        return "—"
    if isinstance(v, float):  # values and references to six digits: the tolerances are as fine as 1e-4
        return html.escape(f"{v:.6g}" if key in ("value", "reference") else fmt(v))
    return html.escape(str(v))


def _page(title: str, body: str) -> str:
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f"<title>{html.escape(title)}</title><link rel='stylesheet' href='report.css'></head>"
        f"<body><main>\n<h1>{html.escape(title)}</h1>\n{body}\n</main></body></html>\n"
    )


def _counts(rows):
    return (
        sum(r["passed"] is True for r in rows),
        sum(r["passed"] is False for r in rows),
        sum(r["passed"] is None for r in rows),
    )


def method_page(method: str, rows: list) -> str:
    """One method's scorecard as an HTML page."""
    label = rows[0].get("label") or method if rows else method
    p, f, n = _counts(rows)
    head = "".join(f"<th>{html.escape(t)}</th>" for _, t in COLUMNS)
    body = "\n".join(
        "<tr>" + "".join(f"<td>{_cell(k, r.get(k))}</td>" for k, _ in COLUMNS) + "</tr>" for r in rows
    )
    text = (
        f"<p>{p} passed, {f} failed, {n} not run. A check that does not apply to the method, or that "
        "it cannot run, is listed with the reason. Checks, references and tolerances: docs/validate.md. "
        "<a href='index.html'>All methods</a>.</p>\n"
        f"<table><thead><tr>{head}</tr></thead><tbody>\n{body}\n</tbody></table>"
    )
    return _page(f"Validation scorecard: {label}", text)


def index_page(rows: list) -> str:
    """One line per method: its counts and a link to its scorecard."""
    lines = []
    for m in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == m]
        p, f, n = _counts(mine)
        label = mine[0].get("label") or m
        lines.append(
            f"<tr><td><a href='{page_name(m)}'>{html.escape(label)}</a></td><td>{html.escape(m)}</td>"
            f"<td>{p}</td><td>{f}</td><td>{n}</td></tr>"
        )
    text = (
        "<p>Every method against the suite's published, closed-form and independent values "
        "(<code>dttmm validate</code>; <a href='scorecard.json'>scorecard.json</a>).</p>\n"
        "<table><thead><tr><th>method</th><th>name</th><th>passed</th><th>failed</th><th>not run</th>"
        "</tr></thead><tbody>\n" + "\n".join(lines) + "\n</tbody></table>"
    )
    return _page("Validation scorecards", text)


def write(rows: list, out_dir) -> list:
    """``out_dir/index.html``, ``out_dir/<method>.html`` and the stylesheet; returns the paths."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(CSS, out / "report.css")
    paths = [out / "index.html"]
    paths[0].write_text(index_page(rows), encoding="utf-8")
    for m in dict.fromkeys(r["method"] for r in rows):
        path = out / page_name(m)
        path.write_text(method_page(m, [r for r in rows if r["method"] == m]), encoding="utf-8")
        paths.append(path)
    return paths


def scorecard_links(out_dir) -> list:
    """[(method, label, page path relative to ``out_dir``, passed, failed, not run)] of the
    scorecards written in ``out_dir`` by ``dttmm validate`` ([] when there are none)."""
    import json

    path = Path(out_dir) / "scorecard.json"
    if not path.is_file():
        return []
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return []
    counts: dict = {}
    for r in rows:
        p, f, n = counts.get(r["method"], (0, 0, 0))
        counts[r["method"]] = (
            p + (r["passed"] is True),
            f + (r["passed"] is False),
            n + (r["passed"] is None),
        )
    labels = {r["method"]: r.get("label") or r["method"] for r in rows}
    return [(m, labels[m], page_name(m), *c) for m, c in counts.items()]


def links_section(validate_dir, report_dir):
    """A report section linking each method's scorecard written by ``dttmm validate`` in
    ``validate_dir``, paths relative to ``report_dir``; None when there are no scorecards.

    For ``reports.build``: ``sec = links_section(validate_dir, out)`` and, when not None, append
    it to the report's sections.
    """
    import os

    import pandas as pd

    from .render import Section

    links = scorecard_links(validate_dir)
    if not links:
        return None
    rel = Path(os.path.relpath(Path(validate_dir), Path(report_dir)))
    table = pd.DataFrame(
        [
            {"method": label, "passed": p, "failed": f, "not run": n, "scorecard": str(rel / page)}
            for _, label, page, p, f, n in links
        ]
    )
    failed = [label for _, label, _, _, f, _ in links if f]
    text = [
        f"Each method against the suite's published, closed-form and independent values (dttmm validate; "
        f"index: {rel / 'index.html'}; checks and tolerances: docs/validate.md).",
        ("Failed a check: " + ", ".join(failed) + ".") if failed else "Every check that ran passed.",
    ]
    return Section(
        "Validation scorecards", [], text, [("validate_scorecards", table, "Scorecards")], "validate"
    )
