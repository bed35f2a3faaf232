"""The engine of the global-equation solver: recursive assembly of M(q) and of the
generalized forces, Cholesky solve, and the whole fixed-step time loop — one source, two
engines. numba compiles this file (``engine="numba"``, the default when numba imports);
:mod:`reference_models._global_python` imports the very same file a second time with ``njit``
as the identity (``engine="python"``, alias ``"numpy"``): the same algorithm uncompiled, for
debugging, for Python user laws and as the only engine without numba. The readable numpy
mechanics of :mod:`reference_models._global_numpy` (dense Jacobian products, no time loop)
are the independent one-step check of both.

Assembly without dense Jacobian products. Every coordinate q_j moves the bodies outboard
of it as a planar joint: an angle-type coordinate (α, φ) turns them about a pivot p_j, a
translation (u, v) shifts them along a unit direction d_j. Its twist, written at the world
origin as (ω, v_O), is s_j = (1, p_y, −p_x) or (0, d_x, d_y). A body's reference frame
(r, θ) moves with V = Σ s_j q̇_j over the coordinates that move it, and (ṙ, θ̇) = X(r) V with
X(r) = [[−r_y, 1, 0], [r_x, 0, 1], [1, 0, 0]]. Element el's kinetic energy is
½ pᵀ M_el p on p = (ṙ_I, θ̇, ė_el), so in (V, ė_el) its mass is
[[Xᵀ M_rr X, Xᵀ M_re], [·, M_ee]]. Summing from the tip inwards, with I_c(j) the sum of the
3 × 3 body inertias Xᵀ M_rr X of all bodies that q_j moves,

    M_ij = s_iᵀ I_c(j) s_j + s_iᵀ (Xᵀ M_re)_el[:, a_j]   (i before element el's own block)
    M_ij = s_iᵀ I_c(j) s_j + (M_ee)_el[a_i, a_j]          (i, j both of element el),

where j is the a_j-th elastic coordinate of el (the second term is absent for a joint
angle j). The generalized forces follow alike from the body wrenches Xᵀ f_rr. One column
of M costs O(N) and the assembly O(N²); the solve is a Cholesky factorisation (O(N³/3)).
The element data (moments, frames, velocity terms) are the same formulas as the numpy
mechanics in :mod:`reference_models._global_numpy`; only the summation differs.

Closed-loop pd/pid joints (:class:`Loop`) add :func:`dttmm.control.pd_torque` at the iterate
and its linearisation to each solve (:func:`_laws`); their solves use LU, as the exact ω̇ row
makes the iteration matrix unsymmetric. Open-loop runs keep the Cholesky solve. User laws
(Python callables, ``Loop.laws``) are called by the uncompiled engine only
(:func:`_user_laws`); the compiled engine refuses them.
"""

from __future__ import annotations

from collections import namedtuple
from pathlib import Path

import numpy as np

from dttmm import control, iteration
from dttmm.control import gains, pd_torque
from dttmm.iteration import stop_rule
from dttmm.jit import HAVE_NUMBA, cache_dir, cached_njit
from dttmm.kernel import recorder

from ._global_control import omega_rows

#: True in the uncompiled copy (:mod:`reference_models._global_python`) or without numba
PURE = not HAVE_NUMBA or __name__.endswith("._global_python")

if PURE:  # the DT-TMM recorder's cubic Hermite weights, uncompiled
    from dttmm.kernel_python.recorder import hermite_weights
else:
    from dttmm.kernel.recorder import hermite_weights

# numba's cache notices edits to this file only, not to the compiled functions it takes from
# elsewhere: the cache lives in a folder named by a hash of all of them (see dttmm.jit)
_SOURCES = (Path(__file__), Path(control.__file__), Path(iteration.__file__), Path(recorder.__file__))
_CACHE_DIR = None if PURE else cache_dir("global-numba", Path(__file__).resolve().parent, _SOURCES)


def njit(**options):
    """``numba.njit(**options)`` with its cache (``cache=True``) in the per-hash folder; the
    identity in the uncompiled copy."""
    return cached_njit(_CACHE_DIR, **options)


# the pd/pid law τ = clip((L0 + g_M J_hub ω̇)/(1 + g_M), ±limit) and its slopes, inlined
_pd = njit(inline="always")(pd_torque)
# the suite's one stop rule of a tolerance-driven iteration, inlined
_stop_rule = njit(inline="always")(stop_rule)

# status codes of the time loop
OK, NONFINITE = 0, 1

Pack = namedtuple(
    "Pack",
    [
        "kind",
        "owner",
        "fpos",
        "alpha_idx",
        "first_el",
        "e_idx",
        "length",
        "sigma0",
        "Sbar",
        "c0",
        "b0",
        "c1",
        "SS",
        "H",
        "mass",
        "hub_m",
        "hub_J",
        "gravity",
        "body_pos",
        "body_el",
        "body_pay",
        "pay_m",
        "pay_J",
        "pay_off",
        "EA",
        "EI",
        "mu",
        "second",
        "free",
        "presc",
        "tq_idx",
        "tq_drive",
        "mo_drive",
    ],
)

# The closed-loop joints, apart from Pack: every compiled call passes its tuples field by field,
# and the open-loop assembly should not pay for fields it never reads.
Loop = namedtuple("Loop", ["joint", "row", "omega", "gains", "pid", "user", "laws"])


def pack(lay, case) -> Pack:
    """Arrays of a global_newmark layout, in the order the compiled functions read them."""
    nel = lay.length.size
    # bodies in chain order: element el at position el, a payload at its link's tip (last + ½)
    pos, el, pay = [], [], []
    pay_of = {i: p for p, (i, _, _) in enumerate(lay.payloads)}
    for e in range(nel):
        pos.append(float(e))
        el.append(e)
        pay.append(-1)
        i = int(lay.link_of[e])
        if e == lay.last_el[i] and i in pay_of:
            pos.append(e + 0.5)
            el.append(e)
            pay.append(pay_of[i])
    drives = case.scenario.drives
    tq = [i for i, d in enumerate(drives) if d.kind == "torque" and not d.closed_loop]
    f8 = np.float64
    return Pack(
        kind=lay.kind.astype(np.int64),
        owner=lay.owner.astype(np.int64),
        fpos=lay.f_pos.astype(f8),
        alpha_idx=lay.alpha_idx.astype(np.int64),
        first_el=lay.first_el.astype(np.int64),
        e_idx=lay.e_idx.astype(np.int64),
        length=lay.length.astype(f8),
        sigma0=lay.sigma0,
        Sbar=lay.Sbar,
        c0=lay.c0,
        b0=lay.b0,
        c1=lay.c1,
        SS=lay.SS,
        H=lay.H,
        mass=lay.mass.astype(f8),
        hub_m=lay.hub_m.astype(f8),
        hub_J=lay.hub_J.astype(f8),
        gravity=lay.gravity.astype(f8),
        body_pos=np.array(pos, f8),
        body_el=np.array(el, np.int64),
        body_pay=np.array(pay, np.int64),
        pay_m=np.array([m for _, m, _ in lay.payloads] + [0.0], f8),
        pay_J=np.array([J for _, _, J in lay.payloads] + [0.0], f8),
        pay_off=np.array([*(lay.pay_offset or [(0.0, 0.0)] * len(lay.payloads)), (0.0, 0.0)], f8),
        EA=lay.EA.astype(f8),
        EI=lay.EI.astype(f8),
        mu=lay.mu.astype(f8),
        second=lay.second.astype(np.int64),
        free=lay.free.astype(np.int64),
        presc=lay.presc.astype(np.int64),
        tq_idx=lay.alpha_idx[tq].astype(np.int64),
        tq_drive=np.array(tq, np.int64),
        mo_drive=np.array([i for i, d in enumerate(drives) if d.kind == "motion"], np.int64),
    )


def pack_loop(lay, case, laws=None) -> Loop:
    """The closed-loop joints of ``case``: drive index, q index of α, ω̇ row (nc, N), gains
    (nc, 6) = (kp, kd, ki, g_M, limit, J_hub), 1.0 for a pid law (integral state), 1.0 for a
    user law, and ``laws``: the user laws as one Python callable
    (c, t, left, q, q̇, M_root) -> (τ, ∂τ/∂α, ∂τ/∂α̇) for closed-loop joint c (uncompiled engine
    only; an empty array otherwise)."""
    drives = case.scenario.drives
    cl = np.array([i for i, d in enumerate(drives) if d.closed_loop], np.int64)
    g = gains(case)
    rows = [[g.kp[i], g.kd[i], g.ki[i], g.moment_gain[i], g.limit[i], g.j_hub[i]] for i in cl]
    return Loop(
        joint=cl,
        row=lay.alpha_idx[cl].astype(np.int64),
        omega=omega_rows(lay)[cl].astype(np.float64),
        gains=np.array(rows, np.float64).reshape(-1, 6),
        pid=np.array([float(drives[i].law.name == "pid") for i in cl], np.float64),
        user=np.array([float(g.code[i] == control.CODE_USER) for i in cl], np.float64),
        laws=np.zeros(0) if laws is None else laws,
    )


# ----------------------------------------------------------------------------------------------
# Kinematics
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _elastic(P, q, e):
    """Elastic coordinates (or rates) per element into e (Nel, 3); zero where absent."""
    nel = P.e_idx.shape[0]
    e[:, :] = 0.0
    for el in range(nel):
        for a in range(3):
            j = P.e_idx[el, a]
            if j >= 0:
                e[el, a] = q[j]
    return e


@njit(cache=True)
def _angles(P, q, e, th):
    """Cross-section angle (or its rate) at every element's inboard node, into th (Nel,)."""
    nel = e.shape[0]
    acc = 0.0
    link = 0
    for el in range(nel):
        if el > 0:
            acc += e[el - 1, 2]
        if link < P.first_el.size and P.first_el[link] == el:
            acc += q[P.alpha_idx[link]]
            link += 1
        th[el] = acc


@njit(cache=True)
def frames(P, Wk, q):
    """Into the workspace: e (Nel, 3), θ (Nel,), cos θ, sin θ, r_I (Nel, 2), r_O (Nel, 2)."""
    e, th, c, s, rI, rO = Wk.e, Wk.th, Wk.c, Wk.s, Wk.rI, Wk.rO
    _elastic(P, q, e)
    _angles(P, q, e, th)
    nel = e.shape[0]
    for el in range(nel):
        c[el], s[el] = np.cos(th[el]), np.sin(th[el])
    x = 0.0
    y = 0.0
    for el in range(nel):
        rI[el, 0], rI[el, 1] = x, y
        dx, dy = P.length[el] + e[el, 0], e[el, 1]
        x += c[el] * dx - s[el] * dy
        y += s[el] * dx + c[el] * dy
        rO[el, 0], rO[el, 1] = x, y


@njit(cache=True)
def _twists(P, rI, rO, c, s, S):
    """Twist s_j (N, 3) of every coordinate at the world origin, into S."""
    N = P.kind.size
    S[:, :] = 0.0
    link = 0
    for j in range(N):
        kd = P.kind[j]
        if kd == 0:
            p = P.first_el[link]
            link += 1
            S[j, 0], S[j, 1], S[j, 2] = 1.0, rI[p, 1], -rI[p, 0]
        else:
            el = P.owner[j]
            if kd == 1:
                S[j, 1], S[j, 2] = c[el], s[el]
            elif kd == 2:
                S[j, 1], S[j, 2] = -s[el], c[el]
            else:
                S[j, 0], S[j, 1], S[j, 2] = 1.0, rO[el, 1], -rO[el, 0]


@njit(cache=True)
def _bias(P, Wk, qd):
    """Into the workspace: velocity-only accelerations of the inboard frames b_I and outboard
    nodes b_O (Nel, 2), angular rates θ̇ (Nel,) and elastic rates ė (Nel, 3)."""
    e, c, s, ed, thd, bI, bO = Wk.e, Wk.c, Wk.s, Wk.ed, Wk.thd, Wk.bI, Wk.bO
    _elastic(P, qd, ed)
    _angles(P, qd, ed, thd)
    nel = e.shape[0]
    x = 0.0
    y = 0.0
    for el in range(nel):
        bI[el, 0], bI[el, 1] = x, y
        w = thd[el]
        lx = -w * w * (P.length[el] + e[el, 0]) - 2 * w * ed[el, 1]
        ly = -w * w * e[el, 1] + 2 * w * ed[el, 0]
        x += c[el] * lx - s[el] * ly
        y += s[el] * lx + c[el] * ly
        bO[el, 0], bO[el, 1] = x, y


# ----------------------------------------------------------------------------------------------
# Element terms and recursive assembly
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _element(P, el, e, c, s, thd, ed, bI, Mel, fel):
    """Mass matrix Mel (6, 6) and force fel (6,) = gravity − velocity terms − Mel·(bias of p)
    of element el on p = (r_I, θ, u, v, φ), hub included (same formulas as the numpy mechanics,
    written out in scalars: these run once per element and iteration)."""
    ca, sa = c[el], s[el]
    Sb, SS, H, b0, c1 = P.Sbar[el], P.SS[el], P.H[el], P.b0[el], P.c1[el]
    ee, eed = e[el], ed[el]
    sig0 = P.sigma0[el, 0] + Sb[0, 0] * ee[0] + Sb[0, 1] * ee[1] + Sb[0, 2] * ee[2]
    sig1 = P.sigma0[el, 1] + Sb[1, 0] * ee[0] + Sb[1, 1] * ee[1] + Sb[1, 2] * ee[2]
    ap0 = -(sa * sig0 + ca * sig1)  # E A σ
    ap1 = ca * sig0 - sa * sig1
    m = P.mass[el] + P.hub_m[el]
    Mel[0, 0] = m
    Mel[1, 1] = m
    Mel[0, 1] = 0.0
    Mel[0, 2], Mel[1, 2] = ap0, ap1
    w = thd[el]
    g0, g1 = P.gravity[0], P.gravity[1]
    atg0, atg1 = ca * g0 + sa * g1, -sa * g0 + ca * g1  # Aᵀ g
    J = P.c0[el] + P.hub_J[el]
    hb = 0.0
    for a in range(3):
        be = b0[a] + SS[a, 0] * ee[0] + SS[a, 1] * ee[1] + SS[a, 2] * ee[2]
        J += (b0[a] + be) * ee[a]
        hb += be * eed[a]
        Mel[0, 3 + a] = ca * Sb[0, a] - sa * Sb[1, a]
        Mel[1, 3 + a] = sa * Sb[0, a] + ca * Sb[1, a]
        Mel[2, 3 + a] = -(c1[a] + H[0, a] * ee[0] + H[1, a] * ee[1] + H[2, a] * ee[2])
        Hed = H[a, 0] * eed[0] + H[a, 1] * eed[1] + H[a, 2] * eed[2]
        fel[3 + a] = Sb[0, a] * atg0 + Sb[1, a] * atg1 + w * w * be - 2 * w * Hed
        for b in range(3):
            Mel[3 + a, 3 + b] = SS[a, b]
    Mel[2, 2] = J
    for i in range(6):
        for j in range(i):
            Mel[i, j] = Mel[j, i]
    sed0 = Sb[0, 0] * eed[0] + Sb[0, 1] * eed[1] + Sb[0, 2] * eed[2]
    sed1 = Sb[1, 0] * eed[0] + Sb[1, 1] * eed[1] + Sb[1, 2] * eed[2]
    l0 = -w * w * sig0 - 2 * w * sed1
    l1 = -w * w * sig1 + 2 * w * sed0
    fel[0] = m * g0 - (ca * l0 - sa * l1)
    fel[1] = m * g1 - (sa * l0 + ca * l1)
    fel[2] = ap0 * g0 + ap1 * g1 - 2 * w * hb
    for i in range(6):
        fel[i] -= Mel[i, 0] * bI[el, 0] + Mel[i, 1] * bI[el, 1]


@njit(cache=True)
def _offset_payload(P, p, el, th, w, bO, M3, f3):
    """Mass matrix M3 (3, 3) and force f3 (3,) on (r_tip, θ_tip) of payload p, its centre of
    mass at ρ = A(θ) d from the tip: M = [[m I, m Eρ], [m (Eρ)ᵀ, J + m ρ·ρ]],
    F = m (g − b_O + θ̇² ρ), f3 = (F, ρ × F)."""
    mp = P.pay_m[p]
    c, s = np.cos(th), np.sin(th)
    rx = c * P.pay_off[p, 0] - s * P.pay_off[p, 1]
    ry = s * P.pay_off[p, 0] + c * P.pay_off[p, 1]
    M3[0, 0], M3[1, 1] = mp, mp
    M3[0, 1] = M3[1, 0] = 0.0
    M3[0, 2] = M3[2, 0] = -mp * ry
    M3[1, 2] = M3[2, 1] = mp * rx
    M3[2, 2] = P.pay_J[p] + mp * (rx * rx + ry * ry)
    F0 = mp * (P.gravity[0] - bO[el, 0] + w * w * rx)
    F1 = mp * (P.gravity[1] - bO[el, 1] + w * w * ry)
    f3[0], f3[1], f3[2] = F0, F1, rx * F1 - ry * F0


@njit(cache=True)
def _to_twist(r, M6, f6, Iout, wout, Cout):
    """For a frame at r: Iout = Xᵀ M_rr X (3, 3), wout = Xᵀ f_r (3,) and, when Cout has
    rows, Cout = Xᵀ M_re (3, 3); M6 and f6 are on (r_x, r_y, θ, [u, v, φ]). The columns of
    X are x_ω = (−r_y, r_x, 1), x_vx = (1, 0, 0), x_vy = (0, 1, 0)."""
    rx, ry = r[0], r[1]
    for col in range(3):  # Xᵀ (M x_ω), Xᵀ (M x_vx), Xᵀ (M x_vy) as columns of Iout
        if col == 0:
            u0 = -ry * M6[0, 0] + rx * M6[0, 1] + M6[0, 2]
            u1 = -ry * M6[1, 0] + rx * M6[1, 1] + M6[1, 2]
            u2 = -ry * M6[2, 0] + rx * M6[2, 1] + M6[2, 2]
        else:
            u0, u1, u2 = M6[0, col - 1], M6[1, col - 1], M6[2, col - 1]
        Iout[0, col] = -ry * u0 + rx * u1 + u2
        Iout[1, col] = u0
        Iout[2, col] = u1
    if Cout.shape[0] == 3:
        for a in range(3):
            col = 3 + a
            Cout[0, a] = -ry * M6[0, col] + rx * M6[1, col] + M6[2, col]
            Cout[1, a] = M6[0, col]
            Cout[2, a] = M6[1, col]
    wout[0] = -ry * f6[0] + rx * f6[1] + f6[2]
    wout[1] = f6[0]
    wout[2] = f6[1]


Work = namedtuple(
    "Work",
    [
        "e",
        "th",
        "c",
        "s",
        "rI",
        "rO",
        "S",
        "ed",
        "thd",
        "bI",
        "bO",
        "Ib",
        "wb",
        "Cel",
        "Fel",
        "Mel",
        "fel",
        "M3",
        "f3",
        "G",
        "F",
        "Ic",
        "W",
    ],
)


@njit(cache=True)
def workspace(P):
    """Work arrays of :func:`assemble_ws`, allocated once per run (at small N the
    allocations would cost more than the arithmetic)."""
    nel, N, nb = P.e_idx.shape[0], P.kind.size, P.body_pos.size
    return Work(
        np.zeros((nel, 3)),
        np.zeros(nel),
        np.zeros(nel),
        np.zeros(nel),
        np.zeros((nel, 2)),
        np.zeros((nel, 2)),
        np.zeros((N, 3)),
        np.zeros((nel, 3)),
        np.zeros(nel),
        np.zeros((nel, 2)),
        np.zeros((nel, 2)),
        np.zeros((nb, 3, 3)),
        np.zeros((nb, 3)),
        np.zeros((nel, 3, 3)),
        np.zeros((nel, 6)),
        np.zeros((6, 6)),
        np.zeros(6),
        np.zeros((3, 3)),
        np.zeros(3),
        np.zeros((N, 3)),
        np.zeros((N, 3)),
        np.zeros((3, 3)),
        np.zeros(3),
    )


@njit(cache=True)
def assemble(P, q, qd, M, f):
    """Fill M(q) (N, N) and f = Q_gravity − h(q, q̇) (N,) (no joint torques, no elastic or
    damping forces) by the composite-inertia recursion of the module docstring."""
    assemble_ws(P, workspace(P), q, qd, M, f)


@njit(cache=True)
def assemble_ws(P, Wk, q, qd, M, f):
    """:func:`assemble` with the work arrays given."""
    frames(P, Wk, q)
    e, c, s, rI, rO, S = Wk.e, Wk.c, Wk.s, Wk.rI, Wk.rO, Wk.S
    _twists(P, rI, rO, c, s, S)
    _bias(P, Wk, qd)
    bI, bO, thd, ed = Wk.bI, Wk.bO, Wk.thd, Wk.ed
    nb = P.body_pos.size
    Ib, wb, Cel, Fel = Wk.Ib, Wk.wb, Wk.Cel, Wk.Fel
    SSel = P.SS
    Mel, fel, M3, f3 = Wk.Mel, Wk.fel, Wk.M3, Wk.f3
    for b in range(nb):
        el = P.body_el[b]
        p = P.body_pay[b]
        if p < 0:
            _element(P, el, e, c, s, thd, ed, bI, Mel, fel)
            _to_twist(rI[el], Mel, fel, Ib[b], wb[b], Cel[el])
            for r in range(6):
                Fel[el, r] = fel[r]
        elif P.pay_off[p, 0] == 0.0 and P.pay_off[p, 1] == 0.0:
            mp = P.pay_m[p]
            M3[0, 0], M3[1, 1], M3[2, 2] = mp, mp, P.pay_J[p]
            f3[0] = mp * (P.gravity[0] - bO[el, 0])
            f3[1] = mp * (P.gravity[1] - bO[el, 1])
            _to_twist(rO[el], M3, f3, Ib[b], wb[b], Cel[el, 0:0])
        else:  # centre of mass at ρ = A(θ_tip) d off the tip
            _offset_payload(P, p, el, Wk.th[el] + e[el, 2], thd[el] + ed[el, 2], bO, M3, f3)
            _to_twist(rO[el], M3, f3, Ib[b], wb[b], Cel[el, 0:0])
            M3[0, 2] = M3[1, 2] = M3[2, 0] = M3[2, 1] = 0.0
            f3[2] = 0.0
    N = P.kind.size
    G, F, Ic, W = Wk.G, Wk.F, Wk.Ic, Wk.W
    Ic[:, :] = 0.0
    W[:] = 0.0
    b = nb - 1
    for j in range(N - 1, -1, -1):
        while b >= 0 and P.body_pos[b] >= P.fpos[j]:
            for r in range(3):
                W[r] += wb[b, r]
                for t in range(3):
                    Ic[r, t] += Ib[b, r, t]
            b -= 1
        s0, s1, s2 = S[j, 0], S[j, 1], S[j, 2]  # explicit 3-vectors: BLAS calls cost more here
        f[j] = s0 * W[0] + s1 * W[1] + s2 * W[2]
        for r in range(3):
            F[j, r] = Ic[r, 0] * s0 + Ic[r, 1] * s1 + Ic[r, 2] * s2
            G[j, r] = F[j, r]
        if P.kind[j] > 0:
            el, a = P.owner[j], P.kind[j] - 1
            for r in range(3):
                G[j, r] += Cel[el, r, a]
            f[j] += Fel[el, 3 + a]
    for j in range(N):
        own_j = P.owner[j]
        for i in range(j + 1):
            if own_j >= 0 and P.owner[i] == own_j:
                v = S[i, 0] * F[j, 0] + S[i, 1] * F[j, 1] + S[i, 2] * F[j, 2]
                v += SSel[own_j, P.kind[i] - 1, P.kind[j] - 1]
            else:
                v = S[i, 0] * G[j, 0] + S[i, 1] * G[j, 1] + S[i, 2] * G[j, 2]
            M[i, j] = v
            M[j, i] = v


# ----------------------------------------------------------------------------------------------
# Elastic and damping forces (block diagonal per element)
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def element_forces(P, el, e3, ed3, fi, KT, fd, Dt):
    """Internal force fi (3,), its tangent KT (3, 3), damping force fd (3,) and its rate
    tangent Dt (3, 3) of element el on (u, v, φ).

    U = ½ EA l ε² + ½ wᵀK_b w, w = (v, φ), ε = u/l (+ ½ wᵀGw, second order); Kelvin-Voigt
    damping with rate ε̇ = u̇/l (+ wᵀGẇ) and ẇ: fd_u = μ EA ε̇, fd_w = μ (EA l ε̇ G w + K_b ẇ).
    Dt = ∂fd/∂ė; the dependence of fd on e is left out of the iteration matrix (it keeps the
    matrix symmetric; the residual is exact, so the converged step is unchanged).
    """
    l, EA, mu = P.length[el], P.EA[el], P.mu[el]
    cb = P.EI[el] / l**3
    k00, k01, k11 = 12.0 * cb, -6.0 * cb * l, 4.0 * cb * l * l  # K_b
    g00, g01, g11 = 6.0 / (5.0 * l * l), -1.0 / (10.0 * l), 2.0 / 15.0  # G
    v, ph, vd, phd = e3[1], e3[2], ed3[1], ed3[2]
    sec = P.second[el] == 1
    if sec:
        gw0, gw1 = g00 * v + g01 * ph, g01 * v + g11 * ph
    else:
        gw0, gw1 = 0.0, 0.0
    eps = e3[0] / l + 0.5 * (v * gw0 + ph * gw1)
    epsd = ed3[0] / l + vd * gw0 + phd * gw1
    fi[0] = EA * eps
    fi[1] = EA * l * eps * gw0 + k00 * v + k01 * ph
    fi[2] = EA * l * eps * gw1 + k01 * v + k11 * ph
    fd[0] = mu * EA * epsd
    fd[1] = mu * (EA * l * epsd * gw0 + k00 * vd + k01 * phd)
    fd[2] = mu * (EA * l * epsd * gw1 + k01 * vd + k11 * phd)
    KT[0, 0] = EA / l
    KT[0, 1] = KT[1, 0] = EA * gw0
    KT[0, 2] = KT[2, 0] = EA * gw1
    b00 = EA * l * gw0 * gw0 + k00
    b01 = EA * l * gw0 * gw1 + k01
    b11 = EA * l * gw1 * gw1 + k11
    for a in range(3):
        for b in range(3):
            Dt[a, b] = mu * KT[a, b] if (a == 0 or b == 0) else 0.0
    Dt[1, 1], Dt[1, 2], Dt[2, 1], Dt[2, 2] = mu * b00, mu * b01, mu * b01, mu * b11
    ge = EA * l * eps if sec else 0.0
    KT[1, 1] = b00 + ge * g00
    KT[1, 2] = KT[2, 1] = b01 + ge * g01
    KT[2, 2] = b11 + ge * g11


@njit(cache=True)
def add_elastic(P, q, qd, cq, cv, A, rhs, x):
    """A += cq K_T + cv D_t and rhs += −f_int − f_d + (cq K_T + cv D_t) x, element by element."""
    nel = P.e_idx.shape[0]
    e3 = np.zeros(3)
    ed3 = np.zeros(3)
    fi = np.zeros(3)
    fd = np.zeros(3)
    KT = np.zeros((3, 3))
    Dt = np.zeros((3, 3))
    for el in range(nel):
        for a in range(3):
            j = P.e_idx[el, a]
            e3[a] = q[j] if j >= 0 else 0.0
            ed3[a] = qd[j] if j >= 0 else 0.0
        element_forces(P, el, e3, ed3, fi, KT, fd, Dt)
        for a in range(3):
            i = P.e_idx[el, a]
            if i < 0:
                continue
            rhs[i] -= fi[a] + fd[a]
            for b in range(3):
                j = P.e_idx[el, b]
                if j < 0:
                    continue
                t = cq * KT[a, b] + cv * Dt[a, b]
                A[i, j] += t
                rhs[i] += t * x[j]


# ----------------------------------------------------------------------------------------------
# Linear solve with prescribed coordinates
# ----------------------------------------------------------------------------------------------


@njit(cache=True)
def _chol_solve(A, b):
    """x = A⁻¹b for symmetric A: Cholesky (LAPACK potrf) and two triangular substitutions;
    LU when A is not positive definite."""
    n = b.size
    try:
        L = np.linalg.cholesky(A)
    except Exception:  # noqa: BLE001 -- numba catches only Exception; potrf reports non-SPD
        return np.linalg.solve(A, b)
    y = np.empty(n)
    for i in range(n):
        acc = b[i]
        for k in range(i):
            acc -= L[i, k] * y[k]
        y[i] = acc / L[i, i]
    x = np.empty(n)
    for i in range(n - 1, -1, -1):
        acc = y[i]
        for k in range(i + 1, n):
            acc -= L[k, i] * x[k]
        x[i] = acc / L[i, i]
    return x


@njit(cache=True)
def solve_partitioned(P, A, rhs, x, lu=False):
    """Solve A x = rhs for the free entries of x (prescribed entries of x given); return the
    residual force A[P] x − rhs[P] on the prescribed coordinates (their joint torques)."""
    F, Pp = P.free, P.presc
    nf = F.size
    Aff = np.empty((nf, nf))
    bf = np.empty(nf)
    for a in range(nf):
        i = F[a]
        acc = rhs[i]
        for p in Pp:
            acc -= A[i, p] * x[p]
        bf[a] = acc
        for b in range(nf):
            Aff[a, b] = A[i, F[b]]
    xf = np.linalg.solve(Aff, bf) if lu else _chol_solve(Aff, bf)
    for a in range(nf):
        x[F[a]] = xf[a]
    tau = np.zeros(Pp.size)
    for r in range(Pp.size):
        i = Pp[r]
        tau[r] = A[i] @ x - rhs[i]
    return tau


@njit(cache=True)
def _forward_system(P, q, qd, Qtau, pres_acc):
    """(M, Q − h − f_int − f_d, q̈ holding the prescribed accelerations, 0 elsewhere) of the
    forward dynamics at (q, q̇)."""
    N = q.size
    M = np.empty((N, N))
    f = np.empty(N)
    assemble(P, q, qd, M, f)
    rhs = f + Qtau
    x = np.zeros(N)
    for r in range(P.presc.size):
        x[P.presc[r]] = pres_acc[r]
    add_elastic(P, q, qd, 0.0, 0.0, M, rhs, x)
    return M, rhs, x


@njit(cache=True)
def forward(P, q, qd, Qtau, pres_acc):
    """q̈ of M q̈ = Q − h − f_int − f_d with the prescribed q̈ given; joint torques of the
    prescribed joints. ``q``, ``qd`` hold the prescribed values."""
    M, rhs, x = _forward_system(P, q, qd, Qtau, pres_acc)
    tau = solve_partitioned(P, M, rhs, x)
    return x, tau


@njit(cache=True)
def _laws(C, t, left, q, qd, x, ff, ref, zc, dz, cq, cv, M, rhs, tau, used, slope):
    """The closed-loop laws at the iterate x (q, q̇ its coordinates) at time t (left limit if
    ``left``): torques into tau (nc,) and, when M has rows, their linearisation added to
    M q̈ = rhs: the slope in the joint's own α̈ (through α, α̇ and z = zc + dz·α) on the diagonal
    and the slope in ω̇ along its exact row W_c, which makes M unsymmetric (solved by LU).
    Lagging the inboard part of ω̇ at the iterate instead keeps M symmetric, but that fixed
    point diverges where the inertia felt by the joint with every other coordinate free is
    small (an inner joint at t = 0), so the row is kept exact. User laws: :func:`_user_laws`
    (``used``, ``slope``: their torques of the last solve and their slopes)."""
    N = x.size
    for c in range(C.row.size):
        if C.user[c] != 0.0:
            continue
        r = C.row[c]
        wd = 0.0
        for j in range(N):
            wd += C.omega[c, j] * x[j]
        g = C.gains[c]
        z = zc[c] + dz[c] * q[r]
        t_c, da, dv, dzz, dw = _pd(
            g[0], g[1], g[2], g[3], g[4], g[5], ff[c], ref[c, 0], ref[c, 1], z, q[r], qd[r], wd
        )
        tau[c] = t_c
        if M.shape[0] > 0:
            s = da * cq + dv * cv + dzz * dz[c] * cq
            M[r, r] -= s
            rhs[r] += t_c - s * x[r] - dw * wd
            for j in range(N):
                M[r, j] -= dw * C.omega[c, j]
    _user_laws(C, t, left, q, qd, x, cq, cv, M, rhs, tau, used, slope)


def _user_laws_python(C, t, left, q, qd, x, cq, cv, M, rhs, tau, used, slope):
    """The user laws (Python callables, ``C.laws``) at the iterate x: each sees the root
    bending moment M_root = τ_used − J_hub ω̇ of the iterate, τ_used the torque its last solve
    applied (``used``); torques into tau and, when M has rows, the slope s = ∂τ/∂α c_q +
    ∂τ/∂α̇ c_v on the diagonal (into ``slope``); the dependence on M_root and on other joints is
    resolved by the repeated solves."""
    for c in range(C.row.size):
        if C.user[c] == 0.0:
            continue
        r = C.row[c]
        wd = C.omega[c] @ x
        tau[c], da, dv = C.laws(c, t, left, q, qd, used[c] - C.gains[c, 5] * wd)
        if M.shape[0] > 0:
            s = da * cq + dv * cv
            slope[c] = s
            M[r, r] -= s
            rhs[r] += tau[c] - s * x[r]


if PURE:
    _user_laws = _user_laws_python
else:  # the compiled engine has no user laws (refused by the driver)

    @njit(inline="always")
    def _user_laws(C, t, left, q, qd, x, cq, cv, M, rhs, tau, used, slope):
        return None


@njit(cache=True)
def _applied(C, tau_c, slope, new, x, used):
    """The torques the user laws applied in a solve that moved the iterate from x to new:
    τ + s (α̈_new − α̈_x), the τ_used of their next M_root."""
    for c in range(C.row.size):
        if C.user[c] != 0.0:
            r = C.row[c]
            used[c] = tau_c[c] + slope[c] * (new[r] - x[r])


@njit(cache=True)
def forward_closed(P, C, t, left, q, qd, Qtau, pres_acc, ff, ref, z, used, tol, maxit):
    """:func:`forward` with the closed-loop laws at time t (integral states z; ``used``: the
    user laws' torques, in and out): the laws' dependence on ω̇ is iterated until
    :func:`dttmm.iteration.stop_rule` holds (relative tolerance ``tol``, at most ``maxit``
    solves). Returns (q̈, τ of prescribed joints, τ of the closed-loop joints, converged)."""
    M0, rhs0, x = _forward_system(P, q, qd, Qtau, pres_acc)
    nc = C.row.size
    tau_c = np.zeros(nc)
    dz = np.zeros(nc)
    slope = np.zeros(nc)
    tau = np.zeros(P.presc.size)
    prev = np.inf
    converged = False
    for it in range(maxit):
        M = M0.copy()
        rhs = rhs0.copy()
        _laws(C, t, left, q, qd, x, ff, ref, z, dz, 0.0, 0.0, M, rhs, tau_c, used, slope)
        new = x.copy()
        tau = solve_partitioned(P, M, rhs, new, True)
        _applied(C, tau_c, slope, new, x, used)
        dx = np.max(np.abs(new - x))
        x = new
        stop, converged = _stop_rule(it, dx, prev, np.max(np.abs(x)), tol)
        if stop:
            break
        prev = dx
    _laws(C, t, left, q, qd, x, ff, ref, z, dz, 0.0, 0.0, M0[:0], rhs0[:0], tau_c, used, slope)
    return x, tau, tau_c, converged


@njit(cache=True)
def kinetic(P, q, qd):
    """½ q̇ᵀ M(q) q̇."""
    N = q.size
    M = np.empty((N, N))
    f = np.empty(N)
    assemble(P, q, np.zeros(N), M, f)
    return 0.5 * qd @ (M @ qd)


# ----------------------------------------------------------------------------------------------
# Fixed-step time loop (Newmark / generalized-α, frozen-coefficient iteration)
# ----------------------------------------------------------------------------------------------

IT_TOL, IT_FIXED = 0, 1


@njit(cache=True)
def _load_drives(P, tq, mo, Q, tau_link):
    """Generalized torques Q (N,) and the link torque vector from one row of the drive tables."""
    Q[:] = 0.0
    for r in range(P.tq_idx.size):
        Q[P.tq_idx[r]] = tq[r]
        tau_link[P.tq_drive[r]] = tq[r]


@njit(cache=True)
def _iterate(
    P,
    C,
    Wk,
    itmode,
    nfix,
    tol,
    maxit,
    t,
    qt,
    qtd,
    cq,
    cv,
    x,
    Q,
    mo,
    M,
    f,
    ff,
    ref,
    zc,
    dz,
    tau_c,
    used,
    slope,
):
    """Iterate the q̈ of the step ending at t (in place in x); returns (τ of the prescribed
    joints, solves, converged); the closed-loop torques at the final iterate go into tau_c.
    Stopping rule: :func:`dttmm.iteration.stop_rule`, as in DT-TMM."""
    N = x.size
    Pp = P.presc
    nsolve = maxit if itmode == IT_TOL else nfix + 1
    prev = np.inf
    converged = itmode == IT_FIXED
    tau = np.zeros(Pp.size)
    qi = np.empty(N)
    qdi = np.empty(N)
    it = 0
    for it in range(nsolve):
        for i in range(N):
            qi[i] = qt[i] + cq * x[i]
            qdi[i] = qtd[i] + cv * x[i]
        for r in range(Pp.size):
            qi[Pp[r]], qdi[Pp[r]] = mo[r, 0], mo[r, 1]
        assemble_ws(P, Wk, qi, qdi, M, f)
        rhs = f + Q
        add_elastic(P, qi, qdi, cq, cv, M, rhs, x)
        if tau_c.size:
            _laws(C, t, True, qi, qdi, x, ff, ref, zc, dz, cq, cv, M, rhs, tau_c, used, slope)
        new = x.copy()
        tau = solve_partitioned(P, M, rhs, new, tau_c.size > 0)
        if tau_c.size:
            _applied(C, tau_c, slope, new, x, used)
        dx = np.max(np.abs(new - x)) if N else 0.0
        x[:] = new
        if itmode == IT_TOL:
            stop, converged = _stop_rule(it, dx, prev, np.max(np.abs(x)), tol)
            if stop:
                break
            prev = dx
    if tau_c.size:
        for i in range(N):
            qi[i] = qt[i] + cq * x[i]
            qdi[i] = qtd[i] + cv * x[i]
        _laws(C, t, True, qi, qdi, x, ff, ref, zc, dz, cq, cv, M[:0], f[:0], tau_c, used, slope)
    return tau, it + 1, converged


@njit(cache=True)
def _record(P, rq, rqd, rtau, c, q, qd, tau):
    rq[c] = q
    rqd[c] = qd
    rtau[c] = tau


@njit(cache=True)
def _emit(P, C, t0, q0, qd0, tau0, t1, q1, qd1, tau1, tol_t, outt, out_tq, out_mo, rq, rqd, rtau, c):
    """Record every output time in (t0, t1]: the step end when it falls on t1, else cubic
    Hermite of (q, q̇); prescribed joints from their law, their torques linear in time."""
    Pp = P.presc
    while c < outt.size and outt[c] <= t1 + tol_t:
        t = outt[c]
        if abs(t - t1) <= tol_t:
            _record(P, rq, rqd, rtau, c, q1, qd1, tau1)
            c += 1
            continue
        H = t1 - t0
        s = (t - t0) / H
        w0, w1, w2, w3, v0, v1, v2, v3 = hermite_weights(s, H)  # the DT-TMM recorder's weights
        q = w0 * q0 + w1 * qd0 + w2 * q1 + w3 * qd1
        qd = v0 * q0 + v1 * qd0 + v2 * q1 + v3 * qd1
        tau = np.zeros(tau0.size)
        for r in range(Pp.size):
            q[Pp[r]], qd[Pp[r]] = out_mo[c, r, 0], out_mo[c, r, 1]
            dr = P.mo_drive[r]
            tau[dr] = (1 - s) * tau0[dr] + s * tau1[dr]
        for r in range(P.tq_drive.size):
            tau[P.tq_drive[r]] = out_tq[c, r]
        for r in range(C.joint.size):
            dr = C.joint[r]
            tau[dr] = (1 - s) * tau0[dr] + s * tau1[dr]
        _record(P, rq, rqd, rtau, c, q, qd, tau)
        c += 1
    return c


@njit(cache=True)
def _first_nonfinite(q, qd, qdd):
    N = q.size
    for i in range(N):
        if not np.isfinite(q[i]):
            return i
    for i in range(N):
        if not np.isfinite(qd[i]):
            return N + i
    for i in range(N):
        if not np.isfinite(qdd[i]):
            return 2 * N + i
    return -1


@njit(cache=True)
def run(
    P,
    C,
    coef,
    itmode,
    nfix,
    tol,
    maxit,
    t_end,
    restart,
    tq_l,
    mo_l,
    tq_r,
    mo_r,
    q,
    qd,
    qdd,
    a,
    tau,
    outt,
    out_tq,
    out_mo,
    rq,
    rqd,
    rtau,
    uncon,
    stats,
    ff_l,
    ref_l,
    ff_r,
    ref_r,
    z,
    err,
):
    """Step the schedule t_end from the state (q, q̇, q̈, a, τ) at t = 0, recording outputs.

    Closed-loop joints: their feedforward ff (nt, nc) and reference (α_ref, α̇_ref) ref
    (nt, nc, 2) on the schedule (left limits; ``_r``: right limits at restarts), the integral
    states z (nc,) and err = α_ref − α (nc,) at t = 0 (both updated in place).

    stats: [0] solves, [1] max solves per step, [2] unconverged steps, [3] steps done,
    [4] outputs recorded (in: those at t = 0), [5] first non-finite entry of [q, q̇, q̈],
    [6] forward-dynamics solves with closed-loop laws (restarts) left unconverged. Returns OK or NONFINITE (the failed step is
    stats[3]; outputs up to the step before it are recorded)."""
    beta, gamma, am, af = coef[0], coef[1], coef[2], coef[3]
    N = q.size
    M = np.empty((N, N))
    f = np.empty(N)
    Q = np.zeros(N)
    Wk = workspace(P)
    Pp = P.presc
    c = int(stats[4])
    t0 = 0.0
    tol_t = 1e-9 * t_end[0] if t_end.size else 0.0
    nc = C.row.size
    zc = np.zeros(nc)
    dz = np.zeros(nc)
    tau_c = np.zeros(nc)
    used = np.zeros(nc)
    slope = np.zeros(nc)
    for n in range(t_end.size):
        stats[3] = n
        t1 = t_end[n]
        dt = t1 - t0
        mix = (af * qdd - am * a) / (1 - am)
        qt = q + dt * qd + dt * dt * (0.5 - beta) * a + beta * dt * dt * mix
        qtd = qd + dt * (1 - gamma) * a + gamma * dt * mix
        cq = beta * dt * dt * (1 - af) / (1 - am)
        cv = gamma * dt * (1 - af) / (1 - am)
        tau1 = tau.copy()
        _load_drives(P, tq_l[n], mo_l[n], Q, tau1)
        x = qdd.copy()
        for r in range(Pp.size):
            x[Pp[r]] = mo_l[n, r, 2]
        for j in range(nc):  # trapezoidal integral state: z_{n+1} = zc + dz α_{n+1}
            pid = C.pid[j]
            zc[j] = pid * (z[j] + 0.5 * dt * (err[j] + ref_l[n, j, 0]))
            dz[j] = -0.5 * dt * pid
            used[j] = tau[C.joint[j]]  # a user law's first M_root: the torque of the last step
        tau_p, ns, ok = _iterate(
            P,
            C,
            Wk,
            itmode,
            nfix,
            tol,
            maxit,
            t1,
            qt,
            qtd,
            cq,
            cv,
            x,
            Q,
            mo_l[n],
            M,
            f,
            ff_l[n],
            ref_l[n],
            zc,
            dz,
            tau_c,
            used,
            slope,
        )
        stats[0] += ns
        stats[1] = max(stats[1], ns)
        if not ok:
            stats[2] += 1
            uncon[n] = True
        q1 = qt + cq * x
        qd1 = qtd + cv * x
        a1 = ((1 - af) * x + af * qdd - am * a) / (1 - am)
        for r in range(Pp.size):
            i = Pp[r]
            q1[i], qd1[i], a1[i] = mo_l[n, r, 0], mo_l[n, r, 1], mo_l[n, r, 2]
            tau1[P.mo_drive[r]] = tau_p[r]
        for j in range(nc):
            r = C.row[j]
            z[j] = zc[j] + dz[j] * q1[r]
            err[j] = ref_l[n, j, 0] - q1[r]
            tau1[C.joint[j]] = tau_c[j]
        bad = _first_nonfinite(q1, qd1, x)
        if bad >= 0:
            stats[4] = c
            stats[5] = bad
            return NONFINITE
        c = _emit(P, C, t0, q, qd, tau, t1, q1, qd1, tau1, tol_t, outt, out_tq, out_mo, rq, rqd, rtau, c)
        q, qd, qdd, a, tau = q1, qd1, x, a1, tau1
        if restart[n]:
            _load_drives(P, tq_r[n], mo_r[n], Q, tau1.copy())
            if nc:
                for j in range(nc):
                    used[j] = tau[C.joint[j]]
                qdd, _, _, fd_ok = forward_closed(
                    P, C, t1, False, q, qd, Q, mo_r[n, :, 2].copy(), ff_r[n], ref_r[n], z, used, tol, maxit
                )
                if not fd_ok:
                    stats[6] += 1
            else:
                qdd, _ = forward(P, q, qd, Q, mo_r[n, :, 2].copy())
            a = qdd.copy()
        t0 = t1
    stats[3] = t_end.size
    stats[4] = c
    return OK
