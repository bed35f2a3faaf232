"""What the drivers of both DT-TMM kernels (planar :mod:`dttmm.kernel.driver`, spatial
:mod:`dttmm.spatial.solver`) share around their compiled time loops: the run in chunks with a
progress bar, the run options the integrator and the iteration setting fix, and the residual
check's summary in the Result's meta.
"""

from __future__ import annotations

import time
from collections.abc import Callable

#: a run whose time, estimated after its first chunk, exceeds this many seconds shows a
#: progress bar (unless ``progress=False``)
PROGRESS_AFTER = 2.0
#: a run with a progress bar is split into this many calls of the kernel
PROGRESS_CHUNKS = 200

#: fixed sweep counts and "auto": the residual check (one extra sweep, not applied) runs at
#: the first step, every CHECK_EVERY-th step and the last step — ≤ 1/64 more sweeps
CHECK_EVERY = 64


def progress_bar(total: int, enabled: bool):
    """A tqdm bar of ``total`` steps on stderr, or None (not ``enabled``, or no tqdm)."""
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency, but the bar is optional
        return None
    return tqdm(total=total, unit="step", desc="dttmm", leave=False)


def run_chunked(
    run: Callable[[int, int], object],
    n_steps: int,
    progress: bool | None,
    steps_done: Callable[[object], int],
    failed: Callable[[object], bool],
    after: float = PROGRESS_AFTER,
):
    """Run the time loop ``run(first, stop)`` (steps first … stop − 1; it returns what
    ``steps_done`` and ``failed`` read): in one call if ``progress`` is False; else a first
    chunk of n_steps/PROGRESS_CHUNKS steps, timed; then, with a progress bar (``progress``
    True, or None and the estimated run time above ``after`` s) in chunks between bar
    updates, else the rest in one call. The chunks give the one call's run bit for bit.
    Returns what the last call of ``run`` returned (the bar, if any, closed)."""
    if progress is False:
        return run(0, n_steps)
    chunk = max(1, n_steps // PROGRESS_CHUNKS)
    t0 = time.perf_counter()
    out = run(0, min(chunk, n_steps))
    done = steps_done(out)
    if failed(out) or done >= n_steps:
        return out
    estimate = (time.perf_counter() - t0) * n_steps / max(done, 1)
    bar = progress_bar(n_steps, progress if progress is not None else estimate > after)
    if bar is None:
        return run(done, n_steps)
    bar.update(done)
    for a in range(done, n_steps, chunk):
        out = run(a, min(n_steps, a + chunk))
        bar.update(steps_done(out) - a)
        if failed(out):
            break
    bar.close()
    return out


def step_options(family, iterations, codes, rk4: dict) -> dict:
    """The fields of a kernel's ``loop.Options`` that the integrator and the ``iterations``
    setting fix: β, γ, α_m, α_f, lte = |β − 1/6|/β (the Newmark truncation error
    (β − 1/6)h²Δq̈ over βh²), the iteration mode (``codes``: the kernel's codes of "to the
    tolerance", "auto", "m + 1 sweeps") and sweep count, the residual-check period. ``family``
    None (RK4): the mode of ``iterations`` and no residual check, overridden by ``rk4``."""
    to_tol, auto, fixed = codes
    if iterations is None:
        mode, n_fixed = to_tol, 0  # the tolerance is the check: no residual check
    elif iterations == "auto":
        mode, n_fixed = auto, 0
    else:
        mode, n_fixed = fixed, int(iterations)
    if family is None:
        return {"iteration": mode, "n_fixed": n_fixed, "check_every": 0, **rk4}
    beta = family.beta
    return {
        "beta": float(beta),
        "gamma": float(family.gamma),
        "alpha_m": float(family.alpha_m),
        "alpha_f": float(family.alpha_f),
        "lte": float(abs(beta - 1.0 / 6.0) / beta),
        "iteration": mode,
        "n_fixed": n_fixed,
        "check_every": CHECK_EVERY if mode != to_tol else 0,
    }


def residual_meta(meta: dict, t_end, checks, flagged, first, worst, ratio, resid) -> None:
    """The residual checks' summary into ``meta``: their count, how many were flagged, the
    times of the first flagged and the worst step (None where none), the worst ratio and
    residual; nothing when no check ran."""
    if not checks:
        return
    t_of = lambda j: float(t_end[j]) if j >= 0 else None
    meta.update(
        residual_checks=int(checks),
        residual_flagged=int(flagged),
        residual_first_t=t_of(int(first)),
        residual_worst_t=t_of(int(worst)),
        residual_worst_ratio=float(ratio),
        residual_worst=float(resid),
    )
