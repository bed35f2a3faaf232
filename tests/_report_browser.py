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


def available() -> bool:
    """Whether a Chromium binary is on this machine."""
    return Path(CHROMIUM).exists()


def probe(page: Path, timeout: float = 120) -> dict:
    """{"imgs": [{src, w, complete}], "secs": [{id, title, text, imgs, tables}]} of ``page``."""
    page = Path(page)
    copy = page.with_name("_probe_" + page.name)
    copy.write_text(page.read_text().replace("</body>", _PROBE + "</body>"))
    try:
        with tempfile.TemporaryDirectory() as profile:
            out = subprocess.run(
                [CHROMIUM, *FLAGS, f"--user-data-dir={profile}", "--dump-dom", copy.resolve().as_uri()],
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
