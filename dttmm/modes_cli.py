"""``dttmm modes CASE -k K [--n N] [--t T] [--out DIR]``: natural frequencies and mode shapes.

Prints the frequencies (Hz), writes ``<case>_modes.csv`` (frequency and damping ratio of each
mode), ``<case>_shapes.csv`` (M-normalised shapes over the free coordinates),
``<case>_deflections.csv`` (transverse node deflections of each link per mode) and
``<case>_modes.png`` (the first elastic modes' deflections along the arm) and, with
``--animate``, ``<case>_modes.mp4`` (the first elastic modes oscillating; a GIF without ffmpeg).
Motion-driven joints are held, torque-driven joints free. A spatial case (``kind =
"spatial"``) is linearised by :mod:`dttmm.spatial.linear`, at rest or, with ``--equilibrium``,
about its static equilibrium; its deflections CSV has a ``component`` column (y, z, twist).
Exit codes are those of :mod:`dttmm.cli`.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from .casefiles import load_case
from .cliparse import (
    EXIT_FAILED,
    EXIT_OK,
    OneLineParser,
    add_option,
    bad_input,
    number,
    pyplot,
    save_figure,
)
from .errors import InputError

__all__ = ["modes_parser", "run_modes"]

N_PLOT = 4  # elastic modes drawn in the PNG


def modes_parser() -> OneLineParser:
    p = OneLineParser(
        prog="dttmm modes",
        description="Natural frequencies and mode shapes of a case, linearised by DT-TMM "
        "(motion-driven joints held, torque-driven joints free).",
    )
    p.add_argument("case", help="case TOML file (format: docs/cases.md)")
    add_option(p, "elements", required=True)
    p.add_argument("--n", type=int, default=6, help="number of lowest modes (default 6)")
    p.add_argument("--t", type=number, default=0.0, help="time of the drives' laws (s, default 0)")
    add_option(p, "strain")
    p.add_argument(
        "--equilibrium",
        action="store_true",
        help="spatial arms: linearise about the static equilibrium under gravity and loads (default: rest)",
    )
    add_option(p, "out", default="out/modes")
    p.add_argument(
        "--animate", action="store_true", help="also write the first elastic modes oscillating (.mp4 or .gif)"
    )
    return p


def _table(m) -> str:
    has_z = m.damping_ratios is not None
    lines = ["mode  frequency [Hz]" + ("  damping ratio" if has_z else "")]
    for i, f in enumerate(m.frequencies):
        row = f"{i + 1:4d}  {f:14.6g}"
        if has_z:
            row += f"  {m.damping_ratios[i]:13.6g}"
        lines.append(row)
    return "\n".join(lines)


def _write_csv(m, name: str, out: Path) -> list[Path]:
    import pandas as pd

    nm = m.frequencies.size
    cols = [f"mode_{i + 1}" for i in range(nm)]
    freq = pd.DataFrame(
        {"mode": np.arange(1, nm + 1), "frequency_hz": m.frequencies, "omega2": m.eigenvalues}
    )
    if m.damping_ratios is not None:
        freq["damping_ratio"] = m.damping_ratios
    shapes = pd.DataFrame(m.shapes, columns=cols)
    shapes.insert(0, "coordinate", list(m.linearization.coordinates))
    rows = []
    for i, (s, w) in enumerate(zip(m.s, m.deflections)):
        if m.twists is None:
            parts = [(None, w)]
        else:  # spatial: the offsets along the link frame's y and z, and the twist
            parts = [("y", w[..., 0]), ("z", w[..., 1]), ("twist", m.twists[i])]
        for comp, v in parts:
            df = pd.DataFrame(v.T, columns=cols)
            df.insert(0, "s_m", s)
            if comp is not None:
                df.insert(0, "component", comp)
            df.insert(0, "link", i + 1)
            rows.append(df)
    paths = [out / f"{name}_modes.csv", out / f"{name}_shapes.csv", out / f"{name}_deflections.csv"]
    for df, p in zip((freq, shapes, pd.concat(rows, ignore_index=True)), paths):
        df.to_csv(p, index=False)
    return paths


def _curves(m, i):
    """Per link, the (values, line style) drawn for mode i."""
    if m.twists is None:
        return [[(d[i], "-")] for d in m.deflections]
    return [[(d[i, :, 0], "-"), (d[i, :, 1], "--"), (tw[i], ":")] for d, tw in zip(m.deflections, m.twists)]


def plot_modes(m, path: Path, title: str = "") -> Path:
    """PNG of the first elastic modes: transverse deflection (each mode scaled to a peak of 1)
    against the arc length along the arm, links one after the other (spatial arms: the offsets
    along the link frame's y (solid) and z (dashed) and the twist in rad (dotted), scaled
    together)."""
    plt = pyplot()
    offsets = np.concatenate(([0.0], np.cumsum([s[-1] for s in m.s])))
    fig, ax = plt.subplots(figsize=(7, 4))
    elastic = [i for i in range(m.frequencies.size) if m.frequencies[i] > 0][:N_PLOT]
    for c, i in enumerate(elastic):
        curves = _curves(m, i)
        peak = max(np.abs(v).max() for per_link in curves for v, _ in per_link) or 1.0
        for j, (s, o, per_link) in enumerate(zip(m.s, offsets, curves)):
            for v, ls in per_link:
                label = f"mode {i + 1}: {m.frequencies[i]:.4g} Hz" if j == 0 and ls == "-" else None
                ax.plot(s + o, v / peak, marker=".", ls=ls, color=f"C{c}", label=label)
    for o in offsets[1:-1]:
        ax.axvline(o, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("arc length along the arm [m]")
    ax.set_ylabel("deflection in the link's root frame [-]")
    return save_figure(fig, [ax], path, title)


def run_modes(a) -> int:
    """Run ``dttmm modes`` for the parsed arguments ``a``; return the exit code."""
    from .linear import _spatial, modes
    from .simulate_cli import prepare_out

    try:
        if a.n < 1:
            raise InputError("--n", a.n, "must be an integer ≥ 1")
        case = load_case(a.case)  # the input is accepted before anything is written
        spatial = _spatial(case)
        if a.equilibrium and not spatial:
            raise InputError("--equilibrium", True, "is for spatial arms (a planar arm linearises at rest)")
        if getattr(a, "animate", False) and spatial:
            raise InputError("--animate", True, "mode animations are drawn for planar arms only")
        out = prepare_out(a.out)
        m = modes(case, a.elements, a.t, "equilibrium" if a.equilibrium else None, n=a.n, strain=a.strain)
    except InputError as exc:
        return bad_input(exc)
    except np.linalg.LinAlgError as exc:
        print(f"dttmm: modes failed: singular system at t = {a.t:g} s ({exc})", file=sys.stderr)
        return EXIT_FAILED
    name = case.name or "case"
    print(_table(m))
    for w in m.warnings:
        print(f"warning: {w}", file=sys.stderr)
    paths = _write_csv(m, name, out)
    paths.append(plot_modes(m, out / f"{name}_modes.png", f"{name}: DT-TMM modes, k = {a.elements}"))
    if getattr(a, "animate", False):
        from .animate import mode_animation, save

        try:
            paths.append(save(mode_animation(m, case), out / f"{name}_modes.mp4"))
        except InputError as exc:
            return bad_input(exc)
    print(f"wrote {', '.join(str(p) for p in paths)}")
    return EXIT_OK
