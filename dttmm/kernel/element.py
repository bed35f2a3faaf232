"""Element-level passes of the kernel: frame angles, known elastic forces, effective elastic
mass, and the ONE function for an element's mass, velocity and gravity terms
(:func:`element_terms`) that the Riccati sweep, the plain sweep and the energy all use.

The element is that of :mod:`dttmm.element` (corotational frame at the inboard node,
s(ξ, e) = s0(ξ) + S(ξ) e, constant moments of s0 and S); here written as scalar code over the
padded coordinates (u, v, φ), exploiting the sparsity of the moments (u couples to (v, φ) only
through D2 and C_SES; :func:`dttmm.kernel.layout.build_model` checks the pattern).
"""

from __future__ import annotations

import math

from ._jit import CONTRACT, njit

#: |φ| below which cos/sin of the element rotation come from their Taylor series
PHI_SMALL = 0.1


@njit(fastmath=CONTRACT)
def rotate(c, s, th_new, phi):
    """(cos, sin) of θ_new = θ + φ from (cos θ, sin θ): A(θ + φ) = A(θ)A(φ), with cos φ, sin φ
    from their Taylor series for |φ| ≤ PHI_SMALL (truncation < 1e-22, below round-off) and from
    libm on θ_new otherwise. The composition adds ~1 ulp per element (≲ 1e-13 after 1000)."""
    if abs(phi) > PHI_SMALL:
        return math.cos(th_new), math.sin(th_new)
    p2 = phi * phi
    sp = phi * (
        1.0 + p2 * (-1.0 / 6 + p2 * (1.0 / 120 + p2 * (-1.0 / 5040 + p2 * (1.0 / 362880 - p2 / 39916800))))
    )
    cp = 1.0 + p2 * (
        -0.5
        + p2 * (1.0 / 24 + p2 * (-1.0 / 720 + p2 * (1.0 / 40320 + p2 * (-1.0 / 3628800 + p2 / 479001600))))
    )
    return c * cp - s * sp, s * cp + c * sp


@njit(inline="always")
def coord_base(e_start, ne, pad, j):
    """Index in q of the padded u of element j of a link whose elastic coordinates start at
    ``e_start`` (its v is at +1, φ at +2)."""
    return e_start + j * ne - pad


@njit(nrt=False)
def angles(md, q, qd, data):
    """Kinematic pass (base → tip): frame cos/sin and rate of every element, padded e and ė
    (a rigid link's segments: its root frame, e = ė = 0 as zeroed by :func:`make_data`)."""
    k = md.k
    th0 = 0.0
    thd0 = 0.0
    for i in range(md.n):
        off = md.pad[i]
        es, ne = md.e_start[i], md.ne[i]
        th = th0 + q[md.i_alpha[i]]
        thd = thd0 + qd[md.i_alpha[i]]
        cth = math.cos(th)
        sth = math.sin(th)
        if md.rigid[i]:  # rigid link: every segment in the root frame, no elastic coordinates
            for j in range(k):
                g = i * k + j
                data.c[g] = cth
                data.s[g] = sth
                data.td[g] = thd
            th0 = th
            thd0 = thd
            continue
        b = 0
        for j in range(k):
            g = i * k + j
            if j > 0:
                cth, sth = rotate(cth, sth, th, q[b + 2])  # b, th: from element j − 1, θ_j
            data.c[g] = cth
            data.s[g] = sth
            data.td[g] = thd
            b = coord_base(es, ne, off, j)
            if off:
                data.e[g, 0] = 0.0
                data.ed[g, 0] = 0.0
            else:
                data.e[g, 0] = q[b]
                data.ed[g, 0] = qd[b]
            data.e[g, 1] = q[b + 1]
            data.ed[g, 1] = qd[b + 1]
            data.e[g, 2] = q[b + 2]
            data.ed[g, 2] = qd[b + 2]
            th += q[b + 2]
            thd += qd[b + 2]
        th0 = th
        thd0 = thd


@njit(nrt=False)
def elastic_known(md, qt, qdt, data):
    """K ê + D ê' of every element (constant during the frozen-coefficient iteration); for a
    link with second-order strain D ê' only (D = μK), and ê, ê' themselves in ``data.e_hat``
    (its elastic and damping forces are taken at each iterate inside the sweep,
    see :func:`second_order_terms` and :func:`second_order_damping`)."""
    k = md.k
    for i in range(md.n):
        off = md.pad[i]
        es, ne = md.e_start[i], md.ne[i]
        so = md.second_order[i]
        if md.rigid[i]:  # no elastic coordinates: f_known stays zero
            continue
        for j in range(k):
            g = i * k + j
            b = coord_base(es, ne, off, j)
            e0 = 0.0 if off else qt[b]
            d0 = 0.0 if off else qdt[b]
            e1, e2 = qt[b + 1], qt[b + 2]
            d1, d2 = qdt[b + 1], qdt[b + 2]
            if so:
                data.e_hat[g, 0] = e0
                data.e_hat[g, 1] = e1
                data.e_hat[g, 2] = e2
                data.e_hat[g, 3] = d0
                data.e_hat[g, 4] = d1
                data.e_hat[g, 5] = d2
                for r in range(3):
                    data.f_known[g, r] = md.D[i, r, 0] * d0 + md.D[i, r, 1] * d1 + md.D[i, r, 2] * d2
            else:
                for r in range(3):
                    data.f_known[g, r] = (
                        md.K[i, r, 0] * e0
                        + md.K[i, r, 1] * e1
                        + md.K[i, r, 2] * e2
                        + md.D[i, r, 0] * d0
                        + md.D[i, r, 1] * d1
                        + md.D[i, r, 2] * d2
                    )


@njit(nrt=False)
def effective_mass(md, cq, cv, data):
    """M̃_ee = C_SS + c_q K + c_v D per link (+ the unit dummy mass of an inextensible link);
    c_q and c_v are kept for the per-element tangents of second-order links."""
    for i in range(md.n):
        for r in range(3):
            for c in range(3):
                data.Mt[i, r, c] = md.CSS[i, r, c] + cq * md.K[i, r, c] + cv * md.D[i, r, c]
        data.Mt[i, 0, 0] += md.dummy[i]
        data.cq[i, 0] = cq
        data.cq[i, 1] = cv


@njit(inline="always")
def strain_constants(md, i):
    """Second-order strain constants of link i: (EA, EA·l, 1/l, G (4, row-major), K_b (4,
    row-major), K_uu)."""
    return (
        md.EA[i],
        md.EAl[i],
        md.inv_l[i],
        md.G[i, 0, 0],
        md.G[i, 0, 1],
        md.G[i, 1, 0],
        md.G[i, 1, 1],
        md.K[i, 1, 1],
        md.K[i, 1, 2],
        md.K[i, 2, 1],
        md.K[i, 2, 2],
        md.K[i, 0, 0],
    )


@njit(fastmath=CONTRACT, inline="always")
def second_order_terms(sc, e0, e1, e2):
    """Second-order strain of one element (:func:`dttmm.element.elastic_forces`) with the
    constants ``sc`` of :func:`strain_constants`: ε = u/l + ½ wᵀGw, w = (v, φ);
    f_u = EA ε, f_w = EA l ε G w + K_b w. Returns f (3) and the tangent K_T = ∂f/∂e as its u–w
    row (T01, T02) and ΔT = K_T,ww − K_b (2×2, row-major); K_T,uu = EA/l = K_uu."""
    EA, EAl, il, G00, G01, G10, G11, Kb00, Kb01, Kb10, Kb11, _Kuu = sc
    Gw1 = G00 * e1 + G01 * e2
    Gw2 = G10 * e1 + G11 * e2
    eps = e0 * il + 0.5 * (e1 * Gw1 + e2 * Gw2)
    Nl = EAl * eps
    a1 = EAl * Gw1
    a2 = EAl * Gw2
    f0 = EA * eps
    f1 = Nl * Gw1 + (Kb00 * e1 + Kb01 * e2)
    f2 = Nl * Gw2 + (Kb10 * e1 + Kb11 * e2)
    return (
        f0,
        f1,
        f2,
        EA * Gw1,
        EA * Gw2,
        a1 * Gw1 + Nl * G00,
        a1 * Gw2 + Nl * G01,
        a2 * Gw1 + Nl * G10,
        a2 * Gw2 + Nl * G11,
    )


@njit(fastmath=CONTRACT, inline="always")
def second_order_damping(mu, EA, EAl, G00, G01, G10, G11, e1, e2, d0, d1, d2):
    """Second-order part of the Kelvin-Voigt damping of one element (μ ≠ 0).

    The damping acts on the rate of the strain measure of :func:`second_order_terms`:
    dissipation R = ½ μ [EA l ε̇² + ẇᵀK_b ẇ], ε̇ = u̇/l + wᵀGẇ, so f_d = D(e) ė with
    D(e) = μ [[EA/l, EA (Gw)ᵀ], [EA Gw, EA l (Gw)(Gw)ᵀ + K_b]] = μK + ΔD(e). The sweep takes
    D at the iterate e and ė = ê' + c_v ë (exact in ė): the known part μK ê' is in
    ``f_known`` and c_v μK in M̃_ee; this returns the rest, ΔD(e) ê' (3) and ΔD(e) as its
    entries (0, 1), (0, 2), (1, 1), (1, 2), (2, 2) (symmetric; ΔD_00 = 0)."""
    Gw1 = G00 * e1 + G01 * e2
    Gw2 = G10 * e1 + G11 * e2
    mEA = mu * EA
    b1 = mEA * Gw1
    b2 = mEA * Gw2
    gwd = Gw1 * d1 + Gw2 * d2
    s = mEA * d0 + (mu * EAl) * gwd
    c1 = (mu * EAl) * Gw1
    c2 = (mu * EAl) * Gw2
    return mEA * gwd, Gw1 * s, Gw2 * s, b1, b2, c1 * Gw1, c1 * Gw2, c2 * Gw2


@njit(inline="always")
def element_state(data, g):
    """(cos θ, sin θ, θ̇, e (3), ė (3)) of element g: the arguments of :func:`element_terms`
    between ``lc`` and gravity."""
    e, ed = data.e, data.ed
    return (data.c[g], data.s[g], data.td[g], e[g, 0], e[g, 1], e[g, 2], ed[g, 0], ed[g, 1], ed[g, 2])


@njit(inline="always")
def link_constants(md, i, g0, g1):
    """The nonzero element moments of link i and its element weight, read once per link (a
    tuple of scalars that :func:`element_terms` unpacks)."""
    m = md.m[i]
    return (
        m,
        m * g0,
        m * g1,
        md.cs0[i, 0],
        md.CS[i, 0, 0],
        md.CS[i, 1, 1],
        md.CS[i, 1, 2],
        md.cs0s0[i],
        md.cs0S[i, 0],
        md.d1[i, 1],
        md.d1[i, 2],
        md.D2[i, 0, 1],
        md.D2[i, 0, 2],
        md.D2[i, 1, 0],
        md.D2[i, 2, 0],
        md.CSS[i, 0, 0],
        md.CSS[i, 1, 1],
        md.CSS[i, 1, 2],
        md.CSS[i, 2, 2],
        md.CSES[i, 0, 1],
        md.CSES[i, 0, 2],
        md.CSES[i, 1, 0],
        md.CSES[i, 2, 0],
        md.sO0[i, 0],
        md.sO0[i, 1],
        md.su[i],
    )


@njit(fastmath=CONTRACT, inline="always")
def element_terms(lc, c, s, td, e0, e1, e2, f0, f1, f2, g0, g1):
    """Mass, velocity and gravity terms of one element and its outboard map
    (:func:`dttmm.element.element_terms` and :func:`dttmm.element.outboard_maps`).

    lc: :func:`link_constants`; (c, s, td): cos, sin and rate of the frame angle θ;
    e, f = ė: padded elastic coordinates and rates; g: gravity. Returns the tuple

    ``ms0, ms1`` ∫ s (local); ``rem0, rem1, Jt`` the entries (0, 2), (1, 2), (2, 2) of M_aa
    (M_aa = [[m, 0, rem0], [0, m, rem1], [rem0, rem1, Jt]]); ``A`` = M_ae (3×3, row-major);
    ``ha0..2`` = h̄_a; ``he0..2`` = h̄_e without the elastic force; ``rx, ry`` = A s_O;
    ``gb0, gb1`` = γ̄_O (its rotation entry is 0). B_a = [[1, 0, −ry], [0, 1, rx], [0, 0, 1]]
    and B_e = [[s_u c, −s, 0], [s_u s, c, 0], [0, 0, 1]] follow from (c, s, rx, ry).
    """
    (
        _m,
        mg0,
        mg1,
        s00,
        C00,
        C11,
        C12,
        css0,
        q0,
        d11,
        d12,
        D01,
        D02,
        D10,
        D20,
        S00,
        S11,
        S12,
        S22,
        E01,
        E02,
        E10,
        E20,
        so00,
        so01,
        su,
    ) = lc
    ms0 = s00 + C00 * e0
    ms1 = C11 * e1 + C12 * e2
    rem0 = -c * ms1 - s * ms0
    rem1 = -s * ms1 + c * ms0
    cse0 = S00 * e0
    sS1 = S11 * e1 + S12 * e2
    sS2 = S12 * e1 + S22 * e2
    sS0 = q0 + cse0
    Jt = css0 + 2.0 * q0 * e0 + (e0 * cse0 + e1 * sS1 + e2 * sS2)
    A00 = c * C00
    A10 = s * C00
    A01 = -s * C11
    A11 = c * C11
    A02 = -s * C12
    A12 = c * C12
    A20 = e1 * D10 + e2 * D20
    A21 = d11 + e0 * D01
    A22 = d12 + e0 * D02
    v0 = C00 * f0
    v1 = C11 * f1 + C12 * f2
    td2 = td * td
    tdd = 2.0 * td
    hr0 = -td2 * ms0 - tdd * v1
    hr1 = -td2 * ms1 + tdd * v0
    ha0 = c * hr0 - s * hr1 - mg0
    ha1 = s * hr0 + c * hr1 - mg1
    ha2 = tdd * (sS0 * f0 + sS1 * f1 + sS2 * f2) - (rem0 * g0 + rem1 * g1)
    rt0 = c * g0 + s * g1
    rt1 = -s * g0 + c * g1
    he0 = -td2 * sS0 + tdd * (E01 * f1 + E02 * f2) - C00 * rt0
    he1 = -td2 * sS1 + tdd * (E10 * f0) - C11 * rt1
    he2 = -td2 * sS2 + tdd * (E20 * f0) - C12 * rt1
    so0 = so00 + su * e0
    so1 = so01 + e1
    rx = c * so0 - s * so1
    ry = s * so0 + c * so1
    sf0 = su * f0
    gb0 = -td2 * rx + tdd * (-c * f1 - s * sf0)
    gb1 = -td2 * ry + tdd * (-s * f1 + c * sf0)
    return (
        ms0,
        ms1,
        rem0,
        rem1,
        Jt,
        (A00, A01, A02, A10, A11, A12, A20, A21, A22),
        ha0,
        ha1,
        ha2,
        he0,
        he1,
        he2,
        rx,
        ry,
        gb0,
        gb1,
    )
