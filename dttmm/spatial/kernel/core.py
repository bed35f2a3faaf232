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


@njit(inline="always")
def copy3(a, b):
    b[0] = a[0]
    b[1] = a[1]
    b[2] = a[2]


@njit(inline="always")
def copy33(A, B):
    for a in range(3):
        for b in range(3):
            B[a, b] = A[a, b]


@njit(inline="always")
def matmul33(A, B, C):
    """C = A B (3×3, C distinct from A and B)."""
    for a in range(3):
        for b in range(3):
            C[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]


@njit(inline="always")
def matmul33t(A, B, C):
    """C = A Bᵀ (3×3, C distinct from A and B)."""
    for a in range(3):
        for b in range(3):
            C[a, b] = A[a, 0] * B[b, 0] + A[a, 1] * B[b, 1] + A[a, 2] * B[b, 2]


@njit(inline="always")
def axis_rotation_into(ax, ang, R):
    """Rodrigues: the rotation by ``ang`` about the unit axis ``ax`` into R."""
    x, y, z = ax[0], ax[1], ax[2]
    s = math.sin(ang)
    c = 1.0 - math.cos(ang)
    # K² = a aᵀ − |a|² I
    t2 = x * x + y * y + z * z
    R[0, 0] = 1.0 + c * (x * x - t2)
    R[0, 1] = -s * z + c * (x * y)
    R[0, 2] = s * y + c * (x * z)
    R[1, 0] = s * z + c * (x * y)
    R[1, 1] = 1.0 + c * (y * y - t2)
    R[1, 2] = -s * x + c * (y * z)
    R[2, 0] = -s * y + c * (x * z)
    R[2, 1] = s * x + c * (y * z)
    R[2, 2] = 1.0 + c * (z * z - t2)


@njit(inline="always", nrt=False)
def kin_rigid(md, ws, i, R, p, v, w):
    """Kinematics of rigid link i (docs/spatial.md §5, "Rigid links"): its k slots are rigid
    segments s = (l, 0, 0) with no coordinates (e = 0, exp(φ) = J_L = I); (R, p; v, ω) move in
    place from the link frame to its tip (R and ω unchanged)."""
    l = md.l[i]
    for j in range(md.k[i]):
        el = md.el0[i] + j
        for a in range(3):
            ws.pw[el, a] = p[a]
            ws.vl[el, a] = v[a]
            ws.wl[el, a] = w[a]
            ws.jdO[el, a] = 0.0
            ws.sO[el, a] = 0.0
            for b in range(3):
                ws.Rw[el, a, b] = R[a, b]
                ws.E[el, a, b] = 1.0 if a == b else 0.0
                ws.JO[el, a, b] = 1.0 if a == b else 0.0
        for a in range(6):
            ws.e[el, a] = 0.0
            ws.ed[el, a] = 0.0
        ws.sO[el, 0] = l
        for a in range(3):
            p[a] += R[a, 0] * l
        # v ← v + ω × (l, 0, 0)
        v[1] += w[2] * l
        v[2] -= w[1] * l


@njit(inline="always", nrt=False)
def kin_link(md, ws, i, q, qd, R, p, v, w):
    """Frames, origins and velocities of the elements of link i into ``ws``, from the root
    element frame (R, p; v, ω in its components), which move in place to the last outboard node.
    Keeps each outboard node's exp(φ), J_L(φ), J̇_L φ̇ and position (ws.E, JO, jdO, sO) for the
    sweeps."""
    if md.rigid[i] == 1:
        kin_rigid(md, ws, i, R, p, v, w)
        return
    S4 = md.Sig[i, 4]
    s04 = md.s0[i, 4]
    T = ws.Tk
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
        J = ws.JO[el]
        so3_into(e[3], e[4], e[5], ed[3], ed[4], ed[5], E, J, ws.jdO[el])
        # the node's position and rate: S4 = [D | 0] (checked by build_model)
        x0 = s04[0] + S4[0, 0] * e[0]
        x1 = s04[1] + e[1]
        x2 = s04[2] + e[2]
        d0 = S4[0, 0] * ed[0]
        d1 = ed[1]
        d2 = ed[2]
        ws.sO[el, 0] = x0
        ws.sO[el, 1] = x1
        ws.sO[el, 2] = x2
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
        matmul33(R, E, T)
        copy33(T, R)


@njit(nrt=False)
def kinematics(md, ws, q, qd):
    """Frames, origins and velocities of every element and link tip at (q, q̇) into ``ws``."""
    R = ws.Rk
    p = ws.pk
    v = ws.vk
    w = ws.wk
    T = ws.Tk
    U = ws.Uk
    copy33(md.Rbase, R)
    copy3(md.pbase, p)
    for a in range(3):
        v[a] = 0.0
        w[a] = 0.0
    copy33(R, ws.RT[0])
    copy3(p, ws.pT[0])
    copy3(v, ws.vT[0])
    copy3(w, ws.wT[0])
    for i in range(md.n):
        ip = md.par[i] + 1
        if ip != i:  # a branch: start from the parent's tip frame
            copy33(ws.RT[ip], R)
            copy3(ws.pT[ip], p)
            copy3(ws.vT[ip], v)
            copy3(ws.wT[ip], w)
        al = 0.0
        ald = 0.0
        if md.locked[i] == 0:
            al = q[md.ia[i]]
            ald = qd[md.ia[i]]
        # C = R_rpy Rot(a, α) Rx(roll)
        C = ws.C[i]
        axis_rotation_into(md.axis[i], al, T)
        matmul33(md.Crpy[i], T, U)
        matmul33(U, md.Q[i], C)
        o = md.org[i]
        aT = md.aT[i]
        for a in range(3):
            p[a] += R[a, 0] * o[0] + R[a, 1] * o[1] + R[a, 2] * o[2]
        vj0 = v[0] + w[1] * o[2] - w[2] * o[1]
        vj1 = v[1] + w[2] * o[0] - w[0] * o[2]
        vj2 = v[2] + w[0] * o[1] - w[1] * o[0]
        wj0 = w[0] + aT[0] * ald
        wj1 = w[1] + aT[1] * ald
        wj2 = w[2] + aT[2] * ald
        for a in range(3):
            v[a] = C[0, a] * vj0 + C[1, a] * vj1 + C[2, a] * vj2
            w[a] = C[0, a] * wj0 + C[1, a] * wj1 + C[2, a] * wj2
        matmul33(R, C, T)
        copy33(T, R)
        kin_link(md, ws, i, q, qd, R, p, v, w)
        # tip frame: R_O Rx(−roll)
        Qi = md.Q[i]
        v0, v1, v2 = v[0], v[1], v[2]
        w0, w1, w2 = w[0], w[1], w[2]
        for a in range(3):
            v[a] = Qi[a, 0] * v0 + Qi[a, 1] * v1 + Qi[a, 2] * v2
            w[a] = Qi[a, 0] * w0 + Qi[a, 1] * w1 + Qi[a, 2] * w2
        matmul33t(R, Qi, T)
        copy33(T, R)
        copy33(R, ws.RT[i + 1])
        copy3(p, ws.pT[i + 1])
        copy3(v, ws.vT[i + 1])
        copy3(w, ws.wT[i + 1])


@njit(nrt=False)
def tip_frames(md, ws, q):
    """The tip frames and origins of every link at q into ws.RT, ws.pT (as :func:`kinematics`
    computes them, bit for bit), nothing else: the positions of a configuration without its
    velocities and the sweep's element data (the closures' gaps at the sweep's q̈)."""
    R = ws.Rk
    p = ws.pk
    T = ws.Tk
    U = ws.Uk
    copy33(md.Rbase, R)
    copy3(md.pbase, p)
    copy33(R, ws.RT[0])
    copy3(p, ws.pT[0])
    for i in range(md.n):
        ip = md.par[i] + 1
        if ip != i:
            copy33(ws.RT[ip], R)
            copy3(ws.pT[ip], p)
        al = 0.0 if md.locked[i] == 1 else q[md.ia[i]]
        C = ws.C[i]
        axis_rotation_into(md.axis[i], al, T)
        matmul33(md.Crpy[i], T, U)
        matmul33(U, md.Q[i], C)
        o = md.org[i]
        for a in range(3):
            p[a] += R[a, 0] * o[0] + R[a, 1] * o[1] + R[a, 2] * o[2]
        matmul33(R, C, T)
        copy33(T, R)
        if md.rigid[i] == 1:
            l = md.l[i]
            for _j in range(md.k[i]):
                for a in range(3):
                    p[a] += R[a, 0] * l
        else:
            S4 = md.Sig[i, 4]
            s04 = md.s0[i, 4]
            E = ws.E3
            for j in range(md.k[i]):
                r = md.ie[md.el0[i] + j]
                if md.ext[i] == 1:
                    e0 = q[r]
                    r += 1
                else:
                    e0 = 0.0
                x, y, z = q[r + 2], q[r + 3], q[r + 4]
                t2 = x * x + y * y + z * z
                a_, b_, _c, _db, _dc = so3_coefficients(t2)
                E[0, 0] = 1.0 + b_ * (x * x - t2)
                E[0, 1] = -a_ * z + b_ * (x * y)
                E[0, 2] = a_ * y + b_ * (x * z)
                E[1, 0] = a_ * z + b_ * (x * y)
                E[1, 1] = 1.0 + b_ * (y * y - t2)
                E[1, 2] = -a_ * x + b_ * (y * z)
                E[2, 0] = -a_ * y + b_ * (x * z)
                E[2, 1] = a_ * x + b_ * (y * z)
                E[2, 2] = 1.0 + b_ * (z * z - t2)
                x0 = s04[0] + S4[0, 0] * e0
                x1 = s04[1] + q[r]
                x2 = s04[2] + q[r + 1]
                for a in range(3):
                    p[a] += R[a, 0] * x0 + R[a, 1] * x1 + R[a, 2] * x2
                matmul33(R, E, T)
                copy33(T, R)
        matmul33t(R, md.Q[i], T)
        copy33(T, R)
        copy33(R, ws.RT[i + 1])
        copy3(p, ws.pT[i + 1])


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
def so3_scalars(x, y, z, dx, dy, dz):
    """:func:`so3_into` as scalars: the rows of exp([ψ]×) and J_L(ψ), then J̇_L ψ̇ (21 values)."""
    t2 = x * x + y * y + z * z
    a, b, c, db, dc = so3_coefficients(t2)
    q00 = x * x - t2
    q11 = y * y - t2
    q22 = z * z - t2
    q01 = x * y
    q02 = x * z
    q12 = y * z
    pp = 2.0 * (x * dx + y * dy + z * dz)
    u0 = y * dz - z * dy
    u1 = z * dx - x * dz
    u2 = x * dy - y * dx
    return (
        1.0 + b * q00,
        -a * z + b * q01,
        a * y + b * q02,
        a * z + b * q01,
        1.0 + b * q11,
        -a * x + b * q12,
        -a * y + b * q02,
        a * x + b * q12,
        1.0 + b * q22,
        1.0 + c * q00,
        -b * z + c * q01,
        b * y + c * q02,
        b * z + c * q01,
        1.0 + c * q11,
        -b * x + c * q12,
        -b * y + c * q02,
        b * x + c * q12,
        1.0 + c * q22,
        db * pp * u0 + dc * pp * (y * u2 - z * u1) + c * (dy * u2 - dz * u1),
        db * pp * u1 + dc * pp * (z * u0 - x * u2) + c * (dz * u0 - dx * u2),
        db * pp * u2 + dc * pp * (x * u1 - y * u0) + c * (dx * u1 - dy * u0),
    )


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


# ---------------------------------------------------------------- articulated inertias ------


@njit(inline="always")
def rotate_pc(R, tr, P, c, T):
    """In place: P ← B P Bᵀ, c ← B c with B = blockdiag(R, R) (Rᵀ with ``tr``), for a symmetric
    6×6 P (its upper blocks are read, the whole matrix written); T is 3×3 scratch."""
    for bi in range(2):
        for bj in range(bi, 2):
            # T = R · P_blk, then P_blk = T · Rᵀ (upper triangle of a diagonal block)
            for a in range(3):
                for b in range(3):
                    if tr:
                        T[a, b] = (
                            R[0, a] * P[3 * bi, 3 * bj + b]
                            + R[1, a] * P[3 * bi + 1, 3 * bj + b]
                            + R[2, a] * P[3 * bi + 2, 3 * bj + b]
                        )
                    else:
                        T[a, b] = (
                            R[a, 0] * P[3 * bi, 3 * bj + b]
                            + R[a, 1] * P[3 * bi + 1, 3 * bj + b]
                            + R[a, 2] * P[3 * bi + 2, 3 * bj + b]
                        )
            for a in range(3):
                b0 = a if bi == bj else 0
                for b in range(b0, 3):
                    if tr:
                        t = T[a, 0] * R[0, b] + T[a, 1] * R[1, b] + T[a, 2] * R[2, b]
                    else:
                        t = T[a, 0] * R[b, 0] + T[a, 1] * R[b, 1] + T[a, 2] * R[b, 2]
                    P[3 * bi + a, 3 * bj + b] = t
                    P[3 * bj + b, 3 * bi + a] = t
        c0 = c[3 * bi]
        c1 = c[3 * bi + 1]
        c2 = c[3 * bi + 2]
        for a in range(3):
            if tr:
                c[3 * bi + a] = R[0, a] * c0 + R[1, a] * c1 + R[2, a] * c2
            else:
                c[3 * bi + a] = R[a, 0] * c0 + R[a, 1] * c1 + R[a, 2] * c2


@njit(inline="always")
def shift_pc(P, c, s0, s1, s2, N):
    """In place: P ← Xᵀ P X, c ← Xᵀ c with X = [[I, −[s]×], [0, I]] (a load at a point s moved to
    the origin), in closed form: with P = [[A, B], [Bᵀ, C]], N = B − A[s]×,
    Xᵀ P X = [[A, N], [Nᵀ, C + [s]×N − Bᵀ[s]×]]; N is 3×3 scratch."""
    for a in range(3):
        r0 = P[a, 0]
        r1 = P[a, 1]
        r2 = P[a, 2]
        # row a of A[s]× is (A[a, :] × s)
        N[a, 0] = P[a, 3] - (r1 * s2 - r2 * s1)
        N[a, 1] = P[a, 4] - (r2 * s0 - r0 * s2)
        N[a, 2] = P[a, 5] - (r0 * s1 - r1 * s0)
    for a in range(3):
        for b in range(a, 3):
            # ([s]×N)[a, b] = (s × N[:, b])[a];  (Bᵀ[s]×)[a, b] = (B[:, a] × s)[b]
            if a == 0:
                sn = s1 * N[2, b] - s2 * N[1, b]
            elif a == 1:
                sn = s2 * N[0, b] - s0 * N[2, b]
            else:
                sn = s0 * N[1, b] - s1 * N[0, b]
            if b == 0:
                bs = P[1, 3 + a] * s2 - P[2, 3 + a] * s1
            elif b == 1:
                bs = P[2, 3 + a] * s0 - P[0, 3 + a] * s2
            else:
                bs = P[0, 3 + a] * s1 - P[1, 3 + a] * s0
            t = P[3 + a, 3 + b] + sn - bs
            P[3 + a, 3 + b] = t
            P[3 + b, 3 + a] = t
    for a in range(3):
        for b in range(3):
            P[a, 3 + b] = N[a, b]
            P[3 + b, a] = N[a, b]
    f0 = c[0]
    f1 = c[1]
    f2 = c[2]
    c[3] += s1 * f2 - s2 * f1
    c[4] += s2 * f0 - s0 * f2
    c[5] += s0 * f1 - s1 * f0


@njit(inline="always")
def add_translation(P, m, a0, a1, a2):
    """The translational rows of a body's P: P[:3, :3] += m I and −[a]× in the upper right
    (a = m d, d its centre)."""
    P[0, 0] += m
    P[1, 1] += m
    P[2, 2] += m
    P[0, 4] += a2
    P[0, 5] -= a1
    P[1, 3] -= a2
    P[1, 5] += a0
    P[2, 3] += a1
    P[2, 4] -= a0


@njit(inline="always")
def add_rigid(P, c, m, J, d0, d1, d2, f0, f1, f2, n0, n1, n2):
    """A rigid body (mass m, inertia J about its centre d) added at the origin: P += Xᵀ M X =
    [[m I, −m[d]×], [m[d]×, J − m[d]×[d]×]] and c += Xᵀ (f, n) = (f, n + d × f), with (f, n) the
    body's bias load at its centre (X the transfer to d)."""
    md0 = m * d0
    md1 = m * d1
    md2 = m * d2
    dd = d0 * d0 + d1 * d1 + d2 * d2
    add_translation(P, m, md0, md1, md2)
    # m[d]× in the lower left
    P[4, 0] += md2
    P[5, 0] -= md1
    P[3, 1] -= md2
    P[5, 1] += md0
    P[3, 2] += md1
    P[4, 2] -= md0
    # J − m[d]×[d]× = J + m(|d|² I − d dᵀ)
    P[3, 3] += J[0, 0] + m * dd - md0 * d0
    P[4, 4] += J[1, 1] + m * dd - md1 * d1
    P[5, 5] += J[2, 2] + m * dd - md2 * d2
    P[3, 4] += J[0, 1] - md0 * d1
    P[4, 3] += J[1, 0] - md1 * d0
    P[3, 5] += J[0, 2] - md0 * d2
    P[5, 3] += J[2, 0] - md2 * d0
    P[4, 5] += J[1, 2] - md1 * d2
    P[5, 4] += J[2, 1] - md2 * d1
    c[0] += f0
    c[1] += f1
    c[2] += f2
    c[3] += n0 + d1 * f2 - d2 * f1
    c[4] += n1 + d2 * f0 - d0 * f2
    c[5] += n2 + d0 * f1 - d1 * f0


@njit(inline="always")
def nonzero_body(m, J):
    if m > 0.0:
        return True
    for a in range(3):
        for b in range(3):
            if J[a, b] != 0.0:
                return True
    return False


@njit(inline="always")
def schur_into(M, r, L, Y, P, c):
    """The Schur complement of the element's elastic block: M_ee = L Lᵀ (Cholesky; L lower with
    1/L_jj on its diagonal, into L), Y = L⁻¹ [M_eA | r_e] (into Y), P = M_AA − YᵀY and
    c = r_A − Yᵀ y (into P, c); M (12×12 over (A, ë)) and r (12,) hold the upper triangle and
    the right-hand side. Returns ok (False when M_ee is not positive definite)."""
    for j in range(6):
        t = M[6 + j, 6 + j]
        for k in range(j):
            t -= L[j, k] * L[j, k]
        if not t > 0.0:
            return False
        dinv = 1.0 / math.sqrt(t)
        L[j, j] = dinv
        for a in range(j + 1, 6):
            u = M[6 + j, 6 + a]
            for k in range(j):
                u -= L[a, k] * L[j, k]
            L[a, j] = u * dinv
    for a in range(6):
        dinv = L[a, a]
        for b in range(7):
            t = M[b, 6 + a] if b < 6 else r[6 + a]
            for k in range(a):
                t -= L[a, k] * Y[k, b]
            Y[a, b] = t * dinv
    for a in range(6):
        t = r[a]
        for k in range(6):
            t -= Y[k, a] * Y[k, 6]
        c[a] = t
        for b in range(a, 6):
            t = M[a, b]
            for k in range(6):
                t -= Y[k, a] * Y[k, b]
            P[a, b] = t
            P[b, a] = t
    return True


@njit(inline="always", nrt=False)
def element_step(md, i, el, g0, g1, g2, cq, cv, ehat, edhat, fext, ws):
    """Backward step over element ``el`` of link i, in place: ws.P, ws.c from the outboard node
    (outboard frame components) to the element's root (its own frame components); keeps the
    factor of the elastic block and the reduced right-hand sides (ws.Lc, ws.Y) for the forward
    sweep. (g0, g1, g2): gravity in the element frame. Returns ok.

    The element matrix M (12×12 over (A, ë); only its upper triangle is formed) uses the
    structure of the shape tables (build_model checks it): each column of Σ_g and Ψ_g has one
    entry, so a Gauss body's maps cost a scalar per column; the outboard node's rigid transfer is
    the closed form of :func:`shift_pc`; then M_ee = L Lᵀ (Cholesky), Y = L⁻¹ [M_eA | r_e] and
    P_root = M_AA − YᵀY, c_root = r_A − Yᵀ y.

    The passes: :func:`gauss_bodies` (the four Gauss bodies), :func:`constant_blocks`,
    :func:`outboard_node` (the outboard node's P, c through the element), :func:`elastic_forces`,
    then the dummy axial coordinate and :func:`schur_into`."""
    M = ws.M12
    r = ws.r12
    for a in range(12):
        r[a] = 0.0
        for b in range(a, 12):
            M[a, b] = 0.0
    sums = gauss_bodies(md, i, el, g0, g1, g2, ws, M, r)
    constant_blocks(md, i, M, sums)
    outboard_node(md, i, el, ws, M, r)
    elastic_forces(md, i, el, cq, cv, ehat, edhat, fext, ws, M, r)
    if md.ext[i] == 0:  # the dummy u: unit mass, no coupling, no load
        for a in range(6):
            M[a, 6] = 0.0
        for b in range(7, 12):
            M[6, b] = 0.0
        M[6, 6] = 1.0
        r[6] = 0.0
    return schur_into(M, r, ws.Lc[el], ws.Y[el], ws.P, ws.c)


@njit(inline="always", nrt=False)
def gauss_bodies(md, i, el, g0, g1, g2, ws, M, r):
    """The four Gauss bodies of element ``el`` of link i into M (upper triangle) and r: their
    loads (gravity (g0, g1, g2) in the element frame, velocity products) and the blocks of M that
    depend on e (the rotational ones by :func:`gauss_rotation`). Returns the sums
    (Σ m x, Σ m x su, Σ m x n3, Σ m x n4) that :func:`constant_blocks` places."""
    e = ws.e[el]
    ed = ws.ed[el]
    e0 = e[0]
    e1 = e[1]
    e2 = e[2]
    e3 = e[3]
    e4 = e[4]
    e5 = e[5]
    f0_ = ed[0]
    f1_ = ed[1]
    f2_ = ed[2]
    f3_ = ed[3]
    f4_ = ed[4]
    f5_ = ed[5]
    w0 = ws.wl[el, 0]
    w1 = ws.wl[el, 1]
    w2 = ws.wl[el, 2]
    ms0 = 0.0
    ms1 = 0.0
    ms2 = 0.0
    # Σ m x su, Σ m x n3, Σ m x n4 (the e-dependent translational block of M_Ae)
    au0 = 0.0
    au1 = 0.0
    au2 = 0.0
    a30 = 0.0
    a31 = 0.0
    a32 = 0.0
    a40 = 0.0
    a41 = 0.0
    a42 = 0.0
    for gp in range(4):
        Sg = md.Sig[i, gp]
        Pg = md.Psi[i, gp]
        su = Sg[0, 0]
        n3 = Sg[1, 1]
        n4 = Sg[1, 5]
        px = Pg[0, 3]
        d3 = Pg[2, 1]
        d4 = Pg[2, 5]
        x0 = md.s0[i, gp, 0] + su * e0
        x1 = n3 * e1 + n4 * e5
        x2 = n3 * e2 - n4 * e4
        d0 = su * f0_
        d1 = n3 * f1_ + n4 * f5_
        d2 = n3 * f2_ - n4 * f4_
        p0 = px * e3
        p1 = d4 * e4 - d3 * e2
        p2 = d3 * e1 + d4 * e5
        q0 = px * f3_
        q1 = d4 * f4_ - d3 * f2_
        q2 = d3 * f1_ + d4 * f5_
        (
            E00, E01, E02, E10, E11, E12, E20, E21, E22,
            J00, J01, J02, J10, J11, J12, J20, J21, J22,
            jd0, jd1, jd2,
        ) = so3_scalars(p0, p1, p2, q0, q1, q2)  # fmt: skip
        j0 = J00 * q0 + J01 * q1 + J02 * q2
        j1 = J10 * q0 + J11 * q1 + J12 * q2
        j2 = J20 * q0 + J21 * q1 + J22 * q2
        # accelerations: a_g = X A + S ë + ζ, ζ = (ω×(ω×s) + 2ω×ṡ, ω×(J ψ̇) + J̇ ψ̇)
        u0 = w1 * x2 - w2 * x1
        u1 = w2 * x0 - w0 * x2
        u2 = w0 * x1 - w1 * x0
        zl0 = w1 * u2 - w2 * u1 + 2.0 * (w1 * d2 - w2 * d1)
        zl1 = w2 * u0 - w0 * u2 + 2.0 * (w2 * d0 - w0 * d2)
        zl2 = w0 * u1 - w1 * u0 + 2.0 * (w0 * d1 - w1 * d0)
        za0 = w1 * j2 - w2 * j1 + jd0
        za1 = w2 * j0 - w0 * j2 + jd1
        za2 = w0 * j1 - w1 * j0 + jd2
        m = md.mg[i, gp]
        # translational: the blocks of m GᵀG, G = [I, −[s]×, Σ], that depend on e; the constant
        # ones (Σm I, Σ mΣ, Σ mΣᵀΣ) and −[Σ m s]× are added after the loop
        fl0 = m * (zl0 - g0)
        fl1 = m * (zl1 - g1)
        fl2 = m * (zl2 - g2)
        r[0] += fl0
        r[1] += fl1
        r[2] += fl2
        r[3] += x1 * fl2 - x2 * fl1
        r[4] += x2 * fl0 - x0 * fl2
        r[5] += x0 * fl1 - x1 * fl0
        mx0 = m * x0
        mx1 = m * x1
        mx2 = m * x2
        ms0 += mx0
        ms1 += mx1
        ms2 += mx2
        au0 += su * mx0
        au1 += su * mx1
        au2 += su * mx2
        a30 += n3 * mx0
        a31 += n3 * mx1
        a32 += n3 * mx2
        a40 += n4 * mx0
        a41 += n4 * mx1
        a42 += n4 * mx2
        ss = x0 * x0 + x1 * x1 + x2 * x2
        M[3, 3] += m * (ss - x0 * x0)
        M[3, 4] -= mx0 * x1
        M[3, 5] -= mx0 * x2
        M[4, 4] += m * (ss - x1 * x1)
        M[4, 5] -= mx1 * x2
        M[5, 5] += m * (ss - x2 * x2)
        # Σᵀ f: columns u (su, row 0), v (n3, row 1), w (n3, row 2), φy (−n4, row 2), φz (n4, row 1)
        r[6] += su * fl0
        r[7] += n3 * fl1
        r[8] += n3 * fl2
        r[10] -= n4 * fl2
        r[11] += n4 * fl1
        gauss_rotation(
            md,
            i,
            gp,
            M,
            r,
            w0,
            w1,
            w2,
            px,
            d3,
            d4,
            (E00, E01, E02, E10, E11, E12, E20, E21, E22),
            (J00, J01, J02, J10, J11, J12, J20, J21, J22),
            j0,
            j1,
            j2,
            za0,
            za1,
            za2,
        )
    return ms0, ms1, ms2, au0, au1, au2, a30, a31, a32, a40, a41, a42


@njit(inline="always", nrt=False)
def gauss_rotation(md, i, gp, M, r, w0, w1, w2, px, d3, d4, Et, Jt, j0, j1, j2, za0, za1, za2):
    """The rotational part of Gauss body ``gp``: its inertia Iw = E diag(I) Eᵀ in the element
    frame, the load fa = Iw ζ_a + ω_g × Iw ω_g into r, and Iw, Iw J Ψ, Ψᵀ Jᵀ Iw J Ψ into M
    (E, J: the body's rotation and its rate map at ψ = Ψ e; j = J ψ̇, za: ζ_a)."""
    E00, E01, E02, E10, E11, E12, E20, E21, E22 = Et
    J00, J01, J02, J10, J11, J12, J20, J21, J22 = Jt
    # rotational: Iw = E diag(I) Eᵀ, its load fa = Iw ζ_a + ω_g × Iw ω_g, H = [0, I, J Ψ]
    Ig = md.Ig[i, gp]
    I0 = Ig[0]
    I1 = Ig[1]
    I2 = Ig[2]
    # Iw = E diag(I) Eᵀ (symmetric)
    e00 = E00 * I0
    e01 = E01 * I1
    e02 = E02 * I2
    e10 = E10 * I0
    e11 = E11 * I1
    e12 = E12 * I2
    e20 = E20 * I0
    e21 = E21 * I1
    e22 = E22 * I2
    i00 = e00 * E00 + e01 * E01 + e02 * E02
    i01 = e00 * E10 + e01 * E11 + e02 * E12
    i02 = e00 * E20 + e01 * E21 + e02 * E22
    i11 = e10 * E10 + e11 * E11 + e12 * E12
    i12 = e10 * E20 + e11 * E21 + e12 * E22
    i22 = e20 * E20 + e21 * E21 + e22 * E22
    wg0 = w0 + j0
    wg1 = w1 + j1
    wg2 = w2 + j2
    h0 = i00 * wg0 + i01 * wg1 + i02 * wg2
    h1 = i01 * wg0 + i11 * wg1 + i12 * wg2
    h2 = i02 * wg0 + i12 * wg1 + i22 * wg2
    fa0 = i00 * za0 + i01 * za1 + i02 * za2 + wg1 * h2 - wg2 * h1
    fa1 = i01 * za0 + i11 * za1 + i12 * za2 + wg2 * h0 - wg0 * h2
    fa2 = i02 * za0 + i12 * za1 + i22 * za2 + wg0 * h1 - wg1 * h0
    r[3] += fa0
    r[4] += fa1
    r[5] += fa2
    M[3, 3] += i00
    M[3, 4] += i01
    M[3, 5] += i02
    M[4, 4] += i11
    M[4, 5] += i12
    M[5, 5] += i22
    # IJ = Iw J; Jᵀ fa; U = Jᵀ Iw J
    k00 = i00 * J00 + i01 * J10 + i02 * J20
    k01 = i00 * J01 + i01 * J11 + i02 * J21
    k02 = i00 * J02 + i01 * J12 + i02 * J22
    k10 = i01 * J00 + i11 * J10 + i12 * J20
    k11 = i01 * J01 + i11 * J11 + i12 * J21
    k12 = i01 * J02 + i11 * J12 + i12 * J22
    k20 = i02 * J00 + i12 * J10 + i22 * J20
    k21 = i02 * J01 + i12 * J11 + i22 * J21
    k22 = i02 * J02 + i12 * J12 + i22 * J22
    jf0 = J00 * fa0 + J10 * fa1 + J20 * fa2
    jf1 = J01 * fa0 + J11 * fa1 + J21 * fa2
    jf2 = J02 * fa0 + J12 * fa1 + J22 * fa2
    u00 = J00 * k00 + J10 * k10 + J20 * k20
    u01 = J00 * k01 + J10 * k11 + J20 * k21
    u02 = J00 * k02 + J10 * k12 + J20 * k22
    u11 = J01 * k01 + J11 * k11 + J21 * k21
    u12 = J01 * k02 + J11 * k12 + J21 * k22
    u22 = J02 * k02 + J12 * k12 + J22 * k22
    # Ψ: columns v (d3, row 2), w (−d3, row 1), φx (px, row 0), φy (d4, row 1), φz (d4, row 2)
    r[7] += d3 * jf2
    r[8] -= d3 * jf1
    r[9] += px * jf0
    r[10] += d4 * jf1
    r[11] += d4 * jf2
    M[3, 7] += d3 * k02
    M[3, 8] -= d3 * k01
    M[3, 9] += px * k00
    M[3, 10] += d4 * k01
    M[3, 11] += d4 * k02
    M[4, 7] += d3 * k12
    M[4, 8] -= d3 * k11
    M[4, 9] += px * k10
    M[4, 10] += d4 * k11
    M[4, 11] += d4 * k12
    M[5, 7] += d3 * k22
    M[5, 8] -= d3 * k21
    M[5, 9] += px * k20
    M[5, 10] += d4 * k21
    M[5, 11] += d4 * k22
    # Ψᵀ U Ψ
    t33 = d3 * d3
    t34 = d3 * d4
    t44 = d4 * d4
    tp3 = px * d3
    tp4 = px * d4
    M[7, 7] += t33 * u22
    M[7, 8] -= t33 * u12
    M[7, 9] += tp3 * u02
    M[7, 10] += t34 * u12
    M[7, 11] += t34 * u22
    M[8, 8] += t33 * u11
    M[8, 9] -= tp3 * u01
    M[8, 10] -= t34 * u11
    M[8, 11] -= t34 * u12
    M[9, 9] += px * px * u00
    M[9, 10] += tp4 * u01
    M[9, 11] += tp4 * u02
    M[10, 10] += t44 * u11
    M[10, 11] += t44 * u12
    M[11, 11] += t44 * u22


@njit(inline="always", nrt=False)
def constant_blocks(md, i, M, sums):
    """The translational blocks of M from the sums of :func:`gauss_bodies` and the constant
    ones of the element (Σm I, Σ mΣ, Σ mΣᵀΣ)."""
    ms0, ms1, ms2, au0, au1, au2, a30, a31, a32, a40, a41, a42 = sums
    # the e-dependent translational block of M_Ae, rows 3-5: Σ m [x]× Σ
    M[4, 6] += au2
    M[5, 6] -= au1
    M[3, 7] -= a32
    M[5, 7] += a30
    M[3, 8] += a31
    M[4, 8] -= a30
    M[3, 10] -= a41
    M[4, 10] += a40
    M[3, 11] -= a42
    M[5, 11] += a40
    # the constant translational blocks and −[Σ m s]×
    add_translation(M, md.mel[i], ms0, ms1, ms2)
    CS = md.CS[i]
    CSS = md.CSS[i]
    for a in range(6):
        M[0, 6 + a] += CS[0, a]
        M[1, 6 + a] += CS[1, a]
        M[2, 6 + a] += CS[2, a]
        for b in range(a, 6):
            M[6 + a, 6 + b] += CSS[a, b]


@njit(inline="always", nrt=False)
def outboard_node(md, i, el, ws, M, r):
    """The outboard node of element ``el`` (frame exp(φ), its velocity-product acceleration into
    ws.zO): the outboard P, c (ws.P, ws.c) turned into the element frame in place and their
    transfer Xᵀ P X, Xᵀ P S, Sᵀ P S, Xᵀ ρ, Sᵀ ρ (ρ = P ζ + c) into M and r."""
    f0_ = ws.ed[el, 0]
    f1_ = ws.ed[el, 1]
    f2_ = ws.ed[el, 2]
    f3_ = ws.ed[el, 3]
    f4_ = ws.ed[el, 4]
    f5_ = ws.ed[el, 5]
    w0 = ws.wl[el, 0]
    w1 = ws.wl[el, 1]
    w2 = ws.wl[el, 2]
    Iw = ws.Iw
    IJ = ws.IJ
    # (D = diag(1 or 0 for the dummy u, 1, 1); the dummy's row and column are reset below)
    EO = ws.E[el]
    JO = ws.JO[el]
    jdO = ws.jdO[el]
    x0 = ws.sO[el, 0]
    x1 = ws.sO[el, 1]
    x2 = ws.sO[el, 2]
    d0 = md.Sig[i, 4, 0, 0] * f0_
    d1 = f1_
    d2 = f2_
    j0 = JO[0, 0] * f3_ + JO[0, 1] * f4_ + JO[0, 2] * f5_
    j1 = JO[1, 0] * f3_ + JO[1, 1] * f4_ + JO[1, 2] * f5_
    j2 = JO[2, 0] * f3_ + JO[2, 1] * f4_ + JO[2, 2] * f5_
    u0 = w1 * x2 - w2 * x1
    u1 = w2 * x0 - w0 * x2
    u2 = w0 * x1 - w1 * x0
    zO = ws.zO[el]
    zO[0] = w1 * u2 - w2 * u1 + 2.0 * (w1 * d2 - w2 * d1)
    zO[1] = w2 * u0 - w0 * u2 + 2.0 * (w2 * d0 - w0 * d2)
    zO[2] = w0 * u1 - w1 * u0 + 2.0 * (w0 * d1 - w1 * d0)
    zO[3] = w1 * j2 - w2 * j1 + jdO[0]
    zO[4] = w2 * j0 - w0 * j2 + jdO[1]
    zO[5] = w0 * j1 - w1 * j0 + jdO[2]
    # the outboard P, c into this frame (in place): B P Bᵀ, B c with B = blockdiag(E, E)
    P = ws.P
    c = ws.c
    rotate_pc(EO, False, P, c, Iw)
    # ρ = P ζ + c
    rho = ws.rho
    for a in range(6):
        t = c[a]
        for k in range(6):
            t += P[a, k] * zO[k]
        rho[a] = t
    # with P = [[A, B], [Bᵀ, C]]: N = B − A[s]×, Cs = [s]×B + C
    N = ws.N3
    Cs = ws.Cs
    for a in range(3):
        r0 = P[a, 0]
        r1 = P[a, 1]
        r2 = P[a, 2]
        N[a, 0] = P[a, 3] - (r1 * x2 - r2 * x1)
        N[a, 1] = P[a, 4] - (r2 * x0 - r0 * x2)
        N[a, 2] = P[a, 5] - (r0 * x1 - r1 * x0)
    for b in range(3):
        b0 = P[0, 3 + b]
        b1 = P[1, 3 + b]
        b2 = P[2, 3 + b]
        Cs[0, b] = P[3, 3 + b] + x1 * b2 - x2 * b1
        Cs[1, b] = P[4, 3 + b] + x2 * b0 - x0 * b2
        Cs[2, b] = P[5, 3 + b] + x0 * b1 - x1 * b0
    # M_AA += Xᵀ P X = [[A, N], [Nᵀ, C + [s]×N − Bᵀ[s]×]]
    for a in range(3):
        for b in range(a, 3):
            M[a, b] += P[a, b]
        for b in range(3):
            M[a, 3 + b] += N[a, b]
    for a in range(3):
        for b in range(a, 3):
            if a == 0:
                sn = x1 * N[2, b] - x2 * N[1, b]
            elif a == 1:
                sn = x2 * N[0, b] - x0 * N[2, b]
            else:
                sn = x0 * N[1, b] - x1 * N[0, b]
            if b == 0:
                bs = P[1, 3 + a] * x2 - P[2, 3 + a] * x1
            elif b == 1:
                bs = P[2, 3 + a] * x0 - P[0, 3 + a] * x2
            else:
                bs = P[0, 3 + a] * x1 - P[1, 3 + a] * x0
            M[3 + a, 3 + b] += P[3 + a, 3 + b] + sn - bs
    # M_Ae += Xᵀ P S = [[A D, B J], [Nᵀ D, Cs J]];  M_ee += Sᵀ P S = [[D A D, D B J], [., Jᵀ C J]]
    for a in range(3):
        for b in range(3):
            bj = P[a, 3] * JO[0, b] + P[a, 4] * JO[1, b] + P[a, 5] * JO[2, b]
            M[a, 6 + b] += P[a, b]
            M[a, 9 + b] += bj
            M[6 + a, 9 + b] += bj
            M[3 + a, 6 + b] += N[b, a]
            M[3 + a, 9 + b] += Cs[a, 0] * JO[0, b] + Cs[a, 1] * JO[1, b] + Cs[a, 2] * JO[2, b]
            if b >= a:
                M[6 + a, 6 + b] += P[a, b]
    for b in range(3):
        # C J into IJ
        for a in range(3):
            IJ[a, b] = P[3 + a, 3] * JO[0, b] + P[3 + a, 4] * JO[1, b] + P[3 + a, 5] * JO[2, b]
    for a in range(3):
        for b in range(a, 3):
            M[9 + a, 9 + b] += JO[0, a] * IJ[0, b] + JO[1, a] * IJ[1, b] + JO[2, a] * IJ[2, b]
    # r_A += Xᵀ ρ, r_e += Sᵀ ρ
    y0 = rho[0]
    y1 = rho[1]
    y2 = rho[2]
    r[0] += y0
    r[1] += y1
    r[2] += y2
    r[3] += x1 * y2 - x2 * y1 + rho[3]
    r[4] += x2 * y0 - x0 * y2 + rho[4]
    r[5] += x0 * y1 - x1 * y0 + rho[5]
    r[6] += y0
    r[7] += y1
    r[8] += y2
    for a in range(3):
        r[9 + a] += JO[0, a] * rho[3] + JO[1, a] * rho[4] + JO[2, a] * rho[5]


@njit(inline="always", nrt=False)
def elastic_forces(md, i, el, cq, cv, ehat, edhat, fext, ws, M, r):
    """The elastic and damping forces of element ``el`` into r and their stiffness into M,
    implicit in a Newmark step (ê, ê' the predictors; c_q, c_v its coefficients)."""
    e = ws.e[el]
    f = ws.f6
    if md.so[i] == 0:
        # f = K e, K_T = K, D = μK: f + K_T(ê − e) + D ê' = K (ê + μ ê'); K has the pattern of
        # build.stiffness (checked by build_model)
        K = md.K[i]
        mu = md.mu[i]
        ck = cq + cv * mu
        for a in range(6):
            f[a] = ehat[a] + mu * edhat[a]
        r[6] += K[0, 0] * f[0] - fext[0]
        r[7] += K[1, 1] * f[1] + K[1, 5] * f[5] - fext[1]
        r[8] += K[2, 2] * f[2] + K[2, 4] * f[4] - fext[2]
        r[9] += K[3, 3] * f[3] - fext[3]
        r[10] += K[4, 2] * f[2] + K[4, 4] * f[4] - fext[4]
        r[11] += K[5, 1] * f[1] + K[5, 5] * f[5] - fext[5]
        M[6, 6] += ck * K[0, 0]
        M[7, 7] += ck * K[1, 1]
        M[7, 11] += ck * K[1, 5]
        M[8, 8] += ck * K[2, 2]
        M[8, 10] += ck * K[2, 4]
        M[9, 9] += ck * K[3, 3]
        M[10, 10] += ck * K[4, 4]
        M[11, 11] += ck * K[5, 5]
    else:
        KT = ws.KT
        D = ws.D6
        elastic_into(md, i, e, f, KT, D)
        for a in range(6):
            t = f[a] - fext[a]
            for b in range(6):
                t += KT[a, b] * (ehat[b] - e[b]) + D[a, b] * edhat[b]
                if b >= a:
                    M[6 + a, 6 + b] += cq * KT[a, b] + cv * D[a, b]
            r[6 + a] += t


#: per-link input rows (``mot`` of :func:`sweep`): columns 0–2 the motion law (α, α̇, α̈), then
#: from LOAD_COL on the external load at the link's tip (dttmm.spatial.scenario.load_inputs):
#: world force, world moment, tip-frame force, tip-frame moment
LOAD_COL = 3
INPUT_COLS = LOAD_COL + 12


@njit(inline="always", nrt=False)
def tip_load(inp, i, Rw, E, Qi, c):
    """The external load at the tip of link i (``inp[i, LOAD_COL:]``, when the rows have those
    columns) into the bias c of the outboard element frame R_O = Rw·E (world), moment about the
    tip point: the inboard part then exerts P·A + c − (F, M). World components x_W become
    R_Oᵀ x_W = Eᵀ(Rwᵀ x_W); tip-frame components x_T become Qᵀ x_T."""
    if inp.shape[1] < INPUT_COLS:
        return
    k = LOAD_COL
    for a in range(3):
        fw = 0.0
        mw = 0.0
        for b in range(3):
            fb = Rw[0, b] * inp[i, k] + Rw[1, b] * inp[i, k + 1] + Rw[2, b] * inp[i, k + 2]
            mb = Rw[0, b] * inp[i, k + 3] + Rw[1, b] * inp[i, k + 4] + Rw[2, b] * inp[i, k + 5]
            fw += E[b, a] * fb
            mw += E[b, a] * mb
        ft = Qi[0, a] * inp[i, k + 6] + Qi[1, a] * inp[i, k + 7] + Qi[2, a] * inp[i, k + 8]
        mt = Qi[0, a] * inp[i, k + 9] + Qi[1, a] * inp[i, k + 10] + Qi[2, a] * inp[i, k + 11]
        c[a] -= fw + ft
        c[3 + a] -= mw + mt


@njit(inline="always", nrt=False)
def backward_rigid(md, ws, i, keep):
    """The backward sweep over rigid link i (tip → root), in place on ws.P, ws.c: each slot
    moves the load from its outboard end s = (l, 0, 0) to its root, P ← XᵀPX, c ← Xᵀ(c + Pζ)
    with ζ = (ω × (ω × s), 0) its velocity-product acceleration (kept in ws.zO for the forward
    sweep); the body (mass m, centre d, inertia J about d; bias (m(ω × (ω × d) − g), ω × Jω))
    joins at the root slot, so it is outboard of the link's root cut only."""
    P = ws.P
    c = ws.c
    gv = md.grav
    l = md.l[i]
    for j in range(md.k[i] - 1, -1, -1):
        el = md.el0[i] + j
        w = ws.wl[el]
        w0 = w[0]
        w1 = w[1]
        w2 = w[2]
        # ω × s = (0, ω_z l, −ω_y l); ζ = ω × (ω × s)
        u1 = w2 * l
        u2 = -w1 * l
        zO = ws.zO[el]
        zO[0] = w1 * u2 - w2 * u1
        zO[1] = -w0 * u2
        zO[2] = w0 * u1
        zO[3] = 0.0
        zO[4] = 0.0
        zO[5] = 0.0
        for a in range(6):
            c[a] += P[a, 0] * zO[0] + P[a, 1] * zO[1] + P[a, 2] * zO[2]
        shift_pc(P, c, l, 0.0, 0.0, ws.N3)
        if j == 0 and nonzero_body(md.rb_m[i], md.rb_J[i]):
            Rw = ws.Rw[el]
            h0 = Rw[0, 0] * gv[0] + Rw[1, 0] * gv[1] + Rw[2, 0] * gv[2]
            h1 = Rw[0, 1] * gv[0] + Rw[1, 1] * gv[1] + Rw[2, 1] * gv[2]
            h2 = Rw[0, 2] * gv[0] + Rw[1, 2] * gv[1] + Rw[2, 2] * gv[2]
            d = md.rb_c[i]
            m = md.rb_m[i]
            J = md.rb_J[i]
            v0 = w1 * d[2] - w2 * d[1]
            v1 = w2 * d[0] - w0 * d[2]
            v2 = w0 * d[1] - w1 * d[0]
            z0 = w1 * v2 - w2 * v1
            z1 = w2 * v0 - w0 * v2
            z2 = w0 * v1 - w1 * v0
            k0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
            k1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
            k2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
            add_rigid(
                P,
                c,
                m,
                J,
                d[0],
                d[1],
                d[2],
                m * (z0 - h0),
                m * (z1 - h1),
                m * (z2 - h2),
                w1 * k2 - w2 * k1,
                w2 * k0 - w0 * k2,
                w0 * k1 - w1 * k0,
            )
        if keep:
            for r in range(6):
                for s in range(6):
                    ws.Pc[el, r, s] = P[r, s]
                ws.Pc[el, r, 6] = c[r]
    return True


@njit(inline="always", nrt=False)
def backward_link(md, ws, i, cq, cv, qhat, qdhat, forces, keep):
    """The backward sweep over the elements of link i, in place on ws.P, ws.c (tip → root),
    keeping each element root's (P, c) in ws.Pc with ``keep`` (for the cut loads). Returns ok."""
    if md.rigid[i] == 1:
        return backward_rigid(md, ws, i, keep)
    ok = True
    ehat = ws.eh
    edhat = ws.edh
    fext = ws.fx
    gv = md.grav
    for j in range(md.k[i] - 1, -1, -1):
        el = md.el0[i] + j
        Rw = ws.Rw[el]
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
        if keep:
            for r in range(6):
                for s in range(6):
                    ws.Pc[el, r, s] = ws.P[r, s]
                ws.Pc[el, r, 6] = ws.c[r]
    return ok


@njit(inline="always")
def load_world(R, f, loads, ic):
    """The load f (frame components) in world components into loads[ic]."""
    for bl in range(2):
        for a in range(3):
            loads[ic, 3 * bl + a] = R[a, 0] * f[3 * bl] + R[a, 1] * f[3 * bl + 1] + R[a, 2] * f[3 * bl + 2]


@njit(inline="always", nrt=False)
def forward_link(md, ws, i, A, qdd, want_loads, loads, ic):
    """The forward sweep over the elements of link i: A (root acceleration of the link, its own
    frame) in place to the outboard node of the last element, ë into qdd, cut loads from row
    ``ic`` on. Returns the next cut row."""
    edd = ws.f6
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
            load_world(ws.Rw[el], f, loads, ic)
        ic += 1
        if md.rigid[i] == 1:
            # a rigid slot: A ← X A + ζ, X A = (a + α × s, α), s = (l, 0, 0), same frame
            l = md.l[i]
            zO = ws.zO[el]
            b1 = A[4]
            b2 = A[5]
            A[0] += zO[0]
            A[1] += b2 * l + zO[1]
            A[2] += -b1 * l + zO[2]
            continue
        # ë = −L⁻ᵀ (Y [A; 1])
        L = ws.Lc[el]
        Y = ws.Y[el]
        for a in range(5, -1, -1):
            t = Y[a, 6]
            for b in range(6):
                t += Y[a, b] * A[b]
            for k in range(a + 1, 6):
                t += L[k, a] * edd[k]
            edd[a] = -t * L[a, a]
        r0 = md.ie[el]
        if md.ext[i] == 1:
            for s in range(6):
                qdd[r0 + s] = edd[s]
        else:
            for s in range(5):
                qdd[r0 + s] = edd[s + 1]
        # the outboard node: A_O = X A + S ë + ζ (element frame), then into its own frame
        x0 = ws.sO[el, 0]
        x1 = ws.sO[el, 1]
        x2 = ws.sO[el, 2]
        J = ws.JO[el]
        zO = ws.zO[el]
        b0 = A[3]
        b1 = A[4]
        b2 = A[5]
        l0 = A[0] + b1 * x2 - b2 * x1 + edd[0] + zO[0]
        l1 = A[1] + b2 * x0 - b0 * x2 + edd[1] + zO[1]
        l2 = A[2] + b0 * x1 - b1 * x0 + edd[2] + zO[2]
        n0 = b0 + J[0, 0] * edd[3] + J[0, 1] * edd[4] + J[0, 2] * edd[5] + zO[3]
        n1 = b1 + J[1, 0] * edd[3] + J[1, 1] * edd[4] + J[1, 2] * edd[5] + zO[4]
        n2 = b2 + J[2, 0] * edd[3] + J[2, 1] * edd[4] + J[2, 2] * edd[5] + zO[5]
        E = ws.E[el]
        for a in range(3):
            A[a] = E[0, a] * l0 + E[1, a] * l1 + E[2, a] * l2
            A[3 + a] = E[0, a] * n0 + E[1, a] * n1 + E[2, a] * n2
    return ic


@njit(nrt=False, inline="always")
def sweep(md, ws, cq, cv, qhat, qdhat, tau, mot, forces, qdd, want_loads, loads):
    """:func:`riccati_sweep` with ``want_loads`` a plain bool: the time loop passes a literal
    ``False``, :func:`accelerations` a variable, and numba would compile the sweep once for each
    type (minutes on a fresh checkout); ``bool()`` of either is one type, so one compilation."""
    return riccati_sweep(md, ws, cq, cv, qhat, qdhat, tau, mot, forces, qdd, bool(want_loads), loads)


@njit(inline="always", nrt=False)
def add_payload(md, ws, i, Qi, el_last, P, c):
    """Link i's payload (at its tip, outboard element frame; gravity and the velocity
    products of the tip's ω) into P, c."""
    gv = md.grav
    if nonzero_body(md.pay_m[i], md.pay_J[i]):
        wT = ws.wT[i + 1]
        o0 = Qi[0, 0] * wT[0] + Qi[1, 0] * wT[1] + Qi[2, 0] * wT[2]
        o1 = Qi[0, 1] * wT[0] + Qi[1, 1] * wT[1] + Qi[2, 1] * wT[2]
        o2 = Qi[0, 2] * wT[0] + Qi[1, 2] * wT[1] + Qi[2, 2] * wT[2]
        # gravity in the outboard frame R_O = R_w E
        Rw = ws.Rw[el_last]
        E = ws.E[el_last]
        h0 = Rw[0, 0] * gv[0] + Rw[1, 0] * gv[1] + Rw[2, 0] * gv[2]
        h1 = Rw[0, 1] * gv[0] + Rw[1, 1] * gv[1] + Rw[2, 1] * gv[2]
        h2 = Rw[0, 2] * gv[0] + Rw[1, 2] * gv[1] + Rw[2, 2] * gv[2]
        gO0 = E[0, 0] * h0 + E[1, 0] * h1 + E[2, 0] * h2
        gO1 = E[0, 1] * h0 + E[1, 1] * h1 + E[2, 1] * h2
        gO2 = E[0, 2] * h0 + E[1, 2] * h1 + E[2, 2] * h2
        d = md.pay_d[i]
        m = md.pay_m[i]
        Jp = md.pay_J[i]
        # ζ = ω×(ω×d); bias (m(ζ − g), ω × Jω)
        u0 = o1 * d[2] - o2 * d[1]
        u1 = o2 * d[0] - o0 * d[2]
        u2 = o0 * d[1] - o1 * d[0]
        z0 = o1 * u2 - o2 * u1
        z1 = o2 * u0 - o0 * u2
        z2 = o0 * u1 - o1 * u0
        k0 = Jp[0, 0] * o0 + Jp[0, 1] * o1 + Jp[0, 2] * o2
        k1 = Jp[1, 0] * o0 + Jp[1, 1] * o1 + Jp[1, 2] * o2
        k2 = Jp[2, 0] * o0 + Jp[2, 1] * o1 + Jp[2, 2] * o2
        add_rigid(
            P,
            c,
            m,
            Jp,
            d[0],
            d[1],
            d[2],
            m * z0 - m * gO0,
            m * z1 - m * gO1,
            m * z2 - m * gO2,
            o1 * k2 - o2 * k1,
            o2 * k0 - o0 * k2,
            o0 * k1 - o1 * k0,
        )


@njit(inline="always", nrt=False)
def add_hub(md, ws, i, P, c):
    """Link i's hub (at its root point, the first element's frame) into P, c."""
    gv = md.grav
    # hub at the root point
    el0 = md.el0[i]
    wF = ws.wl[el0]
    if nonzero_body(md.hub_m[i], md.hub_J[i]):
        Rw = ws.Rw[el0]
        h0 = Rw[0, 0] * gv[0] + Rw[1, 0] * gv[1] + Rw[2, 0] * gv[2]
        h1 = Rw[0, 1] * gv[0] + Rw[1, 1] * gv[1] + Rw[2, 1] * gv[2]
        h2 = Rw[0, 2] * gv[0] + Rw[1, 2] * gv[1] + Rw[2, 2] * gv[2]
        m = md.hub_m[i]
        Jh = md.hub_J[i]
        k0 = Jh[0, 0] * wF[0] + Jh[0, 1] * wF[1] + Jh[0, 2] * wF[2]
        k1 = Jh[1, 0] * wF[0] + Jh[1, 1] * wF[1] + Jh[1, 2] * wF[2]
        k2 = Jh[2, 0] * wF[0] + Jh[2, 1] * wF[1] + Jh[2, 2] * wF[2]
        add_rigid(
            P,
            c,
            m,
            Jh,
            0.0,
            0.0,
            0.0,
            -m * h0,
            -m * h1,
            -m * h2,
            wF[1] * k2 - wF[2] * k1,
            wF[2] * k0 - wF[0] * k2,
            wF[0] * k1 - wF[1] * k0,
        )


@njit(inline="always", nrt=False)
def joint_to_parent(md, ws, i, tau, mot, forces, P, c, T):
    """Link i's joint in the backward sweep: its velocity-product term (ws.zJ), the projection
    of P, c on the joint's motion (motion joints: α̈ known; torque joints: τ, a closed-loop
    law's slope as a stiffness), then P, c to the parent's tip frame and into its sum (ws.Pacc).
    Returns ok (the projection's pivot sᵀPs − slope positive)."""
    good = True
    # joint: velocity-product term in root-frame components, then the projection
    C = ws.C[i]
    wTp = ws.wT[md.par[i] + 1]
    o = md.org[i]
    u0 = wTp[1] * o[2] - wTp[2] * o[1]
    u1 = wTp[2] * o[0] - wTp[0] * o[2]
    u2 = wTp[0] * o[1] - wTp[1] * o[0]
    z0 = wTp[1] * u2 - wTp[2] * u1
    z1 = wTp[2] * u0 - wTp[0] * u2
    z2 = wTp[0] * u1 - wTp[1] * u0
    zJ = ws.zJ[i]
    for a in range(3):
        zJ[a] = C[0, a] * z0 + C[1, a] * z1 + C[2, a] * z2
        zJ[3 + a] = 0.0
    if md.locked[i] == 0:
        ald = ws.acc[i, 2]
        aF = md.aF[i]
        t0 = C[0, 0] * wTp[0] + C[1, 0] * wTp[1] + C[2, 0] * wTp[2]
        t1 = C[0, 1] * wTp[0] + C[1, 1] * wTp[1] + C[2, 1] * wTp[2]
        t2 = C[0, 2] * wTp[0] + C[1, 2] * wTp[1] + C[2, 2] * wTp[2]
        zJ[3] += (t1 * aF[2] - t2 * aF[1]) * ald
        zJ[4] += (t2 * aF[0] - t0 * aF[2]) * ald
        zJ[5] += (t0 * aF[1] - t1 * aF[0]) * ald
        Ps = ws.Ps
        for r in range(6):
            Ps[r] = P[r, 3] * aF[0] + P[r, 4] * aF[1] + P[r, 5] * aF[2]
        if md.motion[i] == 1:
            add = mot[i, 2]
            for r in range(6):
                c[r] += Ps[r] * add
        else:
            # a closed-loop torque τ = tau + slope·α̈ (its law linearised in α̈) acts as a
            # joint stiffness: sᵀP s − slope in the projection (0 for an open-loop torque)
            Dj = aF[0] * Ps[3] + aF[1] * Ps[4] + aF[2] * Ps[5] - ws.slope[i]
            if not Dj > 0.0:
                good = False
                Dj = 1.0
            g0 = (tau[i] + forces[md.ia[i]] - (aF[0] * c[3] + aF[1] * c[4] + aF[2] * c[5])) / Dj
            for r in range(6):
                c[r] += Ps[r] * g0
                for s in range(6):
                    P[r, s] -= Ps[r] * Ps[s] / Dj
    # to the parent frame at its origin: f_T = X_oᵀ Cb (P̂ (A'_F) + ĉ), A'_F = Cbᵀ X_o A_T + zJ
    for r in range(6):
        t = c[r]
        for s in range(6):
            t += P[r, s] * zJ[s]
        c[r] = t
    rotate_pc(C, False, P, c, T)
    shift_pc(P, c, o[0], o[1], o[2], T)
    # into the parent's tip frame: the first child's load is copied, further ones added
    ip = md.par[i] + 1
    Pa = ws.Pacc[ip]
    if ws.nacc[ip] == 0:
        for a in range(6):
            Pa[a, 6] = c[a]
            for b in range(6):
                Pa[a, b] = P[a, b]
    else:
        for a in range(6):
            Pa[a, 6] += c[a]
            for b in range(6):
                Pa[a, b] += P[a, b]
    ws.nacc[ip] += 1
    return good


@njit(inline="always", nrt=False)
def joint_forward(md, ws, i, tau, mot, forces, A, qdd):
    """Link i's joint in the forward sweep: from A (the root acceleration without the joint's
    own) the joint's α̈ (motion joints: their law; torque joints: from the articulated inertia
    ws.PF) into A, qdd, ws.acc[i, 0] and its torque into ws.acc[i, 1]."""
    PF = ws.PF[i]
    if md.locked[i] == 0:
        aF = md.aF[i]
        if md.motion[i] == 1:
            add = mot[i, 2]
        else:
            Dj = 0.0
            fa = 0.0
            for r in range(3):
                t = PF[3 + r, 6]
                ps = 0.0
                for s in range(6):
                    t += PF[3 + r, s] * A[s]
                for s in range(3):
                    ps += PF[3 + r, 3 + s] * aF[s]
                Dj += aF[r] * ps
                fa += aF[r] * t
            Dj -= ws.slope[i]  # a closed-loop law's joint stiffness (0 for an open-loop torque)
            add = (tau[i] + forces[md.ia[i]] - fa) / Dj
        for r in range(3):
            A[3 + r] += aF[r] * add
        qdd[md.ia[i]] = add
        ws.acc[i, 0] = add
        tq = 0.0
        for r in range(3):
            t = PF[3 + r, 6]
            for s in range(6):
                t += PF[3 + r, s] * A[s]
            tq += aF[r] * t
        ws.acc[i, 1] = tq


@njit(inline="always", nrt=False)
def tip_cut_load(md, ws, i, A, loads, ic, T):
    """The cut load at link i's tip (world components) into loads[ic], from A (the tip's
    acceleration, outboard element frame) and the tip's (P, c) kept in ws.Ptip."""
    el_last = md.el0[i] + md.k[i] - 1
    Pt = ws.Ptip[i]
    f = ws.A6b
    for a in range(6):
        t = Pt[a, 6]
        for b in range(6):
            t += Pt[a, b] * A[b]
        f[a] = t
    matmul33(ws.Rw[el_last], ws.E[el_last], T)
    load_world(T, f, loads, ic)


@njit(nrt=False)
def riccati_sweep(md, ws, cq, cv, qhat, qdhat, tau, mot, forces, qdd, want_loads, loads):
    """One Riccati sweep at the kinematics in ``ws`` (from :func:`kinematics`): q̈ into ``qdd``,
    per joint α̈ and torque into ws.acc, and with ``want_loads`` the cut loads (nel + n, 6)
    (force, moment; world components) at every element root and link tip. ``qhat``/``qdhat``:
    the known parts of the elastic coordinates and rates (Newmark predictors; the state itself
    for the acceleration solver, with cq = cv = 0). ``tau`` (n,): torques of torque joints;
    ``mot`` (n, 3) or (n, INPUT_COLS): α, α̇, α̈ of motion joints (and the tip loads, see
    :func:`tip_load`); ``forces`` (n_dof,) generalized forces on the
    coordinates besides the drives (virtual work Qᵀδq; on a torque joint's angle they add to its
    torque). Returns ok. Allocates nothing."""
    P = ws.P
    c = ws.c
    T = ws.Tk
    for i in range(md.n + 1):
        ws.nacc[i] = 0
    ok = True
    for i in range(md.n - 1, -1, -1):
        # the children's (P, c), summed in the tip frame (none: a free tip)
        Pa = ws.Pacc[i + 1]
        if ws.nacc[i + 1] == 0:
            for a in range(6):
                c[a] = 0.0
                for b in range(6):
                    P[a, b] = 0.0
        else:
            for a in range(6):
                c[a] = Pa[a, 6]
                for b in range(6):
                    P[a, b] = Pa[a, b]
        # tip frame → outboard element frame (x_O = Qᵀ x_T), then the payload
        Qi = md.Q[i]
        rotate_pc(Qi, True, P, c, T)
        el_last = md.el0[i] + md.k[i] - 1
        add_payload(md, ws, i, Qi, el_last, P, c)
        tip_load(mot, i, ws.Rw[el_last], ws.E[el_last], Qi, c)
        for r in range(6):
            for s in range(6):
                ws.Ptip[i, r, s] = P[r, s]
            ws.Ptip[i, r, 6] = c[r]
        ok = backward_link(md, ws, i, cq, cv, qhat, qdhat, forces, want_loads) and ok
        add_hub(md, ws, i, P, c)
        for r in range(6):
            for s in range(6):
                ws.PF[i, r, s] = P[r, s]
            ws.PF[i, r, 6] = c[r]
        ok = joint_to_parent(md, ws, i, tau, mot, forces, P, c, T) and ok
    # forward sweep: the base does not move
    A = ws.A6
    for a in range(6):
        A[a] = 0.0
        ws.Atip[0, a] = 0.0
    ic = 0
    for i in range(md.n):
        ip = md.par[i] + 1
        if ip != i:  # a branch: start from the parent's tip acceleration
            for a in range(6):
                A[a] = ws.Atip[ip, a]
        C = ws.C[i]
        o = md.org[i]
        zJ = ws.zJ[i]
        # A ← Cbᵀ X_o A + zJ, X_o A = (a + α × o, α)
        b0 = A[3]
        b1 = A[4]
        b2 = A[5]
        l0 = A[0] + b1 * o[2] - b2 * o[1]
        l1 = A[1] + b2 * o[0] - b0 * o[2]
        l2 = A[2] + b0 * o[1] - b1 * o[0]
        for a in range(3):
            A[a] = C[0, a] * l0 + C[1, a] * l1 + C[2, a] * l2 + zJ[a]
            A[3 + a] = C[0, a] * b0 + C[1, a] * b1 + C[2, a] * b2 + zJ[3 + a]
        joint_forward(md, ws, i, tau, mot, forces, A, qdd)
        for r in range(3):  # the link root's angular acceleration (closed-loop moment feedback)
            ws.wdF[i, r] = A[3 + r]
        ic = forward_link(md, ws, i, A, qdd, want_loads, loads, ic)
        if want_loads:
            tip_cut_load(md, ws, i, A, loads, ic, T)
        ic += 1
        Qi = md.Q[i]
        for bl in range(2):
            v0 = A[3 * bl]
            v1 = A[3 * bl + 1]
            v2 = A[3 * bl + 2]
            for a in range(3):
                A[3 * bl + a] = Qi[a, 0] * v0 + Qi[a, 1] * v1 + Qi[a, 2] * v2
        for a in range(6):
            ws.Atip[i + 1, a] = A[a]
    for r in range(qdd.shape[0]):
        if not math.isfinite(qdd[r]):
            ok = False
    return ok


@njit(nrt=False)
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
        if md.rigid[i] == 1:
            if nonzero_body(md.rb_m[i], md.rb_J[i]):
                v = ws.vl[el0]
                w = ws.wl[el0]
                d = md.rb_c[i]
                vc = v + cross(w, d)
                T += 0.5 * md.rb_m[i] * np.dot(vc, vc) + 0.5 * np.dot(w, mv(md.rb_J[i], w))
                V -= md.rb_m[i] * np.dot(g, ws.pw[el0] + mv(ws.Rw[el0], d))
        for j in range(md.k[i] * (1 - md.rigid[i])):
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
