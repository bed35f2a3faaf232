"""Load a report page in headless Chromium and read back what the browser saw.

A copy of the page with a small script beside it is opened with ``--dump-dom``; after the
load event the script records, for every image, whether it decoded (``naturalWidth``), and for
every section, how much it shows besides its heading. Used by the report tests; the tests are
skipped when Chromium is absent.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser") or "/usr/bin/chromium"
FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--allow-file-access-from-files",
    "--virtual-time-budget=10000",
]
_PROBE = """
<script>
window.addEventListener('load', () => {
  const imgs = [...document.images].map(i => ({src: i.getAttribute('src'), w: i.naturalWidth,
                                              complete: i.complete}));
  const secs = [...document.querySelectorAll('section')].map(s => {
    const body = [...s.children].filter(c => c.tagName !== 'H2');
    return {id: s.id, title: (s.querySelector('h2') || {}).textContent || '',
            text: body.map(c => c.textContent.trim()).join(' ').length,
            imgs: s.querySelectorAll('img').length, tables: s.querySelectorAll('table').length};
  });
  const pre = document.createElement('pre');
  pre.id = 'probe-result';
  pre.textContent = JSON.stringify({imgs, secs});
  document.body.appendChild(pre);
});
</script>
"""


_LAYOUT = """
<script>
window.addEventListener('load', () => {
  const tables = [...document.querySelectorAll('table')].map(t => ({
    id: t.id, w: t.scrollWidth, cw: t.parentElement.clientWidth,
    fits: t.getBoundingClientRect().right <= t.parentElement.getBoundingClientRect().right + 1}));
  const top = sel => { const e = document.querySelector(sel);
                       return e ? e.getBoundingClientRect().top + window.scrollY : null; };
  const pre = document.createElement('pre');
  pre.id = 'probe-result';
  pre.textContent = JSON.stringify({
    scrollWidth: document.documentElement.scrollWidth, innerWidth: window.innerWidth,
    innerHeight: window.innerHeight, height: document.documentElement.scrollHeight,
    tables, text: document.body.innerText,
    tops: {answers: top('#answers'), figure: top('#summary-figure img'),
           answersEnd: (() => { const e = document.querySelector('#answers');
                                return e ? e.getBoundingClientRect().bottom + window.scrollY : null; })()},
    imgs: [...document.images].map(i => ({src: i.getAttribute('src'), w: i.naturalWidth,
                                           shown: i.getBoundingClientRect().width})),
  });
  document.body.appendChild(pre);
});
</script>
"""


def available() -> bool:
    """Whether a Chromium binary is on this machine."""
    return Path(CHROMIUM).exists()


def probe(page: Path, timeout: float = 120, *, script: str = _PROBE, size=(1366, 768)) -> dict:
    """{"imgs": [{src, w, complete}], "secs": [{id, title, text, imgs, tables}]} of ``page``
    (or what ``script`` records, e.g. :func:`layout`), in a window of ``size`` pixels."""
    page = Path(page)
    copy = page.with_name("_probe_" + page.name)
    copy.write_text(page.read_text().replace("</body>", script + "</body>"))
    try:
        with tempfile.TemporaryDirectory() as profile:
            out = subprocess.run(
                [
                    CHROMIUM,
                    *FLAGS,
                    f"--user-data-dir={profile}",
                    f"--window-size={size[0]},{size[1]}",
                    "--dump-dom",
                    copy.resolve().as_uri(),
                ],
                capture_output=True,
                check=False,
                text=True,
                timeout=timeout,
            )
    finally:
        copy.unlink()
    m = re.search(r'<pre id="probe-result">(.*?)</pre>', out.stdout, re.DOTALL)
    if m is None:
        raise RuntimeError(f"no probe result from chromium (rc {out.returncode}): {out.stderr[-2000:]}")
    return json.loads(m.group(1).replace("&lt;", "<").replace("&gt;", ">").replace("&amp;", "&"))


def layout(page: Path, size=(1366, 768), timeout: float = 120) -> dict:
    """What a reader sees of ``page`` in a ``size`` window: document and window widths, each
    table's width against its container's, the visible text, the tops of the front page's
    answers and summary figure (px from the top of the page), the images."""
    return probe(page, timeout, script=_LAYOUT, size=size)


def screenshot(page: Path, png: Path, width: int = 1280, height: int = 1800, timeout: float = 120) -> Path:
    """Save a PNG of the top of ``page`` as Chromium renders it."""
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run(
            [
                CHROMIUM,
                *FLAGS,
                f"--user-data-dir={profile}",
                f"--screenshot={Path(png).resolve()}",
                f"--window-size={width},{height}",
                Path(page).resolve().as_uri(),
            ],
            capture_output=True,
            timeout=timeout,
            check=True,
        )
    return Path(png)
