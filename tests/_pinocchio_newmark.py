"""The rigid arm of :mod:`reference_models.pinocchio_rigid` stepped by Newmark (β = ¼, γ = ½,
Newton on the joint-space equations τ(q, q̇, q̈) = τ_applied with RNEA and its derivatives),
for the rigid-limit tests: the same step as DT-TMM's Newmark on the same rigid dynamics, so
the time-discretisation errors cancel and stiffened beams must agree to 1e-6 rad.

Open-loop drives only; it runs on the step schedule and Hermite output of
``pinocchio_rigid._simulate``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

from reference_models import pinocchio_rigid as pr

OPTIONS = {"beta": 0.25, "gamma": 0.5, "tol": 1e-12, "max_iter": 25}


def _residual(arm, t, tau_f, qf, vf, af, c_q, c_v):
    """Residual τ(q, v, q̈)_f − τ_f at t (motion laws: left limit) and its Jacobian in q̈_f
    for q_f = q_pred + c_q q̈_f, v_f = v_pred + c_v q̈_f."""
    q, v, a = arm.full(t, True, qf, vf, af)
    tau = pin.rnea(arm.model, arm.data, q, v, a)
    dq, dv, M = pin.computeRNEADerivatives(arm.model, arm.data, q, v, a)
    M = arm._sym(M)
    if arm.all_free:
        return tau - tau_f, M + c_q * dq + c_v * dv
    ff = arm.ff
    return tau[arm.f] - tau_f, M[ff] + c_q * dq[ff] + c_v * dv[ff]


def _newmark(arm, q, v, T, restart, opts, stats):
    """Node arrays (T, Q, V, A_right, A_left) of the Newmark steps on the schedule T."""
    beta, gamma, tol, max_iter = opts["beta"], opts["gamma"], opts["tol"], opts["max_iter"]
    N = T.size - 1
    Q, V = np.empty((N + 1, q.size)), np.empty((N + 1, q.size))
    Ar, Al = np.empty_like(Q), np.empty_like(Q)
    Q[0], V[0] = q, v
    a = arm.acc(T[0], False, q, v)
    Al[0] = a
    for k in range(N):
        t1 = T[k + 1]
        dt = t1 - T[k]
        Ar[k] = a
        qp = q + dt * v + dt * dt * (0.5 - beta) * a
        vp = v + dt * (1 - gamma) * a
        cq, cv = beta * dt * dt, gamma * dt
        an = a.copy()
        tau1 = arm.tau_f(t1, True)
        for _ in range(max_iter):
            r, J = _residual(arm, t1, tau1, qp + cq * an, vp + cv * an, an, cq, cv)
            da = np.linalg.solve(J, -r)
            an = an + da
            if not math.isfinite(float(an.sum())) or np.abs(da).max() <= tol * (1.0 + np.abs(an).max()):
                break
        else:
            raise AssertionError(f"Newton iteration of the Newmark step to t = {t1} did not converge")
        q, v = qp + cq * an, vp + cv * an
        if not math.isfinite(float(q.sum() + v.sum() + an.sum())):
            raise AssertionError(f"non-finite state at t = {t1}")
        Q[k + 1], V[k + 1], Al[k + 1] = q, v, an
        # after a drive jump restart from the right-limit acceleration
        a = arm.acc(t1, False, q, v) if restart[k] else an
    Ar[N] = a
    return T, Q, V, Ar, Al


def simulate(case, h, **options):
    """The rigid arm of ``case`` by Newmark with step h (s); a :class:`dttmm.Result`.
    Options: beta, gamma, tol (relative Newton correction), max_iter."""
    return pr._simulate(case, h, "newmark", None, options, _newmark, {"newmark": OPTIONS})
