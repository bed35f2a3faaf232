"""The report's Motion section: frames stored as a table, drawn from it alone, shown in a real
browser (the videos load, have frames and a non-zero duration; the still frames decode)."""

from __future__ import annotations

import json
import re
import subprocess
import tempfile
from pathlib import Path

import _report_browser as report_browser
import matplotlib.image as mpimg
import pandas as pd
import pytest
from conftest import case, shortened

from dttmm import case_to_dict
from dttmm.animate import ffmpeg_path
from reports import animations
from reports.build import Inputs
from reports.render import write

_VIDEO_PROBE = """
<script>
window.addEventListener('load', () => {
  const vids = [...document.querySelectorAll('video')];
  const ready = vids.map(v => new Promise(done => {
    if (v.readyState >= 2) return done();
    v.addEventListener('loadeddata', done); v.addEventListener('error', done); setTimeout(done, 5000);
  }));
  Promise.all(ready).then(() => {
    const pre = document.createElement('pre');
    pre.id = 'probe-videos';
    pre.textContent = JSON.stringify(vids.map(v => ({src: v.getAttribute('src'), ready: v.readyState,
      duration: v.duration, w: v.videoWidth, error: v.error && v.error.code,
      frames: v.getVideoPlaybackQuality().totalVideoFrames})));
    document.body.appendChild(pre);
  });
});
</script>
"""


def _videos(page: Path) -> list:
    copy = page.with_name("_probe_videos.html")
    copy.write_text(page.read_text().replace("</body>", _VIDEO_PROBE + "</body>"))
    with tempfile.TemporaryDirectory() as profile:
        out = subprocess.run(
            [
                report_browser.CHROMIUM,
                *report_browser.FLAGS,
                f"--user-data-dir={profile}",
                "--dump-dom",
                copy.as_uri(),
            ],
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
    copy.unlink()
    m = re.search(r'<pre id="probe-videos">(.*?)</pre>', out.stdout, re.DOTALL)
    assert m, out.stderr[-2000:]
    return json.loads(m.group(1).replace("&amp;", "&"))


@pytest.fixture(scope="module")
def motion(tmp_path_factory):
    cases = {
        "three_link": shortened(case("three_link"), 0.5, 0.01),
        "spin_up": shortened(case("spin_up"), 0.5, 0.01),
    }
    table = animations.motion_table(cases, {"k": 4, "max_frames": 5})["motion"]
    folder = tmp_path_factory.mktemp("motion")
    meta = {"cases": {n: case_to_dict(c) for n, c in cases.items()}}
    inp = Inputs({"motion": table}, meta, folder / "figures", folder / "bench")
    sec = animations.section(inp)
    index, _ = write(folder, "motion", [], [sec], pd.DataFrame(), {})
    page = index.parent / "motion.html"  # the Motion page of the site
    assert page.exists()
    return table, sec, page, meta


def test_the_table_holds_every_frame_of_both_methods(motion):
    table = motion[0]
    assert set(table.case) == {"three_link", "spin_up"} and set(table.method) == {"dttmm", "pinocchio-rigid"}
    per = table.groupby(["case", "method"]).frame.nunique()
    assert (per == 5).all()  # 0.5 s at 20 frames per second would be 11: capped at 5
    three = table[(table.case == "three_link") & (table.method == "dttmm")]
    assert len(three) == 5 * 3 * animations.MOTION["points"]


def test_section_draws_one_animation_per_case_with_a_still(motion):
    _, sec, page, meta = motion
    assert len(sec.figures) == 2
    ext = ".mp4" if ffmpeg_path() else ".gif"
    for path, caption in sec.figures:
        assert path.endswith(ext) and ("bending" in caption or "true scale" in caption)
        still = page.parent / (path[: -len(ext)] + ".png")
        assert mpimg.imread(still).shape[0] > 100
    assert "Drawn and encoded in" in " ".join(sec.text) and meta["motion_render_s"] > 0


def test_exaggeration_is_a_round_factor_that_shows_the_bending():
    m = animations.Motion(*_bent(0.001))
    assert animations.exaggeration({"a": m}, 1.0) == 50.0  # 0.06 / 0.001 = 60 → 50
    assert animations.exaggeration({"a": animations.Motion(*_bent(0.2))}, 1.0) == 1.0


def _bent(amp):
    import numpy as np

    x = np.linspace(0, 1, 5)
    sh = np.stack([x, amp * np.sin(np.pi * x)], -1)[None, None]
    return np.zeros(1), sh, sh[:, -1, -1]


@pytest.mark.skipif(not report_browser.available(), reason="chromium is not installed")
def test_videos_play_in_a_real_browser(motion):
    page = motion[2]
    if not ffmpeg_path():
        pytest.skip("no ffmpeg: the animations are GIFs (checked as images by the report test)")
    seen = _videos(page)
    assert len(seen) == 2
    for v in seen:
        assert v["error"] is None and v["ready"] >= 2, v
        assert v["duration"] > 0 and v["w"] > 100 and v["frames"] >= 1, v
    imgs = report_browser.probe(page)["imgs"]
    assert imgs and all(i["complete"] and i["w"] > 100 for i in imgs), imgs


@pytest.mark.skipif(not report_browser.available(), reason="chromium is not installed")
def test_videos_are_readable_and_their_controls_sit_below_the_drawing(motion):
    page = motion[2]
    html = page.read_text()
    assert " controls" not in html  # no overlay controls over the drawing
    assert html.count("<button data-video=") == 2
    seen = report_browser.layout(page, (1366, 768))
    assert seen["scrollWidth"] <= seen["innerWidth"]
    stills = [i for i in seen["imgs"] if i["src"].endswith(".png")]
    assert stills and all(i["w"] >= 600 for i in stills), stills  # drawn at 640 px
