"""The stop rule of every tolerance-driven iteration of the suite's step equations.

One plain Python function of scalars, so that the compiled code jits it (the DT-TMM kernel:
its step sweeps and the closed-loop forward dynamics; the compiled global solver) and the
uncompiled code calls it as it is (the numpy global solver): every solver stops its iteration
by the same rule.
"""

from __future__ import annotations

import math

__all__ = ["STAGNATION_FROM", "change_and_size", "residual_ratio", "stop_rule"]

#: the stagnation test applies from this iteration index on (the 4th solve or sweep)
STAGNATION_FROM = 3


def stop_rule(it, dx, prev_dx, xmax, tol):
    """Whether to stop after iteration ``it`` (0-based), and whether the iteration converged.

    dx = max|Δq̈| of this iteration, prev_dx that of the previous one (inf before the first
    comparison), xmax = max|q̈| of the new iterate, tol the relative tolerance. Converged when
    dx ≤ tol·max(1, xmax), or when from the 4th iteration on the change stagnates at the
    round-off floor (dx ≥ 0.9·prev_dx and dx ≤ 1e3·tol·max(1, xmax)); stop unconverged when dx
    is not finite. Returns (stop, converged)."""
    scale = max(1.0, xmax)
    if dx <= tol * scale:
        return True, True
    if it >= STAGNATION_FROM and dx >= 0.9 * prev_dx and dx <= 1e3 * tol * scale:
        return True, True  # stagnation at the round-off floor
    if not math.isfinite(dx):
        return True, False
    return False, False


def change_and_size(a, b, c):
    """(max|a − b|, max|c|) over equal-length arrays: an iteration's change (a, b: the new
    and the old iterate) and the size it is measured against."""
    d = 0.0
    size = 0.0
    for r in range(a.shape[0]):
        d = max(d, abs(a[r] - b[r]))
        size = max(size, abs(c[r]))
    return d, size


def residual_ratio(d, xmax, dq, d2q, tol, lte, gamma):
    """The residual check's ratio (docs/kernel.md, "Residual check"): the correction d =
    max|Δq̈| one more sweep would make over the Newmark truncation error in q and in q̇,
    max(d / (lte·Δq̈ + tol_q̈), γ d / (|γ − ½| Δq̈ + Δ²q̈/12 + γ tol_q̈)), tol_q̈ = tol·max(1,
    xmax), Δq̈ = ``dq``, Δ²q̈ = ``d2q``; it passes at ≤ 1."""
    floor = tol * max(1.0, xmax)
    return max(
        d / (lte * dq + floor),
        gamma * d / (abs(gamma - 0.5) * dq + d2q / 12.0 + gamma * floor),
    )
