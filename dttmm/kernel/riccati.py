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

import math

from ._jit import CONTRACT, njit
from .element import (
    coord_base,
    element_state,
    element_terms,
    link_constants,
    second_order_damping,
    second_order_terms,
    strain_constants,
)


@njit(fastmath=CONTRACT, nrt=False)
def riccati(md, data, tau, acc, xout, torque):
    """One Riccati sweep at the iterate whose angles are in ``data`` (:func:`angles`), with
    ``data.f_known`` and ``data.Mt`` set. Writes q̈ into xout (α̈ and elastic), the joint torques
    into torque, and leaves in ``data`` what :func:`riccati_loads` needs."""
    backward(md, data, tau, acc)
    forward(md, data, xout, torque)


@njit(fastmath=CONTRACT, inline="always")
def _ldl_column(l10, l20, l21, i0, i1, i2, b0, b1, b2):
    """x = H⁻¹ b for H = L D Lᵀ (L's entries l10, l20, l21; D⁻¹ = (i0, i1, i2)): the forward
    and back substitutions of one column."""
    y1 = b1 - l10 * b0
    y2 = b2 - l20 * b0 - l21 * y1
    x2 = y2 * i2
    x1 = y1 * i1 - l21 * x2
    x0 = b0 * i0 - l10 * x1 - l20 * x2
    return x0, x1, x2


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
    K00, K10, K20 = _ldl_column(l10, l20, l21, i0, i1, i2, -X00, -X01, -X02)
    K01, K11, K21 = _ldl_column(l10, l20, l21, i0, i1, i2, -X10, -X11, -X12)
    K02, K12, K22 = _ldl_column(l10, l20, l21, i0, i1, i2, -X20, -X21, -X22)
    k0, k1, k2 = _ldl_column(l10, l20, l21, i0, i1, i2, r0, r1, r2)
    return (K00, K01, K02, K10, K11, K12, K20, K21, K22), k0, k1, k2


@njit(fastmath=CONTRACT, inline="always")
def _element_step(md, i, lc, Mt, so, kin, dh, fk, Pc, g0, g1):
    """Carry (P, c) = ``Pc`` (packed P, then c) across one element from its outboard to its
    inboard cut. Pure arithmetic (the caller loads and stores: helpers inlined into a loop copy
    their tuple arguments, so the workspace is not passed here).

    lc: :func:`link_constants`; md, i: the model and link (second-order constants, read in
    their branch); Mt: the (0, 0), (1, 1), (1, 2),
    (2, 2) entries of M̃_ee, c_q and c_v; so: second-order strain; kin = (cos θ, sin θ, θ̇, e, ė, ê);
    dh: ê' (read only for a damped second-order link, zeros otherwise);
    fk: the known elastic force. Returns (K_a (9, row-major), k_0 (3), (P_I packed, c_I) (9),
    (r_x, r_y, γ̄_x, γ̄_y))."""
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    M00, M11, M12, M22, cq, cv = Mt
    c, s, td, e0, e1, e2, f0, f1, f2, eh0, eh1, eh2 = kin
    (_ms0, _ms1, rem0, rem1, Jt, A, ha0, ha1, ha2, he0, he1, he2, rx, ry, gb0, gb1) = element_terms(
        lc, c, s, td, e0, e1, e2, f0, f1, f2, g0, g1
    )
    he0 = he0 + fk[0]
    he1 = he1 + fk[1]
    he2 = he2 + fk[2]
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
        sc = strain_constants(md, i)
        fu0, fu1, fu2, T01, T02, dT11, dT12, dT21, dT22 = second_order_terms(sc, e0, e1, e2)
        Kb00, Kb01, Kb10, Kb11, Kuu = sc[7], sc[8], sc[9], sc[10], sc[11]
        de0 = eh0 - e0
        de1 = eh1 - e1
        de2 = eh2 - e2
        r0 -= fu0 + (Kuu * de0 + T01 * de1 + T02 * de2)
        r1 -= fu1 + (T01 * de0 + (dT11 + Kb00) * de1 + (dT12 + Kb01) * de2)
        r2 -= fu2 + (T02 * de0 + (dT21 + Kb10) * de1 + (dT22 + Kb11) * de2)
        H01 += cq * T01
        H02 += cq * T02
        H11 += cq * dT11
        H12 += cq * dT12
        H22 += cq * dT22
        mu = md.mu[i]
        if mu != 0.0:
            # damping on the strain rate, D(e) at the iterate: h̃_e += ΔD(e) ê', M̃_ee += c_v ΔD(e)
            g0d, g1d, g2d, D01, D02, D11, D12, D22 = second_order_damping(
                mu, sc[0], sc[1], sc[3], sc[4], sc[5], sc[6], e1, e2, dh[0], dh[1], dh[2]
            )
            r0 -= g0d
            r1 -= g1d
            r2 -= g2d
            H01 += cv * D01
            H02 += cv * D02
            H11 += cv * D11
            H12 += cv * D12
            H22 += cv * D22
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
    return (Ka, (k0, k1, k2), (n00, n01, n02, n11, n12, n22, c0, c1, c2), (rx, ry, gb0, gb1))


@njit(fastmath=CONTRACT, inline="always")
def _gain_update(p00, p01, p02, p11, p12, p22, c0, c1, c2, ga0, ga1, gg):
    """P + outer(P[:, 2], ga) (symmetric; its entries 00, 01, 11) and c + P[:, 2] gg across a
    joint whose rotation is eliminated by the gains ga, gg."""
    return (
        p00 + p02 * ga0,
        p01 + p02 * ga1,
        p11 + p12 * ga1,
        c0 + p02 * gg,
        c1 + p12 * gg,
        c2 + p22 * gg,
    )


@njit(fastmath=CONTRACT, inline="always")
def _joint(m_hub, J_hub, motion, tau_i, acc_i, Pc, g0, g1):
    """Across the hub and joint i: returns ((P, c) on the outboard side of the joint (9),
    (P, c) on its inboard side (9), (ga (3), g0)) with α̈_i = ga·a + g0 (torque-driven) or
    α̈_i = g0 (motion-driven; ga unused).

    A torque-driven joint whose torque is linearised in its own acceleration,
    τ = tau_i + s α̈_i (a closed-loop law, s = ``acc_i``; 0 for an open-loop torque), has the
    joint equation P[2, :]·a + p22 α̈_i + c2 = τ, so α̈_i = −(P[2, :]·a + c2 − tau_i)/(p22 − s)
    and the inboard side f = P a + c + P[:, 2] α̈_i: P_in = P − P[:, 2] P[2, :]/(p22 − s) stays
    symmetric; its row 2 (the joint moment τ as a function of a) vanishes only for s = 0."""
    hub = _rigid_body(Pc, m_hub, J_hub, g0, g1)
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = hub
    if motion:
        gg = acc_i
        ga0 = ga1 = ga2 = 0.0
        c0 += p02 * gg
        c1 += p12 * gg
        c2 += p22 * gg
    elif acc_i == 0.0:
        ga0 = -p02 / p22
        ga1 = -p12 / p22
        ga2 = -1.0
        gg = (tau_i - c2) / p22
        p00, p01, p11, c0, c1, c2 = _gain_update(p00, p01, p02, p11, p12, p22, c0, c1, c2, ga0, ga1, gg)
        p02 = p12 = p22 = 0.0
    else:  # closed loop: the slope s = acc_i acts as a joint stiffness (see above)
        den = p22 - acc_i
        ga0 = -p02 / den
        ga1 = -p12 / den
        ga2 = -p22 / den
        gg = (tau_i - c2) / den
        r = -acc_i / den  # 1 + ga2
        p00, p01, p11, c0, c1, c2 = _gain_update(p00, p01, p02, p11, p12, p22, c0, c1, c2, ga0, ga1, gg)
        p02, p12, p22 = p02 * r, p12 * r, p22 * r
    return hub, (p00, p01, p02, p11, p12, p22, c0, c1, c2), (ga0, ga1, ga2, gg)


@njit(fastmath=CONTRACT, inline="always")
def backward(md, data, tau, acc):
    """Tip → base: (P, c) at every cut, the element gains and the joint gains. The link
    constants are read once per link (:func:`link_constants`), outside the element loop."""
    k = md.k
    g0 = md.grav[0]
    g1 = md.grav[1]
    Pc = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    for i in range(md.n - 1, -1, -1):
        if md.pay_offset[i]:  # payload with its centre of mass off the tip, in the tip frame
            gl = i * k + k - 1
            cf = math.cos(data.e[gl, 2])
            sf = math.sin(data.e[gl, 2])
            ct = data.c[gl] * cf - data.s[gl] * sf
            st = data.s[gl] * cf + data.c[gl] * sf
            tdt = data.td[gl] + data.ed[gl, 2]
            Pc = _offset_body(
                Pc, md.m_pay[i], md.J_pay[i], md.pay_off[i, 0], md.pay_off[i, 1], ct, st, tdt, g0, g1
            )
        else:
            Pc = _rigid_body(Pc, md.m_pay[i], md.J_pay[i], g0, g1)  # payload at the tip of link i
        _store_Pc(data.P_tip, data.c_tip, i, Pc)
        if md.rigid[i]:
            Pc = _rigid_link(md, data, i, Pc, g0, g1)
            hub, Pc, gains = _joint(md.m_hub[i], md.J_hub[i], md.motion[i], tau[i], acc[i], Pc, g0, g1)
            _store_Pc(data.P_hub, data.c_hub, i, hub)
            data.ga[i, 0], data.ga[i, 1], data.ga[i, 2], data.g0[i] = gains
            continue
        lc = link_constants(md, i, g0, g1)
        Mt = (
            data.Mt[i, 0, 0],
            data.Mt[i, 1, 1],
            data.Mt[i, 1, 2],
            data.Mt[i, 2, 2],
            data.cq[i, 0],
            data.cq[i, 1],
        )
        so = md.second_order[i]
        damped = so and md.mu[i] != 0.0
        for j in range(k - 1, -1, -1):
            g = i * k + j
            kin = element_state(data, g) + (data.e_hat[g, 0], data.e_hat[g, 1], data.e_hat[g, 2])
            if damped:  # ê' of a damped second-order link (its strain-rate damping)
                dh = (data.e_hat[g, 3], data.e_hat[g, 4], data.e_hat[g, 5])
            else:
                dh = (0.0, 0.0, 0.0)
            fk = (data.f_known[g, 0], data.f_known[g, 1], data.f_known[g, 2])
            Ka, k0, Pc, rg = _element_step(md, i, lc, Mt, so, kin, dh, fk, Pc, g0, g1)
            (
                data.Ka[g, 0, 0],
                data.Ka[g, 0, 1],
                data.Ka[g, 0, 2],
                data.Ka[g, 1, 0],
                data.Ka[g, 1, 1],
                data.Ka[g, 1, 2],
                data.Ka[g, 2, 0],
                data.Ka[g, 2, 1],
                data.Ka[g, 2, 2],
            ) = Ka
            data.k0[g, 0], data.k0[g, 1], data.k0[g, 2] = k0
            _store_Pc(data.P, data.c_I, g, Pc)
            data.rso[g, 0], data.rso[g, 1], data.gbar[g, 0], data.gbar[g, 1] = rg
        hub, Pc, gains = _joint(md.m_hub[i], md.J_hub[i], md.motion[i], tau[i], acc[i], Pc, g0, g1)
        _store_Pc(data.P_hub, data.c_hub, i, hub)
        data.ga[i, 0], data.ga[i, 1], data.ga[i, 2], data.g0[i] = gains


@njit(fastmath=CONTRACT, inline="always")
def _rigid_link(md, data, i, Pc, g0, g1):
    """Carry (P, c) = ``Pc`` from the tip of rigid link i to its root through its k rigid
    massless segments (the element step without elastic coordinates: P_I = B_aᵀ P B_a,
    c_I = B_aᵀ(P γ̄_O + c), lever arm r = A(θ)(L/k, 0), γ̄_O = −θ̇² r), adding its body at the
    root; stores what the forward sweep and the cut loads read (zero gains) and returns (P, c)
    at the root."""
    k = md.k
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    ls = md.sO0[i, 0]
    for j in range(k - 1, -1, -1):
        g = i * k + j
        c = data.c[g]
        s = data.s[g]
        td = data.td[g]
        rx = c * ls
        ry = s * ls
        gb0 = -td * td * rx
        gb1 = -td * td * ry
        rho0 = p00 * gb0 + p01 * gb1 + c0
        rho1 = p01 * gb0 + p11 * gb1 + c1
        rho2 = p02 * gb0 + p12 * gb1 + c2
        u0 = -ry * p00 + rx * p01 + p02
        u1 = -ry * p01 + rx * p11 + p12
        u2 = -ry * p02 + rx * p12 + p22
        p22 = -ry * u0 + rx * u1 + u2
        p02 = u0
        p12 = u1
        c0 = rho0
        c1 = rho1
        c2 = -ry * rho0 + rx * rho1 + rho2
        Pc = (p00, p01, p02, p11, p12, p22, c0, c1, c2)
        if j == 0:  # the link's body, at the root
            Pc = _offset_body(
                Pc, md.body[i, 0], md.body[i, 3], md.body[i, 1], md.body[i, 2], c, s, td, g0, g1
            )
            p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
        for r in range(3):
            data.k0[g, r] = 0.0
            for t in range(3):
                data.Ka[g, r, t] = 0.0
        _store_Pc(data.P, data.c_I, g, Pc)
        data.rso[g, 0], data.rso[g, 1], data.gbar[g, 0], data.gbar[g, 1] = rx, ry, gb0, gb1
    return Pc


@njit(fastmath=CONTRACT, inline="always")
def _offset_body(Pc, mass, inertia, dx, dy, c, s, td, g0, g1):
    """(P, c) across a rigid body fixed to the frame (c = cos θ, s = sin θ, rate θ̇) at the cut,
    its centre of mass at d = (dx, dy) in the frame, ``inertia`` about the centre of mass:
    with ρ = A(θ) d, F = m (a + θ̈ E ρ − θ̇² ρ − g) and M = J θ̈ + ρ × F."""
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    rx = c * dx - s * dy
    ry = s * dx + c * dy
    mw = mass * td * td
    p00 += mass
    p11 += mass
    p02 -= mass * ry
    p12 += mass * rx
    p22 += inertia + mass * (rx * rx + ry * ry)
    c0 -= mw * rx + mass * g0
    c1 -= mw * ry + mass * g1
    c2 -= mass * (rx * g1 - ry * g0)
    return p00, p01, p02, p11, p12, p22, c0, c1, c2


@njit(fastmath=CONTRACT, inline="always")
def _rigid_body(Pc, mass, inertia, g0, g1):
    """(P, c) across a rigid body at the cut: P += diag(m, m, J), c −= m g."""
    p00, p01, p02, p11, p12, p22, c0, c1, c2 = Pc
    p00 += mass
    p11 += mass
    p22 += inertia
    c0 -= mass * g0
    c1 -= mass * g1
    return p00, p01, p02, p11, p12, p22, c0, c1, c2


@njit(inline="always")
def _store_Pc(P, c, row, Pc):
    """Store (P packed, c) = Pc (9) in row ``row`` of P (·, 6) and c (·, 3)."""
    P[row, 0], P[row, 1], P[row, 2], P[row, 3], P[row, 4], P[row, 5], c[row, 0], c[row, 1], c[row, 2] = Pc


@njit(fastmath=CONTRACT, inline="always")
def forward(md, data, xout, torque):
    """Base → tip: α̈, ë and the cut accelerations from the gains of :func:`backward`."""
    k = md.k
    a0 = a1 = a2 = 0.0
    for i in range(md.n):
        off = md.pad[i]
        es, ne = md.e_start[i], md.ne[i]
        su = md.su[i]
        if md.motion[i]:
            add = data.g0[i]
        else:
            add = data.ga[i, 0] * a0 + data.ga[i, 1] * a1 + data.ga[i, 2] * a2 + data.g0[i]
        a2 += add
        xout[md.i_alpha[i]] = add
        torque[i] = data.P_hub[i, 2] * a0 + data.P_hub[i, 4] * a1 + data.P_hub[i, 5] * a2 + data.c_hub[i, 2]
        for j in range(k):
            g = i * k + j
            data.a[g, 0] = a0
            data.a[g, 1] = a1
            data.a[g, 2] = a2
            q0 = data.Ka[g, 0, 0] * a0 + data.Ka[g, 0, 1] * a1 + data.Ka[g, 0, 2] * a2 + data.k0[g, 0]
            q1 = data.Ka[g, 1, 0] * a0 + data.Ka[g, 1, 1] * a1 + data.Ka[g, 1, 2] * a2 + data.k0[g, 1]
            q2 = data.Ka[g, 2, 0] * a0 + data.Ka[g, 2, 1] * a1 + data.Ka[g, 2, 2] * a2 + data.k0[g, 2]
            if ne:  # a rigid link (ne = 0) has no elastic coordinates
                b = coord_base(es, ne, off, j)
                if not off:
                    xout[b] = q0
                xout[b + 1] = q1
                xout[b + 2] = q2
            c = data.c[g]
            s = data.s[g]
            rx = data.rso[g, 0]
            ry = data.rso[g, 1]
            sq0 = su * q0
            a0 = a0 - ry * a2 + c * sq0 - s * q1 + data.gbar[g, 0]
            a1 = a1 + rx * a2 + s * sq0 + c * q1 + data.gbar[g, 1]
            a2 = a2 + q2
        data.a_tip[i, 0] = a0
        data.a_tip[i, 1] = a1
        data.a_tip[i, 2] = a2


@njit(inline="always")
def _affine(P, c, a0, a1, a2, out):
    """out = P a + c for a packed symmetric P."""
    out[0] = P[0] * a0 + P[1] * a1 + P[2] * a2 + c[0]
    out[1] = P[1] * a0 + P[3] * a1 + P[4] * a2 + c[1]
    out[2] = P[2] * a0 + P[4] * a1 + P[5] * a2 + c[2]


@njit(nrt=False)
def riccati_loads(md, data, loads):
    """Loads (Qx, Qy, M) at every cut from the last Riccati sweep: f = P a + c."""
    k = md.k
    ic = 0
    for i in range(md.n):
        for j in range(k):
            g = i * k + j
            _affine(data.P[g], data.c_I[g], data.a[g, 0], data.a[g, 1], data.a[g, 2], loads[ic])
            ic += 1
        _affine(data.P_tip[i], data.c_tip[i], data.a_tip[i, 0], data.a_tip[i, 1], data.a_tip[i, 2], loads[ic])
        ic += 1
