"""Animations of the arm from :attr:`dttmm.Result.link_shapes` (drawing only; nothing here runs
a solver, and the solver never imports this module).

:func:`arm_animation` draws one or more Results of the same case overlaid: every link as its
deflected centre line, the joints, the hubs and payloads of the case, the end-effector trace, a
clock and the exaggeration factor. :func:`mode_animation` draws mode shapes oscillating.
:func:`save` writes either as .mp4 (ffmpeg from imageio-ffmpeg), .gif (pillow) or .html.

Exaggeration: the drawn point at arc length x of a link is c(x) + X·(r(x) − c(x)), c the
chord from the link's root to its tip, X the factor; roots, tips and the trace are drawn at
their true positions, so only the bending between joints is magnified.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = [
    "FORMATS",
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
    """The ffmpeg executable: imageio-ffmpeg's when installed, else one on PATH, else None."""
    try:
        import imageio_ffmpeg

        return imageio_ffmpeg.get_ffmpeg_exe()
    except (ImportError, RuntimeError):
        return shutil.which("ffmpeg")


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
    pts = np.concatenate([a.reshape(-1, 2) for a in arrays])
    pts = pts[np.isfinite(pts).all(axis=1)]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = max(float((hi - lo).max()), 1e-3)
    c = 0.5 * (lo + hi)
    half = 0.5 * span * (1 + 2 * pad)
    return (c[0] - half, c[0] + half), (c[1] - half, c[1] + half)


def _style(name: str, index: int):
    """(label, colour, line style) of a method from the registry when it is importable."""
    try:
        from experiments.methods import label, style

        st = style(name, index)
        return label(name), st.color, st.linestyle
    except ImportError:
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
):
    """The arm moving, one or more methods overlaid.

    Parameters
    ----------
    results : dict {method name: Result} (or one Result), all on the same output grid, each
        with ``link_shapes`` (nt, n, p, 2) m
    case : dttmm.Case or None
        Draws the hubs (squares at the link roots) and payloads (filled circles at the tips)
        of the case; checked against every Result (:func:`check_matches`).
    exaggerate : factor X on the bending (see the module docstring), stated on every frame
    fps, speed, max_frames : frames per second of video, video speed relative to real time,
        most frames (see :func:`frame_indices`)

    Returns
    -------
    matplotlib.animation.FuncAnimation (its figure is ``.fig``; close it when done)
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

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
    fig, ax = plt.subplots(figsize=figsize, dpi=dpi)
    xl, yl = _limits([d[idx] for d in drawn.values()])
    ax.set_xlim(*xl)
    ax.set_ylim(*yl)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(alpha=0.25)
    ax.plot([0], [0], marker="^", color="0.3", ms=10, ls="none")  # the base
    hubs = (
        []
        if case is None
        else [i for i, lk in enumerate(case.model.links) if lk.hub_mass + lk.hub_inertia > 0]
    )
    pays = [] if case is None else [i for i, lk in enumerate(case.model.links) if lk.payload is not None]
    artists = []
    for j, (name, r) in enumerate(results.items()):
        lab, color, ls = _style(name, j)
        n = r.link_shapes.shape[1]
        links = [
            ax.plot([], [], color=color, ls=ls, lw=2.2, label=lab if i == 0 else None)[0] for i in range(n)
        ]
        joints = ax.plot([], [], "o", color=color, mfc="white", ms=5, ls="none")[0]
        hub = ax.plot([], [], "s", color=color, mfc="none", ms=9, ls="none")[0]
        pay = ax.plot([], [], "o", color=color, ms=8, ls="none")[0]
        trace = ax.plot([], [], color=color, lw=0.8, alpha=0.6)[0]
        artists.append((drawn[name], r.end_effector, links, joints, hub, pay, trace))
    clock = ax.text(0.02, 0.97, "", transform=ax.transAxes, va="top", family="monospace")
    ax.text(
        0.98,
        0.97,
        f"bending ×{exaggerate:g}" if exaggerate != 1 else "true scale",
        transform=ax.transAxes,
        va="top",
        ha="right",
    )
    ax.legend(loc="lower left", fontsize=7, framealpha=0.8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()

    def draw(f):
        s = idx[f]
        out = [clock]
        clock.set_text(f"t = {t[s]:.3f} s")
        for shp, ee, links, joints, hub, pay, trace in artists:
            for i, ln in enumerate(links):
                ln.set_data(shp[s, i, :, 0], shp[s, i, :, 1])
            roots = shp[s, :, 0]
            joints.set_data(roots[:, 0], roots[:, 1])
            hub.set_data(roots[hubs, 0], roots[hubs, 1])
            tips = shp[s, :, -1]
            pay.set_data(tips[pays, 0], tips[pays, 1])
            trace.set_data(ee[: s + 1, 0], ee[: s + 1, 1])
            out += [*links, joints, hub, pay, trace]
        return out

    anim = FuncAnimation(fig, draw, frames=len(idx), interval=1000.0 / fps, blit=False)
    anim.fig, anim.draw_frame, anim.fps = fig, draw, fps
    anim.frame_times = t[idx]
    return anim


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
    matplotlib.animation.FuncAnimation
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation

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
    fig, axes = plt.subplots(nrow, ncol, figsize=(3.6 * ncol, 3.2 * nrow), dpi=dpi, squeeze=False)
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

    anim = FuncAnimation(fig, draw, frames=frames, interval=1000.0 / fps, blit=False)
    anim.fig, anim.draw_frame, anim.fps = fig, draw, fps
    anim.frame_times = tau  # fractions of the period
    return anim


def save(anim, path, fps: float | None = None, progress: bool = False) -> Path:
    """Write ``anim`` to ``path`` (.mp4, .gif or .html) and close its figure.

    .mp4 needs ffmpeg (:func:`ffmpeg_path`); without it the animation is written as a GIF
    next to ``path`` (same name, .gif) and that path is returned. .html embeds an HTML5 video
    (with ffmpeg) or matplotlib's JavaScript player (without). ``progress`` shows a tqdm bar
    over the frames (on stderr).
    """
    import matplotlib
    import matplotlib.pyplot as plt
    from matplotlib.animation import FFMpegWriter, PillowWriter

    path = Path(path)
    if path.suffix not in FORMATS:
        raise InputError("--out", str(path), f"must end in one of {', '.join(FORMATS)}")
    fps = fps or anim.fps
    ff = ffmpeg_path()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(anim.frame_times) if hasattr(anim, "frame_times") else None, desc="frames")
    tick = (lambda i, n: bar.update(1)) if bar is not None else None
    try:
        if path.suffix == ".mp4" and ff is None:
            path = path.with_suffix(".gif")
        if path.suffix == ".mp4":
            matplotlib.rcParams["animation.ffmpeg_path"] = ff
            anim.save(
                path,
                writer=FFMpegWriter(fps=fps, codec="libx264", extra_args=["-pix_fmt", "yuv420p"]),
                progress_callback=tick,
            )
        elif path.suffix == ".gif":
            anim.save(path, writer=PillowWriter(fps=fps), progress_callback=tick)
        else:
            if ff is not None:
                matplotlib.rcParams["animation.ffmpeg_path"] = ff
                body = anim.to_html5_video()
            else:
                body = anim.to_jshtml(fps=fps)
            path.write_text(
                f"<!DOCTYPE html>\n<html><head><meta charset='utf-8'></head><body>{body}</body></html>\n"
            )
    finally:
        if bar is not None:
            bar.close()
        plt.close(anim.fig)
    return path


def save_frame(anim, index: int, path) -> Path:
    """Draw frame ``index`` of ``anim`` and save it as a PNG (the figure stays open)."""
    anim.draw_frame(index)
    anim.fig.savefig(path)
    return Path(path)
