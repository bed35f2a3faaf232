"""Kinematics, the Riccati sweep (tip → base, base → tip), energy and outputs of the spatial
arm at one state (docs/spatial.md §2-3).

Every vector of an element is held in its frame's components: a frame's velocity V = (v, ω)
(v of its origin), its acceleration A = (a, α) (classical: a of the origin), a load (f, n)
(n about the origin) — the load the inboard part exerts on the outboard part. An element is
four Gauss-point bodies (mass and rotary inertia of the quadrature, at r(ξ_g) with
orientation R_s(ξ_g)) and its outboard node; its equations are

    elastic rows   M_ee ë + M_eA A + r_e = 0,   load at its root f = M_AA A + M_eAᵀ ë + r_A

with the outboard part entering through its articulated inertia P and bias c (f_O = P A_O + c),
so that f = P_root A + c_root, P_root = M_AA − M_eAᵀ M_ee⁻¹ M_eA.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import njit

# ---------------------------------------------------------------- small dense algebra -------


@njit(inline="always")
def cross(a, b):
    return np.array((a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]))


@njit(inline="always")
def mv(A, x):
    n, m = A.shape
    y = np.zeros(n)
    for i in range(n):
        s = 0.0
        for j in range(m):
            s += A[i, j] * x[j]
        y[i] = s
    return y


@njit(inline="always")
def mtv(A, x):
    n, m = A.shape
    y = np.zeros(m)
    for j in range(m):
        s = 0.0
        for i in range(n):
            s += A[i, j] * x[i]
        y[j] = s
    return y


@njit(inline="always")
def mm(A, B):
    n, m = A.shape
    p = B.shape[1]
    C = np.zeros((n, p))
    for i in range(n):
        for k in range(m):
            a = A[i, k]
            if a != 0.0:
                for j in range(p):
                    C[i, j] += a * B[k, j]
    return C


@njit(inline="always")
def mtm(A, B):
    """Aᵀ B."""
    m, n = A.shape
    p = B.shape[1]
    C = np.zeros((n, p))
    for k in range(m):
        for i in range(n):
            a = A[k, i]
            if a != 0.0:
                for j in range(p):
                    C[i, j] += a * B[k, j]
    return C


@njit(inline="always")
def rot_blocks(R, P):
    """B P Bᵀ with B = blockdiag(R, R) (6×6 P)."""
    out = np.empty((6, 6))
    for bi in range(2):
        for bj in range(2):
            for i in range(3):
                for j in range(3):
                    s = 0.0
                    for k in range(3):
                        rk = R[i, k]
                        for m in range(3):
                            s += rk * P[3 * bi + k, 3 * bj + m] * R[j, m]
                    out[3 * bi + i, 3 * bj + j] = s
    return out


@njit(inline="always")
def rot6(R, x):
    y = np.empty(6)
    for b in range(2):
        for i in range(3):
            y[3 * b + i] = R[i, 0] * x[3 * b] + R[i, 1] * x[3 * b + 1] + R[i, 2] * x[3 * b + 2]
    return y


@njit(inline="always")
def rot6t(R, x):
    y = np.empty(6)
    for b in range(2):
        for i in range(3):
            y[3 * b + i] = R[0, i] * x[3 * b] + R[1, i] * x[3 * b + 1] + R[2, i] * x[3 * b + 2]
    return y


@njit()
def chol_solve(A, B):
    """Solve A X = B for symmetric positive definite A (n×n) and B (n×m); returns (X, ok)."""
    n = A.shape[0]
    L = np.zeros((n, n))
    for j in range(n):
        s = A[j, j]
        for k in range(j):
            s -= L[j, k] * L[j, k]
        if not s > 0.0:
            return np.zeros_like(B), False
        L[j, j] = math.sqrt(s)
        for i in range(j + 1, n):
            t = A[i, j]
            for k in range(j):
                t -= L[i, k] * L[j, k]
            L[i, j] = t / L[j, j]
    m = B.shape[1]
    X = B.copy()
    for c in range(m):
        for i in range(n):
            t = X[i, c]
            for k in range(i):
                t -= L[i, k] * X[k, c]
            X[i, c] = t / L[i, i]
        for i in range(n - 1, -1, -1):
            t = X[i, c]
            for k in range(i + 1, n):
                t -= L[k, i] * X[k, c]
            X[i, c] = t / L[i, i]
    return X, True


# ---------------------------------------------------------------- rotations -----------------


@njit(inline="always")
def so3_coefficients(t2):
    """(sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³) and the derivatives of the last two in θ²,
    at θ² = t2 (series for θ < 1, closed forms beyond)."""
    if t2 < 1.0:
        a = 0.0
        b = 0.0
        c = 0.0
        db = 0.0
        dc = 0.0
        term = 1.0  # (−t2)^n
        f1 = 1.0  # (2n+1)!
        f2 = 2.0  # (2n+2)!
        f3 = 6.0  # (2n+3)!
        tprev = 1.0  # (−t2)^(n−1)
        for n in range(10):
            a += term / f1
            b += term / f2
            c += term / f3
            if n >= 1:
                db += -n * tprev / f2
                dc += -n * tprev / f3
                tprev = -tprev * t2
            f1 *= (2 * n + 2) * (2 * n + 3)
            f2 *= (2 * n + 3) * (2 * n + 4)
            f3 *= (2 * n + 4) * (2 * n + 5)
            term = -term * t2
        return a, b, c, db, dc
    t = math.sqrt(t2)
    s = math.sin(t)
    co = math.cos(t)
    a = s / t
    b = (1.0 - co) / t2
    c = (t - s) / (t2 * t)
    # d/dθ² = (d/dθ) / (2θ)
    db = (s / t2 - 2.0 * (1.0 - co) / (t2 * t)) / (2.0 * t)
    dc = ((1.0 - co) / (t2 * t) - 3.0 * (t - s) / (t2 * t2)) / (2.0 * t)
    return a, b, c, db, dc


@njit(inline="always")
def exp_jl(psi, psid):
    """exp([ψ]×), J_L(ψ) and J̇_L ψ̇ (the derivative of J_L along ψ̇, applied to ψ̇)."""
    x, y, z = psi[0], psi[1], psi[2]
    t2 = x * x + y * y + z * z
    a, b, c, db, dc = so3_coefficients(t2)
    K = np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))
    K2 = mm(K, K)
    E = np.empty((3, 3))
    J = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            d = 1.0 if i == j else 0.0
            E[i, j] = d + a * K[i, j] + b * K2[i, j]
            J[i, j] = d + b * K[i, j] + c * K2[i, j]
    pp = 2.0 * (x * psid[0] + y * psid[1] + z * psid[2])
    u = cross(psi, psid)
    w = cross(psi, u)
    v = cross(psid, u)
    jd = np.empty(3)
    for i in range(3):
        jd[i] = db * pp * u[i] + dc * pp * w[i] + c * v[i]
    return E, J, jd


@njit(inline="always")
def exp3(psi):
    x, y, z = psi[0], psi[1], psi[2]
    a, b, _c, _db, _dc = so3_coefficients(x * x + y * y + z * z)
    K = np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))
    K2 = mm(K, K)
    E = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            E[i, j] = (1.0 if i == j else 0.0) + a * K[i, j] + b * K2[i, j]
    return E


@njit(inline="always")
def axis_rotation(ax, ang):
    x, y, z = ax[0], ax[1], ax[2]
    K = np.array(((0.0, -z, y), (z, 0.0, -x), (-y, x, 0.0)))
    K2 = mm(K, K)
    s = math.sin(ang)
    c = 1.0 - math.cos(ang)
    R = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            R[i, j] = (1.0 if i == j else 0.0) + s * K[i, j] + c * K2[i, j]
    return R


# ---------------------------------------------------------------- elastic forces ------------


@njit(inline="always")
def strain_gradient(md, i, e):
    """(ε, ∂ε/∂e (6,)) of the second-order axial strain ε = u/l + ½(bᵀGb + cᵀGc), b = (v, φz),
    c = (w, −φy)."""
    G = md.G[i]
    l = md.l[i]
    b0, b1 = e[1], e[5]
    c0, c1 = e[2], -e[4]
    gb0 = G[0, 0] * b0 + G[0, 1] * b1
    gb1 = G[1, 0] * b0 + G[1, 1] * b1
    gc0 = G[0, 0] * c0 + G[0, 1] * c1
    gc1 = G[1, 0] * c0 + G[1, 1] * c1
    eps = e[0] / l + 0.5 * (b0 * gb0 + b1 * gb1 + c0 * gc0 + c1 * gc1)
    g = np.zeros(6)
    g[0] = 1.0 / l
    g[1] = gb0
    g[5] = gb1
    g[2] = gc0
    g[4] = -gc1
    return eps, g


@njit(inline="always")
def elastic_terms(md, i, e):
    """Elastic force f(e) (6,) and its tangent K_T(e) (6, 6) of an element of link i, and the
    damping matrix D(e) (6, 6): D = μK (linear) or μ(EA l ∂ε∂εᵀ + K_b) (second order)."""
    if md.so[i] == 0:
        K = md.K[i]
        f = mv(K, e)
        D = md.mu[i] * K
        return f, K.copy(), D
    eps, g = strain_gradient(md, i, e)
    EA = md.EA[i]
    l = md.l[i]
    Kb = md.Kb[i]
    f = mv(Kb, e)
    KT = Kb.copy()
    D = np.empty((6, 6))
    G = md.G[i]
    # ∂²ε/∂e²: G on (v, φz) = (1, 5), T G T on (w, φy) = (2, 4) with T = diag(1, −1)
    H = np.zeros((6, 6))
    H[1, 1] = G[0, 0]
    H[1, 5] = G[0, 1]
    H[5, 1] = G[1, 0]
    H[5, 5] = G[1, 1]
    H[2, 2] = G[0, 0]
    H[2, 4] = -G[0, 1]
    H[4, 2] = -G[1, 0]
    H[4, 4] = G[1, 1]
    for r in range(6):
        f[r] += EA * l * eps * g[r]
        for s in range(6):
            gg = EA * l * g[r] * g[s]
            KT[r, s] += gg + EA * l * eps * H[r, s]
            D[r, s] = md.mu[i] * (gg + Kb[r, s])
    return f, KT, D


@njit(inline="always")
def strain_energy(md, i, e):
    if md.so[i] == 0:
        return 0.5 * np.dot(e, mv(md.K[i], e))
    eps, _g = strain_gradient(md, i, e)
    return 0.5 * np.dot(e, mv(md.Kb[i], e)) + 0.5 * md.EA[i] * md.l[i] * eps * eps


# ---------------------------------------------------------------- kinematics ----------------


@njit(inline="always")
def unpack(md, i, j, q, qd, e, ed):
    """Padded elastic coordinates (6,) of element j of link i from q into e, ed."""
    r = md.ie[md.el0[i] + j]
    if md.ext[i] == 1:
        for c in range(6):
            e[c] = q[r + c]
            ed[c] = qd[r + c]
    else:
        e[0] = 0.0
        ed[0] = 0.0
        for c in range(5):
            e[c + 1] = q[r + c]
            ed[c + 1] = qd[r + c]


@njit()
def kinematics(md, ws, q, qd):
    """Frames, origins and velocities of every element and link tip at (q, q̇) into ``ws``."""
    R = md.Rbase.copy()
    p = md.pbase.copy()
    v = np.zeros(3)
    w = np.zeros(3)
    for i in range(md.n):
        ws.RT[i] = R
        ws.pT[i] = p
        ws.vT[i] = v
        ws.wT[i] = w
        al = 0.0
        ald = 0.0
        if md.locked[i] == 0:
            al = q[md.ia[i]]
            ald = qd[md.ia[i]]
        C = mm(mm(md.Crpy[i], axis_rotation(md.axis[i], al)), md.Q[i])
        ws.C[i] = C
        o = md.org[i]
        p = p + mv(R, o)
        vj = v + cross(w, o)
        wj = w + md.aT[i] * ald
        v = mtv(C, vj)
        w = mtv(C, wj)
        R = mm(R, C)
        for j in range(md.k[i]):
            el = md.el0[i] + j
            e = ws.e[el]
            ed = ws.ed[el]
            unpack(md, i, j, q, qd, e, ed)
            ws.Rw[el] = R
            ws.pw[el] = p
            ws.vl[el] = v
            ws.wl[el] = w
            sO = md.s0[i, 4] + mv(md.Sig[i, 4], e)
            sOd = mv(md.Sig[i, 4], ed)
            phi = e[3:6]
            phid = ed[3:6]
            E, J, _jd = exp_jl(phi, phid)
            ws.E[el] = E
            p = p + mv(R, sO)
            vo = v + cross(w, sO) + sOd
            wo = w + mv(J, phid)
            v = mtv(E, vo)
            w = mtv(E, wo)
            R = mm(R, E)
        # tip frame: R_O Rx(−roll)
        Qi = md.Q[i]
        v = mv(Qi, v)
        w = mv(Qi, w)
        R = mm(R, Qi.T)
    ws.RT[md.n] = R
    ws.pT[md.n] = p
    ws.vT[md.n] = v
    ws.wT[md.n] = w


@njit(inline="always")
def transfer(d):
    """X(d) = [[I, −[d]×], [0, I]]: the twist at a point d from the origin's twist."""
    X = np.zeros((6, 6))
    for r in range(6):
        X[r, r] = 1.0
    X[0, 4] = d[2]
    X[0, 5] = -d[1]
    X[1, 3] = -d[2]
    X[1, 5] = d[0]
    X[2, 3] = d[1]
    X[2, 4] = -d[0]
    return X


@njit(inline="always")
def add_body(M, X, zeta, b, Maa, rA):
    """A rigid body of inertia M (6×6, at its point) and bias b, whose twist is X V + (terms) and
    acceleration X A + ζ: adds Xᵀ M X to Maa and Xᵀ (M ζ + b) to rA."""
    MX = mm(M, X)
    XMX = mtm(X, MX)
    Mz = mv(M, zeta) + b
    XMz = mtv(X, Mz)
    for r in range(6):
        rA[r] += XMz[r]
        for s in range(6):
            Maa[r, s] += XMX[r, s]


@njit(inline="always")
def body_inertia(m, J):
    M = np.zeros((6, 6))
    M[0, 0] = M[1, 1] = M[2, 2] = m
    for r in range(3):
        for s in range(3):
            M[3 + r, 3 + s] = J[r, s]
    return M


@njit()
def element_step(md, i, el, w, gl, P, c, cq, cv, ehat, edhat, fext, ws):
    """Backward step over element ``el`` of link i: from (P, c) at its outboard node (outboard
    frame components) to (P, c) at its root (own frame components); keeps the gains
    ë = Ka A + k0 and the outboard maps in ``ws``. Returns (P, c, ok)."""
    e = ws.e[el]
    ed = ws.ed[el]
    Mee = np.zeros((6, 6))
    MeA = np.zeros((6, 6))
    Maa = np.zeros((6, 6))
    re = np.zeros(6)
    rA = np.zeros(6)
    for g in range(5):
        Sg = md.Sig[i, g]
        Pg = md.Psi[i, g]
        s = md.s0[i, g] + mv(Sg, e)
        sd = mv(Sg, ed)
        psi = mv(Pg, e)
        psid = mv(Pg, ed)
        E, J, jd = exp_jl(psi, psid)
        S = np.zeros((6, 6))
        JP = mm(J, Pg)
        for r in range(3):
            for cc in range(6):
                S[r, cc] = Sg[r, cc]
                S[3 + r, cc] = JP[r, cc]
        X = transfer(s)
        Jpd = mv(J, psid)
        zl = cross(w, cross(w, s)) + 2.0 * cross(w, sd)
        za = cross(w, Jpd) + jd
        zeta = np.empty(6)
        zeta[:3] = zl
        zeta[3:] = za
        if g < 4:
            m = md.mg[i, g]
            Iw = np.empty((3, 3))
            Ig = md.Ig[i, g]
            for r in range(3):
                for cc in range(3):
                    Iw[r, cc] = (
                        E[r, 0] * Ig[0] * E[cc, 0] + E[r, 1] * Ig[1] * E[cc, 1] + E[r, 2] * Ig[2] * E[cc, 2]
                    )
            M = body_inertia(m, Iw)
            wg = w + Jpd
            gy = cross(wg, mv(Iw, wg))
            b = np.empty(6)
            for r in range(3):
                b[r] = -m * gl[r]
                b[3 + r] = gy[r]
        else:
            EO = E
            ws.E[el] = EO
            M = rot_blocks(EO, P)
            b = rot6(EO, c)
            for r in range(6):
                for cc in range(6):
                    ws.XS[el, r, cc] = X[r, cc]
                    ws.XS[el, r, 6 + cc] = S[r, cc]
                ws.zO[el, r] = zeta[r]
        MS = mm(M, S)
        MX = mm(M, X)
        Mzb = mv(M, zeta) + b
        SMS = mtm(S, MS)
        SMX = mtm(S, MX)
        XMX = mtm(X, MX)
        SMz = mtv(S, Mzb)
        XMz = mtv(X, Mzb)
        for r in range(6):
            re[r] += SMz[r]
            rA[r] += XMz[r]
            for cc in range(6):
                Mee[r, cc] += SMS[r, cc]
                MeA[r, cc] += SMX[r, cc]
                Maa[r, cc] += XMX[r, cc]
    f, KT, D = elastic_terms(md, i, e)
    for r in range(6):
        re[r] += f[r] - fext[r]
        for cc in range(6):
            re[r] += KT[r, cc] * (ehat[cc] - e[cc]) + D[r, cc] * edhat[cc]
            Mee[r, cc] += cq * KT[r, cc] + cv * D[r, cc]
    if md.ext[i] == 0:  # the dummy u: unit mass, no coupling, no load
        for r in range(6):
            Mee[0, r] = 0.0
            Mee[r, 0] = 0.0
            MeA[0, r] = 0.0
        Mee[0, 0] = 1.0
        re[0] = 0.0
    rhs = np.empty((6, 7))
    for r in range(6):
        for cc in range(6):
            rhs[r, cc] = -MeA[r, cc]
        rhs[r, 6] = -re[r]
    sol, ok = chol_solve(Mee, rhs)
    for r in range(6):
        for cc in range(6):
            ws.Ka[el, r, cc] = sol[r, cc]
        ws.k0[el, r] = sol[r, 6]
    Pn = Maa + mtm(MeA, sol[:, :6])
    cn = rA + mtv(MeA, sol[:, 6])
    for r in range(6):
        for cc in range(r + 1, 6):
            s = 0.5 * (Pn[r, cc] + Pn[cc, r])
            Pn[r, cc] = s
            Pn[cc, r] = s
    return Pn, cn, ok


@njit()
def sweep(md, ws, cq, cv, qhat, qdhat, tau, mot, forces, qdd, want_loads, loads):
    """One Riccati sweep at the kinematics in ``ws`` (from :func:`kinematics`): q̈ into ``qdd``,
    per joint α̈ and torque into ws.acc, and with ``want_loads`` the cut loads (nel + n, 6)
    (force, moment; world components) at every element root and link tip. ``qhat``/``qdhat``:
    the known parts of the elastic coordinates and rates (Newmark predictors; the state itself
    for the acceleration solver, with cq = cv = 0). ``tau`` (n,): torques of torque joints;
    ``mot`` (n, 3): α, α̇, α̈ of motion joints; ``forces`` (n_dof,) generalized forces on the
    coordinates besides the drives (virtual work Qᵀδq; on a torque joint's angle they add to its
    torque). Returns ok."""
    P = np.zeros((6, 6))
    fext = np.zeros(6)
    c = np.zeros(6)
    ehat = np.zeros(6)
    edhat = np.zeros(6)
    ok = True
    for i in range(md.n - 1, -1, -1):
        # tip frame → outboard element frame (x_O = Qᵀ x_T), then the payload
        Qi = md.Q[i]
        P = rot_blocks(Qi.T, P)
        c = rot6(Qi.T, c)
        el_last = md.el0[i] + md.k[i] - 1
        RO = mm(ws.Rw[el_last], ws.E[el_last])
        if md.pay_m[i] > 0.0 or np.any(md.pay_J[i] != 0.0):
            wO = mv(Qi.T, ws.wT[i + 1])
            gO = mtv(RO, md.grav)
            d = md.pay_d[i]
            M = body_inertia(md.pay_m[i], md.pay_J[i])
            zeta = np.zeros(6)
            zeta[:3] = cross(wO, cross(wO, d))
            b = np.zeros(6)
            b[:3] = -md.pay_m[i] * gO
            b[3:] = cross(wO, mv(md.pay_J[i], wO))
            add_body(M, transfer(d), zeta, b, P, c)
        for r in range(6):
            for s in range(6):
                ws.Ptip[i, r, s] = P[r, s]
            ws.Ptip[i, r, 6] = c[r]
        for j in range(md.k[i] - 1, -1, -1):
            el = md.el0[i] + j
            gl = mtv(ws.Rw[el], md.grav)
            r0 = md.ie[el]
            if md.ext[i] == 1:
                for s in range(6):
                    ehat[s] = qhat[r0 + s]
                    edhat[s] = qdhat[r0 + s]
                    fext[s] = forces[r0 + s]
            else:
                ehat[0] = 0.0
                edhat[0] = 0.0
                fext[0] = 0.0
                for s in range(5):
                    ehat[s + 1] = qhat[r0 + s]
                    edhat[s + 1] = qdhat[r0 + s]
                    fext[s + 1] = forces[r0 + s]
            P, c, good = element_step(md, i, el, ws.wl[el], gl, P, c, cq, cv, ehat, edhat, fext, ws)
            ok = ok and good
            for r in range(6):
                for s in range(6):
                    ws.Pc[el, r, s] = P[r, s]
                ws.Pc[el, r, 6] = c[r]
        # hub at the root point
        el0 = md.el0[i]
        wF = ws.wl[el0]
        if md.hub_m[i] > 0.0 or np.any(md.hub_J[i] != 0.0):
            gF = mtv(ws.Rw[el0], md.grav)
            M = body_inertia(md.hub_m[i], md.hub_J[i])
            b = np.zeros(6)
            b[:3] = -md.hub_m[i] * gF
            b[3:] = cross(wF, mv(md.hub_J[i], wF))
            add_body(M, transfer(np.zeros(3)), np.zeros(6), b, P, c)
        for r in range(6):
            for s in range(6):
                ws.PF[i, r, s] = P[r, s]
            ws.PF[i, r, 6] = c[r]
        # joint: velocity-product term in root-frame components, then the projection
        C = ws.C[i]
        wTp = ws.wT[i]
        zo = np.zeros(6)
        zo[:3] = cross(wTp, cross(wTp, md.org[i]))
        zJ = rot6t(C, zo)
        s6 = np.zeros(6)
        if md.locked[i] == 0:
            ald = ws.acc[i, 2]
            wTF = mtv(C, wTp)
            aF = md.aF[i]
            za = cross(wTF, aF)
            for r in range(3):
                zJ[3 + r] += za[r] * ald
                s6[3 + r] = aF[r]
        for r in range(6):
            ws.zJ[i, r] = zJ[r]
        if md.locked[i] == 0:
            Ps = mv(P, s6)
            if md.motion[i] == 1:
                add = mot[i, 2]
                for r in range(6):
                    c[r] += Ps[r] * add
            else:
                Dj = np.dot(s6, Ps)
                if not Dj > 0.0:
                    ok = False
                    Dj = 1.0
                g0 = (tau[i] + forces[md.ia[i]] - np.dot(s6, c)) / Dj
                for r in range(6):
                    c[r] += Ps[r] * g0
                    for s in range(6):
                        P[r, s] -= Ps[r] * Ps[s] / Dj
        # to the parent frame at its origin: f_T = X_oᵀ Cb (P̂ (A'_F) + ĉ), A'_F = Cbᵀ X_o A_T + zJ
        c = c + mv(P, zJ)
        Xo = transfer(md.org[i])
        PC = rot_blocks(C, P)
        P = mtm(Xo, mm(PC, Xo))
        c = mtv(Xo, rot6(C, c))
    # forward sweep: the base does not move
    A = np.zeros(6)
    ic = 0
    ed_ = np.zeros(6)
    for i in range(md.n):
        C = ws.C[i]
        Xo = transfer(md.org[i])
        A = rot6t(C, mv(Xo, A)) + ws.zJ[i]
        PF = ws.PF[i]
        if md.locked[i] == 0:
            aF = md.aF[i]
            s6 = np.zeros(6)
            s6[3:] = aF
            if md.motion[i] == 1:
                add = mot[i, 2]
            else:
                Ps = mv(PF[:, :6], s6)
                Dj = np.dot(s6, Ps)
                add = (tau[i] + forces[md.ia[i]] - np.dot(s6, mv(PF[:, :6], A)) - np.dot(s6, PF[:, 6])) / Dj
            for r in range(3):
                A[3 + r] += aF[r] * add
            qdd[md.ia[i]] = add
            ws.acc[i, 0] = add
            fF = mv(PF[:, :6], A) + PF[:, 6]
            ws.acc[i, 1] = np.dot(s6, fF)
        for j in range(md.k[i]):
            el = md.el0[i] + j
            if want_loads:
                f = mv(ws.Pc[el, :, :6], A) + ws.Pc[el, :, 6]
                fw = rot6(ws.Rw[el], f)
                for r in range(6):
                    loads[ic, r] = fw[r]
            ic += 1
            edd = mv(ws.Ka[el], A) + ws.k0[el]
            r0 = md.ie[el]
            if md.ext[i] == 1:
                for s in range(6):
                    qdd[r0 + s] = edd[s]
            else:
                for s in range(5):
                    qdd[r0 + s] = edd[s + 1]
            for s in range(6):
                ed_[s] = edd[s]
            AO = mv(ws.XS[el, :, :6], A) + mv(ws.XS[el, :, 6:], ed_) + ws.zO[el]
            A = rot6t(ws.E[el], AO)
        el_last = md.el0[i] + md.k[i] - 1
        if want_loads:
            f = mv(ws.Ptip[i, :, :6], A) + ws.Ptip[i, :, 6]
            RO = mm(ws.Rw[el_last], ws.E[el_last])
            fw = rot6(RO, f)
            for r in range(6):
                loads[ic, r] = fw[r]
        ic += 1
        A = rot6(md.Q[i], A)
    for r in range(qdd.shape[0]):
        if not math.isfinite(qdd[r]):
            ok = False
    return ok


@njit()
def set_rates(md, ws, qd):
    """Joint rates α̇ into ws.acc[:, 2] (the joint velocity-product terms need them)."""
    for i in range(md.n):
        ws.acc[i, 2] = qd[md.ia[i]] if md.locked[i] == 0 else 0.0


@njit()
def accelerations(md, ws, q, qd, tau, mot, forces, qdd, want_loads, loads):
    """Forward dynamics q̈(q, q̇) (motion joints: the law's α, α̇, α̈ from ``mot`` replace the
    given ones in copies of q, q̇). Returns ok; torques in ws.acc[:, 1]."""
    qs = q.copy()
    qds = qd.copy()
    for i in range(md.n):
        if md.motion[i] == 1:
            qs[md.ia[i]] = mot[i, 0]
            qds[md.ia[i]] = mot[i, 1]
    kinematics(md, ws, qs, qds)
    set_rates(md, ws, qds)
    return sweep(md, ws, 0.0, 0.0, qs, qds, tau, mot, forces, qdd, want_loads, loads)


@njit()
def energy(md, ws):
    """Kinetic + elastic + gravitational energy at the kinematics in ``ws``."""
    T = 0.0
    V = 0.0
    g = md.grav
    for i in range(md.n):
        el0 = md.el0[i]
        if md.hub_m[i] > 0.0 or np.any(md.hub_J[i] != 0.0):
            v = ws.vl[el0]
            w = ws.wl[el0]
            T += 0.5 * md.hub_m[i] * np.dot(v, v) + 0.5 * np.dot(w, mv(md.hub_J[i], w))
            V -= md.hub_m[i] * np.dot(g, ws.pw[el0])
        for j in range(md.k[i]):
            el = el0 + j
            e = ws.e[el]
            ed = ws.ed[el]
            R = ws.Rw[el]
            v0 = ws.vl[el]
            w0 = ws.wl[el]
            for gp in range(4):
                Sg = md.Sig[i, gp]
                Pg = md.Psi[i, gp]
                s = md.s0[i, gp] + mv(Sg, e)
                psi = mv(Pg, e)
                psid = mv(Pg, ed)
                E, J, _jd = exp_jl(psi, psid)
                vg = v0 + cross(w0, s) + mv(Sg, ed)
                wg = w0 + mv(J, psid)
                wb = mtv(E, wg)
                Ig = md.Ig[i, gp]
                m = md.mg[i, gp]
                T += 0.5 * m * np.dot(vg, vg) + 0.5 * (
                    Ig[0] * wb[0] ** 2 + Ig[1] * wb[1] ** 2 + Ig[2] * wb[2] ** 2
                )
                V -= m * np.dot(g, ws.pw[el] + mv(R, s))
            V += strain_energy(md, i, e)
        if md.pay_m[i] > 0.0 or np.any(md.pay_J[i] != 0.0):
            Qi = md.Q[i]
            vO = mv(Qi.T, ws.vT[i + 1])
            wO = mv(Qi.T, ws.wT[i + 1])
            d = md.pay_d[i]
            vc = vO + cross(wO, d)
            RO = mm(ws.RT[i + 1], Qi)
            T += 0.5 * md.pay_m[i] * np.dot(vc, vc) + 0.5 * np.dot(wO, mv(md.pay_J[i], wO))
            V -= md.pay_m[i] * np.dot(g, ws.pT[i + 1] + mv(RO, d))
    return T + V
