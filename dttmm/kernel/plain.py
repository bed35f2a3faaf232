"""The paper's plain transfer sweep (:func:`dttmm.sweeps.plain` is the readable version).

The cut state z = (a, f) is carried base → tip as z = B w with the unknowns
w = (w_0, w_1, w_2, 1) of the base; a torque-driven joint i > 0 eliminates one unknown by its
torque condition (substitution w_before = S w_after); the tip condition f = 0 closes a 3×3
system. Not the default sweep: it loses digits exponentially with mesh refinement, and is
kept for the comparison, so it uses small dense matrices.
"""

from __future__ import annotations

import math

import numpy as np

from ._jit import njit
from .element import (
    element_state,
    element_terms,
    link_constants,
    second_order_damping,
    second_order_terms,
    strain_constants,
)
from .layout import NO_SLOT


@njit()
def dense_terms(md, data, i, g, lc, Maa, Mae, ha, he, Ba, Be, gb):  # outputs: the seven arrays after lc
    """Element g's terms as dense 3×3 matrices (padded): M_aa, M_ae, h̄_a, h̃_e (with the known
    elastic force), B_a, B_e, γ̄_O (from :func:`element_terms`)."""
    c, s, td, e0, e1, e2, f0, f1, f2 = element_state(data, g)
    (_ms0, _ms1, rem0, rem1, Jt, A, ha0, ha1, ha2, he0, he1, he2, rx, ry, gb0, gb1) = element_terms(
        lc, c, s, td, e0, e1, e2, f0, f1, f2, md.grav[0], md.grav[1]
    )
    m, su = lc[0], lc[-1]
    Maa[:, :] = 0.0
    Maa[0, 0] = m
    Maa[1, 1] = m
    Maa[0, 2] = Maa[2, 0] = rem0
    Maa[1, 2] = Maa[2, 1] = rem1
    Maa[2, 2] = Jt
    for r in range(3):
        for cc in range(3):
            Mae[r, cc] = A[3 * r + cc]
    ha[0], ha[1], ha[2] = ha0, ha1, ha2
    he[0] = he0 + data.f_known[g, 0]
    he[1] = he1 + data.f_known[g, 1]
    he[2] = he2 + data.f_known[g, 2]
    Ba[:, :] = 0.0
    Ba[0, 0] = Ba[1, 1] = Ba[2, 2] = 1.0
    Ba[0, 2] = -ry
    Ba[1, 2] = rx
    Be[:, :] = 0.0
    Be[0, 0] = su * c
    Be[1, 0] = su * s
    Be[0, 1] = -s
    Be[1, 1] = c
    Be[2, 2] = 1.0
    gb[0], gb[1], gb[2] = gb0, gb1, 0.0


@njit()
def _second_order_dense(md, data, i, g, Mt, he):
    """Second-order strain of element g: h̃_e += f(e) + K_T(e)(ê − e), M̃_ee += c_q (K_T(e) − K);
    with damping also h̃_e += ΔD(e) ê', M̃_ee += c_v ΔD(e) (:func:`second_order_damping`)."""
    e0, e1, e2 = data.e[g, 0], data.e[g, 1], data.e[g, 2]
    sc = strain_constants(md, i)
    fu0, fu1, fu2, T01, T02, dT11, dT12, dT21, dT22 = second_order_terms(sc, e0, e1, e2)
    K = md.K[i]
    de0 = data.e_hat[g, 0] - e0
    de1 = data.e_hat[g, 1] - e1
    de2 = data.e_hat[g, 2] - e2
    he[0] += fu0 + (K[0, 0] * de0 + T01 * de1 + T02 * de2)
    he[1] += fu1 + (T01 * de0 + (dT11 + K[1, 1]) * de1 + (dT12 + K[1, 2]) * de2)
    he[2] += fu2 + (T02 * de0 + (dT21 + K[2, 1]) * de1 + (dT22 + K[2, 2]) * de2)
    _add_coupling(Mt, data.cq[i, 0], T01, T02, dT11, dT12, dT21, dT22)
    mu = md.mu[i]
    if mu != 0.0:
        ea, eal, _inv_l, g00, g01, g10, g11 = sc[:7]
        g0d, g1d, g2d, D01, D02, D11, D12, D22 = second_order_damping(
            mu, ea, eal, g00, g01, g10, g11, e1, e2, data.e_hat[g, 3], data.e_hat[g, 4], data.e_hat[g, 5]
        )
        he[0] += g0d
        he[1] += g1d
        he[2] += g2d
        _add_coupling(Mt, data.cq[i, 1], D01, D02, D11, D12, D12, D22)


@njit(inline="always")
def _add_coupling(Mt, c, a01, a02, a11, a12, a21, a22):
    """M̃_ee += c A for the A of the second-order strain (its stiffness or damping) with
    A[0, 1] = A[1, 0] = a01, A[0, 2] = A[2, 0] = a02 and the bending block a11 … a22."""
    Mt[0, 1] += c * a01
    Mt[0, 2] += c * a02
    Mt[1, 0] += c * a01
    Mt[2, 0] += c * a02
    Mt[1, 1] += c * a11
    Mt[1, 2] += c * a12
    Mt[2, 1] += c * a21
    Mt[2, 2] += c * a22


@njit()
def solve_small(A, B, X):
    """X = A⁻¹ B for a small dense A (Gaussian elimination with partial pivoting). A, B are
    overwritten. Returns False if A is singular or not finite."""
    nr = A.shape[0]
    nc = B.shape[1]
    if not np.all(np.isfinite(A)):  # overflowed transfer chain: LAPACK reports it singular too
        return False
    for col in range(nr):
        piv = col
        best = abs(A[col, col])
        for r in range(col + 1, nr):
            if abs(A[r, col]) > best:
                best = abs(A[r, col])
                piv = r
        if best == 0.0:
            return False
        if piv != col:
            for cc in range(nr):
                A[col, cc], A[piv, cc] = A[piv, cc], A[col, cc]
            for cc in range(nc):
                B[col, cc], B[piv, cc] = B[piv, cc], B[col, cc]
        for r in range(col + 1, nr):
            fct = A[r, col] / A[col, col]
            if fct != 0.0:
                for cc in range(col, nr):
                    A[r, cc] -= fct * A[col, cc]
                for cc in range(nc):
                    B[r, cc] -= fct * B[col, cc]
    for cc in range(nc):
        for r in range(nr - 1, -1, -1):
            acc = B[r, cc]
            for l in range(r + 1, nr):
                acc -= A[r, l] * X[l, cc]
            X[r, cc] = acc / A[r, r]
    return True


@njit()
def equilibrated_cond(A):
    """2-norm condition number of the 3×3 A after scaling columns, then rows, to unit norm
    (the unknowns are forces and accelerations of very different size; the plain condition
    number would measure units)."""
    if not np.all(np.isfinite(A)):
        return np.inf
    As = A.copy()
    for cc in range(3):
        nrm = math.sqrt(As[0, cc] ** 2 + As[1, cc] ** 2 + As[2, cc] ** 2)
        if nrm > 0:
            for r in range(3):
                As[r, cc] /= nrm
    for r in range(3):
        nrm = math.sqrt(As[r, 0] ** 2 + As[r, 1] ** 2 + As[r, 2] ** 2)
        if nrm > 0:
            for cc in range(3):
                As[r, cc] /= nrm
    return np.linalg.cond(As)


@njit()
def _joint(md, data, i, tau, acc, B, Bn, S):
    """Joint i's condition on B: the base unknowns (joint 1), a known α̈ (motion-driven) or the
    elimination of one unknown by the torque condition (stored in data.subs, data.slot)."""
    data.substituted[i] = False
    if i == 0:
        B[:, :] = 0.0
        if md.motion[0]:  # w = (Fx, Fy, τ1), α̈ known
            B[3, 0] = B[4, 1] = B[5, 2] = 1.0
            B[2, 3] = acc[0]
            data.slot[0] = NO_SLOT
        else:  # w = (Fx, Fy, α̈1), τ1 known
            B[3, 0] = B[4, 1] = 1.0
            B[5, 3] = tau[0]
            B[2, 2] = 1.0
            data.slot[0] = 2
        return
    if md.motion[i]:
        B[2, 3] += acc[i]
        data.slot[i] = NO_SLOT
        return
    # pivot: the unknown the torque row depends on most, relative to its column's size
    piv = 0
    best = -1.0
    for mm in range(3):
        nrm = 0.0
        for r in range(6):
            nrm += B[r, mm] * B[r, mm]
        sc = abs(B[5, mm]) / max(math.sqrt(nrm), 1e-300)
        if sc > best:
            best = sc
            piv = mm
    cp = B[5, piv]
    S[:, :] = 0.0
    for r in range(4):
        S[r, r] = 1.0
    S[piv, piv] = 0.0
    for mm in range(3):
        if mm != piv:
            S[piv, mm] = -B[5, mm] / cp
    S[piv, 3] = (tau[i] - B[5, 3]) / cp
    for r in range(6):
        for cc in range(4):
            acc_ = 0.0
            for l in range(4):
                acc_ += B[r, l] * S[l, cc]
            Bn[r, cc] = acc_
    B[:, :] = Bn
    B[2, piv] += 1.0
    data.subs[i, :, :] = S
    data.substituted[i] = True
    data.slot[i] = piv


@njit()
def _rigid_body(md, B, mass, inertia):
    """Across a rigid body (hub or payload): f⁺ = f⁻ − M a + m g."""
    for cc in range(4):
        B[3, cc] -= mass * B[0, cc]
        B[4, cc] -= mass * B[1, cc]
        B[5, cc] -= inertia * B[2, cc]
    B[3, 3] += mass * md.grav[0]
    B[4, 3] += mass * md.grav[1]


@njit()
def _element_solve(Mt, Maa, Mae, ha, he, Ba, Be, T, BeT, G, rhs, sol):  # T..sol: scratch and output
    """ë = E (a_I, f_I, 1) of one element: sol (3, 7) = E. T = B_a⁻ᵀ. Returns False if singular."""
    T[:, :] = 0.0
    T[0, 0] = T[1, 1] = T[2, 2] = 1.0
    T[2, 0] = -Ba[0, 2]
    T[2, 1] = -Ba[1, 2]
    for r in range(3):
        for cc in range(3):
            acc_ = 0.0
            for l in range(3):
                acc_ += Be[l, r] * T[l, cc]
            BeT[r, cc] = acc_
    for r in range(3):
        for cc in range(3):
            acc_ = Mt[r, cc]
            for l in range(3):
                acc_ -= BeT[r, l] * Mae[l, cc]
            G[r, cc] = acc_
        for cc in range(3):
            acc_ = -Mae[cc, r]
            for l in range(3):
                acc_ += BeT[r, l] * Maa[l, cc]
            rhs[r, cc] = acc_
            rhs[r, 3 + cc] = -BeT[r, cc]
        acc_ = -he[r]
        for l in range(3):
            acc_ += BeT[r, l] * ha[l]
        rhs[r, 6] = acc_
    return solve_small(G, rhs, sol)


@njit()
def _transfer(Maa, Mae, ha, Ba, Be, gb, T, sol, U):
    """The element's transfer map (a_I, f_I, 1) → (a_O, f_O): U (6, 7)."""
    U[:, :] = 0.0
    for r in range(3):
        for cc in range(3):
            ea = Ba[r, cc]
            ef = 0.0
            for l in range(3):
                ea += Be[r, l] * sol[l, cc]
                ef += Be[r, l] * sol[l, 3 + cc]
            U[r, cc] = ea
            U[r, 3 + cc] = ef
        e0_ = gb[r]
        for l in range(3):
            e0_ += Be[r, l] * sol[l, 6]
        U[r, 6] = e0_
    # rows 3..5: T (−Maa − Mae Ea), T (I − Mae Ef), T (−ha − Mae E0)
    for cc in range(7):
        tmp0 = 0.0
        tmp1 = 0.0
        tmp2 = 0.0
        for r in range(3):
            if cc < 3:
                base = -Maa[r, cc]
            elif cc < 6:
                base = 1.0 if r == cc - 3 else 0.0
            else:
                base = -ha[r]
            for l in range(3):
                base -= Mae[r, l] * sol[l, cc]
            if r == 0:
                tmp0 = base
            elif r == 1:
                tmp1 = base
            else:
                tmp2 = base
        U[3, cc] = tmp0
        U[4, cc] = tmp1
        U[5, cc] = T[2, 0] * tmp0 + T[2, 1] * tmp1 + tmp2


@njit()
def _apply(U, B, Bn):
    """B ← U (B, 1): the cut state after the element."""
    for r in range(6):
        for cc in range(4):
            acc_ = 0.0
            for l in range(6):
                acc_ += U[r, l] * B[l, cc]
            Bn[r, cc] = acc_
        Bn[r, 3] += U[r, 6]
    B[:, :] = Bn


@njit()
def _transfer_chain(md, data, tau, acc):
    """Base → tip: B at every cut (data.cuts) and the element maps (data.E). Returns (ok, B at the
    end of the arm)."""
    B = np.zeros((6, 4))
    Bn = np.zeros((6, 4))
    S = np.zeros((4, 4))
    Maa, Mae, Ba, Be = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    T, BeT, G, Mt = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    ha, he, gb = np.zeros(3), np.zeros(3), np.zeros(3)
    rhs = np.zeros((3, 7))
    U = np.zeros((6, 7))
    k = md.k
    ic = 0
    for i in range(md.n):
        _joint(md, data, i, tau, acc, B, Bn, S)
        _rigid_body(md, B, md.m_hub[i], md.J_hub[i])
        lc = link_constants(md, i, md.grav[0], md.grav[1])
        for j in range(k):
            g = i * k + j
            data.cuts[ic, :, :] = B
            ic += 1
            dense_terms(md, data, i, g, lc, Maa, Mae, ha, he, Ba, Be, gb)
            Mt[:, :] = data.Mt[i]
            if md.second_order[i]:
                _second_order_dense(md, data, i, g, Mt, he)
            if not _element_solve(Mt, Maa, Mae, ha, he, Ba, Be, T, BeT, G, rhs, data.E[g]):
                return False, B
            _transfer(Maa, Mae, ha, Ba, Be, gb, T, data.E[g], U)
            _apply(U, B, Bn)
        data.cuts[ic, :, :] = B
        ic += 1
        _rigid_body(md, B, md.m_pay[i], md.J_pay[i])
    return True, B


@njit()
def _cut_state(cut, w, z, r0):
    """z[r0:] = (B w)[r0:] at one cut."""
    for r in range(r0, 6):
        z[r] = cut[r, 0] * w[0] + cut[r, 1] * w[1] + cut[r, 2] * w[2] + cut[r, 3] * w[3]


@njit()
def _back_substitute(md, data, wst, acc, xout, torque, loads):
    """With the unknowns w of every link known: α̈, ë, joint torques and cut loads."""
    k = md.k
    ic = 0
    z = np.zeros(6)
    for i in range(md.n):
        wi = wst[i]
        off = md.pad[i]
        xout[md.i_alpha[i]] = acc[i] if md.motion[i] else wi[data.slot[i]]
        for j in range(k):
            _cut_state(data.cuts[ic], wi, z, 0)
            if j == 0:  # torque at the joint: f⁻_θ = f⁺_θ + (M_h a⁺)_θ
                torque[i] = z[5] + md.J_hub[i] * z[2]
            loads[ic, 0] = z[3]
            loads[ic, 1] = z[4]
            loads[ic, 2] = z[5]
            E = data.E[i * k + j]
            b = md.e_start[i] + j * md.ne[i] - off
            for r in range(off, 3):
                v = E[r, 6]
                for cc in range(3):
                    v += E[r, cc] * z[cc] + E[r, 3 + cc] * z[3 + cc]
                xout[b + r] = v
            ic += 1
        _cut_state(data.cuts[ic], wi, z, 3)
        loads[ic, 0] = z[3]
        loads[ic, 1] = z[4]
        loads[ic, 2] = z[5]
        ic += 1


@njit()
def plain(md, data, tau, acc, xout, torque, loads):
    """One plain sweep at the iterate in ``data``. Fills xout (q̈), torque and loads (all cuts).
    Returns (ok, equilibrated condition number of the final 3×3 system)."""
    ok, B = _transfer_chain(md, data, tau, acc)
    if not ok:
        return False, np.inf
    A3 = np.ascontiguousarray(B[3:, :3])
    cond = equilibrated_cond(A3)
    rhs3 = np.empty((3, 1))
    for r in range(3):
        rhs3[r, 0] = -B[3 + r, 3]
    u = np.zeros((3, 1))
    if not solve_small(A3.copy(), rhs3, u):
        return False, np.inf
    # undo the joint eliminations tip → base: w at every link
    wst = np.zeros((md.n, 4))
    wv = np.array([u[0, 0], u[1, 0], u[2, 0], 1.0])
    for i in range(md.n - 1, -1, -1):
        wst[i, :] = wv
        if data.substituted[i]:
            S = data.subs[i]
            wn = np.zeros(4)
            for r in range(4):
                for c in range(4):
                    wn[r] += S[r, c] * wv[c]
            wv = wn
    _back_substitute(md, data, wst, acc, xout, torque, loads)
    return True, cond
