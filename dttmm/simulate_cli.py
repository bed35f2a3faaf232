"""``dttmm simulate CASE --elements K --h H --out DIR``: run DT-TMM, write the table and a plot.

Exit codes are those of :mod:`dttmm.cli`.
"""

from __future__ import annotations

import json
import sys
import tempfile
from pathlib import Path

from .api import simulate
from .casefiles import load_case
from .cliparse import EXIT_FAILED, EXIT_INPUT, EXIT_NOT_OK, EXIT_OK, bad_input, pyplot, save_figure  # noqa: F401
from .errors import InputError, SimulationError
from .resources import check_run_size

#: the options of ``dttmm simulate`` that are keywords of :func:`dttmm.simulate` by the same name
SOLVER_OPTIONS = ("integrator", "sweep", "iterations", "tol", "rho_inf", "strain", "engine")


def plot_result(res, path: Path, title: str = "") -> Path:
    """PNG with tip deflections (top) and joint angles (bottom) against time."""
    fig, (a1, a2) = pyplot().subplots(2, 1, figsize=(7, 5.5), sharex=True)
    defl = res.tip_deflection
    if defl.ndim == 3:  # a spatial arm: the deflections along the link frame's y and z
        for i in range(defl.shape[1]):
            for c, ax in enumerate("yz"):
                a1.plot(res.t, defl[:, i, c] * 1e3, label=f"link {i + 1}, {ax}")
    else:
        for i in range(res.n_joints):
            a1.plot(res.t, defl[:, i] * 1e3, label=f"link {i + 1}")
    for i in range(res.n_joints):
        a2.plot(res.t, res.joint_angle[:, i], label=f"joint {i + 1}")
    a1.set_ylabel("tip deflection [mm]")
    a2.set_ylabel("joint angle [rad]")
    a2.set_xlabel("t [s]")
    return save_figure(fig, [a1, a2], path, title)


def prepare_out(out) -> Path:
    """Create the output folder and prove it writable, before any computing.

    Raises InputError on ``--out`` when it cannot be created or written.
    """
    out = Path(out)
    try:
        out.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=out, prefix=".dttmm-write-test-"):
            pass
    except OSError as exc:
        raise InputError(
            "--out", str(out), f"cannot create or write the folder ({exc.strerror or exc})"
        ) from None
    return out


def _close_progress_bars():
    """End any progress bar a failed run left open, so that the next message has its own line."""
    try:
        from tqdm import tqdm
    except ImportError:
        return
    for bar in list(getattr(tqdm, "_instances", ())):
        bar.close()


def _own_line(message: str) -> None:
    """Print a message on stderr on a line of its own, even after a cleared progress bar
    (which leaves the cursor after a carriage return, not a newline)."""
    _close_progress_bars()
    print("\n" + message, file=sys.stderr)


def _write(res, case, a, out: Path) -> None:
    name = case.name or "case"
    df = res.to_frame()
    table = out / f"{name}.{a.format}"
    if a.format == "parquet":
        df.to_parquet(table)
    else:
        df.to_csv(table, index=False)
    meta = dict(res.meta)
    meta.update(wall_time=res.wall_time, n_steps=res.n_steps, case=str(a.case))
    (out / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    written = [str(table), str(out / "meta.json")]
    if res.t.size >= 2:
        png = plot_result(
            res, out / f"{name}.png", f"{case.name}: DT-TMM k = {a.elements}, h = {a.h:g} s ({a.integrator})"
        )
        written.insert(1, str(png))
    print(f"wrote {', '.join(written)}  (solve {res.wall_time:.3g} s, {res.n_steps} steps)")


def run_simulate(a) -> int:
    """Run ``dttmm simulate`` for the parsed arguments ``a``; return the exit code."""
    try:
        case = load_case(a.case)  # the input is accepted before anything is written
        check_run_size(case, a.elements, a.h, shape_points=getattr(a, "shape_points", 0))
        out = prepare_out(a.out)
        options = {k: getattr(a, k) for k in SOLVER_OPTIONS}
        options.update(shape_points=getattr(a, "shape_points", 0), kernel=getattr(a, "kernel", None))
        res = simulate(case, elements_per_link=a.elements, h=a.h, progress=True, **options)
    except InputError as exc:
        _close_progress_bars()
        return bad_input(exc)
    except SimulationError as exc:
        res = exc.partial
        msg = f"dttmm: simulation failed: {' '.join(str(exc).split())}"
        if res is None:
            _own_line(msg)
            return EXIT_FAILED
        t_last = res.t[-1] if res.t.size else 0.0
        _own_line(f"{msg}; writing the partial result up to t = {t_last:.6g} s")
        _write(res, case, a, out)
        return EXIT_FAILED
    _write(res, case, a, out)
    status = getattr(res, "status", "ok")
    print(f"status: {status}")
    for w in getattr(res, "warnings", ()):
        print(f"warning: {w}")
    if status == "ok":
        return EXIT_OK
    return EXIT_FAILED if status == "failed" else EXIT_NOT_OK
