"""Coefficients of the Newmark family on the minimal coordinates.

Generalised-α in the Arnold–Brüls form: the equations of motion hold at t_{n+1} for the true
accelerations q̈_{n+1}, and an auxiliary acceleration a drives the update

    (1 − α_m) a_{n+1} + α_m a_n = (1 − α_f) q̈_{n+1} + α_f q̈_n
    q_{n+1} = q_n + h q̇_n + h²(½ − β) a_n + βh² a_{n+1}
    q̇_{n+1} = q̇_n + h(1 − γ) a_n + γh a_{n+1}

so q_{n+1} = q̃ + c_q q̈_{n+1}, q̇_{n+1} = q̃' + c_v q̈_{n+1}: the same structure as Newmark
(α_m = α_f = 0), only with other predictors and coefficients. ρ∞ = 1 is the trapezoidal rule.
"""

from __future__ import annotations

from dataclasses import dataclass

from ._validate import finite
from .errors import InputError

__all__ = ["NewmarkFamily", "newmark_family"]


@dataclass(frozen=True)
class NewmarkFamily:
    beta: float
    gamma: float
    alpha_m: float = 0.0
    alpha_f: float = 0.0


def newmark_family(integrator: str, *, beta=None, gamma=None, rho_inf=None) -> NewmarkFamily:
    """Coefficients of "newmark" (β = ¼, γ = ½ unless given) or "generalized-alpha" (Chung–Hulbert
    from the spectral radius at infinity ``rho_inf``, default 0.9)."""
    if integrator == "newmark":
        b = 0.25 if beta is None else finite("beta", beta)
        g = 0.5 if gamma is None else finite("gamma", gamma)
        if not (0 < b <= 0.5) or not (0.5 <= g <= 1.0):
            raise InputError("beta/gamma", (b, g), "need 0 < β ≤ ½ and ½ ≤ γ ≤ 1")
        return NewmarkFamily(b, g)
    if integrator == "generalized-alpha":
        r = 0.9 if rho_inf is None else finite("rho_inf", rho_inf)
        if not 0.0 <= r <= 1.0:
            raise InputError("rho_inf", rho_inf, "must lie in [0, 1]")
        am = (2 * r - 1) / (r + 1)
        af = r / (r + 1)
        g = 0.5 + af - am
        return NewmarkFamily(0.25 * (g + 0.5) ** 2, g, am, af)
    raise InputError("integrator", integrator, "unknown (newmark, generalized-alpha, rk4)")
