"""Write a report (``index.html`` and ``REPORT.md``) from sections of figures, text and tables."""

from __future__ import annotations

import html
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["Section", "write"]

MAX_ROWS = 30  # rows shown inline; the CSV beside the report has them all


@dataclass
class Section:
    """One report section: figures (PNG file names relative to the report), sentences under
    them, and tables (name, DataFrame) shown inline and linked as CSV (``data/<name>.csv``)."""

    title: str
    figures: list = field(default_factory=list)
    text: list = field(default_factory=list)
    tables: list = field(default_factory=list)
    anchor: str = ""


def _fmt(v) -> str:
    if isinstance(v, (float, np.floating)):
        return "NaN" if not np.isfinite(v) else f"{v:.4g}"
    return str(v)


def _md_table(df: pd.DataFrame) -> str:
    df = df.head(MAX_ROWS)
    head = "| " + " | ".join(map(str, df.columns)) + " |"
    sep = "|" + "---|" * len(df.columns)
    rows = [
        "| " + " | ".join(_fmt(v).replace("|", "/") for v in r) + " |" for r in df.itertuples(index=False)
    ]
    return "\n".join([head, sep, *rows])


def _html_table(df: pd.DataFrame) -> str:
    return df.head(MAX_ROWS).to_html(
        index=False, float_format=lambda x: f"{x:.4g}", na_rep="NaN", border=0, classes="t"
    )


def _more(df, name) -> str:
    return f" (first {MAX_ROWS} of {len(df)} rows)" if len(df) > MAX_ROWS else ""


def write(
    out, title: str, summary: list, sections: list, omissions: pd.DataFrame, footer: dict, notes: list = ()
) -> tuple[Path, Path]:
    """Write ``out/index.html`` and ``out/REPORT.md``; return both paths."""
    out = Path(out)
    md, h = [f"# {title}", "", "## Summary", ""], [f"<h1>{html.escape(title)}</h1>", "<h2>Summary</h2><ul>"]
    for s in summary:
        md.append(f"- {s}")
        h.append(f"<li>{html.escape(s)}</li>")
    h.append("</ul>")
    for n in notes:
        md += ["", f"> {n}"]
        h.append(f"<p class='note'>{html.escape(n)}</p>")
    for sec in sections:
        md += ["", f"## {sec.title}", ""]
        h.append(f"<h2 id='{sec.anchor}'>{html.escape(sec.title)}</h2>")
        for png, caption in sec.figures:
            md += [f"![{caption}]({png})", ""]
            h.append(
                f"<figure><img src='{png}' alt='{html.escape(caption)}'>"
                f"<figcaption>{html.escape(caption)}</figcaption></figure>"
            )
        for s in sec.text:
            md.append(s + " ")
        h.append("<p>" + " ".join(html.escape(s) for s in sec.text) + "</p>")
        for name, df in sec.tables:
            md += ["", f"Table `{name}`{_more(df, name)} — [CSV](data/{name}.csv)", "", _md_table(df)]
            h.append(f"<p>Table <code>{name}</code>{_more(df, name)} — <a href='data/{name}.csv'>CSV</a></p>")
            h.append(_html_table(df))
    md += ["", "## Omissions", ""]
    h.append("<h2>Omissions</h2>")
    if omissions.empty:
        md.append("None: every planned run produced an error value.")
        h.append("<p>None: every planned run produced an error value.</p>")
    else:
        md += [
            f"{len(omissions)} planned run(s) have no error value; each is kept in the tables as NaN with "
            "its reason ([CSV](data/omissions.csv)).",
            "",
            _md_table(omissions),
        ]
        h.append(
            f"<p>{len(omissions)} planned run(s) have no error value; each is kept in the tables as NaN "
            "with its reason (<a href='data/omissions.csv'>CSV</a>).</p>" + _html_table(omissions)
        )
    md += ["", "## Provenance", ""]
    h.append("<h2>Provenance</h2><ul>")
    for k, v in footer.items():
        text = ", ".join(f"{a} {b}" for a, b in v.items()) if isinstance(v, dict) else str(v)
        md.append(f"- **{k}**: {text}")
        h.append(f"<li><b>{html.escape(k)}</b>: {html.escape(text)}</li>")
    h.append("</ul>")
    style = (
        "body{font-family:sans-serif;max-width:1100px;margin:auto;padding:1em}img{max-width:100%}"
        "table.t{border-collapse:collapse;font-size:80%}table.t td,table.t th{padding:2px 6px;"
        "border-bottom:1px solid #ddd}.note{background:#f6f6e8;padding:.5em}figcaption{font-size:85%}"
    )
    page = (
        f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
        f"<style>{style}</style></head><body>" + "\n".join(h) + "</body></html>"
    )
    (out / "index.html").write_text(page)
    (out / "REPORT.md").write_text("\n".join(md) + "\n")
    return out / "index.html", out / "REPORT.md"
