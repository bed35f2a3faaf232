"""``dttmm animate``: watch the arm move.

``dttmm animate CASE [-k K] [--h H] [--method NAME[@H] ...] [--exaggerate X] [--out FILE]`` runs
the case (planar, or spatial: drawn in 3-D) with every method named (default: dttmm) and draws
them overlaid;
``dttmm animate RESULT.parquet [--case CASE]`` draws a stored Result (a table written by
``dttmm simulate --format parquet --shape-points P``). FILE ends in .mp4 (ffmpeg from
imageio-ffmpeg; a GIF beside it when ffmpeg is absent), .gif or .html. Exit codes are those of
:mod:`dttmm.cli`; a Result without link shapes, or one that does not match the case, is a
one-line error (exit 2).
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

from .casefiles import load_case
from .cliparse import EXIT_FAILED, EXIT_OK, OneLineParser, add_option, bad_input, number
from .errors import InputError, SimulationError

__all__ = ["animate_parser", "run_animate"]


def animate_parser() -> OneLineParser:
    p = OneLineParser(
        prog="dttmm animate",
        description="Animate a case (run by one or more methods, overlaid) or a stored Result.",
        epilog="Methods: the names of experiments.methods (dttmm, global, exudyn-ancf, exudyn-beam, "
        "mujoco-chain, pinocchio-rigid, ...); NAME@H runs that method with step H.",
    )
    p.add_argument("source", help="case TOML file, or a Result table (.parquet)")
    p.add_argument("--case", default=None, help="with a .parquet Result: its case (draws hubs, payloads)")
    add_option(p, "elements", default=8, help="elements per link (default 8)")
    add_option(p, "h", default=1e-3, help="time step (s, default 1e-3)")
    p.add_argument("--method", action="append", default=None, help="method to run (repeatable)")
    p.add_argument("--exaggerate", type=number, default=1.0, help="bending magnification (default 1)")
    p.add_argument("--points", type=int, default=17, help="shape points per link (default 17)")
    p.add_argument("--fps", type=number, default=20.0, help="frames per second (default 20)")
    p.add_argument("--speed", type=number, default=1.0, help="video time / real time (default 1)")
    p.add_argument("--max-frames", type=int, default=400, help="most frames (default 400)")
    p.add_argument(
        "--out", default=None, help="output file .mp4 | .gif | .html (default out/animate/CASE.mp4)"
    )
    return p


def _method_spec(text: str, h: float):
    name, _, step = text.partition("@")
    if not step:
        return name, h
    try:
        return name, float(step)
    except ValueError:
        raise InputError("--method", text, "must be NAME or NAME@H with H a step in s") from None


def _registry():
    """The harness's method registry (``experiments.methods``), imported only now: the solver
    package does not depend on the harness (as ``dttmm report``); None when it is absent."""
    try:
        return importlib.import_module("experiments.methods")
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.split(".")[0] == "experiments":
            return None
        raise


def styles(names) -> dict:
    """{name: (label, colour, line style)} from the registry, {} without it."""
    methods = _registry()
    if methods is None:
        return {}
    looks = {n: methods.style(n, i) for i, n in enumerate(names)}
    return {n: (methods.label(n), st.color, st.linestyle) for n, st in looks.items()}


def run_case(case, specs, k: int, points: int) -> dict:
    """{method: Result} of ``case`` for every (method, h) in ``specs``, with link shapes."""
    if [m for m, _ in specs] == ["dttmm"]:
        from .api import simulate

        return {
            "dttmm": simulate(case, elements_per_link=k, h=specs[0][1], shape_points=points, progress=None)
        }
    methods = _registry()
    if methods is None:
        raise InputError("--method", specs, "needs the experiments package (run from a checkout)")
    out = {}
    for name, h in specs:
        if name not in methods.names():
            raise InputError("--method", name, f"unknown (one of: {', '.join(methods.names())})")
        out[name] = methods.run(name, case, k, h, shape_points=points)
    return out


def _load_result(path: Path):
    import pandas as pd

    from .result import Result
    from .spatial.result import SpatialResult

    try:
        df = pd.read_parquet(path)
        return (SpatialResult if df.attrs.get("kind") == "spatial" else Result).from_frame(df)
    except (OSError, ValueError, KeyError) as exc:
        raise InputError("RESULT", str(path), f"is not a Result table ({type(exc).__name__})") from None


def run_animate(a) -> int:
    """Run ``dttmm animate`` for the parsed arguments ``a``; return the exit code."""
    from . import animate

    src = Path(a.source)
    try:
        if a.points < 2:
            raise InputError("--points", a.points, "must be an integer ≥ 2")
        if a.out is not None and Path(a.out).suffix not in animate.FORMATS:
            raise InputError("--out", a.out, f"must end in one of {', '.join(animate.FORMATS)}")
        if src.suffix == ".parquet":
            if a.method:
                raise InputError("--method", a.method, "applies to a case file, not to a stored Result")
            case = load_case(a.case) if a.case else None
            res = _load_result(src)
            results = {res.meta.get("method", "result"): res}
            name = case.name if case is not None and case.name else src.stem
        else:
            case = load_case(src)
            specs = [_method_spec(m, a.h) for m in (a.method or ["dttmm"])]
            results = run_case(case, specs, a.elements, a.points)
            name = case.name or src.stem
        k_text = "" if src.suffix == ".parquet" else f", k = {a.elements}"
        anim = animate.arm_animation(
            results,
            case,
            exaggerate=a.exaggerate,
            fps=a.fps,
            speed=a.speed,
            max_frames=a.max_frames,
            title=f"{name}{k_text}",
            styles=styles(list(results)),
        )
        out = Path(a.out) if a.out else Path("out/animate") / f"{name}.mp4"
        out.parent.mkdir(parents=True, exist_ok=True)
        written = animate.save(anim, out, progress=True)
    except InputError as exc:
        return bad_input(exc)
    except SimulationError as exc:
        print(f"dttmm: simulation failed: {' '.join(str(exc).split())}", file=sys.stderr)
        return EXIT_FAILED
    note = "" if written.suffix == out.suffix else " (no ffmpeg: wrote a GIF instead)"
    print(f"wrote {written}{note}")
    return EXIT_OK
