"""Write a report (``index.html`` and ``REPORT.md``) from sections of figures, text and tables.

The HTML page opens with the lead paragraphs, the scoreboard and a table of contents; sections,
figures and tables are numbered; the stylesheet ``report.css`` is copied beside the page.
"""

from __future__ import annotations

import html
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

__all__ = ["Section", "fmt", "write"]

MAX_ROWS = 30  # rows shown inline; the CSV beside the report has them all
CSS = Path(__file__).with_name("report.css")


@dataclass
class Section:
    """One report section: figures (PNG path relative to the report, or an MP4 video with its still
    frame beside it as ``<stem>.png``; caption), sentences under
    them, tables (name, DataFrame[, title]) shown inline and linked as CSV (``data/<name>.csv``), the
    HTML anchor, and an optional sentence for the report's summary."""

    title: str
    figures: list = field(default_factory=list)
    text: list = field(default_factory=list)
    tables: list = field(default_factory=list)
    anchor: str = ""
    summary: str = ""
    bullets: bool = False  # the sentences as a list instead of a paragraph


def fmt(v) -> str:
    """A table cell: floats with three significant digits, NaN as 'NaN'."""
    if isinstance(v, (float, np.floating)):
        return "NaN" if not np.isfinite(v) else f"{v:.3g}"
    return str(v)


def _md_table(df: pd.DataFrame) -> str:
    df = df.head(MAX_ROWS)
    head = "| " + " | ".join(map(str, df.columns)) + " |"
    sep = "|" + "---|" * len(df.columns)
    rows = ["| " + " | ".join(fmt(v).replace("|", "/") for v in r) + " |" for r in df.itertuples(index=False)]
    return "\n".join([head, sep, *rows])


def _html_table(df: pd.DataFrame) -> str:
    body = df.head(MAX_ROWS).to_html(
        index=False, float_format=lambda x: f"{x:.3g}", na_rep="NaN", border=0, classes="t"
    )
    return f"<div class='tw'>{body}</div>"


def _more(df) -> str:
    return f" (first {MAX_ROWS} of {len(df)} rows)" if len(df) > MAX_ROWS else ""


class _Page:
    """Markdown and HTML written side by side, with running figure and table numbers."""

    def __init__(self):
        self.md, self.h, self.n_fig, self.n_tab = [], [], 0, 0

    def heading(self, title, anchor, numbered=True):
        self.md += ["", f"## {title}", ""]
        cls = "" if numbered else " class='front'"
        self.h.append(f"<section id='{anchor}'><h2{cls}>{html.escape(title)}</h2>")

    def end(self):
        self.h.append("</section>")

    def bullets(self, sentences):
        self.md += [f"- {x}" for x in sentences] + [""]
        self.h.append("<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in sentences) + "</ul>")

    def para(self, sentences):
        if sentences:
            self.md += [" ".join(sentences), ""]
            self.h.append("<p>" + " ".join(html.escape(s) for s in sentences) + "</p>")

    def figure(self, png, caption):
        self.n_fig += 1
        cap = f"Figure {self.n_fig}. {caption}"
        if png.endswith(".mp4"):  # a video: its still frame (same name, .png) is poster and fallback
            still = png[: -len(".mp4")] + ".png"
            self.md += [f"[![{cap}]({still})]({png})", "", f"*{cap}* ([video]({png}))", ""]
            self.h.append(
                f"<figure><video src='{png}' poster='{still}' controls loop muted autoplay playsinline "
                f"preload='auto'><img src='{still}' alt='{html.escape(caption)}'></video>"
                f"<figcaption>{html.escape(cap)}</figcaption></figure>"
            )
            return
        self.md += [f"![{cap}]({png})", "", f"*{cap}*", ""]
        self.h.append(
            f"<figure><img src='{png}' alt='{html.escape(caption)}'>"
            f"<figcaption>{html.escape(cap)}</figcaption></figure>"
        )

    def table(self, name, df, title=""):
        self.n_tab += 1
        cap = f"Table {self.n_tab}. {title or name}{_more(df)}"
        self.md += [f"{cap} — [CSV](data/{name}.csv)", "", _md_table(df), ""]
        self.h.append(
            f"<p class='tcap'>{html.escape(cap)} — <a href='data/{name}.csv'>CSV</a></p>" + _html_table(df)
        )

    def section(self, sec: Section, numbered=True):
        self.heading(sec.title, sec.anchor, numbered)
        for png, caption in sec.figures:
            self.figure(png, caption)
        (self.bullets if sec.bullets else self.para)(sec.text)
        for name, df, *title in sec.tables:
            self.table(name, df, *title)
        if not (sec.figures or sec.text or sec.tables):
            self.para(["Nothing to show."])
        self.end()


def _omissions(omissions: pd.DataFrame) -> Section:
    if omissions.empty:
        return Section(
            "Omissions", text=["None: every planned run produced an error value."], anchor="omissions"
        )
    text = [
        (
            f"{len(omissions)} planned run(s) have no error value; each is kept in the tables as NaN with "
            "its reason (data/omissions.csv)."
        )
    ]
    return Section("Omissions", text=text, tables=[("omissions", omissions)], anchor="omissions")


def _provenance(page: _Page, footer: dict):
    page.heading("Provenance", "provenance")
    page.h.append("<ul>")
    for k, v in footer.items():
        text = ", ".join(f"{a} {b}" for a, b in v.items()) if isinstance(v, dict) else str(v)
        page.md.append(f"- **{k}**: {text}")
        page.h.append(f"<li><b>{html.escape(k)}</b>: {html.escape(text)}</li>")
    page.h.append("</ul>")
    page.end()


def write(
    out,
    title: str,
    summary: list,
    sections: list,
    omissions: pd.DataFrame,
    footer: dict,
    notes: list = (),
    *,
    lead: list = (),
    front: Section | None = None,
) -> tuple[Path, Path]:
    """Write ``out/index.html``, ``out/REPORT.md`` and ``out/report.css``; return the two pages.

    ``lead``: paragraphs under the title; ``front``: a section shown before the contents (the
    scoreboard, unnumbered); ``summary``: sentences of the first numbered section.
    """
    out = Path(out)
    page = _Page()
    page.md += [f"# {title}", ""]
    page.h.append(f"<header><h1>{html.escape(title)}</h1></header>")
    for p in lead:
        page.para([p])
    for n in notes:
        page.md += [f"> {n}", ""]
        page.h.append(f"<p class='note'>{html.escape(n)}</p>")
    if front is not None:
        page.section(front, numbered=False)
    body = [
        Section("Summary", text=list(summary), anchor="summary", bullets=True),
        *sections,
        _omissions(omissions),
    ]
    toc = [(s.title, s.anchor or f"s{i}") for i, s in enumerate(body)] + [("Provenance", "provenance")]
    page.md += ["## Contents", ""] + [f"{i}. [{t}](#{a})" for i, (t, a) in enumerate(toc, 1)] + [""]
    page.h.append(
        "<nav id='contents'><h2 class='front'>Contents</h2><ol>"
        + "".join(f"<li><a href='#{a}'>{html.escape(t)}</a></li>" for t, a in toc)
        + "</ol></nav>"
    )
    for i, sec in enumerate(body):
        sec.anchor = sec.anchor or f"s{i}"
        page.section(sec)
    _provenance(page, footer)
    shutil.copyfile(CSS, out / "report.css")
    doc = (
        f"<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        f"<meta name='viewport' content='width=device-width, initial-scale=1'><title>{html.escape(title)}</title>"
        "<link rel='stylesheet' href='report.css'></head><body><main>"
        + "\n".join(page.h)
        + "</main></body></html>"
    )
    (out / "index.html").write_text(doc)
    (out / "REPORT.md").write_text("\n".join(page.md) + "\n")
    return out / "index.html", out / "REPORT.md"
