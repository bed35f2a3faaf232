"""The time loop of the spatial kernel: Newmark family (generalised-α in the Arnold–Brüls form)
on q with implicit elastic and damping forces and the suite's stop rule, or RK4 on the
acceleration solver; output sampling on the grid by cubic Hermite interpolation between step
ends (q from (q, q̇), q̇ from (q̇, q̈), torques linear)."""

from __future__ import annotations

import math

import numpy as np

from ...iteration import stop_rule
from ._jit import njit
from .core import kinematics, set_rates, sweep

_stop_rule = njit(inline="always")(stop_rule)

INT_NEWMARK, INT_RK4 = 0, 1
ST_OK, ST_NONFINITE, ST_SINGULAR, ST_RUNAWAY = 0, 1, 2, 3
#: an elastic rotation beyond this (rad) or a displacement beyond this many element lengths
#: stops the run: the state is diverging
RUNAWAY_ANGLE, RUNAWAY_LENGTHS = 2.0 * np.pi, 10.0


@njit()
def accel(md, ws, q, qd, tau, mot, forces, out, torque):
    """q̈ at (q, q̇) with the motion joints' α, α̇ from ``mot`` (q, q̇ are updated in place);
    torques into ``torque``. Returns ok."""
    for i in range(md.n):
        if md.motion[i] == 1:
            q[md.ia[i]] = mot[i, 0]
            qd[md.ia[i]] = mot[i, 1]
    kinematics(md, ws, q, qd)
    set_rates(md, ws, qd)
    ok = sweep(md, ws, 0.0, 0.0, q, qd, tau, mot, forces, out, False, np.zeros((0, 6)))
    joint_torques(md, ws, tau, torque)
    return ok


@njit()
def joint_torques(md, ws, tau, torque):
    """Per joint: the law's torque (torque joints) or the sweep's (motion joints); 0 if locked."""
    for i in range(md.n):
        if md.locked[i] == 1:
            torque[i] = 0.0
        elif md.motion[i] == 1:
            torque[i] = ws.acc[i, 1]
        else:
            torque[i] = tau[i]


@njit()
def check_state(md, q):
    """ST_OK, or ST_NONFINITE / ST_RUNAWAY for a diverging state."""
    for r in range(q.shape[0]):
        if not math.isfinite(q[r]):
            return ST_NONFINITE
    for i in range(md.n):
        off = 0 if md.ext[i] == 1 else -1
        for j in range(md.k[i]):
            r0 = md.ie[md.el0[i] + j]
            for c in range(6):
                if c + off < 0:
                    continue
                v = abs(q[r0 + c + off])
                lim = RUNAWAY_ANGLE if c >= 3 else RUNAWAY_LENGTHS * md.l[i]
                if v > lim:
                    return ST_RUNAWAY
    return ST_OK


@njit()
def hermite(x, h):
    x2 = x * x
    x3 = x2 * x
    return 2 * x3 - 3 * x2 + 1, (x3 - 2 * x2 + x) * h, -2 * x3 + 3 * x2, (x3 - x2) * h


@njit()
def run(
    md,
    ws,
    integrator,
    beta,
    gamma,
    alpha_m,
    alpha_f,
    tol,
    max_it,
    n_fixed,
    t_end,
    restart,
    tau_l,
    mot_l,
    tau_r,
    mot_r,
    tau_m,
    mot_m,
    q,
    qd,
    qdd,
    aux,
    ts,
    oq,
    oqd,
    otau,
    stats,
):
    """The whole time loop from the state (q, q̇, q̈, aux) at t = 0, sampling the state on the
    grid ``ts`` into oq, oqd (nt, n_dof) and otau (nt, n). ``n_fixed`` ≥ 0: exactly n_fixed + 1
    sweeps per Newmark step; −1: to tolerance. stats: [sweeps, max sweeps, unconverged steps,
    status, failed step, samples written]. Returns the number of steps taken."""
    n = md.n
    nd = q.shape[0]
    ns = t_end.shape[0]
    zero_f = np.zeros(nd)
    torque = np.zeros(n)
    tq0 = np.zeros(n)
    q0 = q.copy()
    qd0 = qd.copy()
    qdd0 = qdd.copy()
    qt = np.zeros(nd)
    qdt = np.zeros(nd)
    x = np.zeros(nd)
    xn = np.zeros(nd)
    qi = np.zeros(nd)
    qdi = np.zeros(nd)
    k2 = np.zeros(nd)
    k3 = np.zeros(nd)
    ka = np.zeros(nd)
    kb = np.zeros(nd)
    kc = np.zeros(nd)
    noload = np.zeros((0, 6))
    # torques at t = 0 (right limits)
    ok = accel(md, ws, q.copy(), qd.copy(), tau_r[ns], mot_r[ns], zero_f, xn, torque)
    js = 0
    nt = ts.shape[0]
    while js < nt and ts[js] <= 1e-12:
        for r in range(nd):
            oq[js, r] = q[r]
            oqd[js, r] = qd[r]
        for i in range(n):
            otau[js, i] = torque[i]
        js += 1
    t0 = 0.0
    s = 0
    while s < ns:
        t1 = t_end[s]
        h = t1 - t0
        for r in range(nd):
            q0[r] = q[r]
            qd0[r] = qd[r]
            qdd0[r] = qdd[r]
        for i in range(n):
            tq0[i] = torque[i]
        tau = tau_l[s]
        mot = mot_l[s]
        if integrator == INT_NEWMARK:
            hh = h * h
            sc = (1.0 - alpha_f) / (1.0 - alpha_m)
            cq = beta * hh * sc
            cv = gamma * h * sc
            i1m = 1.0 / (1.0 - alpha_m)
            for r in range(nd):
                corr = (alpha_f * qdd[r] - alpha_m * aux[r]) * i1m
                qt[r] = q[r] + h * qd[r] + hh * (0.5 - beta) * aux[r] + beta * hh * corr
                qdt[r] = qd[r] + h * (1.0 - gamma) * aux[r] + gamma * h * corr
                x[r] = qdd[r]
            for i in range(n):
                if md.motion[i] == 1:
                    x[md.ia[i]] = mot[i, 2]
            prev = np.inf
            used = 0
            converged = False
            nmax = max_it if n_fixed < 0 else n_fixed + 1
            for it in range(nmax):
                for r in range(nd):
                    qi[r] = qt[r] + cq * x[r]
                    qdi[r] = qdt[r] + cv * x[r]
                for i in range(n):
                    if md.motion[i] == 1:
                        qi[md.ia[i]] = mot[i, 0]
                        qdi[md.ia[i]] = mot[i, 1]
                kinematics(md, ws, qi, qdi)
                set_rates(md, ws, qdi)
                ok = sweep(md, ws, cq, cv, qt, qdt, tau, mot, zero_f, xn, False, noload)
                used += 1
                dx = 0.0
                xmax = 0.0
                for r in range(nd):
                    dx = max(dx, abs(xn[r] - x[r]))
                    xmax = max(xmax, abs(xn[r]))
                    x[r] = xn[r]
                if not ok:
                    break
                if n_fixed >= 0:
                    converged = it == nmax - 1
                    continue
                stop, converged = _stop_rule(it, dx, prev, xmax, tol)
                if stop:
                    break
                prev = dx
            stats[0] += used
            stats[1] = max(stats[1], used)
            if not converged and n_fixed < 0:
                stats[2] += 1
            joint_torques(md, ws, tau, torque)
            for r in range(nd):
                anew = ((1.0 - alpha_f) * x[r] + alpha_f * qdd[r] - alpha_m * aux[r]) * i1m
                q[r] = qt[r] + cq * x[r]
                qd[r] = qdt[r] + cv * x[r]
                aux[r] = anew
                qdd[r] = x[r]
            for i in range(n):
                if md.motion[i] == 1:
                    q[md.ia[i]] = mot[i, 0]
                    qd[md.ia[i]] = mot[i, 1]
                    qdd[md.ia[i]] = mot[i, 2]
        else:
            hf = 0.5 * h
            for r in range(nd):
                qi[r] = q[r] + hf * qd[r]
                qdi[r] = qd[r] + hf * qdd[r]
                k2[r] = qdi[r]
            ok = accel(md, ws, qi, qdi, tau_m[s], mot_m[s], zero_f, ka, torque)
            for r in range(nd):
                k2[r] = qdi[r]
            if ok:
                for r in range(nd):
                    qi[r] = q[r] + hf * k2[r]
                    qdi[r] = qd[r] + hf * ka[r]
                ok = accel(md, ws, qi, qdi, tau_m[s], mot_m[s], zero_f, kb, torque)
                for r in range(nd):
                    k3[r] = qdi[r]
            if ok:
                for r in range(nd):
                    qi[r] = q[r] + h * k3[r]
                    qdi[r] = qd[r] + h * kb[r]
                ok = accel(md, ws, qi, qdi, tau, mot, zero_f, kc, torque)
            if ok:
                for r in range(nd):
                    q[r] = q[r] + h / 6.0 * (qd[r] + 2.0 * k2[r] + 2.0 * k3[r] + qdi[r])
                    qd[r] = qd[r] + h / 6.0 * (qdd[r] + 2.0 * ka[r] + 2.0 * kb[r] + kc[r])
                ok = accel(md, ws, q, qd, tau, mot, zero_f, qdd, torque)
            stats[0] += 4
            stats[1] = 4
        status = check_state(md, q) if ok else ST_SINGULAR
        if status == ST_OK:
            for r in range(nd):
                if not math.isfinite(qd[r]):
                    status = ST_NONFINITE
        if status != ST_OK:
            stats[3] = status
            stats[4] = s
            stats[5] = js
            return s
        # samples in (t0, t1]
        eps = 1e-9 * h
        while js < nt and ts[js] <= t1 + eps:
            xx = (ts[js] - t0) / h
            if abs(ts[js] - t1) <= eps:
                xx = 1.0
            w0, w1, w2, w3 = hermite(xx, h)
            for r in range(nd):
                oq[js, r] = w0 * q0[r] + w1 * qd0[r] + w2 * q[r] + w3 * qd[r]
                oqd[js, r] = w0 * qd0[r] + w1 * qdd0[r] + w2 * qd[r] + w3 * qdd[r]
            for i in range(n):
                otau[js, i] = (1.0 - xx) * tq0[i] + xx * torque[i]
            js += 1
        # a drive jumps at t1: restart from the right limits
        if restart[s]:
            ok = accel(md, ws, q, qd, tau_r[s], mot_r[s], zero_f, qdd, torque)
            for r in range(nd):
                aux[r] = qdd[r]
        t0 = t1
        s += 1
    stats[5] = js
    return ns
