"""Output sampling inside the time loop: the state on the output grid (cubic Hermite between
step ends, linear for torques and loads), and kinematics and energy at a state."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ._jit import njit
from .element import coord_base, element_terms, link_constants, rotate


class Record(NamedTuple):
    """Output arrays on the grid ``t`` (rows: output times), filled by :func:`record`.

    angle, rate, torque, root_angle (nt, n); root, tip (nt, n, 2); energy (nt,) or (0,) when
    not wanted; loads (nl, n_cuts, 3) every ``load_stride``-th sample as (M, Qx, Qy), or
    (0, n_cuts, 3) with ``load_stride`` 0 when not wanted; q (nt, n_dof) the coordinates at
    the output times (for the link shapes), or (0, n_dof) when not wanted.
    """

    t: np.ndarray
    angle: np.ndarray
    rate: np.ndarray
    torque: np.ndarray
    root: np.ndarray
    tip: np.ndarray
    root_angle: np.ndarray
    energy: np.ndarray
    loads: np.ndarray
    load_stride: int
    q: np.ndarray


@njit()
def hermite_weights(x, h):
    """Cubic Hermite basis at the fraction x ∈ [0, 1] of an interval of length h:
    y(x) = w0 y0 + w1 ẏ0 + w2 y1 + w3 ẏ1 and ẏ(x) = v0 y0 + v1 ẏ0 + v2 y1 + v3 ẏ1.
    Returns (w0, w1, w2, w3, v0, v1, v2, v3)."""
    x2 = x * x
    x3 = x2 * x
    h00 = 2 * x3 - 3 * x2 + 1
    h10 = x3 - 2 * x2 + x
    h01 = -2 * x3 + 3 * x2
    h11 = x3 - x2
    d00 = (6 * x2 - 6 * x) / h
    d10 = 3 * x2 - 4 * x + 1
    d01 = (-6 * x2 + 6 * x) / h
    d11 = 3 * x2 - 2 * x
    return h00, h10 * h, h01, h11 * h, d00, d10, d01, d11


@njit(inline="always")
def _energy(lc, md, i, frame, e, f):
    """Kinetic + elastic + gravitational energy of one element, frame = (cos θ, sin θ, θ̇, ẋ_I,
    ẏ_I, x_I, y_I) of its inboard node, e and f = ė its padded coordinates, as (T + U, g·∫r dm): T = ½ p'ᵀ M_aa p' + p'ᵀ M_ae ė
    + ½ ėᵀ C_SS ė with p' = (ṙ_I, θ̇), U(e) the strain energy."""
    c, s, thd, vx, vy, px, py = frame
    e0, e1, e2 = e
    f0, f1, f2 = f
    g0, g1 = md.grav[0], md.grav[1]
    (ms0, ms1, rem0, rem1, Jt, A, _ha0, _ha1, _ha2, _he0, _he1, _he2, _rx, _ry, _gb0, _gb1) = element_terms(
        lc, c, s, thd, e0, e1, e2, f0, f1, f2, g0, g1
    )
    m = lc[0]
    Tae = (
        (vx * A[0] + vy * A[3] + thd * A[6]) * f0
        + (vx * A[1] + vy * A[4] + thd * A[7]) * f1
        + (vx * A[2] + vy * A[5] + thd * A[8]) * f2
    )
    Tee = 0.0
    Vee = 0.0
    for r in range(3):
        sf = 0.0
        ke = 0.0
        for l in range(3):
            sf += md.CSS[i, r, l] * f[l]
            ke += md.K[i, r, l] * e[l]
        Tee += f[r] * sf
        Vee += e[r] * ke
    if md.second_order[i]:  # U = ½ EA l ε² + ½ wᵀK_b w (element.strain_energy)
        Gw1 = md.G[i, 0, 0] * e1 + md.G[i, 0, 1] * e2
        Gw2 = md.G[i, 1, 0] * e1 + md.G[i, 1, 1] * e2
        eps = e0 * md.inv_l[i] + 0.5 * (e1 * Gw1 + e2 * Gw2)
        Vee = md.EAl[i] * eps * eps + (
            e1 * (md.K[i, 1, 1] * e1 + md.K[i, 1, 2] * e2) + e2 * (md.K[i, 2, 1] * e1 + md.K[i, 2, 2] * e2)
        )
    Taa = m * (vx * vx + vy * vy) + 2.0 * thd * (rem0 * vx + rem1 * vy) + Jt * thd * thd
    comx = m * px + (c * ms0 - s * ms1)
    comy = m * py + (s * ms0 + c * ms1)
    return 0.5 * (Taa + 2.0 * Tae + Tee) + 0.5 * Vee, comx * g0 + comy * g1


@njit(inline="always")
def _body_energy(mass, inertia, dx, dy, c, s, thd, vx, vy):
    """Kinetic energy of a rigid body fixed to a frame (cos θ, sin θ, rate θ̇) whose origin
    moves at (vx, vy), its centre of mass at d = (dx, dy) in the frame, ``inertia`` about the
    centre of mass; and m ρ = m A(θ) d (the first moment about the origin, for gravity)."""
    rx = c * dx - s * dy
    ry = s * dx + c * dy
    ux = vx - thd * ry
    uy = vy + thd * rx
    return 0.5 * (mass * (ux * ux + uy * uy) + inertia * thd * thd), (mass * rx, mass * ry)


@njit(inline="always")
def _payload_energy(md, i, c, s, thd, vx, vy, px, py, g0, g1):
    """Kinetic + gravitational energy of the payload of link i (tip frame cos, sin, rate; tip
    position and velocity)."""
    m = md.m_pay[i]
    t, w = _body_energy(m, md.J_pay[i], md.pay_off[i, 0], md.pay_off[i, 1], c, s, thd, vx, vy)
    return t - (m * (px * g0 + py * g1) + w[0] * g0 + w[1] * g1)


@njit(nrt=False)
def sample(md, q, qd, j, rec):
    """Link roots, tips, root angles and (if recorded) the total energy at the state (q, q̇),
    written to row j of ``rec``."""
    g0, g1 = md.grav[0], md.grav[1]
    want_energy = rec.energy.shape[0] > 0
    px = py = 0.0
    vx = vy = 0.0
    th0 = thd0 = 0.0
    etot = 0.0
    for i in range(md.n):
        off = md.pad[i]
        es, ne = md.e_start[i], md.ne[i]
        su = md.su[i]
        th = th0 + q[md.i_alpha[i]]
        thd = thd0 + qd[md.i_alpha[i]]
        rec.root[j, i, 0] = px
        rec.root[j, i, 1] = py
        rec.root_angle[j, i] = th
        if want_energy:
            mh, jh = md.m_hub[i], md.J_hub[i]
            etot += 0.5 * (mh * (vx * vx + vy * vy) + jh * thd * thd) - mh * (px * g0 + py * g1)
        if md.rigid[i]:  # straight segments of length L/k in the root frame; the body at the root
            c = math.cos(th)
            s = math.sin(th)
            if want_energy:
                tb, wb = _body_energy(
                    md.body[i, 0], md.body[i, 3], md.body[i, 1], md.body[i, 2], c, s, thd, vx, vy
                )
                etot += tb - (md.body[i, 0] * (px * g0 + py * g1) + wb[0] * g0 + wb[1] * g1)
            ls = md.sO0[i, 0]
            for _jj in range(md.k):
                px += c * ls
                py += s * ls
                vx += -thd * s * ls
                vy += thd * c * ls
            rec.tip[j, i, 0] = px
            rec.tip[j, i, 1] = py
            if want_energy:
                etot += _payload_energy(md, i, c, s, thd, vx, vy, px, py, g0, g1)
            th0 = th
            thd0 = thd
            continue
        lc = link_constants(md, i, g0, g1)
        c = math.cos(th)
        s = math.sin(th)
        e2 = 0.0
        for jj in range(md.k):
            if jj > 0:
                c, s = rotate(c, s, th, e2)  # e2 = φ of element jj − 1, th = θ_jj
            b = coord_base(es, ne, off, jj)
            e0 = 0.0 if off else q[b]
            f0 = 0.0 if off else qd[b]
            e1, e2 = q[b + 1], q[b + 2]
            f1, f2 = qd[b + 1], qd[b + 2]
            so0 = md.sO0[i, 0] + su * e0
            so1 = md.sO0[i, 1] + e1
            rx = c * so0 - s * so1
            ry = s * so0 + c * so1
            sf0 = su * f0
            dvx = -thd * ry + (c * sf0 - s * f1)
            dvy = thd * rx + (s * sf0 + c * f1)
            if want_energy:
                tu, wg = _energy(lc, md, i, (c, s, thd, vx, vy, px, py), (e0, e1, e2), (f0, f1, f2))
                etot += tu
                etot -= wg
            px += rx
            py += ry
            vx += dvx
            vy += dvy
            th += e2
            thd += f2
        rec.tip[j, i, 0] = px
        rec.tip[j, i, 1] = py
        if want_energy:
            if md.pay_offset[i]:
                etot += _payload_energy(md, i, math.cos(th), math.sin(th), thd, vx, vy, px, py, g0, g1)
            else:
                mp, jp = md.m_pay[i], md.J_pay[i]
                etot += 0.5 * (mp * (vx * vx + vy * vy) + jp * thd * thd) - mp * (px * g0 + py * g1)
        th0 = th
        thd0 = thd
    if want_energy:
        rec.energy[j] = etot


@njit(nrt=False)
def record(md, t0, t1, s0, s1, scratch, ptr, rec):
    """Sample every output time in (t0, t1] between the step-end states s0 and s1, each
    (q, q̇, torque, loads); ``scratch`` = two (n_dof,) arrays. Returns the new sample pointer."""
    q0, qd0, tau0, ld0 = s0
    q1, qd1, tau1, ld1 = s1
    qs, qds = scratch
    nt = rec.t.shape[0]
    nd = q0.shape[0]
    ncuts = ld1.shape[0]
    eps = 1e-9 * (t1 - t0)
    h = t1 - t0
    stride = rec.load_stride
    while ptr < nt and rec.t[ptr] <= t1 + eps:
        tj = rec.t[ptr]
        exact = abs(tj - t1) <= eps
        if exact:
            x = 1.0
            qq = q1
            vv = qd1
        else:
            x = (tj - t0) / h
            w0, w1, w2, w3, v0, v1, v2, v3 = hermite_weights(x, h)
            for r in range(nd):
                qs[r] = w0 * q0[r] + w1 * qd0[r] + w2 * q1[r] + w3 * qd1[r]
                qds[r] = v0 * q0[r] + v1 * qd0[r] + v2 * q1[r] + v3 * qd1[r]
            qq = qs
            vv = qds
        for i in range(md.n):
            rec.angle[ptr, i] = qq[md.i_alpha[i]]
            rec.rate[ptr, i] = vv[md.i_alpha[i]]
            rec.torque[ptr, i] = tau1[i] if exact else (1 - x) * tau0[i] + x * tau1[i]
        sample(md, qq, vv, ptr, rec)
        if rec.q.shape[0] > 0:
            for r in range(nd):
                rec.q[ptr, r] = qq[r]
        if stride > 0 and ptr % stride == 0:
            jl = ptr // stride
            for c in range(ncuts):
                for r in range(3):
                    v = ld1[c, r] if exact else (1 - x) * ld0[c, r] + x * ld1[c, r]
                    rec.loads[jl, c, (r + 1) % 3] = v  # (Qx, Qy, M) -> (M, Qx, Qy)
        ptr += 1
    return ptr
