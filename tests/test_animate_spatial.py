"""3-D animations of spatial arms: ``arm_animation`` on link shapes (nt, n, p, 3), a GIF with
frames, and ``dttmm animate`` on a spatial case file (small: few frames, few points)."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("matplotlib")
pytest.importorskip("PIL")

from dttmm import InputError, animate, load_case  # noqa: E402

CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases" / "spatial"


def helix(nt=6, n=2, p=5):
    """A made-up spatial motion: two unit links turning about z and lifting out of the plane."""
    t = np.linspace(0.0, 1.0, nt)
    sh = np.zeros((nt, n, p, 3))
    u = np.linspace(0.0, 1.0, p)
    for j, tt in enumerate(t):
        root = np.zeros(3)
        for i in range(n):
            d = np.array([np.cos(tt + i), np.sin(tt + i), 0.3 * tt])
            d /= np.linalg.norm(d)
            sh[j, i] = root + u[:, None] * d
            root = sh[j, i, -1]
    return SimpleNamespace(t=t, link_shapes=sh, end_effector=sh[:, -1, -1].copy(), meta={"method": "made-up"})


def test_3d_frames_move_and_axes_are_equal():
    r = helix()
    anim = animate.arm_animation(r, max_frames=None, fps=5.0, dpi=40, figsize=(3, 3))
    ax = anim.fig.axes[0]
    assert ax.name == "3d"
    spans = [np.diff(lim)[0] for lim in (ax.get_xlim(), ax.get_ylim(), ax.get_zlim())]
    np.testing.assert_allclose(spans, spans[0])
    lo, hi = zip(ax.get_xlim(), ax.get_ylim(), ax.get_zlim())
    pts = r.link_shapes.reshape(-1, 3)
    assert np.all(pts >= np.array(lo)) and np.all(pts <= np.array(hi))  # the whole motion fits
    f0, f1 = anim.frame(0), anim.frame(len(anim) - 1)
    assert f0.shape == f1.shape and f0.shape[2] == 3
    assert np.any(f0 != f1)


def test_mixed_dimensions_refused():
    r3 = helix()
    r2 = SimpleNamespace(
        t=r3.t, link_shapes=r3.link_shapes[..., :2], end_effector=r3.end_effector[:, :2], meta={}
    )
    with pytest.raises(InputError, match="mix planar and spatial"):
        animate.arm_animation({"a": r3, "b": r2})


def test_spatial_gif_has_frames(tmp_path):
    from PIL import Image

    anim = animate.arm_animation(helix(nt=4), max_frames=None, fps=4.0, dpi=40, figsize=(3, 3))
    path = animate.save(anim, tmp_path / "arm.gif")
    with Image.open(path) as im:
        assert im.n_frames == 4


def test_cli_animates_a_spatial_case(tmp_path):
    """``dttmm animate`` on a spatial case file: the spatial kernel with link shapes, a GIF."""
    from PIL import Image

    from dttmm.cli import main

    text = (CASES / "two_joint_arm.toml").read_text()
    text = text.replace("duration = 1.0", "duration = 0.04").replace(
        "output_step = 1e-3", "output_step = 0.01"
    )
    src = tmp_path / "arm.toml"
    src.write_text(text)
    assert load_case(src).scenario.duration == 0.04
    out = tmp_path / "arm.gif"
    code = main(
        ["animate", str(src), "-k", "2", "--h", "1e-3", "--points", "4", "--fps", "100", "--out", str(out)]
    )
    assert code == 0
    with Image.open(out) as im:
        assert im.n_frames == 5


def test_cli_animates_a_stored_spatial_result(tmp_path):
    """``dttmm simulate --format parquet --shape-points P`` on a spatial case, then ``dttmm
    animate`` on the stored table: a SpatialResult read back, drawn in 3-D."""
    from PIL import Image

    from dttmm.cli import main

    text = (CASES / "two_joint_arm.toml").read_text()
    text = text.replace("duration = 1.0", "duration = 0.03").replace(
        "output_step = 1e-3", "output_step = 0.01"
    )
    src = tmp_path / "arm.toml"
    src.write_text(text)
    out = tmp_path / "run"
    args = ["simulate", str(src), "-k", "2", "--h", "1e-3", "--shape-points", "4", "--format", "parquet"]
    assert main([*args, "--out", str(out)]) == 0
    gif = tmp_path / "stored.gif"
    stored = str(out / "two_joint_arm.parquet")
    assert main(["animate", stored, "--case", str(src), "--fps", "100", "--out", str(gif)]) == 0
    with Image.open(gif) as im:
        assert im.n_frames == 4
