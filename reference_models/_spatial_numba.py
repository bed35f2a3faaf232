"""Compiled mechanics of the spatial global-equation solver (:mod:`reference_models.spatial_global`):
the mass matrix M(q) and the generalized forces f = Q_g − h(q, q̇) at one state in O(N²), and
the frames with the twists of every coordinate for the loads, closures and closed-loop laws.

The readable numpy mechanics of :mod:`reference_models.spatial_global` (``engine="numpy"``) form
M = Σ m J_vᵀJ_v + Σ J_ωᵀ I J_ω from the dense Jacobians of every body; they are the independent
check of this module (tests/test_spatial_global_compiled.py: M and f to round-off on every
shipped spatial case, trees, loops and rigid links included). The numbers are the same
mechanics; only the summation differs.

**Twists.** Every coordinate q_j moves the bodies outboard of it rigidly: a joint angle α turns
them about the joint axis a through the joint point p; an element's u, v, w shift them along the
element frame's axes R_I e_s; its φx, φy, φz turn them about the outboard node r_O with the
angular velocity R_I J_L(φ) e_s. Its twist, written at the world origin as (ω, v_O), is
s_j = (a, p × a), (0, R_I e_s) or (ω_s, r_O × ω_s); a body at r moves with v = v_O + ω × r.
Only the element's own material points (its 4 Gauss points) move with its coordinates
non-rigidly: v_g = R_I S_g ė, ω_g = R_I J_L(ψ_g) P_g ė.

**Composite inertias.** With I_c the 6 × 6 inertia at the world origin of the bodies outboard
of coordinate j's element node (its payload, the later elements, the subtrees on its tip) and
c_j = I_c s_j + Σ_g (m r_g × a_g + I_g b_g, m a_g) (a_g, b_g the columns of R_I S_g and
R_I J_L P_g; absent for a joint angle, whose bodies all move rigidly),

    M_ij = s_iᵀ c_j                                  (i inboard of j's element or joint)
    M_ij = s_iᵀ I_c s_j + Σ_g m a_g,iᵀ a_g,j + b_g,iᵀ I_g b_g,j   (i, j of one element)

and 0 for coordinates on different branches of a tree. The forces follow alike from the bodies'
wrenches at the origin, (r × F + N, F) with F = m(g − a_b), N = −(I α_b + ω × I ω).

**Velocity terms.** The body velocities are formed along the chain at the complex configuration
q + iε q̇ (ε = 1e-30; every map analytic, as in the numpy mechanics): their real parts are the
velocities, their imaginary parts over ε the accelerations J̇q̇ at q̈ = 0.
"""

from __future__ import annotations

from collections import namedtuple
from pathlib import Path

import numpy as np

from dttmm.jit import HAVE_NUMBA, cache_dir, cached_njit

_CACHE_DIR = (
    cache_dir("spatial-global-numba", Path(__file__).resolve().parent, (Path(__file__),))
    if HAVE_NUMBA
    else None
)

EPS = 1e-30  # complex step
_SMALL = 1e-6  # |θ²| below which the Taylor series are used (as the numpy mechanics)


def njit(**options):
    """``numba.njit(**options)`` with its cache in the per-hash folder (the identity without numba)."""
    return cached_njit(_CACHE_DIR, **options)


Pack = namedtuple(
    "Pack",
    [
        "k",
        "parent",
        "alpha_idx",
        "e_idx",
        "length",
        "axis",
        "origin_R",
        "origin_p",
        "roll_R",
        "base_R",
        "base_p",
        "gravity",
        "s0",
        "S",
        "Pm",
        "I_g",
        "body_m",
        "body_c",
        "body_J",
        "anc",
        "K_el",
        "EA",
        "mu",
        "second",
    ],
)

Work = namedtuple(
    "Work",
    [
        "tw",
        "Rl",
        "pl",
        "Rt",
        "pt",
        "Vt",
        "RI",
        "rI",
        "nodes",
        "br",
        "bI",
        "bv",
        "bw",
        "ba",
        "bal",
        "A",
        "B",
        "col",
        "IC",
        "WC",
    ],
)


def _groups(lay):
    """Coordinates grouped by what moves together: per link its joint (α, or nothing for a
    locked joint) and then each element; returns (group of each coordinate (N,), the strict
    ancestor table of the groups (G, G), the joint group and the last group of each link)."""
    n, k = lay.n_links, lay.k
    G = n * (k + 1)
    up = np.full(G, -1)
    joint_group = np.arange(n) * (k + 1)
    last_group = joint_group + k
    for i in range(n):
        g0 = joint_group[i]
        up[g0] = last_group[lay.parent[i]] if lay.parent[i] >= 0 else -1
        up[g0 + 1 : g0 + k + 1] = np.arange(g0, g0 + k)
    anc = np.zeros((G, G), bool)
    for g in range(G):
        a = up[g]
        while a >= 0:
            anc[a, g] = True
            a = up[a]
    group = np.empty(lay.n_dof, int)
    for i in range(n):
        if lay.alpha_idx[i] >= 0:
            group[lay.alpha_idx[i]] = joint_group[i]
        for j in range(k):
            idx = lay.e_idx[i * k + j]
            group[idx[idx >= 0]] = joint_group[i] + 1 + j
    return group, anc, joint_group, last_group


def pack(lay) -> tuple[Pack, Work, np.ndarray, np.ndarray]:
    """The compiled functions' arrays of a spatial_global layout, a workspace, and the tables
    (n, N) of the coordinates that move each link's frame (``link``) and tip frame (``tip``)."""
    n, k, N = lay.n_links, lay.k, lay.n_dof
    nel, ng = lay.m_g.shape
    group, anc, joint_group, last_group = _groups(lay)
    reach = anc | np.eye(anc.shape[0], dtype=bool)  # ancestor or the group itself
    moves_link = reach[group][:, joint_group].T  # coordinate j's group reaches the link frame
    moves_tip = reach[group][:, last_group].T
    zeros3 = np.zeros((n, 3))
    P = Pack(
        k=k,
        parent=lay.parent.astype(np.int64),
        alpha_idx=lay.alpha_idx.astype(np.int64),
        e_idx=lay.e_idx.astype(np.int64),
        length=lay.length.astype(float),
        axis=lay.axis.astype(float),
        origin_R=lay.origin_R.astype(float),
        origin_p=lay.origin_p.astype(float),
        roll_R=lay.roll_R.astype(float),
        base_R=lay.base_R.astype(float),
        base_p=lay.base_p.astype(float),
        gravity=lay.gravity.astype(float),
        s0=np.ascontiguousarray(lay.s0, float),
        S=np.ascontiguousarray(lay.S, float),
        Pm=np.ascontiguousarray(lay.P, float),
        I_g=np.ascontiguousarray(lay.I_g, float),
        # bodies: the Gauss points (el·ng + g), then per link its hub, payload, rigid body
        body_m=np.concatenate([lay.m_g.ravel(), lay.hub_m, lay.pay_m, lay.rb_m]).astype(float),
        body_c=np.concatenate([zeros3, lay.pay_c, lay.rb_c]).astype(float),
        body_J=np.concatenate([lay.hub_J, lay.pay_J, lay.rb_J]).astype(float),
        anc=np.ascontiguousarray(anc[group][:, group]),
        K_el=np.ascontiguousarray(lay.K_el, float),
        EA=np.array([np.nan if ea is None else ea for ea in lay.EA], float),
        mu=lay.mu.astype(float),
        second=lay.second.astype(np.bool_),
    )
    nb = nel * ng + 3 * n
    c = np.complex128
    W = Work(
        tw=np.zeros((N, 6), c),
        Rl=np.zeros((n, 3, 3), c),
        pl=np.zeros((n, 3), c),
        Rt=np.zeros((n, 3, 3), c),
        pt=np.zeros((n, 3), c),
        Vt=np.zeros((n, 6), c),
        RI=np.zeros((nel, 3, 3)),
        rI=np.zeros((nel, 3)),
        nodes=np.zeros((nel, 3)),
        br=np.zeros((nb, 3)),
        bI=np.zeros((nb, 3, 3)),
        bv=np.zeros((nb, 3)),
        bw=np.zeros((nb, 3)),
        ba=np.zeros((nb, 3)),
        bal=np.zeros((nb, 3)),
        A=np.zeros((nel, ng, 3, 6)),
        B=np.zeros((nel, ng, 3, 6)),
        col=np.zeros((N, 6)),
        IC=np.zeros((n, 6, 6)),
        WC=np.zeros((n, 6)),
    )
    return P, W, moves_link, moves_tip


# ----------------------------------------------------------------------------------------------
# small complex 3-vector and 3 × 3 algebra
# ----------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def _cross(a, b, out):
    x = a[1] * b[2] - a[2] * b[1]
    y = a[2] * b[0] - a[0] * b[2]
    z = a[0] * b[1] - a[1] * b[0]
    out[0], out[1], out[2] = x, y, z


@njit(cache=True)
def _mm(A, B, out):
    """out = A @ B (3 × 3; out may not alias A or B)."""
    for i in range(3):
        for j in range(3):
            out[i, j] = A[i, 0] * B[0, j] + A[i, 1] * B[1, j] + A[i, 2] * B[2, j]


@njit(cache=True)
def _mv(A, x, out):
    for i in range(3):
        out[i] = A[i, 0] * x[0] + A[i, 1] * x[1] + A[i, 2] * x[2]


@njit(cache=True)
def _even(t):
    """sin θ/θ, (1 − cos θ)/θ², (θ − sin θ)/θ³ as analytic functions of t = θ² (complex)."""
    if abs(t) < _SMALL:
        a = 1.0 - t / 6.0 + t * t / 120.0 - t * t * t / 5040.0
        b = 0.5 - t / 24.0 + t * t / 720.0 - t * t * t / 40320.0
        c = 1.0 / 6.0 - t / 120.0 + t * t / 5040.0 - t * t * t / 362880.0
        return a, b, c
    th = np.sqrt(t)
    s = np.sin(th)
    return s / th, (1.0 - np.cos(th)) / t, (th - s) / (t * th)


@njit(cache=True)
def _quadratic(psi, x, y, out):
    """out = I + x[ψ]× + y[ψ]×², with [ψ]×² = ψψᵀ − (ψ·ψ) I (no conjugate: analytic in ψ)."""
    t = psi[0] * psi[0] + psi[1] * psi[1] + psi[2] * psi[2]
    for i in range(3):
        for j in range(3):
            out[i, j] = y * psi[i] * psi[j]
        out[i, i] += 1.0 - y * t
    out[0, 1] -= x * psi[2]
    out[0, 2] += x * psi[1]
    out[1, 0] += x * psi[2]
    out[1, 2] -= x * psi[0]
    out[2, 0] -= x * psi[1]
    out[2, 1] += x * psi[0]


@njit(cache=True)
def _exp(psi, out):
    a, b, _ = _even(psi[0] * psi[0] + psi[1] * psi[1] + psi[2] * psi[2])
    _quadratic(psi, a, b, out)


@njit(cache=True)
def _left_jacobian(psi, out):
    _, b, c = _even(psi[0] * psi[0] + psi[1] * psi[1] + psi[2] * psi[2])
    _quadratic(psi, b, c, out)


@njit(cache=True)
def _rot_axis(axis, angle, out):
    """Rot(a, α) = I + sin α [a]× + (1 − cos α)[a]×² for a unit axis a."""
    _quadratic(axis + 0j, np.sin(angle), 1.0 - np.cos(angle), out)


# ----------------------------------------------------------------------------------------------
# the chain: frames, twists, bodies
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _rjr(R, J, out):
    """out = R J Rᵀ (real 3 × 3)."""
    for i in range(3):
        for j in range(3):
            acc = 0.0
            for a in range(3):
                for b in range(3):
                    acc += R[i, a] * J[a, b] * R[j, b]
            out[i, j] = acc


@njit(cache=True)
def _rigid_body(P, W, b, j, p, R, V):
    """Body b (a hub, payload or rigid link body; constants j of body_c/body_J) rigid with the
    frame (p, R) moving with the twist V: its position, world inertia, velocity and the
    accelerations J̇q̇ (imaginary parts over ε)."""
    r = np.empty(3, np.complex128)
    v = np.empty(3, np.complex128)
    _mv(R, P.body_c[j] + 0j, r)
    r += p
    _cross(V[:3], r, v)
    v += V[3:]
    _rjr(R.real, P.body_J[j], W.bI[b])
    for i in range(3):
        W.br[b, i] = r[i].real
        W.bv[b, i] = v[i].real
        W.bw[b, i] = V[i].real
        W.ba[b, i] = v[i].imag / EPS
        W.bal[b, i] = V[i].imag / EPS


@njit(cache=True)
def _gauss_bodies(P, W, el, R, p, V, e, ed):
    """The element's material points (bodies el·ng + g): position, world inertia, velocity,
    accelerations J̇q̇, and the own-element maps W.A = R_I S_g, W.B = R_I J_L(ψ_g) P_g."""
    ng = P.I_g.shape[1]
    c128 = np.complex128
    sg, psi, r = np.empty(3, c128), np.empty(3, c128), np.empty(3, c128)
    v, w, tmp = np.empty(3, c128), np.empty(3, c128), np.empty(3, c128)
    T, RB, Rg = np.empty((3, 3), c128), np.empty((3, 3), c128), np.empty((3, 3), c128)
    A, B = np.empty((3, 6), c128), np.empty((3, 6), c128)
    for g in range(ng):
        S, Pg = P.S[el, g], P.Pm[el, g]
        for i in range(3):
            a0 = P.s0[el, g, i] + 0j
            a1 = 0j
            for s in range(6):
                a0 += S[i, s] * e[s]
                a1 += Pg[i, s] * e[s]
            sg[i], psi[i] = a0, a1
        _mv(R, sg, r)
        r += p
        _left_jacobian(psi, T)
        _mm(R, T, RB)
        _exp(psi, T)
        _mm(R, T, Rg)
        for i in range(3):
            for s in range(6):
                A[i, s] = R[i, 0] * S[0, s] + R[i, 1] * S[1, s] + R[i, 2] * S[2, s]
                B[i, s] = RB[i, 0] * Pg[0, s] + RB[i, 1] * Pg[1, s] + RB[i, 2] * Pg[2, s]
        _cross(V[:3], r, tmp)
        for i in range(3):
            vi = V[3 + i] + tmp[i]
            wi = V[i] + 0j
            for s in range(6):
                vi += A[i, s] * ed[s]
                wi += B[i, s] * ed[s]
            v[i], w[i] = vi, wi
        b = el * ng + g
        Rr = Rg.real
        for i in range(3):
            for j in range(3):
                W.bI[b, i, j] = (
                    Rr[i, 0] * P.I_g[el, g, 0] * Rr[j, 0]
                    + Rr[i, 1] * P.I_g[el, g, 1] * Rr[j, 1]
                    + Rr[i, 2] * P.I_g[el, g, 2] * Rr[j, 2]
                )
            W.br[b, i] = r[i].real
            W.bv[b, i] = v[i].real
            W.bw[b, i] = w[i].real
            W.ba[b, i] = v[i].imag / EPS
            W.bal[b, i] = w[i].imag / EPS
            for s in range(6):
                W.A[el, g, i, s] = A[i, s].real
                W.B[el, g, i, s] = B[i, s].real


@njit(cache=True)
def _turn(tw, w, c, rate, V):
    """tw = (ω, c × ω): the twist at the world origin of a turn with angular velocity ω about
    the point c, per unit rate; V += tw · rate."""
    v = np.empty(3, np.complex128)
    _cross(c, w, v)
    for i in range(3):
        tw[i] = w[i]
        tw[3 + i] = v[i]
        V[i] += w[i] * rate
        V[3 + i] += v[i] * rate


@njit(cache=True)
def chain(P, q, qd, W):
    """The frames (W.Rl, pl: link frames; W.Rt, pt: tip frames), the tip frames' twists (W.Vt) and the
    twist of every coordinate (W.tw, at the world origin) at the complex configuration q
    (q + iε q̇ for the accelerations J̇q̇); the bodies' positions, world inertias, angular
    velocities, accelerations at q̈ = 0 (real) and the own-element maps (:func:`_gauss_bodies`)."""
    n = P.parent.size
    k = P.k
    nel, ng = P.I_g.shape[0], P.I_g.shape[1]
    c128 = np.complex128
    R, R2, T = np.empty((3, 3), c128), np.empty((3, 3), c128), np.empty((3, 3), c128)
    p, V, tmp, tmp2 = np.empty(3, c128), np.empty(6, c128), np.empty(3, c128), np.empty(3, c128)
    e, ed = np.empty(6, c128), np.empty(6)
    W.tw[:] = 0.0
    for L in range(n):
        par = P.parent[L]
        if par < 0:
            R[:] = P.base_R
            p[:] = P.base_p
            V[:] = 0.0
        else:
            R[:] = W.Rt[par]
            p[:] = W.pt[par]
            V[:] = W.Vt[par]
        _mv(R, P.origin_p[L] + 0j, tmp)
        p += tmp
        _mm(R, P.origin_R[L] + 0j, R2)
        R[:] = R2
        a = P.alpha_idx[L]
        if a >= 0:
            _mv(R, P.axis[L] + 0j, tmp)
            _turn(W.tw[a], tmp, p, qd[a], V)
            _rot_axis(P.axis[L], q[a], T)
            _mm(R, T, R2)
            R[:] = R2
        W.Rl[L], W.pl[L] = R, p
        _rigid_body(P, W, nel * ng + L, L, p, R, V)  # hub
        _rigid_body(P, W, nel * ng + 2 * n + L, 2 * n + L, p, R, V)  # rigid link body
        _mm(R, P.roll_R[L] + 0j, R2)
        R[:] = R2
        for jel in range(k):
            el = L * k + jel
            for s in range(6):
                idx = P.e_idx[el, s]
                e[s] = q[idx] if idx >= 0 else 0.0
                ed[s] = qd[idx] if idx >= 0 else 0.0
            for i in range(3):
                W.rI[el, i] = p[i].real
                for j in range(3):
                    W.RI[el, i, j] = R[i, j].real
            _gauss_bodies(P, W, el, R, p, V, e, ed)
            # the outboard node r_O = r_I + R_I (l + u, v, w); the twists of e (about r_O)
            tmp2[0], tmp2[1], tmp2[2] = P.length[el] + e[0], e[1], e[2]
            _mv(R, tmp2, tmp)
            p += tmp
            for i in range(3):
                W.nodes[el, i] = p[i].real
            _left_jacobian(e[3:], T)
            _mm(R, T, R2)
            for s in range(6):
                idx = P.e_idx[el, s]
                if idx < 0:
                    continue
                if s < 3:  # a shift along the element frame's axis s
                    for i in range(3):
                        W.tw[idx, 3 + i] = R[i, s]
                        V[3 + i] += R[i, s] * ed[s]
                else:
                    _turn(W.tw[idx], R2[:, s - 3], p, ed[s], V)
            _exp(e[3:], T)
            _mm(R, T, R2)
            R[:] = R2
        _mm(R, P.roll_R[L].T + 0j, R2)
        R[:] = R2
        W.Rt[L], W.pt[L], W.Vt[L] = R, p, V
        _rigid_body(P, W, nel * ng + n + L, n + L, p, R, V)  # payload


@njit(cache=True)
def _spatial_inertia(m, r, I, out):
    """out += the 6 × 6 inertia at the world origin, on twists (ω, v_O), of a body of mass m at
    r with the world inertia I: [[I − m[r]×², m[r]×], [−m[r]×, m 1]]."""
    rr = r[0] * r[0] + r[1] * r[1] + r[2] * r[2]
    for i in range(3):
        for j in range(3):
            out[i, j] += I[i, j] - m * r[i] * r[j]
        out[i, i] += m * rr
        out[i + 3, i + 3] += m
    # m[r]× in the upper right, its transpose (−m[r]×) in the lower left
    K = ((0.0, -r[2], r[1]), (r[2], 0.0, -r[0]), (-r[1], r[0], 0.0))
    for i in range(3):
        for j in range(3):
            out[i, j + 3] += m * K[i][j]
            out[j + 3, i] += m * K[i][j]


@njit(cache=True, inline="always")
def _dot6(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3] + a[4] * b[4] + a[5] * b[5]


@njit(cache=True)
def _mv6(A, x, out):
    for i in range(6):
        out[i] = _dot6(A[i], x)


@njit(cache=True)
def _body_wrenches(P, W, F, Nr, wr):
    """Per body: its inertia and gravity force F = m(g − a), the moment of its rotary inertia
    forces Nr = −(I α + ω × I ω), and its wrench at the origin wr = (r × F + Nr, F)."""
    g = P.gravity
    Iw, Ia, tmp = np.empty(3), np.empty(3), np.empty(3)
    for b in range(P.body_m.size):
        m = P.body_m[b]
        for i in range(3):
            F[b, i] = m * (g[i] - W.ba[b, i])
        _mv(W.bI[b], W.bw[b], Iw)
        _mv(W.bI[b], W.bal[b], Ia)
        _cross(W.bw[b], Iw, tmp)
        for i in range(3):
            Nr[b, i] = -(Ia[i] + tmp[i])
        _cross(W.br[b], F[b], tmp)
        for i in range(3):
            wr[b, i] = tmp[i] + Nr[b, i]
            wr[b, 3 + i] = F[b, i]


@njit(cache=True)
def _own_mass(P, W, el, s, t, Ib):
    """Σ_g m a_g,s·a_g,t + b_g,sᵀ I_g b_g,t: the element's own Gauss points in M_st."""
    ng = P.I_g.shape[1]
    val = 0.0
    for g in range(ng):
        b = el * ng + g
        _mv(W.bI[b], W.B[el, g, :, t], Ib)
        for i in range(3):
            val += P.body_m[b] * W.A[el, g, i, s] * W.A[el, g, i, t] + W.B[el, g, i, s] * Ib[i]
    return val


@njit(cache=True)
def _element_block(P, W, el, IC, WC, tw, F, Nr, M, f):
    """The element's coordinates: their columns c_j (W.col), forces and the element's own
    block of M, with the composite (IC, WC) of the bodies outboard of its node."""
    ng = P.I_g.shape[1]
    c = np.empty(6)
    tmp, Ib = np.empty(3), np.empty(3)
    for s in range(6):
        ci = P.e_idx[el, s]
        if ci < 0:
            continue
        _mv6(IC, tw[ci], c)
        fs = _dot6(tw[ci], WC)
        for gg in range(ng):
            b = el * ng + gg
            m = P.body_m[b]
            a_s, b_s = W.A[el, gg, :, s], W.B[el, gg, :, s]
            _cross(W.br[b], a_s, tmp)
            _mv(W.bI[b], b_s, Ib)
            for i in range(3):
                c[i] += m * tmp[i] + Ib[i]
                c[3 + i] += m * a_s[i]
                fs += a_s[i] * F[b, i] + b_s[i] * Nr[b, i]
        W.col[ci] = c
        f[ci] = fs
        for s2 in range(s, 6):
            cj = P.e_idx[el, s2]
            if cj < 0:
                continue
            _mv6(IC, tw[cj], c)
            val = _dot6(tw[ci], c) + _own_mass(P, W, el, s, s2, Ib)
            M[ci, cj] = val
            M[cj, ci] = val


@njit(cache=True)
def _add_body(P, W, b, wr, IC, WC):
    _spatial_inertia(P.body_m[b], W.br[b], W.bI[b], IC)
    for i in range(6):
        WC[i] += wr[b, i]


@njit(cache=True)
def assemble(P, q, qd, W, M, f):
    """M(q) (N, N) and f = Q_g − h(q, q̇) (N,) into M and f (module notes)."""
    chain(P, q + 1j * EPS * qd, qd, W)
    n = P.parent.size
    k = P.k
    nel, ng = P.I_g.shape[0], P.I_g.shape[1]
    nb = P.body_m.size
    N = q.size
    tw = np.ascontiguousarray(W.tw.real)
    F, Nr, wr = np.empty((nb, 3)), np.empty((nb, 3)), np.empty((nb, 6))
    _body_wrenches(P, W, F, Nr, wr)
    M[:] = 0.0
    f[:] = 0.0
    W.IC[:] = 0.0
    W.WC[:] = 0.0
    c = np.empty(6)
    for L in range(n - 1, -1, -1):
        IC, WC = W.IC[L], W.WC[L]
        _add_body(P, W, nel * ng + n + L, wr, IC, WC)  # the payload, outboard of every node
        for jel in range(k - 1, -1, -1):
            el = L * k + jel
            _element_block(P, W, el, IC, WC, tw, F, Nr, M, f)
            for gg in range(ng):
                _add_body(P, W, el * ng + gg, wr, IC, WC)
        _add_body(P, W, nel * ng + L, wr, IC, WC)  # hub
        _add_body(P, W, nel * ng + 2 * n + L, wr, IC, WC)  # rigid link body
        a = P.alpha_idx[L]
        if a >= 0:
            _mv6(IC, tw[a], c)
            W.col[a] = c
            f[a] = _dot6(tw[a], WC)
            M[a, a] = _dot6(tw[a], c)
        par = P.parent[L]
        if par >= 0:
            W.IC[par] += IC
            W.WC[par] += WC
    for j in range(N):
        for i in range(N):
            if P.anc[i, j]:
                val = _dot6(tw[i], W.col[j])
                M[i, j] = val
                M[j, i] = val


class Frames:
    """The frames of :func:`chain` with the velocity Jacobians (n, 3, N) of the link and tip
    frames' points and rotations: the fields of spatial_global's numpy frames that the loads,
    closures, closed-loop laws and outputs read (complex where q is; the element frames
    ``RI``, ``rI``, coordinates ``e`` and outboard ``nodes`` real)."""

    def __init__(self, packed, q, qd=None):
        P, W, moves_link, moves_tip = packed
        q = np.asarray(q)
        chain(P, q + 0j, np.zeros(q.size) if qd is None else qd, W)
        real = not np.iscomplexobj(q)
        pick = (lambda x: x.real.copy()) if real else (lambda x: x.copy())
        tw = pick(W.tw)
        self.R_link, self.p_link = pick(W.Rl), pick(W.pl)
        self.R_tip, self.p_tip = pick(W.Rt), pick(W.pt)
        self.Jr_link, self.Jw_link = _jacobians(tw, self.p_link, moves_link)
        self.Jr_tip, self.Jw_tip = _jacobians(tw, self.p_tip, moves_tip)
        self.RI, self.rI, self.nodes = W.RI.copy(), W.rI.copy(), W.nodes.copy()
        self.e = np.where(P.e_idx >= 0, q.real[P.e_idx], 0.0)


def kinetic_potential(packed, q, qd) -> tuple[float, float]:
    """Kinetic energy Σ ½ m v² + ½ ωᵀIω and gravity potential −Σ m gᵀr of the bodies at (q, q̇)."""
    P, W = packed[:2]
    chain(P, q + 0j, qd, W)
    m = P.body_m
    kin = 0.5 * np.sum(m * np.sum(W.bv * W.bv, -1)) + 0.5 * np.einsum("pi,pij,pj->", W.bw, W.bI, W.bw)
    return float(kin), -float(np.sum(m * (W.br @ P.gravity)))


def body_motion(packed, q, qd, qdd):
    """Per body at the state (q, q̇, q̈): mass, position, world inertia, angular velocity,
    acceleration and angular acceleration; the element roots (nel, 3) and link tips (n, 3)."""
    P, W = packed[:2]
    chain(P, q + 1j * EPS * qd, qd, W)
    r, I, om = W.br.copy(), W.bI.copy(), W.bw.copy()
    ba, bal = W.ba.copy(), W.bal.copy()
    rI, tips = W.rI.copy(), W.pt.real.copy()
    chain(P, q + 0j, qdd, W)  # the "velocities" of the rates q̈: J q̈
    return P.body_m, r, I, om, W.bv + ba, W.bw + bal, rI, tips


def _jacobians(tw, points, moves):
    """(J_r, J_ω) (n, 3, N) of the points (n, 3), each moved by the coordinates ``moves`` (n, N):
    the columns ω_j and v_O,j + ω_j × r of their twists."""
    w = tw[:, :3]
    Jw = np.where(moves[:, None, :], w.T[None], 0.0)
    v = tw[None, :, 3:] + np.cross(w[None], points[:, None, :])
    Jr = np.where(moves[:, None, :], np.swapaxes(v, 1, 2), 0.0)
    return Jr, Jw


# ----------------------------------------------------------------------------------------------
# elastic and damping forces of the second-order strain (the linear strain is K q, D q̇)
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _strain_terms(l, e, second, grad, hess):
    """Axial strain ε of an extensible element and its gradient and Hessian on e (as
    spatial_global's ``strain_terms``): ε = u/l (+ ½ (bᵀGb + cᵀGc)), b = (v, φz), c = (w, −φy)."""
    grad[:] = 0.0
    hess[:] = 0.0
    grad[0] = 1.0 / l
    eps = e[0] / l
    if second:
        g00, g01, g11 = 6.0 / (5.0 * l * l), -1.0 / (10.0 * l), 2.0 / 15.0
        gb0, gb1 = g00 * e[1] + g01 * e[5], g01 * e[1] + g11 * e[5]
        gc0, gc1 = g00 * e[2] - g01 * e[4], g01 * e[2] - g11 * e[4]
        eps += 0.5 * (e[1] * gb0 + e[5] * gb1 + e[2] * gc0 - e[4] * gc1)
        grad[1], grad[5], grad[2], grad[4] = gb0, gb1, gc0, -gc1
        hess[1, 1], hess[1, 5], hess[5, 1], hess[5, 5] = g00, g01, g01, g11
        hess[2, 2], hess[2, 4], hess[4, 2], hess[4, 4] = g00, -g01, -g01, g11
    return eps


@njit(cache=True)
def strain_forces(P, q, qd, f, K, damping):
    """Of every element with the axial strain ε (linear bending and torsion): the internal force
    f and tangent K, returning the strain energy U; or, with ``damping``, the Kelvin–Voigt force
    f and rate tangent K of the dissipation ½μ[EA l ε̇² + ėᵀK_b ė] (returning 0)."""
    f[:] = 0.0
    K[:] = 0.0
    e, ed, fe = np.empty(6), np.empty(6), np.empty(6)
    Ke = np.empty((6, 6))
    grad, hess = np.empty(6), np.empty((6, 6))
    U = 0.0
    for el in range(P.e_idx.shape[0]):
        idx = P.e_idx[el]
        for s in range(6):
            e[s] = q[idx[s]] if idx[s] >= 0 else 0.0
            ed[s] = qd[idx[s]] if idx[s] >= 0 else 0.0
        Ke[:] = P.K_el[el]
        Ke[0, 0] = 0.0  # the axial part comes from ε
        x = ed if damping else e
        fe[:] = Ke @ x
        if not damping:
            U += 0.5 * (e @ fe)
        if not np.isnan(P.EA[el]):
            eps = _strain_terms(P.length[el], e, P.second[el], grad, hess)
            c = P.EA[el] * P.length[el]
            amount = grad @ ed if damping else eps
            if not damping:
                U += 0.5 * c * eps * eps
            for i in range(6):
                fe[i] += c * amount * grad[i]
                for j in range(6):
                    Ke[i, j] += c * (grad[i] * grad[j] + (0.0 if damping else eps * hess[i, j]))
        w = P.mu[el] if damping else 1.0
        for i in range(6):
            if idx[i] < 0:
                continue
            f[idx[i]] += w * fe[i]
            for j in range(6):
                if idx[j] >= 0:
                    K[idx[i], idx[j]] += w * Ke[i, j]
    return U
