"""Animations: drawing from link shapes, the encoders, ``dttmm animate`` and ``dttmm modes --animate``.

The PNG frames of two animations (three frames each) are written to ``out/test_frames/`` under
the repository root, for the docs and the issue's closing note.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from conftest import CASES, case, shortened

import dttmm
from dttmm import animate
from dttmm.cli import main
from experiments import methods

FRAMES = Path(__file__).resolve().parents[1] / "out" / "test_frames"


@pytest.fixture(scope="module")
def three_runs():
    c = shortened(case("three_link"), 0.6, 0.01)
    return c, {
        "dttmm": dttmm.simulate(c, elements_per_link=4, h=1e-3, shape_points=9, progress=False),
        "pinocchio-rigid": methods.run("pinocchio-rigid", c, None, 1e-3, shape_points=9),
    }


def test_exaggeration_scales_the_bending_and_keeps_the_ends():
    x = np.linspace(0, 1, 5)
    bent = np.stack([x, 0.01 * np.sin(np.pi * x)], -1)[None]
    e = animate.exaggerated(bent, 10.0)
    np.testing.assert_allclose(e[..., [0, -1], :], bent[..., [0, -1], :], atol=1e-15)
    np.testing.assert_allclose(e[..., 1], 10 * bent[..., 1], atol=1e-15)
    line = np.stack([x, 2 * x], -1)
    np.testing.assert_allclose(animate.exaggerated(line, 7.0), line, atol=1e-15)


def test_frames_cover_the_run_at_the_asked_rate():
    t = np.arange(0, 2.0005, 1e-3)
    idx = animate.frame_indices(t, fps=20, speed=1.0)
    assert idx[0] == 0 and idx[-1] == t.size - 1 and idx.size == 41
    assert animate.frame_indices(t, fps=20, max_frames=10).size == 10


def _frames(anim, tag: str, at=(0.0, 0.5, 1.0)):
    """Three frames (at these fractions of the animation) as PNGs in FRAMES; they must differ."""
    FRAMES.mkdir(parents=True, exist_ok=True)
    n = len(anim.frame_times)
    idx = [round(a * (n - 1)) for a in at]
    paths = [animate.save_frame(anim, i, FRAMES / f"{tag}_{j}.png") for j, i in enumerate(idx)]
    imgs = [mpimg.imread(p) for p in paths]
    assert all(im.shape == imgs[0].shape and im.shape[0] > 100 for im in imgs)
    assert not np.array_equal(imgs[0], imgs[1]) and not np.array_equal(imgs[1], imgs[2])
    return paths


def test_arm_animation_overlays_methods_and_writes_frames_and_a_gif(three_runs, tmp_path):
    c, runs = three_runs
    looks = {n: (methods.label(n), methods.style(n).color, methods.style(n).linestyle) for n in runs}
    anim = animate.arm_animation(runs, c, exaggerate=10.0, fps=10, title="three_link", styles=looks)
    assert len(anim.frame_times) == 7  # 0.6 s at 10 frames per second, ends included
    labels = [t.get_text() for t in anim.fig.axes[0].get_legend().get_texts()]
    assert labels == [methods.label("dttmm"), methods.label("pinocchio-rigid")]
    texts = [t.get_text() for t in anim.fig.axes[0].texts]
    assert "bending ×10" in texts
    _frames(anim, "three_link")
    anim.draw_frame(3)
    assert any(t.startswith("t = 0.300 s") for t in (x.get_text() for x in anim.fig.axes[0].texts))
    gif = animate.save(anim, tmp_path / "a.gif")
    from PIL import Image

    with Image.open(gif) as im:
        assert im.n_frames == 7 and im.info.get("duration", 0) > 0


def test_mp4_and_html(three_runs, tmp_path):
    ff = pytest.importorskip("imageio_ffmpeg")
    c, runs = three_runs
    mp4 = animate.save(animate.arm_animation(runs["dttmm"], c, fps=10), tmp_path / "a.mp4")
    n, secs = ff.count_frames_and_secs(str(mp4))
    assert n == 7 and secs > 0
    html = animate.save(animate.arm_animation(runs["dttmm"], c, fps=10), tmp_path / "a.html")
    assert "<video" in html.read_text()


def test_mode_animation_oscillates_and_writes_frames():
    c = case("three_link")
    m = dttmm.modes(c, 4, n=6)
    anim = animate.mode_animation(m, c, frames=12)
    assert len(anim.fig.axes) >= 4
    paths = _frames(anim, "three_link_modes", at=(3 / 11, 9 / 11, 1 / 11))  # sin(2πτ) = 1, −1, ½
    assert all(p.exists() for p in paths)
    import matplotlib.pyplot as plt

    plt.close(anim.fig)


def test_result_without_shapes_or_of_another_case_is_refused(three_runs):
    c, runs = three_runs
    plain = dttmm.simulate(shortened(c, 0.05), elements_per_link=2, h=1e-3, progress=False)
    with pytest.raises(dttmm.InputError, match="no link shapes"):
        animate.arm_animation(plain, c)
    with pytest.raises(dttmm.InputError, match="does not match the case"):
        animate.arm_animation(runs["dttmm"], case("single_link"))


def test_cli_animates_a_case_and_a_stored_result(tmp_path, capsys):
    src = tmp_path / "short.toml"
    dttmm.save_case(shortened(case("three_link"), 0.1, 0.01), src)
    out = tmp_path / "a.gif"
    assert main(["animate", str(src), "-k", "2", "--exaggerate", "5", "--out", str(out)]) == 0
    assert out.exists()
    methods_args = ["--method", "dttmm", "--method", "pinocchio-rigid@2e-3", "--method", "mujoco-chain@1e-4"]
    assert main(["animate", str(src), "-k", "2", *methods_args, "--out", str(tmp_path / "m.html")]) == 0
    assert "<video" in (tmp_path / "m.html").read_text() or "image/gif" in (tmp_path / "m.html").read_text()
    capsys.readouterr()
    assert main(["animate", str(src), "--method", "nosuch", "--out", str(out)]) == 2
    assert "nosuch" in capsys.readouterr().err
    # a stored Result with shapes animates; one without is a one-line error
    folder = tmp_path / "sim"
    args = ["simulate", str(src), "-k", "2", "--h", "1e-3", "--format", "parquet", "--out", str(folder)]
    assert main([*args, "--shape-points", "5"]) == 0
    table = next(folder.glob("*.parquet"))
    assert main(["animate", str(table), "--case", str(src), "--out", str(tmp_path / "b.gif")]) == 0
    capsys.readouterr()
    assert main(["animate", str(table), "--case", str(CASES / "single_link.toml"), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "does not match the case" in err
    assert main([*args[:-1], str(tmp_path / "plain")]) == 0
    plain = next((tmp_path / "plain").glob("*.parquet"))
    capsys.readouterr()
    assert main(["animate", str(plain), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no link shapes" in err
    assert main(["animate", str(src), "--out", str(tmp_path / "a.avi")]) == 2
    assert "--out" in capsys.readouterr().err


def test_modes_cli_animate(tmp_path):
    assert (
        main(["modes", str(CASES / "single_link.toml"), "-k", "4", "--animate", "--out", str(tmp_path)]) == 0
    )
    anim = [p for p in tmp_path.iterdir() if p.suffix in (".mp4", ".gif")]
    assert len(anim) == 1 and anim[0].stat().st_size > 1000
