"""An adaptive reference for the tests: the global solver's forward dynamics (the numpy
mechanics of :func:`reference_models.global_newmark.accelerations`) integrated by
scipy's ``solve_ivp`` (Radau or DOP853), restarted at every drive breakpoint.

Independent of the fixed-step time loop it checks: only the one-step forward dynamics are
shared. Open-loop drives only (``accelerations`` refuses closed-loop laws).
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from dttmm.result import tip_deflection
from reference_models import _global_numpy as gnp
from reference_models import global_newmark as gn


def adaptive_reference(case, k, *, method="DOP853", rtol=1e-10, atol=1e-12, strain="linear"):
    """Joint angles (nt, n) and tip deflections (nt, n) on ``case.scenario.output_times``.

    The state is y = [q_F, q̇_F] (free coordinates; motion-driven joints follow their law).
    Inside a piece [a, b] between breakpoints the drives are evaluated at min(t, b⁻) with b⁻
    the float just below b, so the piece sees the left limit of a jump at b."""
    lay = gnp._layout(case, k, strain)  # built once: accelerations() would rebuild it per call
    names = lay.names
    n_dof = len(names)
    alpha = np.array([i for i, nm in enumerate(names) if nm.startswith("alpha_")])
    drives = case.scenario.drives
    motion = [(alpha[i], d) for i, d in enumerate(drives) if d.kind == "motion"]
    free = np.setdiff1d(np.arange(n_dof), [j for j, _ in motion])
    nf = free.size

    def full(y, t):
        q, qd = np.zeros(n_dof), np.zeros(n_dof)
        q[free], qd[free] = y[:nf], y[nf:]
        for j, d in motion:
            q[j], qd[j] = d.motion(t)[:2]
        return q, qd

    q0, qd0 = np.zeros(n_dof), np.zeros(n_dof)
    for i, d in enumerate(drives):
        q0[alpha[i]], qd0[alpha[i]] = d.initial_angle, d.initial_rate
    y = np.concatenate([q0[free], qd0[free]])
    times = case.scenario.output_times
    edges = [0.0, *case.scenario.breakpoints, case.scenario.duration]
    out_q = np.full((times.size, n_dof), np.nan)
    for a, b in zip(edges[:-1], edges[1:]):
        below = np.nextafter(b, a)

        def rhs(t, yy, below=below):
            tt = min(t, below)
            q, qd = full(yy, tt)
            qdd = gnp._forward(case, lay, q, qd, tt, False)[0]  # = gn.accelerations(..., tt)
            return np.concatenate([yy[nf:], qdd[free]])

        sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol, dense_output=True)
        assert sol.success, sol.message
        sel = (times >= a - 1e-12) & (times <= b + 1e-12)
        for j in np.flatnonzero(sel):
            t = min(max(times[j], a), b)
            out_q[j] = full(sol.sol(t), times[j])[0]  # the motion laws are continuous in α
        y = sol.y[:, -1]
    angles = out_q[:, alpha]
    tips = np.empty_like(angles)
    for j in range(times.size):
        fr = gn.kinematics(case, k, out_q[j])
        tips[j] = tip_deflection(fr["root"], fr["root_angle"], fr["tip"])
    return angles, tips
