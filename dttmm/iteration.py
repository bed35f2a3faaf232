"""The stop rule of every tolerance-driven iteration of the suite's step equations.

One plain Python function of scalars, so that the compiled code jits it (the DT-TMM kernel:
its step sweeps and the closed-loop forward dynamics; the compiled global solver) and the
uncompiled code calls it as it is (the numpy global solver): every solver stops its iteration
by the same rule.
"""

from __future__ import annotations

import math

__all__ = ["STAGNATION_FROM", "stop_rule"]

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
