"""Compiled equations of motion of the assumed modes method and its Newmark-family time loop.

Coordinates q = (α_1 … α_n, δ_1 (N), …, δ_n (N)): joint angles, then the modal amplitudes of
every link. Each body (link, hub, payload) is written in its own frame coordinates
x = (p_x, p_y, θ[, δ]) — the position and angle of its reference frame and, for a link, its
modal amplitudes — with a body mass matrix M_b(θ, δ) and velocity terms h_b; the frames are
functions of q computed from the base outwards (closed-form recursion), with their Jacobians J
and the velocity-product accelerations γ = J̇q̇. Lagrange's equations of the arm are then
M(q) q̈ + f(q, q̇) = Bτ with M = Σ Jᵀ M_b J and f = Σ Jᵀ (M_b γ + h_b) + Kδ + Dδ̇ (the
equations of a body are covariant under the holonomic map x(q)).

Link body (frame at the root cross-section, s(x) the material point in it):
T = ½ m v·v + v·R(θ)(ω E S + S_δ δ̇) + ½ ω² I(δ) + ω dᵀδ̇ + ½ δ̇ᵀ M δ̇ with
S = (ρAL²/2 + σ(δ), cᵀδ), σ = −½ δᵀHδ, I = ρAL³/3 + δᵀAδ. The variants differ in H and A
only (set by the caller): consistent H = H, A = M − P (foreshortening kept to second order);
premature H = 0, A = M; ruthless H = 0, A = 0. The body's equations reduce to
F_v = m a + R E S ω̇ + R S_δ δ̈ − R S ω² + 2ω E R S_δ δ̇ + R(−δ̇ᵀHδ̇, 0),
F_θ = (R E S)·a + I ω̇ + dᵀδ̈ + 2ω δᵀAδ̇,  F_δ = d ω̇ + M δ̈ + S_δᵀ Rᵀ a − ω² A δ,
with gravity as a base acceleration (a → a − g), which is exactly the gradient of the
gravitational potential −g·(m p + R S).

Tip frame: p_t = p + R ℓ, ℓ = (L − ½ δᵀ G δ, φ_Lᵀδ) (G per variant, set by the caller),
θ_t = θ + φ'_Lᵀδ; the next link's frame is the tip frame turned by its joint angle.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from dttmm.control import pd_torque

_pd = njit(inline="always")(pd_torque)

OK, NONFINITE, UNCONVERGED = 0, 1, 2


@njit(cache=True)
def _add_body(Mq, fq, J, Mb, gam, hb, nb):
    """Mq += Jᵀ Mb J, fq += Jᵀ (Mb γ + h) over the first nb rows of J."""
    nq = Mq.shape[0]
    MJ = np.zeros((nb, nq))
    r = np.zeros(nb)
    for k in range(nb):
        s = hb[k]
        for l2 in range(nb):
            s += Mb[k, l2] * gam[l2]
            for b in range(nq):
                MJ[k, b] += Mb[k, l2] * J[l2, b]
        r[k] = s
    for a in range(nq):
        s = 0.0
        for k in range(nb):
            s += J[k, a] * r[k]
        fq[a] += s
        for b in range(nq):
            s = 0.0
            for k in range(nb):
                s += J[k, a] * MJ[k, b]
            Mq[a, b] += s


@njit(cache=True)
def _rigid(Mq, fq, Jp, Jt, gp, m, inertia, g, J, Mb, gam, hb):
    """A rigid body (mass m at the frame origin, inertia about it) on a frame (Jp, Jt, γ)."""
    if m == 0.0 and inertia == 0.0:
        return
    nq = Mq.shape[0]
    Mb[:3, :3] = 0.0
    Mb[0, 0] = m
    Mb[1, 1] = m
    Mb[2, 2] = inertia
    for a in range(nq):
        J[0, a] = Jp[0, a]
        J[1, a] = Jp[1, a]
        J[2, a] = Jt[a]
    gam[0], gam[1], gam[2] = gp[0], gp[1], 0.0
    hb[0], hb[1], hb[2] = -m * g[0], -m * g[1], 0.0
    _add_body(Mq, fq, J, Mb, gam, hb, 3)


@njit(cache=True)
def assemble(q, qd, par, Mq, fq, frames):
    """M(q) and f(q, q̇) of the arm (M q̈ + f = Bτ); frames (n, 6): root x, y, angle, tip x, y,
    angle of every link. ``par`` is the Pack of :mod:`reference_models.assumed_modes`."""
    n, N = par.n, par.N
    nq = q.shape[0]
    Mq[:, :] = 0.0
    fq[:] = 0.0
    g = par.g
    Jp = np.zeros((2, nq))
    Jt = np.zeros(nq)
    gp = np.zeros(2)
    p = np.zeros(2)
    th = 0.0
    J = np.zeros((3 + N, nq))
    Mb = np.zeros((3 + N, 3 + N))
    gam = np.zeros(3 + N)
    hb = np.zeros(3 + N)
    for i in range(n):
        Jt[i] += 1.0
        th += q[i]
        o = n + i * N
        de = q[o : o + N]
        dd = qd[o : o + N]
        w = 0.0
        for a in range(nq):
            w += Jt[a] * qd[a]
        cs, sn = math.cos(th), math.sin(th)
        frames[i, 0], frames[i, 1], frames[i, 2] = p[0], p[1], th
        _rigid(Mq, fq, Jp, Jt, gp, par.hub_m[i], par.hub_J[i], g, J, Mb, gam, hb)
        # --- the link body ------------------------------------------------------------------
        Hc, A, c, d = par.Hc[i], par.A[i], par.c[i], par.d[i]
        Hd = Hc @ de
        Ad = A @ de
        Sx = par.s0[i] - 0.5 * (de @ Hd)
        Sy = c @ de
        RSx, RSy = cs * Sx - sn * Sy, sn * Sx + cs * Sy  # R S
        Mb[:, :] = 0.0
        m = par.m[i]
        Mb[0, 0] = m
        Mb[1, 1] = m
        Mb[0, 2] = -RSy  # R E S = E R S
        Mb[1, 2] = RSx
        Mb[2, 2] = par.I0[i] + de @ Ad
        for k in range(N):
            # R S_δ, S_δ = [−(Hδ)ᵀ; cᵀ]
            Mb[0, 3 + k] = -cs * Hd[k] - sn * c[k]
            Mb[1, 3 + k] = -sn * Hd[k] + cs * c[k]
            Mb[2, 3 + k] = d[k]
            for l2 in range(N):
                Mb[3 + k, 3 + l2] = par.M[i, k, l2]
        for a in range(3 + N):
            for b in range(a):
                Mb[a, b] = Mb[b, a]
        # velocity terms
        RSd0, RSd1 = 0.0, 0.0  # R S_δ δ̇
        for k in range(N):
            RSd0 += Mb[0, 3 + k] * dd[k]
            RSd1 += Mb[1, 3 + k] * dd[k]
        dHd = dd @ (Hc @ dd)
        hb[0] = -RSx * w * w - 2.0 * w * RSd1 - cs * dHd
        hb[1] = -RSy * w * w + 2.0 * w * RSd0 - sn * dHd
        hb[2] = 2.0 * w * (dd @ Ad)
        for k in range(N):
            hb[3 + k] = -w * w * Ad[k]
        for a in range(3 + N):
            hb[a] -= Mb[a, 0] * g[0] + Mb[a, 1] * g[1]
        J[:, :] = 0.0
        for a in range(nq):
            J[0, a] = Jp[0, a]
            J[1, a] = Jp[1, a]
            J[2, a] = Jt[a]
        for k in range(N):
            J[3 + k, o + k] = 1.0
        gam[:] = 0.0
        gam[0], gam[1] = gp[0], gp[1]
        _add_body(Mq, fq, J, Mb, gam, hb, 3 + N)
        # elastic and damping forces
        for k in range(N):
            s = 0.0
            for l2 in range(N):
                s += par.K[i, k, l2] * de[l2] + par.D[i, k, l2] * dd[l2]
            fq[o + k] += s
        # --- the tip frame ------------------------------------------------------------------
        Gd = par.Gc[i] @ de
        lx = par.L[i] - 0.5 * (de @ Gd)
        ly = par.phiL[i] @ de
        Rlx, Rly = cs * lx - sn * ly, sn * lx + cs * ly
        dGd = dd @ (par.Gc[i] @ dd)
        Rld0, Rld1 = 0.0, 0.0  # R ℓ_δ δ̇
        for k in range(N):
            ex, ey = -Gd[k], par.phiL[i, k]
            r0, r1 = cs * ex - sn * ey, sn * ex + cs * ey
            Rld0 += r0 * dd[k]
            Rld1 += r1 * dd[k]
            Jp[0, o + k] += r0
            Jp[1, o + k] += r1
        for a in range(nq):  # E R ℓ θ-column (Jp += (E R ℓ) Jt, done before Jt changes)
            Jp[0, a] += -Rly * Jt[a]
            Jp[1, a] += Rlx * Jt[a]
        gp[0] += -Rlx * w * w - 2.0 * w * Rld1 - cs * dGd
        gp[1] += -Rly * w * w + 2.0 * w * Rld0 - sn * dGd
        p[0] += Rlx
        p[1] += Rly
        for k in range(N):
            Jt[o + k] += par.dphiL[i, k]
            th += par.dphiL[i, k] * de[k]
        frames[i, 3], frames[i, 4], frames[i, 5] = p[0], p[1], th
        _rigid(Mq, fq, Jp, Jt, gp, par.pay_m[i], par.pay_J[i], g, J, Mb, gam, hb)


@njit(cache=True)
def potential(q, par, frames):
    """Elastic + gravitational potential energy (J) at q (frames from :func:`assemble`)."""
    n, N = par.n, par.N
    g = par.g
    V = 0.0
    for i in range(n):
        o = n + i * N
        de = q[o : o + N]
        V += 0.5 * (de @ (par.K[i] @ de))
        x, y, th = frames[i, 0], frames[i, 1], frames[i, 2]
        cs, sn = math.cos(th), math.sin(th)
        Sx = par.s0[i] - 0.5 * (de @ (par.Hc[i] @ de))
        Sy = par.c[i] @ de
        V -= par.m[i] * (g[0] * x + g[1] * y) + g[0] * (cs * Sx - sn * Sy) + g[1] * (sn * Sx + cs * Sy)
        V -= par.hub_m[i] * (g[0] * x + g[1] * y)
        V -= par.pay_m[i] * (g[0] * frames[i, 3] + g[1] * frames[i, 4])
    return V


@njit(cache=True)
def _torques(par, tab, s, q, qd, qdd, z, out, slopes):
    """Joint torques at step-table row s for the state (q, q̇, q̈) and integral states z: open-loop
    tables, pd/pid laws (dttmm.control.pd_torque) with their slopes (n, 4): ∂τ/∂α, ∂τ/∂α̇,
    ∂τ/∂z, ∂τ/∂ω̇."""
    for i in range(par.n):
        slopes[i, :] = 0.0
        if par.code[i] != 1:
            out[i] = tab.ff[s, i]
            continue
        wdot = 0.0
        for a in range(q.shape[0]):
            wdot += par.Wrow[i, a] * qdd[a]
        t, da, dv, dz, dw = _pd(
            par.kp[i], par.kd[i], par.ki[i], par.gm[i], par.limit[i], par.jhub[i],
            tab.ff[s, i], tab.ref[s, i, 0], tab.ref[s, i, 1], z[i], q[i], qd[i], wdot,
        )  # fmt: skip
        out[i] = t
        slopes[i, 0], slopes[i, 1], slopes[i, 2], slopes[i, 3] = da, dv, dz, dw


@njit(cache=True)
def _solve(par, tab, s, qt, qdt, cq, cv, x, z_old, e_old, hz, tol, max_iter, Mq, fq, frames, q, qd):
    """Solve M q̈ + f = Bτ at table row s for the free accelerations x (updated in place) with
    q = q̃ + c_q q̈, q̇ = q̃' + c_v q̈ on the free coordinates and the prescribed joints from the
    table. z_old, e_old, hz: integral states, their last error and the trapezoid weight (h/2;
    0 for an acceleration solve). Returns (iterations, converged)."""
    nq = qt.shape[0]
    n = par.n
    fr = par.free
    nf = fr.shape[0]
    tau = np.zeros(n)
    slopes = np.zeros((n, 4))
    z = np.zeros(n)
    qdd = np.zeros(nq)
    S = np.zeros((nf, nf))
    r = np.zeros(nf)
    prev = np.inf
    conv = False
    it = 0
    while it < max_iter:
        it += 1
        for a in range(nq):
            q[a] = qt[a]
            qd[a] = qdt[a]
            qdd[a] = 0.0
        for j in range(nf):
            a = fr[j]
            q[a] = qt[a] + cq * x[j]
            qd[a] = qdt[a] + cv * x[j]
            qdd[a] = x[j]
        for i in range(n):
            if par.code[i] == 3:  # motion drive
                q[i] = tab.mot[s, i, 0]
                qd[i] = tab.mot[s, i, 1]
                qdd[i] = tab.mot[s, i, 2]
            z[i] = z_old[i] + hz * (e_old[i] + tab.ref[s, i, 0] - q[i])
        assemble(q, qd, par, Mq, fq, frames)
        _torques(par, tab, s, q, qd, qdd, z, tau, slopes)
        for j in range(nf):
            a = fr[j]
            rr = -fq[a]
            for b in range(nq):
                rr -= Mq[a, b] * qdd[b]
            if a < n:
                rr += tau[a]
            r[j] = rr
            for k in range(nf):
                b = fr[k]
                S[j, k] = Mq[a, b] + cv * par.Dfull[a, b] + cq * par.Kfull[a, b]
        for j in range(nf):  # the closed-loop laws' linearisation (α rows)
            a = fr[j]
            if a < n and par.code[a] == 1:
                sl = slopes[a, 0] * cq + slopes[a, 1] * cv - slopes[a, 2] * hz * cq
                for k in range(nf):
                    S[j, k] -= slopes[a, 3] * par.Wrow[a, fr[k]]
                    if fr[k] == a:
                        S[j, k] -= sl
        fin = True
        for j in range(nf):
            if not math.isfinite(r[j]):
                fin = False
        if not fin:
            x[:] = np.nan  # a non-finite iterate: the caller sees a non-finite state
            break
        dx = np.linalg.solve(S, r)
        big, step = 0.0, 0.0
        for j in range(nf):
            x[j] += dx[j]
            step = max(step, abs(dx[j]))
            big = max(big, abs(x[j]))
        if not math.isfinite(step):
            break
        if step <= tol * max(1.0, big) or (
            it >= 3 and step >= 0.9 * prev and step <= 1e3 * tol * max(1.0, big)
        ):
            conv = True  # converged, or stagnating at the round-off floor
            break
        prev = step
    # the state of the last iterate
    for j in range(nf):
        a = fr[j]
        q[a] = qt[a] + cq * x[j]
        qd[a] = qdt[a] + cv * x[j]
    for i in range(n):
        if par.code[i] == 3:
            q[i] = tab.mot[s, i, 0]
            qd[i] = tab.mot[s, i, 1]
        z[i] = z_old[i] + hz * (e_old[i] + tab.ref[s, i, 0] - q[i])
        z_old[i] = z[i]
        e_old[i] = tab.ref[s, i, 0] - q[i]
    return it, conv


@njit(cache=True)
def run(par, tab, T, restart, q0, qd0, beta, gamma, am, af, tol, max_iter, Q, V, Ar, Al, Z):
    """Newmark-family loop (Arnold–Brüls generalised-α; α_m = α_f = 0 is Newmark) on the step
    nodes T (n_steps + 1,). Fills the node states Q, V, the right- and left-limit accelerations
    Ar, Al (full q) and the integral states Z. Returns (status, last node, iterations,
    unconverged steps). Table rows: 2k = left limit at T[k], 2k + 1 = right limit at T[k]."""
    nq = q0.shape[0]
    n = par.n
    fr = par.free
    nf = fr.shape[0]
    Mq = np.zeros((nq, nq))
    fq = np.zeros(nq)
    frames = np.zeros((n, 6))
    q = q0.copy()
    qd = qd0.copy()
    qw = np.zeros(nq)
    qdw = np.zeros(nq)
    z = np.zeros(n)
    e = np.zeros(n)
    for i in range(n):
        if par.code[i] == 3:
            q[i], qd[i] = tab.mot[1, i, 0], tab.mot[1, i, 1]
        e[i] = tab.ref[1, i, 0] - q[i]
    x = np.zeros(nf)  # free accelerations
    acc = np.zeros(nf)  # the auxiliary acceleration of generalised-α
    zz = z.copy()
    ee = e.copy()
    it, ok = _solve(par, tab, 1, q, qd, 0.0, 0.0, x, zz, ee, 0.0, tol, max_iter, Mq, fq, frames, qw, qdw)
    acc[:] = x
    iters = 0
    bad = 0
    qt = np.zeros(nq)
    qdt = np.zeros(nq)
    hh = 0.0
    Q[0], V[0], Z[0] = q, qd, z
    _full_acc(par, tab, 1, x, Ar[0])
    Al[0] = Ar[0]
    nsteps = T.shape[0] - 1
    for k in range(nsteps):
        h = T[k + 1] - T[k]
        hh = h * h
        sc = (1.0 - af) / (1.0 - am)
        cq = beta * hh * sc
        cv = gamma * h * sc
        for a in range(nq):
            qt[a] = q[a]
            qdt[a] = qd[a]
        corr = np.zeros(nf)
        for j in range(nf):
            a = fr[j]
            corr[j] = (af * x[j] - am * acc[j]) / (1.0 - am)
            qt[a] = q[a] + h * qd[a] + hh * (0.5 - beta) * acc[j] + beta * hh * corr[j]
            qdt[a] = qd[a] + h * (1.0 - gamma) * acc[j] + gamma * h * corr[j]
        xn = x.copy()
        it, ok = _solve(
            par, tab, 2 * (k + 1), qt, qdt, cq, cv, xn, z, e, 0.5 * h, tol, max_iter, Mq, fq, frames, q, qd
        )
        iters += it
        if not ok:
            bad += 1
        for j in range(nf):
            acc[j] = sc * xn[j] + corr[j]
        x[:] = xn
        finite = True
        for a in range(nq):
            if not (math.isfinite(q[a]) and math.isfinite(qd[a])):
                finite = False
        if not finite:
            return NONFINITE, k, iters, bad
        Q[k + 1], V[k + 1], Z[k + 1] = q, qd, z
        _full_acc(par, tab, 2 * (k + 1), x, Al[k + 1])
        if restart[k]:  # after a drive jump: restart from the right-limit acceleration
            zz[:] = z
            ee[:] = e
            _solve(
                par,
                tab,
                2 * (k + 1) + 1,
                q,
                qd,
                0.0,
                0.0,
                x,
                zz,
                ee,
                0.0,
                tol,
                max_iter,
                Mq,
                fq,
                frames,
                qw,
                qdw,
            )
            acc[:] = x
            _full_acc(par, tab, 2 * (k + 1) + 1, x, Ar[k + 1])
        else:
            Ar[k + 1] = Al[k + 1]
    return OK, nsteps, iters, bad


@njit(cache=True)
def _full_acc(par, tab, s, x, out):
    for j in range(par.free.shape[0]):
        out[par.free[j]] = x[j]
    for i in range(par.n):
        if par.code[i] == 3:
            out[i] = tab.mot[s, i, 2]


@njit(cache=True)
def outputs(par, tab, q, v, a, z, tau, frames_out, energy):
    """At every output sample s: joint torques tau[s] (laws; motion joints from the equations
    of their α rows), the link frames frames_out[s] (n, 6) and the energy (J)."""
    nt, nq = q.shape
    n = par.n
    Mq = np.zeros((nq, nq))
    fq = np.zeros(nq)
    frames = np.zeros((n, 6))
    t = np.zeros(n)
    slopes = np.zeros((n, 4))
    for s in range(nt):
        assemble(q[s], v[s], par, Mq, fq, frames)
        _torques(par, tab, s, q[s], v[s], a[s], z[s], t, slopes)
        for i in range(n):
            tau[s, i] = t[i]
            if par.code[i] == 3:
                r = fq[i]
                for b in range(nq):
                    r += Mq[i, b] * a[s, b]
                tau[s, i] = r
        frames_out[s] = frames
        ke = 0.0
        for b in range(nq):
            for c in range(nq):
                ke += 0.5 * v[s, b] * Mq[b, c] * v[s, c]
        energy[s] = ke + potential(q[s], par, frames)
