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


# ---------------------------------------------------------------- rotations -----------------


def _series(k0, n, deriv=False):
    """Coefficients (lowest power first) of Σ (−t)^k/(2k + k0)! or of its derivative in t."""
    if not deriv:
        return tuple((-1.0) ** k / math.factorial(2 * k + k0) for k in range(n))
    return tuple((k + 1) * (-1.0) ** (k + 1) / math.factorial(2 * k + 2 + k0) for k in range(n))


#: Taylor coefficients in θ² of sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³ and the derivatives of
#: the last two in θ²; 10 terms (θ² < 1: truncation < 1e-19) and 5 (θ² < 1e-2: < 1e-18)
_A, _B, _C = _series(1, 10), _series(2, 10), _series(3, 10)
_DB, _DC = _series(2, 10, True), _series(3, 10, True)
_A5, _B5, _C5 = _series(1, 5), _series(2, 5), _series(3, 5)
_DB5, _DC5 = _series(2, 5, True), _series(3, 5, True)


@njit(inline="always")
def _horner(cs, t):
    acc = 0.0
    for k in range(len(cs) - 1, -1, -1):
        acc = acc * t + cs[k]
    return acc


@njit(inline="always")
def so3_coefficients(t2):
    """(sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³) and the derivatives of the last two in θ²,
    at θ² = t2 (Taylor series for θ < 1, closed forms beyond)."""
    if t2 < 1e-2:
        return _horner(_A5, t2), _horner(_B5, t2), _horner(_C5, t2), _horner(_DB5, t2), _horner(_DC5, t2)
    if t2 < 1.0:
        return _horner(_A, t2), _horner(_B, t2), _horner(_C, t2), _horner(_DB, t2), _horner(_DC, t2)
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


@njit(nrt=False)
def kin_link(md, ws, i, q, qd, R, p, v, w):
    """Frames, origins and velocities of the elements of link i into ``ws``, from the root
    element frame (R, p; v, ω in its components), which move in place to the last outboard node."""
    S4 = md.Sig[i, 4]
    s04 = md.s0[i, 4]
    J = ws.J3
    T = ws.Iw
    for j in range(md.k[i]):
        el = md.el0[i] + j
        e = ws.e[el]
        ed = ws.ed[el]
        unpack(md, i, j, q, qd, e, ed)
        for a in range(3):
            ws.pw[el, a] = p[a]
            ws.vl[el, a] = v[a]
            ws.wl[el, a] = w[a]
            for b in range(3):
                ws.Rw[el, a, b] = R[a, b]
        E = ws.E[el]
        so3_into(e[3], e[4], e[5], ed[3], ed[4], ed[5], E, J, ws.jd3)
        x0 = s04[0]
        x1 = s04[1]
        x2 = s04[2]
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        for cc in range(6):
            x0 += S4[0, cc] * e[cc]
            x1 += S4[1, cc] * e[cc]
            x2 += S4[2, cc] * e[cc]
            d0 += S4[0, cc] * ed[cc]
            d1 += S4[1, cc] * ed[cc]
            d2 += S4[2, cc] * ed[cc]
        for a in range(3):
            p[a] += R[a, 0] * x0 + R[a, 1] * x1 + R[a, 2] * x2
        vo0 = v[0] + w[1] * x2 - w[2] * x1 + d0
        vo1 = v[1] + w[2] * x0 - w[0] * x2 + d1
        vo2 = v[2] + w[0] * x1 - w[1] * x0 + d2
        wo0 = w[0] + J[0, 0] * ed[3] + J[0, 1] * ed[4] + J[0, 2] * ed[5]
        wo1 = w[1] + J[1, 0] * ed[3] + J[1, 1] * ed[4] + J[1, 2] * ed[5]
        wo2 = w[2] + J[2, 0] * ed[3] + J[2, 1] * ed[4] + J[2, 2] * ed[5]
        for a in range(3):
            v[a] = E[0, a] * vo0 + E[1, a] * vo1 + E[2, a] * vo2
            w[a] = E[0, a] * wo0 + E[1, a] * wo1 + E[2, a] * wo2
            for b in range(3):
                T[a, b] = R[a, 0] * E[0, b] + R[a, 1] * E[1, b] + R[a, 2] * E[2, b]
        for a in range(3):
            for b in range(3):
                R[a, b] = T[a, b]


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
        kin_link(md, ws, i, q, qd, R, p, v, w)
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


@njit(inline="always")
def so3_into(x, y, z, dx, dy, dz, E, J, jd):
    """exp([ψ]×) into E, J_L(ψ) into J and J̇_L ψ̇ into jd, at ψ = (x, y, z), ψ̇ = (dx, dy, dz)."""
    t2 = x * x + y * y + z * z
    a, b, c, db, dc = so3_coefficients(t2)
    q00 = x * x - t2
    q11 = y * y - t2
    q22 = z * z - t2
    q01 = x * y
    q02 = x * z
    q12 = y * z
    E[0, 0] = 1.0 + b * q00
    E[0, 1] = -a * z + b * q01
    E[0, 2] = a * y + b * q02
    E[1, 0] = a * z + b * q01
    E[1, 1] = 1.0 + b * q11
    E[1, 2] = -a * x + b * q12
    E[2, 0] = -a * y + b * q02
    E[2, 1] = a * x + b * q12
    E[2, 2] = 1.0 + b * q22
    J[0, 0] = 1.0 + c * q00
    J[0, 1] = -b * z + c * q01
    J[0, 2] = b * y + c * q02
    J[1, 0] = b * z + c * q01
    J[1, 1] = 1.0 + c * q11
    J[1, 2] = -b * x + c * q12
    J[2, 0] = -b * y + c * q02
    J[2, 1] = b * x + c * q12
    J[2, 2] = 1.0 + c * q22
    pp = 2.0 * (x * dx + y * dy + z * dz)
    u0 = y * dz - z * dy
    u1 = z * dx - x * dz
    u2 = x * dy - y * dx
    jd[0] = db * pp * u0 + dc * pp * (y * u2 - z * u1) + c * (dy * u2 - dz * u1)
    jd[1] = db * pp * u1 + dc * pp * (z * u0 - x * u2) + c * (dz * u0 - dx * u2)
    jd[2] = db * pp * u2 + dc * pp * (x * u1 - y * u0) + c * (dx * u1 - dy * u0)


@njit(inline="always")
def elastic_into(md, i, e, f, KT, D):
    """Elastic force f(e), tangent K_T(e) and damping matrix D(e) of an element of link i into
    f, KT, D: linear K e, K, μK; second order (ε = u/l + ½(bᵀGb + cᵀGc), b = (v, φz),
    c = (w, −φy)) f = K_b e + EA l ε ∂ε, K_T = K_b + EA l (∂ε∂εᵀ + ε ∂²ε), D = μ(EA l ∂ε∂εᵀ + K_b)."""
    mu = md.mu[i]
    if md.so[i] == 0:
        K = md.K[i]
        for r in range(6):
            t = 0.0
            for s in range(6):
                k = K[r, s]
                t += k * e[s]
                KT[r, s] = k
                D[r, s] = mu * k
            f[r] = t
        return
    Kb = md.Kb[i]
    G = md.G[i]
    l = md.l[i]
    EAl = md.EA[i] * l
    b0 = e[1]
    b1 = e[5]
    c0 = e[2]
    c1 = -e[4]
    gb0 = G[0, 0] * b0 + G[0, 1] * b1
    gb1 = G[1, 0] * b0 + G[1, 1] * b1
    gc0 = G[0, 0] * c0 + G[0, 1] * c1
    gc1 = G[1, 0] * c0 + G[1, 1] * c1
    eps = e[0] / l + 0.5 * (b0 * gb0 + b1 * gb1 + c0 * gc0 + c1 * gc1)
    g = (1.0 / l, gb0, gc0, 0.0, -gc1, gb1)
    for r in range(6):
        t = 0.0
        for s in range(6):
            t += Kb[r, s] * e[s]
            gg = EAl * g[r] * g[s]
            KT[r, s] = Kb[r, s] + gg
            D[r, s] = mu * (gg + Kb[r, s])
        f[r] = t + EAl * eps * g[r]
    h = EAl * eps
    KT[1, 1] += h * G[0, 0]
    KT[1, 5] += h * G[0, 1]
    KT[5, 1] += h * G[1, 0]
    KT[5, 5] += h * G[1, 1]
    KT[2, 2] += h * G[0, 0]
    KT[2, 4] -= h * G[0, 1]
    KT[4, 2] -= h * G[1, 0]
    KT[4, 4] += h * G[1, 1]


@njit(inline="always")
def cholesky_solve_into(M, L, sol):
    """Solve M[6:, 6:] X = −[M[6:, :6] | r] (the rhs already in ``sol``) in place, by Cholesky
    into L. Returns ok (False when the block is not positive definite)."""
    for j in range(6):
        t = M[6 + j, 6 + j]
        for k in range(j):
            t -= L[j, k] * L[j, k]
        if not t > 0.0:
            return False
        d = math.sqrt(t)
        L[j, j] = d
        for i in range(j + 1, 6):
            u = M[6 + i, 6 + j]
            for k in range(j):
                u -= L[i, k] * L[j, k]
            L[i, j] = u / d
    for c in range(7):
        for i in range(6):
            t = sol[i, c]
            for k in range(i):
                t -= L[i, k] * sol[k, c]
            sol[i, c] = t / L[i, i]
        for i in range(5, -1, -1):
            t = sol[i, c]
            for k in range(i + 1, 6):
                t -= L[k, i] * sol[k, c]
            sol[i, c] = t / L[i, i]
    return True


@njit(nrt=False)
def element_step(md, i, el, g0, g1, g2, cq, cv, ehat, edhat, fext, ws):
    """Backward step over element ``el`` of link i, in place: ws.P, ws.c from the outboard node
    (outboard frame components) to the element's root (its own frame components); keeps the
    gains ë = Ka A + k0 and the outboard maps in ``ws``. (g0, g1, g2): gravity in the element
    frame. Returns ok."""
    e = ws.e[el]
    ed = ws.ed[el]
    w0 = ws.wl[el, 0]
    w1 = ws.wl[el, 1]
    w2 = ws.wl[el, 2]
    M = ws.M12
    r = ws.r12
    H = ws.H
    B = ws.B
    E = ws.E3
    J = ws.J3
    jd = ws.jd3
    Iw = ws.Iw
    for a in range(12):
        r[a] = 0.0
        for b in range(12):
            M[a, b] = 0.0
    ms0 = 0.0
    ms1 = 0.0
    ms2 = 0.0
    for gp in range(5):
        Sg = md.Sig[i, gp]
        Pg = md.Psi[i, gp]
        s0 = md.s0[i, gp]
        x0 = s0[0]
        x1 = s0[1]
        x2 = s0[2]
        d0 = 0.0
        d1 = 0.0
        d2 = 0.0
        p0 = 0.0
        p1 = 0.0
        p2 = 0.0
        q0 = 0.0
        q1 = 0.0
        q2 = 0.0
        for cc in range(6):
            ec = e[cc]
            edc = ed[cc]
            x0 += Sg[0, cc] * ec
            x1 += Sg[1, cc] * ec
            x2 += Sg[2, cc] * ec
            d0 += Sg[0, cc] * edc
            d1 += Sg[1, cc] * edc
            d2 += Sg[2, cc] * edc
            p0 += Pg[0, cc] * ec
            p1 += Pg[1, cc] * ec
            p2 += Pg[2, cc] * ec
            q0 += Pg[0, cc] * edc
            q1 += Pg[1, cc] * edc
            q2 += Pg[2, cc] * edc
        so3_into(p0, p1, p2, q0, q1, q2, E, J, jd)
        j0 = J[0, 0] * q0 + J[0, 1] * q1 + J[0, 2] * q2
        j1 = J[1, 0] * q0 + J[1, 1] * q1 + J[1, 2] * q2
        j2 = J[2, 0] * q0 + J[2, 1] * q1 + J[2, 2] * q2
        # accelerations: a_g = X A + S ë + ζ, ζ = (ω×(ω×s) + 2ω×ṡ, ω×(J ψ̇) + J̇ ψ̇)
        u0 = w1 * x2 - w2 * x1
        u1 = w2 * x0 - w0 * x2
        u2 = w0 * x1 - w1 * x0
        zl0 = w1 * u2 - w2 * u1 + 2.0 * (w1 * d2 - w2 * d1)
        zl1 = w2 * u0 - w0 * u2 + 2.0 * (w2 * d0 - w0 * d2)
        zl2 = w0 * u1 - w1 * u0 + 2.0 * (w0 * d1 - w1 * d0)
        za0 = w1 * j2 - w2 * j1 + jd[0]
        za1 = w2 * j0 - w0 * j2 + jd[1]
        za2 = w0 * j1 - w1 * j0 + jd[2]
        if gp < 4:
            m = md.mg[i, gp]
            Ig = md.Ig[i, gp]
            # translational: the blocks of m GᵀG, G = [I, −[s]×, Σ], that depend on e; the
            # constant ones (Σm I, Σ mΣ, Σ mΣᵀΣ) and −[Σ m s]× are added after the loop
            fl0 = m * (zl0 - g0)
            fl1 = m * (zl1 - g1)
            fl2 = m * (zl2 - g2)
            r[0] += fl0
            r[1] += fl1
            r[2] += fl2
            r[3] += x1 * fl2 - x2 * fl1
            r[4] += x2 * fl0 - x0 * fl2
            r[5] += x0 * fl1 - x1 * fl0
            ms0 += m * x0
            ms1 += m * x1
            ms2 += m * x2
            ss = x0 * x0 + x1 * x1 + x2 * x2
            M[3, 3] += m * (ss - x0 * x0)
            M[3, 4] -= m * x0 * x1
            M[3, 5] -= m * x0 * x2
            M[4, 4] += m * (ss - x1 * x1)
            M[4, 5] -= m * x1 * x2
            M[5, 5] += m * (ss - x2 * x2)
            for cc in range(6):
                s0c = Sg[0, cc]
                s1c = Sg[1, cc]
                s2c = Sg[2, cc]
                r[6 + cc] += s0c * fl0 + s1c * fl1 + s2c * fl2
                M[3, 6 + cc] += m * (x1 * s2c - x2 * s1c)
                M[4, 6 + cc] += m * (x2 * s0c - x0 * s2c)
                M[5, 6 + cc] += m * (x0 * s1c - x1 * s0c)
            # rotational: Hᵀ Iw H with H = [0, I, J Ψ]
            for a in range(3):
                for b in range(3):
                    Iw[a, b] = (
                        E[a, 0] * Ig[0] * E[b, 0] + E[a, 1] * Ig[1] * E[b, 1] + E[a, 2] * Ig[2] * E[b, 2]
                    )
            wg0 = w0 + j0
            wg1 = w1 + j1
            wg2 = w2 + j2
            h0 = Iw[0, 0] * wg0 + Iw[0, 1] * wg1 + Iw[0, 2] * wg2
            h1 = Iw[1, 0] * wg0 + Iw[1, 1] * wg1 + Iw[1, 2] * wg2
            h2 = Iw[2, 0] * wg0 + Iw[2, 1] * wg1 + Iw[2, 2] * wg2
            fa0 = Iw[0, 0] * za0 + Iw[0, 1] * za1 + Iw[0, 2] * za2 + wg1 * h2 - wg2 * h1
            fa1 = Iw[1, 0] * za0 + Iw[1, 1] * za1 + Iw[1, 2] * za2 + wg2 * h0 - wg0 * h2
            fa2 = Iw[2, 0] * za0 + Iw[2, 1] * za1 + Iw[2, 2] * za2 + wg0 * h1 - wg1 * h0
            for cc in range(6):
                for a in range(3):
                    H[a, 6 + cc] = J[a, 0] * Pg[0, cc] + J[a, 1] * Pg[1, cc] + J[a, 2] * Pg[2, cc]
                for a in range(3):
                    B[a, 6 + cc] = Iw[a, 0] * H[0, 6 + cc] + Iw[a, 1] * H[1, 6 + cc] + Iw[a, 2] * H[2, 6 + cc]
            r[3] += fa0
            r[4] += fa1
            r[5] += fa2
            for a in range(3):
                for b in range(a, 3):
                    M[3 + a, 3 + b] += Iw[a, b]
            for a in range(6):
                ha0 = H[0, 6 + a]
                ha1 = H[1, 6 + a]
                ha2 = H[2, 6 + a]
                r[6 + a] += ha0 * fa0 + ha1 * fa1 + ha2 * fa2
                M[3, 6 + a] += B[0, 6 + a]
                M[4, 6 + a] += B[1, 6 + a]
                M[5, 6 + a] += B[2, 6 + a]
                for b in range(a, 6):
                    M[6 + a, 6 + b] += ha0 * B[0, 6 + b] + ha1 * B[1, 6 + b] + ha2 * B[2, 6 + b]
        else:
            # the outboard node: its frame exp(φ); its maps W = [X | S], X = [[I, −[s]×], [0, I]],
            # S = [[D, 0], [0, J]] (D = diag(1 or 0 for the dummy u, 1, 1), checked by build_model)
            for a in range(3):
                for b in range(3):
                    ws.E[el, a, b] = E[a, b]
            W = ws.XS[el]
            for a in range(6):
                for b in range(12):
                    W[a, b] = 0.0
            for a in range(3):
                W[a, a] = 1.0
                W[3 + a, 3 + a] = 1.0
                W[a, 6 + a] = Sg[a, a]
                for b in range(3):
                    W[3 + a, 9 + b] = J[a, b]
            W[0, 4] = x2
            W[0, 5] = -x1
            W[1, 3] = -x2
            W[1, 5] = x0
            W[2, 3] = x1
            W[2, 4] = -x0
            zO = ws.zO[el]
            zO[0] = zl0
            zO[1] = zl1
            zO[2] = zl2
            zO[3] = za0
            zO[4] = za1
            zO[5] = za2
            # the outboard P, c in this frame: B P Bᵀ, B c with B = blockdiag(E, E)
            P = ws.P
            Pr = ws.Pr
            T = ws.PW  # scratch: E·P by blocks into T[:, :6]
            cr = ws.cr
            c = ws.c
            for bi in range(2):
                for bj in range(2):
                    for a in range(3):
                        for b in range(3):
                            T[3 * bi + a, 3 * bj + b] = (
                                E[a, 0] * P[3 * bi, 3 * bj + b]
                                + E[a, 1] * P[3 * bi + 1, 3 * bj + b]
                                + E[a, 2] * P[3 * bi + 2, 3 * bj + b]
                            )
                for a in range(3):
                    cr[3 * bi + a] = E[a, 0] * c[3 * bi] + E[a, 1] * c[3 * bi + 1] + E[a, 2] * c[3 * bi + 2]
            for a in range(6):
                for bj in range(2):
                    for b in range(3):
                        Pr[a, 3 * bj + b] = (
                            T[a, 3 * bj] * E[b, 0] + T[a, 3 * bj + 1] * E[b, 1] + T[a, 3 * bj + 2] * E[b, 2]
                        )
            # ρ = Pr ζ + cr
            for a in range(6):
                t = cr[a]
                for k in range(6):
                    t += Pr[a, k] * zO[k]
                cr[a] = t
            # PW = Pr W = [Pr X | Pr S]
            PW = ws.PW
            for a in range(6):
                p0_ = Pr[a, 0]
                p1_ = Pr[a, 1]
                p2_ = Pr[a, 2]
                PW[a, 0] = p0_
                PW[a, 1] = p1_
                PW[a, 2] = p2_
                # −P[:, :3][s]× : row (p0, p1, p2)·(−[s]×) = (p1 x2 − p2 x1, p2 x0 − p0 x2, p0 x1 − p1 x0)
                PW[a, 3] = Pr[a, 3] + p1_ * (-x2) + p2_ * x1
                PW[a, 4] = Pr[a, 4] + p0_ * x2 + p2_ * (-x0)
                PW[a, 5] = Pr[a, 5] + p0_ * (-x1) + p1_ * x0
                PW[a, 6] = p0_ * W[0, 6]
                PW[a, 7] = p1_ * W[1, 7]
                PW[a, 8] = p2_ * W[2, 8]
                for b in range(3):
                    PW[a, 9 + b] = Pr[a, 3] * J[0, b] + Pr[a, 4] * J[1, b] + Pr[a, 5] * J[2, b]
            # Xᵀ on the rows of PW (rows A), Sᵀ (rows e, columns e): [s]× Y[:3] + Y[3:]
            for b in range(12):
                y0 = PW[0, b]
                y1 = PW[1, b]
                y2 = PW[2, b]
                for a in range(3):
                    if b >= a:
                        M[a, b] += PW[a, b]
                k0_ = x1 * y2 - x2 * y1 + PW[3, b]
                k1_ = x2 * y0 - x0 * y2 + PW[4, b]
                k2_ = x0 * y1 - x1 * y0 + PW[5, b]
                if b >= 3:
                    M[3, b] += k0_
                if b >= 4:
                    M[4, b] += k1_
                if b >= 5:
                    M[5, b] += k2_
            for a in range(3):
                for b in range(6):
                    if 6 + b >= 6 + a:
                        M[6 + a, 6 + b] += W[a, 6 + a] * PW[a, 6 + b]
                    if 9 + a <= 6 + b:
                        M[9 + a, 6 + b] += (
                            J[0, a] * PW[3, 6 + b] + J[1, a] * PW[4, 6 + b] + J[2, a] * PW[5, 6 + b]
                        )
            y0 = cr[0]
            y1 = cr[1]
            y2 = cr[2]
            r[0] += y0
            r[1] += y1
            r[2] += y2
            r[3] += x1 * y2 - x2 * y1 + cr[3]
            r[4] += x2 * y0 - x0 * y2 + cr[4]
            r[5] += x0 * y1 - x1 * y0 + cr[5]
            for a in range(3):
                r[6 + a] += W[a, 6 + a] * cr[a]
                r[9 + a] += J[0, a] * cr[3] + J[1, a] * cr[4] + J[2, a] * cr[5]
    # the constant translational blocks and −[Σ m s]×
    mel = md.mel[i]
    M[0, 0] += mel
    M[1, 1] += mel
    M[2, 2] += mel
    M[0, 4] += ms2
    M[0, 5] -= ms1
    M[1, 3] -= ms2
    M[1, 5] += ms0
    M[2, 3] += ms1
    M[2, 4] -= ms0
    CS = md.CS[i]
    CSS = md.CSS[i]
    for a in range(6):
        M[0, 6 + a] += CS[0, a]
        M[1, 6 + a] += CS[1, a]
        M[2, 6 + a] += CS[2, a]
        for b in range(a, 6):
            M[6 + a, 6 + b] += CSS[a, b]
    for a in range(12):
        for b in range(a + 1, 12):
            M[b, a] = M[a, b]
    f = ws.f6
    KT = ws.KT
    D = ws.D6
    elastic_into(md, i, e, f, KT, D)
    for a in range(6):
        t = f[a] - fext[a]
        for b in range(6):
            t += KT[a, b] * (ehat[b] - e[b]) + D[a, b] * edhat[b]
            M[6 + a, 6 + b] += cq * KT[a, b] + cv * D[a, b]
        r[6 + a] += t
    if md.ext[i] == 0:  # the dummy u: unit mass, no coupling, no load
        for a in range(12):
            M[6, a] = 0.0
            M[a, 6] = 0.0
        M[6, 6] = 1.0
        r[6] = 0.0
    sol = ws.sol
    for a in range(6):
        for b in range(6):
            sol[a, b] = -M[6 + a, b]
        sol[a, 6] = -r[6 + a]
    ok = cholesky_solve_into(M, ws.L, sol)
    P = ws.P
    c = ws.c
    for a in range(6):
        for b in range(6):
            ws.Ka[el, a, b] = sol[a, b]
        ws.k0[el, a] = sol[a, 6]
    for a in range(6):
        t = r[a]
        for k in range(6):
            t += M[6 + k, a] * sol[k, 6]
        c[a] = t
        for b in range(a, 6):
            t = M[a, b]
            for k in range(6):
                t += M[6 + k, a] * sol[k, b]
            P[a, b] = t
    for a in range(6):
        for b in range(a):
            P[a, b] = P[b, a]
    return ok


#: per-link input rows (``mot`` of :func:`sweep`): columns 0–2 the motion law (α, α̇, α̈), then
#: from LOAD_COL on the external load at the link's tip (dttmm.spatial.scenario.load_inputs):
#: world force, world moment, tip-frame force, tip-frame moment
LOAD_COL = 3
INPUT_COLS = LOAD_COL + 12


@njit(inline="always")
def tip_load(inp, i, RO, Qi, c):
    """The external load at the tip of link i (``inp[i, LOAD_COL:]``, when the rows have those
    columns) into the bias c of the outboard element frame RO (world), moment about the tip point:
    the inboard part then exerts P·A + c − (F, M). Tip-frame components x_T become Qᵀ x_T."""
    if inp.shape[1] < INPUT_COLS:
        return
    k = LOAD_COL
    for a in range(3):
        fw = RO[0, a] * inp[i, k] + RO[1, a] * inp[i, k + 1] + RO[2, a] * inp[i, k + 2]
        mw = RO[0, a] * inp[i, k + 3] + RO[1, a] * inp[i, k + 4] + RO[2, a] * inp[i, k + 5]
        ft = Qi[0, a] * inp[i, k + 6] + Qi[1, a] * inp[i, k + 7] + Qi[2, a] * inp[i, k + 8]
        mt = Qi[0, a] * inp[i, k + 9] + Qi[1, a] * inp[i, k + 10] + Qi[2, a] * inp[i, k + 11]
        c[a] -= fw + ft
        c[3 + a] -= mw + mt


@njit(nrt=False)
def backward_link(md, ws, i, cq, cv, qhat, qdhat, forces, ehat, edhat, fext):
    """The backward sweep over the elements of link i, in place on ws.P, ws.c (tip → root),
    keeping each element root's (P, c) in ws.Pc. Returns ok."""
    ok = True
    for j in range(md.k[i] - 1, -1, -1):
        el = md.el0[i] + j
        Rw = ws.Rw[el]
        gv = md.grav
        g0 = Rw[0, 0] * gv[0] + Rw[1, 0] * gv[1] + Rw[2, 0] * gv[2]
        g1 = Rw[0, 1] * gv[0] + Rw[1, 1] * gv[1] + Rw[2, 1] * gv[2]
        g2 = Rw[0, 2] * gv[0] + Rw[1, 2] * gv[1] + Rw[2, 2] * gv[2]
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
        good = element_step(md, i, el, g0, g1, g2, cq, cv, ehat, edhat, fext, ws)
        ok = ok and good
        for r in range(6):
            for s in range(6):
                ws.Pc[el, r, s] = ws.P[r, s]
            ws.Pc[el, r, 6] = ws.c[r]
    return ok


@njit(nrt=False)
def forward_link(md, ws, i, A, qdd, want_loads, loads, ic):
    """The forward sweep over the elements of link i: A (root acceleration of the link, its own
    frame) in place to the outboard node of the last element, ë into qdd, cut loads from row
    ``ic`` on. Returns the next cut row."""
    for j in range(md.k[i]):
        el = md.el0[i] + j
        if want_loads:
            f = ws.A6b
            Pc = ws.Pc[el]
            for a in range(6):
                t = Pc[a, 6]
                for b in range(6):
                    t += Pc[a, b] * A[b]
                f[a] = t
            Rw = ws.Rw[el]
            for bl in range(2):
                for a in range(3):
                    loads[ic, 3 * bl + a] = (
                        Rw[a, 0] * f[3 * bl] + Rw[a, 1] * f[3 * bl + 1] + Rw[a, 2] * f[3 * bl + 2]
                    )
        ic += 1
        edd = ws.f6
        Ka = ws.Ka[el]
        for a in range(6):
            t = ws.k0[el, a]
            for b in range(6):
                t += Ka[a, b] * A[b]
            edd[a] = t
        r0 = md.ie[el]
        if md.ext[i] == 1:
            for s in range(6):
                qdd[r0 + s] = edd[s]
        else:
            for s in range(5):
                qdd[r0 + s] = edd[s + 1]
        W = ws.XS[el]
        AO = ws.cr
        for a in range(6):
            t = ws.zO[el, a]
            for b in range(6):
                t += W[a, b] * A[b] + W[a, 6 + b] * edd[b]
            AO[a] = t
        E = ws.E[el]
        for bl in range(2):
            for a in range(3):
                A[3 * bl + a] = E[0, a] * AO[3 * bl] + E[1, a] * AO[3 * bl + 1] + E[2, a] * AO[3 * bl + 2]
    return ic


@njit()
def sweep(md, ws, cq, cv, qhat, qdhat, tau, mot, forces, qdd, want_loads, loads):
    """One Riccati sweep at the kinematics in ``ws`` (from :func:`kinematics`): q̈ into ``qdd``,
    per joint α̈ and torque into ws.acc, and with ``want_loads`` the cut loads (nel + n, 6)
    (force, moment; world components) at every element root and link tip. ``qhat``/``qdhat``:
    the known parts of the elastic coordinates and rates (Newmark predictors; the state itself
    for the acceleration solver, with cq = cv = 0). ``tau`` (n,): torques of torque joints;
    ``mot`` (n, 3) or (n, INPUT_COLS): α, α̇, α̈ of motion joints (and the tip loads, see
    :func:`tip_load`); ``forces`` (n_dof,) generalized forces on the
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
        tip_load(mot, i, RO, Qi, c)
        for r in range(6):
            for s in range(6):
                ws.Ptip[i, r, s] = P[r, s]
            ws.Ptip[i, r, 6] = c[r]
        for r in range(6):
            ws.c[r] = c[r]
            for s in range(6):
                ws.P[r, s] = P[r, s]
        ok = backward_link(md, ws, i, cq, cv, qhat, qdhat, forces, ehat, edhat, fext) and ok
        P = ws.P.copy()
        c = ws.c.copy()
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
                # a closed-loop torque τ = tau + slope·α̈ (its law linearised in α̈) acts as a
                # joint stiffness: sᵀP s − slope in the projection (0 for an open-loop torque)
                Dj = np.dot(s6, Ps) - ws.slope[i]
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
                Dj = np.dot(s6, Ps) - ws.slope[i]
                add = (tau[i] + forces[md.ia[i]] - np.dot(s6, mv(PF[:, :6], A) + PF[:, 6])) / Dj
            for r in range(3):
                A[3 + r] += aF[r] * add
            qdd[md.ia[i]] = add
            ws.acc[i, 0] = add
            fF = mv(PF[:, :6], A) + PF[:, 6]
            ws.acc[i, 1] = np.dot(s6, fF)
        for r in range(3):  # the link root's angular acceleration (closed-loop moment feedback)
            ws.wdF[i, r] = A[3 + r]
        ic = forward_link(md, ws, i, A, qdd, want_loads, loads, ic)
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
