"""Write the report as a small static site: a front page (``index.html``), one page per study
reached from a navigation bar on every page, and ``REPORT.md`` holding all of it in one file.

Sections are grouped into pages by their anchor (``PAGES``); a section whose anchor is not
listed gets a page of its own. Figures and tables are numbered across the site; tables are
shown for people (``reports.tables.present``), sortable, the first rows shown and the rest one
click away, every table also linked as CSV. ``report.css`` and ``report.js`` are copied beside
the pages; the site works from the file system.
"""

from __future__ import annotations

import html
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .tables import present

__all__ = ["CSS", "PAGES", "Front", "Section", "fmt", "page_files", "write"]

MAX_ROWS = 30  # rows of a table in REPORT.md; the CSV beside the report has them all
PAGE_ROWS = 15  # rows of a table shown on a page before "show all"
LONG = 24  # characters from which a cell may break inside a word (shorter ones break at spaces only)
DENSE_PX = 1100  # a table far wider than this without breaking words breaks them (class dense;
# report.js adds the class too where the browser finds the table wider than its column)
HTML_ROWS = 400  # rows written into a page at most (the CSV has them all)
HERE = Path(__file__).parent
ASSETS = ("report.css", "report.js")
CSS = HERE / "report.css"  # also the stylesheet of the validation scorecards (reports/validate_page.py)

#: the study pages, in the order of the navigation bar: (file stem, title, section anchors)
PAGES = [
    ("cases", "Cases", ("cases",)),
    ("convergence", "Convergence", ("convergence-k", "convergence-h")),
    ("work-precision", "Work-precision", ("work-precision", "scoreboard-per-case")),
    ("scheme", "Scheme", ("scheme",)),
    ("paper", "Paper figures", ("paper",)),
    ("motion", "Motion", ("motion",)),
    ("loads", "Loads and energy", ("loads",)),
    ("cost", "Cost scaling", ("cost", "bench")),
    ("problems", "Benchmark problems", ("benchmarks",)),
    ("closed-loop", "Closed loop", ("control",)),
    ("validation", "Validation", ("validate",)),
    ("peers", "Peers", ("peers",)),
    ("omissions", "Omissions", ("omissions",)),
    ("provenance", "Provenance", ("summary", "provenance")),
]


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
    html: str = ""  # raw HTML shown after the figures (e.g. a note with a link); not in REPORT.md


@dataclass
class Front:
    """The front page: the three answers (question, answer, page it links to), the summary
    figure (path, caption), the compact scoreboard (name, table, footnotes) and the paragraphs
    under them."""

    answers: list = field(default_factory=list)
    figure: tuple | None = None
    board: tuple | None = None
    lead: list = field(default_factory=list)


def fmt(v) -> str:
    """A table cell in words (``reports.tables.cell``)."""
    from .tables import cell

    return cell(v)


def page_files(sections) -> list[tuple[str, str]]:
    """(file name, title) of every page the sections make, front page first."""
    return [("index.html", "Overview")] + [(f"{stem}.html", title) for stem, title, _ in _group(sections)]


def _group(sections) -> list[tuple[str, str, list]]:
    """(stem, title, sections) per page, in ``PAGES`` order, then unlisted anchors."""
    where = {a: stem for stem, _, anchors in PAGES for a in anchors}
    pages: dict = {stem: (title, []) for stem, title, _ in PAGES}
    for s in sections:
        stem = where.get(s.anchor)
        if stem is None:
            stem = s.anchor or f"page{len(pages)}"
            pages.setdefault(stem, (s.title, []))
        pages[stem][1].append(s)
    return [(stem, t, secs) for stem, (t, secs) in pages.items() if secs]


class _Counter:
    def __init__(self):
        self.fig = self.tab = 0


def _md_table(df: pd.DataFrame) -> str:
    d = present(df.head(MAX_ROWS))
    head = "| " + " | ".join(d.columns) + " |"
    sep = "|" + "---|" * len(d.columns)
    rows = ["| " + " | ".join(v.replace("|", "/") for v in r) + " |" for r in d.itertuples(index=False)]
    return "\n".join([head, sep, *rows])


def _sort_key(v) -> str:
    if isinstance(v, (bool, np.bool_)):
        return ""
    if isinstance(v, (int, float, np.integer, np.floating)) and np.isfinite(v):
        return f" data-v='{float(v):.17g}'"
    return ""


def _html_table(name: str, df: pd.DataFrame) -> str:
    """The table as HTML: headers in words, sortable by a click, the first ``PAGE_ROWS`` rows
    shown and the rest behind a button."""
    shown = df.head(HTML_ROWS)
    words = present(shown)
    cols = list(words.columns)
    keep = [c for c in shown.columns if str(c) not in _hidden() and not str(c).startswith("Unnamed")]
    raw = shown[keep].reset_index(drop=True)
    head = "".join(f"<th scope='col'>{html.escape(c)}</th>" for c in cols)
    body = []
    for i in range(len(words)):
        cells = []
        for j in range(len(cols)):
            v = raw.iat[i, j]
            num = _sort_key(v)
            text = words.iat[i, j]
            cls = " class='n'" if num else " class='long'" if len(text) > LONG else ""
            cells.append(f"<td{cls}{num}>{html.escape(text)}</td>")
        more = " class='more'" if i >= PAGE_ROWS else ""
        body.append(f"<tr{more}>{''.join(cells)}</tr>")
    tid = f"t-{name}"
    dense = " dense" if _min_width_px(words) > DENSE_PX else ""
    out = (
        f"<div class='tw'><table class='t{dense}' id='{html.escape(tid)}'><thead><tr>{head}</tr></thead>"
        f"<tbody>{''.join(body)}</tbody></table></div>"
    )
    if len(words) > PAGE_ROWS:
        rest = (
            f"all {len(words)} rows"
            if len(df) <= HTML_ROWS
            else f"{len(words)} of {len(df)} rows (all in the CSV)"
        )
        out += f"<button class='all' data-table='{html.escape(tid)}'>show {rest}</button>"
    return out


def _min_width_px(words: pd.DataFrame) -> float:
    """About how wide (px at the table's font) the table is when no short cell breaks inside a
    word: per column its longest short cell or header word, a long cell's minimum width."""
    total = 0.0
    for j, c in enumerate(words.columns):
        cells = [len(x) if len(x) <= LONG else 0 for x in words.iloc[:, j]]
        longs = any(len(x) > LONG for x in words.iloc[:, j])
        head = max((len(w) for w in str(c).split()), default=0)
        total += max([head, *cells, 15 if longs else 0]) * 6.5 + 12
    return total


def _hidden():
    from .tables import HIDDEN

    return HIDDEN


class _Page:
    """Markdown and HTML of one page written side by side."""

    def __init__(self, n: _Counter, level: int = 2):
        self.md, self.h, self.n, self.level = [], [], n, level

    def heading(self, title, anchor):
        self.md += ["", "#" * (self.level + 1) + f" {title}", ""]
        self.h.append(f"<section id='{anchor}'><h2>{html.escape(title)}</h2>")

    def end(self):
        self.h.append("</section>")

    def bullets(self, sentences):
        self.md += [f"- {x}" for x in sentences] + [""]
        self.h.append("<ul>" + "".join(f"<li>{html.escape(x)}</li>" for x in sentences) + "</ul>")

    def para(self, sentences, cls=""):
        if sentences:
            self.md += [" ".join(sentences), ""]
            c = f" class='{cls}'" if cls else ""
            self.h.append(f"<p{c}>" + " ".join(html.escape(s) for s in sentences) + "</p>")

    def figure(self, png, caption, cls=""):
        self.n.fig += 1
        cap = f"Figure {self.n.fig}. {caption}"
        c = f" class='{cls}'" if cls else ""
        if png.endswith(".mp4"):
            # a video: its still frame (same name, .png) is poster and fallback; its controls sit
            # below the drawing, never over it
            still = png[: -len(".mp4")] + ".png"
            vid = f"v{self.n.fig}"
            self.md += [f"[![{cap}]({still})]({png})", "", f"*{cap}* ([video]({png}))", ""]
            self.h.append(
                f"<figure class='video'><video id='{vid}' src='{png}' poster='{still}' loop muted autoplay "
                f"playsinline preload='auto'><img src='{still}' alt='{html.escape(caption)}'></video>"
                f"<div class='vc'><button data-video='{vid}' class='play'>pause</button> "
                f"<a href='{png}'>video file</a></div>"
                f"<figcaption>{html.escape(cap)}</figcaption></figure>"
            )
            return
        self.md += [f"![{cap}]({png})", "", f"*{cap}*", ""]
        self.h.append(
            f"<figure{c}><a href='{png}'><img src='{png}' alt='{html.escape(caption)}'></a>"
            f"<figcaption>{html.escape(cap)}</figcaption></figure>"
        )

    def table(self, name, df, title=""):
        self.n.tab += 1
        more = f" (first {MAX_ROWS} of {len(df)} rows)" if len(df) > MAX_ROWS else ""
        cap = f"Table {self.n.tab}. {title or name.replace('_', ' ')}"
        self.md += [f"{cap}{more} — [CSV](data/{name}.csv)", "", _md_table(df), ""]
        self.h.append(
            f"<p class='tcap'>{html.escape(cap)} ({len(df)} rows) — <a href='data/{name}.csv'>CSV</a></p>"
            + _html_table(name, df)
        )

    def section(self, sec: Section, page_title: str = ""):
        if sec.title == page_title:  # the page's heading is the section's heading
            self.md += [""]
            self.h.append(f"<section id='{sec.anchor}'>")
        else:
            self.heading(sec.title, sec.anchor)
        for png, caption in sec.figures:
            self.figure(png, caption)
        if sec.html:
            self.h.append(sec.html)
        (self.bullets if sec.bullets else self.para)(sec.text)
        for name, df, *title in sec.tables:
            self.table(name, df, *title)
        if not (sec.figures or sec.text or sec.tables or sec.html):
            self.para(["Nothing to show."])
        self.end()


def _omissions(omissions: pd.DataFrame) -> Section:
    if omissions.empty:
        return Section(
            "Omissions", text=["None: every planned run produced an error value."], anchor="omissions"
        )
    by = omissions.groupby("study").size()
    text = [
        (
            f"{len(omissions)} planned run(s) have no error value or were not run as planned, each with its "
            "reason: " + ", ".join(f"{n} in {s.replace('_', ' ')}" for s, n in by.items()) + "."
        ),
        "A run drawn as failed in a figure is listed here; the study tables keep the run with its status.",
    ]
    return Section(
        "Omissions", text=text, tables=[("omissions", omissions, "Runs without a value")], anchor="omissions"
    )


def _provenance(footer: dict) -> Section:
    items = []
    for k, v in footer.items():
        text = ", ".join(f"{a} {b}" for a, b in v.items()) if isinstance(v, dict) else str(v)
        items.append(f"{k}: {text}")
    return Section("Provenance", text=items, anchor="provenance", bullets=True)


def _nav(pages, here: str) -> str:
    links = []
    for f, t in pages:
        cur = " aria-current='page'" if f == here else ""
        links.append(f"<a href='{f}'{cur}>{html.escape(t)}</a>")
    return "<nav class='site'>" + "".join(links) + "</nav>"


def _doc(title, page_title, nav, body) -> str:
    full = title if page_title == "Overview" else f"{page_title} — {title}"
    return (
        "<!doctype html><html lang='en'><head><meta charset='utf-8'>"
        "<meta name='viewport' content='width=device-width, initial-scale=1'>"
        f"<title>{html.escape(full)}</title><link rel='stylesheet' href='report.css'></head><body>"
        f"<header class='site'><a class='home' href='index.html'>{html.escape(title)}</a>{nav}</header>"
        f"<main>{body}</main><script src='report.js'></script></body></html>"
    )


def _front(page: _Page, front: Front, pages):
    if front.answers:
        page.md += ["## At a glance", ""]
        page.h.append("<section id='answers' class='answers'>")
        for q, a, href in front.answers:
            page.md += [f"**{q}** {a} ([evidence](#{href.removesuffix('.html')}))", ""]
            page.h.append(
                f"<div class='qa'><h2>{html.escape(q)}</h2><p>{html.escape(a)} "
                f"<a href='{href}'>Evidence&nbsp;→</a></p></div>"
            )
        page.h.append("</section>")
    if front.figure:
        page.md += ["## Summary figure", ""]
        page.h.append("<section id='summary-figure'>")
        page.figure(*front.figure, cls="wide")
        page.h.append("</section>")
    if front.board:
        name, df, notes = front.board
        page.md += ["## Scoreboard", ""]
        page.h.append("<section id='scoreboard'><h2>Scoreboard</h2>")
        page.table(name, df, "CPU time to the common error, relative to the cheapest method of the case")
        if notes:
            page.md += [f"{i}. {n}" for i, n in enumerate(notes, 1)] + [""]
            page.h.append(
                "<ol class='notes'>" + "".join(f"<li>{html.escape(n)}</li>" for n in notes) + "</ol>"
            )
        page.h.append("</section>")
    if front.lead:
        page.h.append("<section id='about'><h2>About this report</h2>")
        page.md += ["## About this report", ""]
        for p in front.lead:
            page.para([p])
        page.h.append("</section>")


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
    front: Front | None = None,
) -> tuple[Path, Path]:
    """Write the site into ``out``: ``index.html`` (the front page), one page per group of
    sections (``PAGES``), ``REPORT.md`` with all of them, and the stylesheet and script; return
    (``index.html``, ``REPORT.md``).

    ``summary``: sentences on the run (size, methods, references), shown on the Provenance page;
    ``front``: the front page's answers, figure and scoreboard; ``lead``: paragraphs about the
    report, on the front page.
    """
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    front = front or Front()
    front.lead = [*front.lead, *lead]
    body = [
        *sections,
        _omissions(omissions),
        Section("Run summary", text=list(summary), anchor="summary", bullets=True),
        _provenance(footer),
    ]
    for i, s in enumerate(body):
        s.anchor = s.anchor or f"s{i}"
    groups = _group(body)
    pages = [("index.html", "Overview")] + [(f"{stem}.html", t) for stem, t, _ in groups]
    n = _Counter()
    md = [f"# {title}", ""]
    fp = _Page(n)
    _front(fp, front, pages)
    for x in notes:
        fp.para([x], "note")
    listing = [
        (f, t, [s.summary for s in secs if s.summary]) for (f, t), (_, _, secs) in zip(pages[1:], groups)
    ]
    fp.h.append("<section id='pages'><h2>Pages</h2><ul class='pages'>")
    fp.md += ["## Pages", ""]
    for f, t, said in listing:
        line = " ".join(said)
        line = line if len(line) <= 220 else line[:219].rsplit(" ", 1)[0] + " …"
        fp.h.append(f"<li><a href='{f}'>{html.escape(t)}</a>{': ' + html.escape(line) if line else ''}</li>")
        fp.md.append(f"- [{t}](#{f[:-5]}){': ' + line if line else ''}")
    fp.h.append("</ul></section>")
    fp.md.append("")
    html_body = f"<h1>{html.escape(title)}</h1>" + "\n".join(fp.h)
    (out / "index.html").write_text(_doc(title, "Overview", _nav(pages, "index.html"), html_body))
    md += fp.md
    for (f, t), (stem, _, secs) in zip(pages[1:], groups):
        p = _Page(n)
        for s in secs:
            p.section(s, t)
        md += ["", f"## {t}", "", f"<a id='{stem}'></a>", "", *p.md]
        (out / f).write_text(_doc(title, t, _nav(pages, f), f"<h1>{html.escape(t)}</h1>" + "\n".join(p.h)))
    for a in ASSETS:
        shutil.copyfile(HERE / a, out / a)
    (out / "REPORT.md").write_text("\n".join(md) + "\n")
    return out / "index.html", out / "REPORT.md"
