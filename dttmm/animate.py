"""Animations of the arm from :attr:`dttmm.Result.link_shapes` (drawing only; nothing here runs
a solver, and the solver never imports this module).

:func:`arm_animation` draws one or more Results of the same case overlaid: every link as its
deflected centre line, the joints, the hubs and payloads of the case, the end-effector trace, a
clock and the exaggeration factor — in the plane for planar link shapes (nt, n, p, 2), in 3-D
(matplotlib's mplot3d, equal axes fixed over the whole motion) for spatial ones (nt, n, p, 3).
:func:`mode_animation` draws mode shapes oscillating.
:func:`save` writes either as .mp4 (ffmpeg from imageio-ffmpeg), .gif (pillow) or .html;
:meth:`Animation.to_matplotlib` gives a matplotlib ``FuncAnimation`` for interactive use.

Exaggeration: the drawn point at arc length x of a link is c(x) + X·(r(x) − c(x)), c the
chord from the link's root to its tip, X the factor; roots, tips and the trace are drawn at
their true positions, so only the bending between joints is magnified.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = [
    "FORMATS",
    "Animation",
    "arm_animation",
    "check_matches",
    "exaggerated",
    "ffmpeg_path",
    "frame_indices",
    "mode_animation",
    "save",
    "save_frame",
]

FORMATS = (".mp4", ".gif", ".html")


def ffmpeg_path() -> str | None:
    """imageio-ffmpeg's ffmpeg executable, or None when imageio-ffmpeg is absent or has none."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return None


@dataclass
class Animation:
    """A drawn animation: its matplotlib figure, ``draw_frame(i)`` that updates the figure to
    frame i and returns the artists it changed, ``frame_times`` (s, or fractions of a period for
    mode shapes) and the frames per second of the video.

    Frames are rendered by blitting: the axes, ticks and grid are drawn once, only the moving
    artists every frame (about ten times faster than redrawing the figure).
    """

    fig: object
    draw_frame: Callable
    frame_times: np.ndarray
    fps: float

    def __len__(self) -> int:
        return len(self.frame_times)

    def _background(self):
        canvas = self.fig.canvas
        if getattr(self, "_bg", None) is None:
            moving = self.draw_frame(0)
            for a in moving:
                a.set_animated(True)
            canvas.draw()
            self._bg = canvas.copy_from_bbox(self.fig.bbox)
        return self._bg

    def frame(self, index: int) -> np.ndarray:
        """Frame ``index`` as RGB pixels (h, w, 3) uint8, h and w even."""
        canvas = self.fig.canvas
        canvas.restore_region(self._background())
        for a in self.draw_frame(index):
            self.fig.draw_artist(a)
        rgb = np.asarray(canvas.buffer_rgba())[..., :3]
        h, w = rgb.shape[0] // 2 * 2, rgb.shape[1] // 2 * 2
        return rgb[:h, :w].copy()

    def frames(self):
        """Every frame in order (see :meth:`frame`)."""
        for i in range(len(self)):
            yield self.frame(i)

    def to_matplotlib(self):
        """The same animation as a ``matplotlib.animation.FuncAnimation`` (for interactive use)."""
        from matplotlib.animation import FuncAnimation

        return FuncAnimation(self.fig, self.draw_frame, frames=len(self), interval=1000.0 / self.fps)


def exaggerated(shapes: np.ndarray, factor: float) -> np.ndarray:
    """Shapes (..., p, 2) with their deviation from the root–tip chord scaled by ``factor``."""
    shapes = np.asarray(shapes, float)
    u = np.linspace(0.0, 1.0, shapes.shape[-2])[:, None]
    chord = shapes[..., :1, :] + u * (shapes[..., -1:, :] - shapes[..., :1, :])
    return chord + factor * (shapes - chord)


def frame_indices(t: np.ndarray, fps: float, speed: float = 1.0, max_frames: int | None = None) -> np.ndarray:
    """Sample indices of the frames: ``fps`` frames per second of video at ``speed`` × real
    time (fewer when ``max_frames`` caps them); always the first and the last sample."""
    t = np.asarray(t, float)
    n = max(2, int(round((t[-1] - t[0]) / speed * fps)) + 1)
    if max_frames is not None:
        n = min(n, max_frames)
    n = min(n, t.size)
    return np.unique(np.searchsorted(t, np.linspace(t[0], t[-1], n) - 1e-12 * max(1.0, abs(t[-1]))))


def check_matches(result, case, what: str = "result") -> None:
    """Refuse a Result without link shapes, or one that does not fit ``case`` (None: no case):
    InputError naming ``what``."""
    if result.link_shapes is None:
        raise InputError(
            what, result.meta.get("method", "?"), "has no link shapes (run with shape_points ≥ 2)"
        )
    if case is None:
        return
    n = case.model.n_links
    if result.link_shapes.shape[1] != n:
        raise InputError(what, f"{result.link_shapes.shape[1]} links", f"does not match the case ({n} links)")
    lengths = np.array([lk.beam.length for lk in case.model.links])
    seg = np.linalg.norm(np.diff(result.link_shapes[0], axis=1), axis=-1).sum(axis=-1)
    if np.any(np.abs(seg - lengths) > 0.05 * lengths):
        raise InputError(
            what,
            "link lengths " + ", ".join(f"{v:.4g}" for v in seg),
            "do not match the case's " + ", ".join(f"{v:.4g}" for v in lengths) + " m",
        )


def _limits(arrays, pad: float = 0.08):
    """Equal-span axis limits ((lo, hi) per coordinate) holding every point of ``arrays``
    (..., d), d = 2 or 3."""
    d = arrays[0].shape[-1]
    pts = np.concatenate([a.reshape(-1, d) for a in arrays])
    pts = pts[np.isfinite(pts).all(axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = max(float((hi - lo).max()), 1e-3)
    c = 0.5 * (lo + hi)
    half = 0.5 * span * (1 + 2 * pad)
    return tuple((c[i] - half, c[i] + half) for i in range(d))


def _style(name: str, index: int, styles):
    """(label, colour, line style) of a method: from ``styles`` when it names it, else the name
    and a colour of the default cycle."""
    if styles and name in styles:
        return tuple(styles[name])
    return name, f"C{index % 10}", "-"


def arm_animation(
    results,
    case=None,
    *,
    exaggerate: float = 1.0,
    fps: float = 20.0,
    speed: float = 1.0,
    max_frames: int | None = 200,
    title: str = "",
    figsize=(5.0, 5.0),
    dpi: int = 80,
    styles: dict | None = None,
):
    """The arm moving, one or more methods overlaid.

    Parameters
    ----------
    results : dict {method name: Result} (or one Result), all on the same output grid, each
        with ``link_shapes`` (nt, n, p, 2) m (drawn in the plane) or (nt, n, p, 3) m (a spatial
        arm, drawn in 3-D)
    case : dttmm.Case, dttmm.spatial.SpatialCase or None
        Draws the hubs (squares at the link roots) and payloads (filled circles at the tips)
        of the case; checked against every Result (:func:`check_matches`).
    exaggerate : factor X on the bending (see the module docstring), stated on every frame
    fps, speed, max_frames : frames per second of video, video speed relative to real time,
        most frames (see :func:`frame_indices`)
    styles : {method name: (label, colour, line style)} for the legend and the curves (the
        harness passes its method registry's, ``experiments.methods.label``/``style``); a name
        not in it is drawn under its own name in a colour of the default cycle

    Returns
    -------
    Animation (its figure is ``.fig``; :func:`save` closes it)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    if not isinstance(results, dict):
        results = {results.meta.get("method", "result"): results}
    if not isinstance(exaggerate, (int, float)) or isinstance(exaggerate, bool) or not exaggerate > 0:
        raise InputError("exaggerate", exaggerate, "must be a positive number")
    for name, r in results.items():
        check_matches(r, case, f"result of {name}")
    first = next(iter(results.values()))
    t = first.t
    for name, r in results.items():
        if r.t.shape != t.shape or np.abs(r.t - t).max() > 1e-9:
            raise InputError(f"result of {name}", f"{r.t.size} samples", "is not on the first result's grid")
    idx = frame_indices(t, fps, speed, max_frames)
    drawn = {name: exaggerated(r.link_shapes, exaggerate) for name, r in results.items()}
    dims = {r.link_shapes.shape[-1] for r in results.values()}
    if len(dims) > 1:
        raise InputError("results", sorted(dims), "mix planar and spatial link shapes")
    if dims == {3}:
        return _arm_animation_3d(results, drawn, case, t, idx, exaggerate, fps, title, figsize, dpi, styles)
    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.subplots()
    xl, yl = _limits([d[idx] for d in drawn.values()])
    ax.set_xlim(*xl)
    ax.set_ylim(*yl)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.25)
    ax.plot([0], [0], marker="^", color="0.3", ms=10, ls="none")  # the base
    return _moving_arms(fig, ax, results, drawn, case, t, idx, exaggerate, fps, title, styles)


def _bodies(case):
    """(links with a hub, links with a payload) of ``case`` (both empty without one)."""
    if case is None:
        return [], []
    links = case.model.links
    hubs = [i for i, lk in enumerate(links) if lk.hub_mass + float(np.sum(np.abs(lk.hub_inertia))) > 0]
    return hubs, [i for i, lk in enumerate(links) if lk.payload is not None]


def _arm_animation_3d(results, drawn, case, t, idx, exaggerate, fps, title, figsize, dpi, styles):
    """:func:`arm_animation` of spatial link shapes (nt, n, p, 3): the same artists in mplot3d
    axes whose limits (a cube: equal aspect) hold the whole drawn motion."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(projection="3d")
    first = next(iter(drawn.values()))
    lims = _limits([d[idx] for d in drawn.values()] + [first[:1, :1, :1]])
    for setter, lim in zip((ax.set_xlim, ax.set_ylim, ax.set_zlim), lims):
        setter(*lim)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    ax.locator_params(nbins=5)
    ax.tick_params(labelsize=7)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_zlabel("z [m]")
    base = first[0, 0, 0]
    ax.plot([base[0]], [base[1]], [base[2]], marker="^", color="0.3", ms=10, ls="none")  # the base
    return _moving_arms(fig, ax, results, drawn, case, t, idx, exaggerate, fps, title, styles, spatial=True)


def _moving_arms(fig, ax, results, drawn, case, t, idx, exaggerate, fps, title, styles, spatial=False):
    """The :class:`Animation` of the arms ``drawn`` (link shapes per method) in ``ax`` (planar,
    or mplot3d axes for ``spatial`` shapes): per method its links, joints, hubs and payloads
    and the end effector's trace, a clock, the scale of the bending, the legend and the title."""
    nil = ([], [], []) if spatial else ([], [])
    hubs, pays = _bodies(case)
    artists = []
    for j, (name, r) in enumerate(results.items()):
        lab, color, ls = _style(name, j, styles)
        n = r.link_shapes.shape[1]
        links = [
            ax.plot(*nil, color=color, ls=ls, lw=2.2, label=lab if i == 0 else None)[0] for i in range(n)
        ]
        joints = ax.plot(*nil, "o", color=color, mfc="white", ms=5, ls="none")[0]
        hub = ax.plot(*nil, "s", color=color, mfc="none", ms=9, ls="none")[0]
        pay = ax.plot(*nil, "o", color=color, ms=8, ls="none")[0]
        trace = ax.plot(*nil, color=color, lw=0.8, alpha=0.6)[0]
        artists.append((drawn[name], r.end_effector, links, joints, hub, pay, trace))
    text = ax.text2D if spatial else ax.text
    clock = text(0.02, 0.97, "", transform=ax.transAxes, va="top", family="monospace")
    scale = f"bending ×{exaggerate:g}" if exaggerate != 1 else "true scale"
    text(0.98, 0.97, scale, transform=ax.transAxes, va="top", ha="right")
    ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    if title:
        ax.set_title(title, fontsize=10)
    if not spatial:
        fig.tight_layout()

    def put(artist, pts):
        if spatial:
            artist.set_data_3d(pts[:, 0], pts[:, 1], pts[:, 2])
        else:
            artist.set_data(pts[:, 0], pts[:, 1])

    def draw(f):
        s = idx[f]
        out = [clock]
        clock.set_text(f"t = {t[s]:.3f} s")
        for shp, ee, links, joints, hub, pay, trace in artists:
            for i, ln in enumerate(links):
                put(ln, shp[s, i])
            roots = shp[s, :, 0]
            put(joints, roots)
            put(hub, roots[hubs])
            put(pay, shp[s, :, -1][pays])
            put(trace, ee[: s + 1])
            out += [*links, joints, hub, pay, trace]
        return out

    return Animation(fig, draw, t[idx], fps)


def mode_animation(modes, case, which=None, *, frames: int = 24, fps: float = 12.0, points: int = 17, dpi=80):
    """Mode shapes oscillating, linearised: r(x, τ) = r₀(x) + a sin(2πτ) (∂r/∂q) φ over one period
    τ ∈ [0, 1), one panel per mode, a scaled so that the largest displacement is 8 % of the
    arm's reach; the dashed line is the arm at the linearisation point.

    Parameters
    ----------
    modes : dttmm.Modes (from :func:`dttmm.modes`)
    case : the case the modes belong to
    which : mode indices (0-based) to draw; default the first four elastic ones

    Returns
    -------
    Animation
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from .shapes import element_shapes
    from .structure import build_structure

    lin = modes.linearization
    st = build_structure(case, lin.elements_per_link, lin.strain)
    if which is None:
        which = [i for i, f in enumerate(modes.frequencies) if f > 0][:4]
    if not which:
        raise InputError("modes", "none", "has no elastic mode to animate")
    reach = sum(lk.beam.length for lk in case.model.links)
    tau = np.arange(frames) / frames
    ref = element_shapes(st, lin.q[None], points)[0]
    curves = []
    for i in which:
        phi = np.zeros(st.n_dof)
        phi[lin.free] = modes.shapes[:, i]
        eps = 1e-7 / max(np.abs(phi).max(), 1e-300)
        unit = (element_shapes(st, (lin.q + eps * phi)[None], points)[0] - ref) / eps  # ∂r/∂q φ
        a = 0.08 * reach / max(np.abs(unit).max(), 1e-300)
        curves.append(ref + a * np.sin(2 * np.pi * tau)[:, None, None, None] * unit)
    ncol = min(len(which), 2)
    nrow = -(-len(which) // ncol)
    fig = Figure(figsize=(3.6 * ncol, 3.2 * nrow), dpi=dpi)
    FigureCanvasAgg(fig)
    axes = fig.subplots(nrow, ncol, squeeze=False)
    lines = []
    for ax, i, c in zip(axes.flat, which, curves):
        xl, yl = _limits([c])
        ax.set_xlim(*xl)
        ax.set_ylim(*yl)
        ax.set_aspect("equal")
        ax.grid(alpha=0.25)
        ax.set_title(f"mode {i + 1}: {modes.frequencies[i]:.4g} Hz", fontsize=9)
        for lk in ref:
            ax.plot(lk[:, 0], lk[:, 1], color="0.7", lw=1, ls="--")
        lines.append([ax.plot([], [], color="C0", lw=2, marker=".", ms=3)[0] for _ in range(st.n_links)])
    for ax in list(axes.flat)[len(which) :]:
        ax.set_visible(False)
    fig.suptitle(f"{case.name or 'case'}: mode shapes (DT-TMM, k = {lin.elements_per_link})", fontsize=10)
    fig.tight_layout()

    def draw(f):
        out = []
        for c, lns in zip(curves, lines):
            for j, ln in enumerate(lns):
                ln.set_data(c[f, j, :, 0], c[f, j, :, 1])
                out.append(ln)
        return out

    return Animation(fig, draw, tau, fps)  # frame times: fractions of the period


def save(anim: Animation, path, fps: float | None = None, progress: bool = False) -> Path:
    """Write ``anim`` to ``path`` (.mp4, .gif or .html).

    .mp4: H.264 through imageio-ffmpeg's ffmpeg; without it the animation is written as a GIF
    next to ``path`` (same name, .gif) and that path is returned. .gif: pillow. .html: one page
    with the video embedded (an animated GIF without ffmpeg). ``progress`` shows a tqdm bar over
    the frames (on stderr). Returns the path written.
    """
    path = Path(path)
    if path.suffix not in FORMATS:
        raise InputError("--out", str(path), f"must end in one of {', '.join(FORMATS)}")
    fps = float(fps or anim.fps)
    video = ffmpeg_path() is not None
    frames = anim.frames()
    if progress:
        from tqdm import tqdm

        frames = tqdm(frames, total=len(anim), desc="frames")
    if path.suffix == ".mp4" and not video:
        path = path.with_suffix(".gif")
    if path.suffix == ".mp4":
        _write_mp4(frames, path, fps)
    elif path.suffix == ".gif":
        _write_gif(frames, path, fps)
    else:
        import base64
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            media = Path(tmp) / ("a.mp4" if video else "a.gif")
            (_write_mp4 if video else _write_gif)(frames, media, fps)
            data = base64.b64encode(media.read_bytes()).decode()
        tag = (
            f"<video controls autoplay loop muted playsinline src='data:video/mp4;base64,{data}'></video>"
            if video
            else f"<img alt='animation' src='data:image/gif;base64,{data}'>"
        )
        path.write_text(
            f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'></head><body>{tag}</body></html>\n"
        )
    return path


def _write_mp4(frames, path: Path, fps: float) -> None:
    import imageio_ffmpeg

    writer = None
    for f in frames:
        if writer is None:
            h, w = f.shape[:2]
            writer = imageio_ffmpeg.write_frames(
                str(path), (w, h), fps=fps, codec="libx264", pix_fmt_out="yuv420p", macro_block_size=2
            )
            writer.send(None)
        writer.send(np.ascontiguousarray(f).tobytes())
    if writer is not None:
        writer.close()


def _write_gif(frames, path: Path, fps: float) -> None:
    from PIL import Image

    imgs = [Image.fromarray(f) for f in frames]
    imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=round(1000.0 / fps), loop=0)


def save_frame(anim: Animation, index: int, path) -> Path:
    """Frame ``index`` of ``anim`` as a PNG (the figure stays open)."""
    from PIL import Image

    Image.fromarray(anim.frame(index)).save(path)
    return Path(path)
