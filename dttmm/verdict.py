"""The verdict of a finished DT-TMM run, one rule for both kernels (docs/kernel.md "Status"):
the energy check of a torque-free stretch and the status with its warnings from the run's
counters in ``meta``."""

from __future__ import annotations

import numpy as np

__all__ = ["ENERGY_GROWTH", "ILL_CONDITIONED", "energy_growth", "energy_scale", "verdict"]

#: energy growth with no input, relative to the run's energy scale, that fails the energy check
#: (converged runs of the shipped cases stay below 1e-5)
ENERGY_GROWTH = 1e-3

#: equilibrated condition number of the plain sweep's final system above which a run is
#: "ill-conditioned": κ·ε > 1e-8, half the digits of a double lost in the last solve alone
ILL_CONDITIONED = 1e8


def energy_scale(mgl: float, t, energy, torque, rate) -> float:
    """Energy scale (J) of a run: the largest of the energy's range, the work of the joint
    torques ∫ Σ|τ α̇| dt (trapezoid on the output grid) and ``mgl`` = m |g| L (total mass,
    gravity, summed link lengths)."""
    p = np.sum(np.abs(torque * rate), axis=1)
    work = float(np.sum(0.5 * (p[1:] + p[:-1]) * np.diff(t))) if t.size > 1 else 0.0
    rng = float(np.nanmax(energy) - np.nanmin(energy)) if energy.size else 0.0
    return max(rng, work, mgl)


def energy_growth(mgl: float, t, energy, torque, rate) -> tuple[float, float | None]:
    """Energy check of a torque-driven run: wherever every joint torque is zero on a stretch of
    output samples, damping can only remove energy, so the total energy must not grow there.
    Returns the largest growth relative to :func:`energy_scale` and its time (0, None: none)."""
    free = np.all(torque == 0.0, axis=1)
    scale = energy_scale(mgl, t, energy, torque, rate)
    idx = np.flatnonzero(free)
    if idx.size < 2 or scale <= 0.0:
        return 0.0, None
    # stretches of consecutive free samples; growth from each stretch's first sample
    starts = idx[np.concatenate(([True], np.diff(idx) > 1))]
    first = starts[np.searchsorted(starts, idx, side="right") - 1]
    growth = (energy[idx] - energy[first]) / scale
    growth[~np.isfinite(growth)] = 0.0
    i = int(np.argmax(growth))
    return (float(growth[i]), float(t[idx[i]])) if growth[i] > 0.0 else (0.0, None)


def verdict(meta: dict, *, iterations, tol: float, max_iterations: int, n_steps: int):
    """(status, warnings) of a finished run: "ill-conditioned" when the plain sweep's largest
    final-system condition number (``meta["final_system_cond"]``) exceeds
    :data:`ILL_CONDITIONED`; "unconverged" when a tolerance-driven step used all
    ``max_iterations`` sweeps (``meta["unconverged_steps"]``), when a forward-dynamics solve with
    closed-loop laws did (``meta["unconverged_solves"]``), when the residual check of a fixed
    sweep count or "auto" flagged a step (``meta["residual_*"]``), or when the energy grew with
    no input (``meta["energy_growth"]``) in a run with ``iterations`` set; else "ok"."""
    stopped = f"stopped after max_iterations = {max_iterations} sweeps before reaching tol = {tol:g}"
    warns = []
    if n_unconv := meta.get("unconverged_steps", 0):
        warns.append(f"{n_unconv} of {n_steps} steps {stopped}")
    if n_fd := meta.get("unconverged_solves", 0):
        warns.append(
            f"{n_fd} forward-dynamics solves with closed-loop laws (t = 0, restarts, RK4 stages) {stopped}"
        )
    if n_flag := meta.get("residual_flagged", 0):
        warns.append(
            f"iterations={iterations!r}: the step equations are not solved to the time-discretisation "
            f"error in {n_flag} of {meta['residual_checks']} checked steps (first at t = "
            f"{meta['residual_first_t']:.6g} s; worst at t = {meta['residual_worst_t']:.6g} s: one more "
            f"sweep would change q̈ by {meta['residual_worst']:.3g} relative, "
            f"{meta['residual_worst_ratio']:.3g} × the truncation error)"
        )
    status = "unconverged" if warns else "ok"
    growth = meta.get("energy_growth", 0.0)
    if growth > ENERGY_GROWTH:
        if iterations is not None:
            status = "unconverged"
        warns.append(
            f"the energy grew with no input: by {growth:.3g} × the run's energy scale (> {ENERGY_GROWTH:g}) "
            f"by t = {meta['energy_growth_t']:.6g} s"
            + (
                f"; iterations={iterations!r} does not solve the step equations well enough"
                if iterations is not None
                else ""
            )
        )
    cond = meta.get("final_system_cond", 0.0)
    if cond > ILL_CONDITIONED:
        status = "ill-conditioned"
        warns.append(
            f"plain sweep: final-system condition number up to {cond:.3g} (> {ILL_CONDITIONED:g}); "
            "use sweep='riccati'"
        )
    return status, warns
