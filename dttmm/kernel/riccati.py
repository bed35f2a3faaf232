"""The Riccati (articulated-inertia) sweep: tip → base the affine relation f = P a + c at every
cut, then base → tip the accelerations. O(N) and stable (:func:`dttmm.sweeps.riccati` is the
readable version).

Per element, with the element terms of :func:`element_terms`:

    H = M̃_ee + B_eᵀ P B_e,  X = M_ae + B_aᵀ P B_e,  ρ = P γ̄_O + c
    ë = K_a a_I + k_0 with K_a = −H⁻¹Xᵀ, k_0 = −H⁻¹(h̃_e + B_eᵀ ρ)
    P_I = M_aa + B_aᵀ P B_a + X K_a,  c_I = h̄_a + B_aᵀ ρ + X k_0

exploiting B_a = [[1, 0, −r_y], [0, 1, r_x], [0, 0, 1]], B_e = blockdiag(A(θ)·diag(s_u, 1), 1),
and factoring the 3×3 SPD block H by LDLᵀ.
"""
from __future__ import annotations

from ._jit import CONTRACT, njit
from .element import coord_base, element_terms, link_constants, second_order_terms


@njit(fastmath=CONTRACT)
def riccati(md, dt, tau, acc, xout, torque):
    """One Riccati sweep at the iterate whose angles are in ``dt`` (:func:`angles`), with
    ``dt.f_known`` and ``dt.Mt`` set. Writes q̈ into xout (α̈ and elastic), the joint torques
    into torque, and leaves in ``dt`` what :func:`riccati_loads` needs."""
    backward(md, dt, tau, acc)
    forward(md, dt, xout, torque)


@njit(fastmath=CONTRACT, inline="always")
def _ldl_solve(H00, H01, H02, H11, H12, H22, X, r0, r1, r2):
    """K_a = H⁻¹(−Xᵀ) (row-major 3×3) and k_0 = H⁻¹ r for the SPD H, by LDLᵀ."""
    (X00, X01, X02, X10, X11, X12, X20, X21, X22) = X
    i0 = 1.0 / H00
    l10 = H01 * i0
    l20 = H02 * i0
    dd1 = H11 - l10 * H01
    i1 = 1.0 / dd1
    l21 = (H12 - l20 * H01) * i1
    dd2 = H22 - l20 * H02 - l21 * l21 * dd1
    i2 = 1.0 / dd2
    y0 = -X00
    y1 = -X01 - l10 * y0
    y2 = -X02 - l20 * y0 - l21 * y1
    K20 = y2 * i2
    K10 = y1 * i1 - l21 * K20
    K00 = y0 * i0 - l10 * K10 - l20 * K20
    y0 = -X10
    y1 = -X11 - l10 * y0
    y2 = -X12 - l20 * y0 - l21 * y1
    K21 = y2 * i2
    K11 = y1 * i1 - l21 * K21
    K01 = y0 * i0 - l10 * K11 - l20 * K21
    y0 = -X20
    y1 = -X21 - l10 * y0
    y2 = -X22 - l20 * y0 - l21 * y1
    K22 = y2 * i2
    K12 = y1 * i1 - l21 * K22
    K02 = y0 * i0 - l10 * K12 - l20 * K22
    y1 = r1 - l10 * r0
    y2 = r2 - l20 * r0 - l21 * y1
    k2 = y2 * i2
    k1 = y1 * i1 - l21 * k2
    k0 = r0 * i0 - l10 * k1 - l20 * k2
    return (K00, K01, K02, K10, K11, K12, K20, K21, K22), k0, k1, k2


@njit(fastmath=CONTRACT, inline="always")
def _element_step(md, dt, i, g, lc, Mt, so, Pc, g0, g1):
    """Carry (P, c) = ``Pc`` (packed P, then c) across element g from its outboard to its
    inboard cut; stores the gains, P_I, c_I, A s_O and γ̄_O in ``dt``. ``Mt`` = the diagonal
    and (1, 2) entries of M̃_ee; ``so``: second-order strain."""
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    M00, M11, M12, M22 = Mt
    c, s = dt.el[g].c, dt.el[g].s
    e0, e1, e2 = dt.el[g].e[0], dt.el[g].e[1], dt.el[g].e[2]
    (ms0, ms1, rem0, rem1, Jt, A, ha0, ha1, ha2, he0, he1, he2, rx, ry, gb0, gb1) = element_terms(
        lc, c, s, dt.el[g].td, e0, e1, e2, dt.el[g].ed[0], dt.el[g].ed[1], dt.el[g].ed[2], g0, g1)
    he0 = he0 + dt.el[g].f_known[0]
    he1 = he1 + dt.el[g].f_known[1]
    he2 = he2 + dt.el[g].f_known[2]
    m, su = lc[0], lc[-1]
    a0 = c * p00 + s * p01
    a1 = c * p01 + s * p11
    a2 = c * p02 + s * p12
    b0 = -s * p00 + c * p01
    b1 = -s * p01 + c * p11
    b2 = -s * p02 + c * p12
    H00 = M00 + su * su * (c * a0 + s * a1)
    H01 = su * (c * b0 + s * b1)
    H02 = su * (c * p02 + s * p12)
    H11 = M11 + (-s * b0 + c * b1)
    H12 = M12 + (-s * p02 + c * p12)
    H22 = M22 + p22
    X00 = A[0] + su * a0
    X10 = A[3] + su * a1
    X20 = A[6] + su * (-ry * a0 + rx * a1 + a2)
    X01 = A[1] + b0
    X11 = A[4] + b1
    X21 = A[7] + (-ry * b0 + rx * b1 + b2)
    X02 = A[2] + p02
    X12 = A[5] + p12
    X22 = A[8] + (-ry * p02 + rx * p12 + p22)
    rho0 = p00 * gb0 + p01 * gb1 + c0
    rho1 = p01 * gb0 + p11 * gb1 + c1
    rho2 = p02 * gb0 + p12 * gb1 + c2
    r0 = -(he0 + su * (c * rho0 + s * rho1))
    r1 = -(he1 + (-s * rho0 + c * rho1))
    r2 = -(he2 + rho2)
    if so:
        # second-order strain at the iterate e (sweeps._elastic_rhs):
        # h̃_e += f(e) + K_T(e)(ê − e), M̃_ee += c_q (K_T(e) − K)
        fu0, fu1, fu2, T01, T02, dT11, dT12, dT21, dT22 = second_order_terms(md, i, e0, e1, e2)
        Kb00, Kb01, Kb10, Kb11 = md.links[i].K[1, 1], md.links[i].K[1, 2], md.links[i].K[2, 1], md.links[i].K[2, 2]
        de0 = dt.el[g].e_hat[0] - e0
        de1 = dt.el[g].e_hat[1] - e1
        de2 = dt.el[g].e_hat[2] - e2
        r0 -= fu0 + (md.links[i].K[0, 0] * de0 + T01 * de1 + T02 * de2)
        r1 -= fu1 + (T01 * de0 + (dT11 + Kb00) * de1 + (dT12 + Kb01) * de2)
        r2 -= fu2 + (T02 * de0 + (dT21 + Kb10) * de1 + (dT22 + Kb11) * de2)
        cq = dt.jt[i].cq
        H01 += cq * T01
        H02 += cq * T02
        H11 += cq * dT11
        H12 += cq * dT12
        H22 += cq * dT22
    X = (X00, X01, X02, X10, X11, X12, X20, X21, X22)
    Ka, k0, k1, k2 = _ldl_solve(H00, H01, H02, H11, H12, H22, X, r0, r1, r2)
    K00, K01, K02, K10, K11, K12, K20, K21, K22 = Ka
    # P_I = M_aa + B_aᵀ P B_a + X K_a ; c_I = h_a + B_aᵀ ρ + X k0
    u0 = -ry * p00 + rx * p01 + p02
    u1 = -ry * p01 + rx * p11 + p12
    u2 = -ry * p02 + rx * p12 + p22
    n00 = m + p00 + (X00 * K00 + X01 * K10 + X02 * K20)
    n01 = p01 + (X00 * K01 + X01 * K11 + X02 * K21)
    n02 = rem0 + u0 + (X00 * K02 + X01 * K12 + X02 * K22)
    n11 = m + p11 + (X10 * K01 + X11 * K11 + X12 * K21)
    n12 = rem1 + u1 + (X10 * K02 + X11 * K12 + X12 * K22)
    n22 = Jt + (-ry * u0 + rx * u1 + u2) + (X20 * K02 + X21 * K12 + X22 * K22)
    c0 = ha0 + rho0 + (X00 * k0 + X01 * k1 + X02 * k2)
    c1 = ha1 + rho1 + (X10 * k0 + X11 * k1 + X12 * k2)
    c2 = ha2 + (-ry * rho0 + rx * rho1 + rho2) + (X20 * k0 + X21 * k1 + X22 * k2)
    dt.el[g].Ka[0, 0] = K00
    dt.el[g].Ka[0, 1] = K01
    dt.el[g].Ka[0, 2] = K02
    dt.el[g].Ka[1, 0] = K10
    dt.el[g].Ka[1, 1] = K11
    dt.el[g].Ka[1, 2] = K12
    dt.el[g].Ka[2, 0] = K20
    dt.el[g].Ka[2, 1] = K21
    dt.el[g].Ka[2, 2] = K22
    dt.el[g].k0[0] = k0
    dt.el[g].k0[1] = k1
    dt.el[g].k0[2] = k2
    _store_sym(dt.el[g].P, n00, n01, n02, n11, n12, n22)
    dt.el[g].c_I[0] = c0
    dt.el[g].c_I[1] = c1
    dt.el[g].c_I[2] = c2
    dt.el[g].rso[0] = rx
    dt.el[g].rso[1] = ry
    dt.el[g].gbar[0] = gb0
    dt.el[g].gbar[1] = gb1
    return n00, n01, n02, n11, n12, n22, c0, c1, c2


@njit(inline="always")
def _store_sym(out, p00, p01, p02, p11, p12, p22):
    """Write a symmetric 3×3 into its packed form ``out`` (6,)."""
    out[0] = p00
    out[1] = p01
    out[2] = p02
    out[3] = p11
    out[4] = p12
    out[5] = p22


@njit(fastmath=CONTRACT, inline="always")
def _joint(md, dt, i, tau, acc, Pc):
    """Across the hub and joint i: returns (P, c) on the inboard side of the joint and stores
    the joint gains α̈_i = ga·a + g0 (torque-driven) or α̈_i = g0 (motion-driven)."""
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    g0, g1 = md.grav[0], md.grav[1]
    mh = md.links[i].m_hub
    p00 += mh
    p11 += mh
    p22 += md.links[i].J_hub
    c0 -= mh * g0
    c1 -= mh * g1
    _store_sym(dt.jt[i].P_hub, p00, p01, p02, p11, p12, p22)
    dt.jt[i].c_hub[0] = c0
    dt.jt[i].c_hub[1] = c1
    dt.jt[i].c_hub[2] = c2
    if md.links[i].motion:
        gg = acc[i]
        dt.jt[i].g0 = gg
        c0 += p02 * gg
        c1 += p12 * gg
        c2 += p22 * gg
    else:
        ga0 = -p02 / p22
        ga1 = -p12 / p22
        ga2 = -1.0
        gg = (tau[i] - c2) / p22
        dt.jt[i].ga[0] = ga0
        dt.jt[i].ga[1] = ga1
        dt.jt[i].ga[2] = ga2
        dt.jt[i].g0 = gg
        # P + outer(P[:, 2], ga), symmetric
        n00 = p00 + p02 * ga0
        n01 = p01 + p02 * ga1
        n11 = p11 + p12 * ga1
        c0 += p02 * gg
        c1 += p12 * gg
        c2 += p22 * gg
        p00, p01, p11 = n00, n01, n11
        p02 = p12 = p22 = 0.0
    return p00, p01, p02, p11, p12, p22, c0, c1, c2


@njit(fastmath=CONTRACT)
def backward(md, dt, tau, acc):
    """Tip → base: (P, c) at every cut, the element gains and the joint gains."""
    k = md.k
    g0 = md.grav[0]
    g1 = md.grav[1]
    p00 = p01 = p02 = p11 = p12 = p22 = 0.0
    c0 = c1 = c2 = 0.0
    for i in range(md.n - 1, -1, -1):
        # payload at the tip of link i
        mp = md.links[i].m_pay
        p00 += mp
        p11 += mp
        p22 += md.links[i].J_pay
        c0 -= mp * g0
        c1 -= mp * g1
        _store_sym(dt.jt[i].P_tip, p00, p01, p02, p11, p12, p22)
        dt.jt[i].c_tip[0] = c0
        dt.jt[i].c_tip[1] = c1
        dt.jt[i].c_tip[2] = c2
        lc = link_constants(md, i, g0, g1)
        Mt = (dt.jt[i].Mt[0, 0], dt.jt[i].Mt[1, 1], dt.jt[i].Mt[1, 2], dt.jt[i].Mt[2, 2])
        so = md.links[i].second_order
        Pc = (p00, p01, p02, p11, p12, p22, c0, c1, c2)
        for j in range(k - 1, -1, -1):
            Pc = _element_step(md, dt, i, i * k + j, lc, Mt, so, Pc, g0, g1)
        p00, p01, p02, p11, p12, p22, c0, c1, c2 = _joint(md, dt, i, tau, acc, Pc)


@njit(fastmath=CONTRACT)
def forward(md, dt, xout, torque):
    """Base → tip: α̈, ë and the cut accelerations from the gains of :func:`backward`."""
    k = md.k
    a0 = a1 = a2 = 0.0
    for i in range(md.n):
        off = md.links[i].pad
        su = md.links[i].su
        if md.links[i].motion:
            add = dt.jt[i].g0
        else:
            add = dt.jt[i].ga[0] * a0 + dt.jt[i].ga[1] * a1 + dt.jt[i].ga[2] * a2 + dt.jt[i].g0
        a2 += add
        xout[md.links[i].i_alpha] = add
        torque[i] = dt.jt[i].P_hub[2] * a0 + dt.jt[i].P_hub[4] * a1 + dt.jt[i].P_hub[5] * a2 + dt.jt[i].c_hub[2]
        for j in range(k):
            g = i * k + j
            dt.el[g].a[0] = a0
            dt.el[g].a[1] = a1
            dt.el[g].a[2] = a2
            q0 = dt.el[g].Ka[0, 0] * a0 + dt.el[g].Ka[0, 1] * a1 + dt.el[g].Ka[0, 2] * a2 + dt.el[g].k0[0]
            q1 = dt.el[g].Ka[1, 0] * a0 + dt.el[g].Ka[1, 1] * a1 + dt.el[g].Ka[1, 2] * a2 + dt.el[g].k0[1]
            q2 = dt.el[g].Ka[2, 0] * a0 + dt.el[g].Ka[2, 1] * a1 + dt.el[g].Ka[2, 2] * a2 + dt.el[g].k0[2]
            b = coord_base(md, i, j)
            if not off:
                xout[b] = q0
            xout[b + 1] = q1
            xout[b + 2] = q2
            c = dt.el[g].c
            s = dt.el[g].s
            rx = dt.el[g].rso[0]
            ry = dt.el[g].rso[1]
            sq0 = su * q0
            a0 = a0 - ry * a2 + c * sq0 - s * q1 + dt.el[g].gbar[0]
            a1 = a1 + rx * a2 + s * sq0 + c * q1 + dt.el[g].gbar[1]
            a2 = a2 + q2
        dt.jt[i].a_tip[0] = a0
        dt.jt[i].a_tip[1] = a1
        dt.jt[i].a_tip[2] = a2


@njit()
def _affine(P, c, a0, a1, a2, out):
    """out = P a + c for a packed symmetric P."""
    out[0] = P[0] * a0 + P[1] * a1 + P[2] * a2 + c[0]
    out[1] = P[1] * a0 + P[3] * a1 + P[4] * a2 + c[1]
    out[2] = P[2] * a0 + P[4] * a1 + P[5] * a2 + c[2]


@njit()
def riccati_loads(md, dt, loads):
    """Loads (Qx, Qy, M) at every cut from the last Riccati sweep: f = P a + c."""
    k = md.k
    ic = 0
    for i in range(md.n):
        for j in range(k):
            g = i * k + j
            _affine(dt.el[g].P, dt.el[g].c_I, dt.el[g].a[0], dt.el[g].a[1], dt.el[g].a[2], loads[ic])
            ic += 1
        _affine(dt.jt[i].P_tip, dt.jt[i].c_tip, dt.jt[i].a_tip[0], dt.jt[i].a_tip[1], dt.jt[i].a_tip[2], loads[ic])
        ic += 1
