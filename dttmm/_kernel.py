"""Compiled DT-TMM step (numba): the whole time loop of :func:`dttmm.simulate` in one kernel.

This is the same algorithm as the readable numpy reference (:mod:`dttmm.element`,
:mod:`dttmm.structure`, :mod:`dttmm.sweeps`, :mod:`dttmm.solver`), written as scalar loops so
that one element costs a few hundred flops and no allocation:

* the structure is packed into two small tables, one row per link: ``LC`` (floats: element
  moments, stiffness, damping, hub and payload) and ``LI`` (ints: layout, joint kind);
* the elastic coordinates of every element are *padded* to three, (u, v, φ): an inextensible
  link gets a decoupled dummy u (unit effective mass, no coupling, zero load), so one code
  path serves ne = 2 and ne = 3 links mixed in one arm. The dummy never enters q;
* per-element workspace ``WE`` (one row of ``NWE`` floats per element, AoS for locality) and
  per-joint workspace ``WJ`` hold everything the sweeps pass between their passes;
* the Riccati sweep exploits the sparsity of the element maps: B_a = [[1, 0, −r_y], [0, 1, r_x],
  [0, 0, 1]], B_e = blockdiag(A(θ)·diag(s_u, 1), 1) (columns u, v, φ), and factors the 3×3
  SPD elastic block by LDLᵀ;
* the plain sweep is a direct port of :func:`dttmm.sweeps.plain` (it is not the default and
  is kept for the comparison, so it uses small dense matrices);
* the Newmark family and RK4 time loops run inside the kernel on drive values precomputed in
  Python (the drive laws are Python objects); step ends needed by the output grid are stored
  in preallocated arrays and the Python side interpolates (cubic Hermite, as the reference
  recorder) and evaluates kinematics and energy with the compiled :func:`sample_outputs`.

numba is optional: without it, ``HAVE_NUMBA`` is False and :mod:`dttmm.solver` uses the numpy
path. All functions are ``@njit(cache=True)``: a second process loads the machine code from
``__pycache__`` instead of compiling (see :func:`warmup`).
"""
from __future__ import annotations

import math
import time

import numpy as np

try:  # numba is an optional dependency (pip install dttmm[fast])
    from numba import njit

    HAVE_NUMBA = True
except Exception:  # pragma: no cover - exercised only without numba
    HAVE_NUMBA = False

    def njit(*args, **kwargs):
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]
        return lambda f: f

__all__ = ["HAVE_NUMBA", "Packed", "pack", "warmup", "is_warm", "run", "accel", "sample_outputs"]

# ---------------------------------------------------------------------------------------------
# Layout of the tables (compile-time constants for numba)
# LC: per-link floats
L_M, L_CS0, L_CS, L_CS0S0, L_CS0S, L_D1 = 0, 1, 3, 9, 10, 13
L_D2, L_CSS, L_CSES, L_K, L_D = 16, 25, 34, 43, 52
L_SO0, L_SU, L_MH, L_JH, L_MP, L_JP, L_LEN, L_DUMMY = 61, 63, 64, 65, 66, 67, 68, 69
# second-order strain (strain="second-order", extensible links only): flag, EA, element length
# l, 1/l, EA·l, G = ∫₀¹ N'ᵀN' dξ (2×2, row-major)
L_SOF, L_EA, L_EL, L_IEL, L_EAL, L_G = 70, 71, 72, 73, 74, 75
NLC = 79
# entries of LC that the Riccati sweep assumes zero (u couples to (v, φ) only through D2, C_SES)
_ZERO = np.array([L_CS0 + 1, L_CS + 1, L_CS + 2, L_CS + 3, L_CS0S + 1, L_CS0S + 2, L_D1]
                 + [L_D2 + r for r in (0, 4, 5, 7, 8)] + [L_CSS + r for r in (1, 2, 3, 6)]
                 + [L_CSES + r for r in (0, 4, 5, 7, 8)] + [L_K + r for r in (1, 2, 3, 6)]
                 + [L_D + r for r in (1, 2, 3, 6)])
# LI: per-link ints
I_NE, I_IA, I_ES, I_MOT, I_OFF = 0, 1, 2, 3, 4
NLI = 5
# WE: per-element workspace
W_C, W_S, W_TD, W_E, W_ED, W_KE, W_KA = 0, 1, 2, 3, 6, 9, 12
W_K0, W_P, W_CC, W_RS, W_GB, W_A = 21, 24, 30, 33, 35, 37
W_EH = 40  # ê (the predictor's elastic coordinates; second-order links only)
NWE = 43
# WJ: per-joint workspace (P packed symmetric: 00, 01, 02, 11, 12, 22)
J_PT, J_CT, J_PP, J_CP, J_GA, J_G0, J_AT, J_MT, J_CQ = 0, 6, 9, 15, 18, 21, 22, 25, 34
NWJ = 35

# floating-point contraction (a·b + c → FMA) only: no reassociation, no finite-math assumptions
_FM = {"contract"}

# run() integer flags
INT_NEWMARK, INT_RK4 = 0, 1
SW_RICCATI, SW_PLAIN = 0, 1
IT_FIXED, IT_TOL, IT_AUTO = 0, 1, 2
# run() status codes
ST_OK, ST_NONFINITE, ST_RUNAWAY = 0, 1, 2


class Packed:
    """The structure as flat arrays for the kernel (built once per run, see :func:`pack`)."""

    def __init__(self, st):
        n = st.n_links
        k = st.k
        LC = np.zeros((n, NLC))
        LI = np.zeros((n, NLI), np.int64)
        lim = np.full(st.n_dof, np.inf)
        for i, lk in enumerate(st.links):
            et = lk.et
            ne, off = et.ne, 3 - et.ne

            def pad2(a):  # (2, ne) -> (2, 3)
                out = np.zeros((2, 3))
                out[:, off:] = a
                return out

            def pad1(a):
                out = np.zeros(3)
                out[off:] = a
                return out

            def padsq(a):
                out = np.zeros((3, 3))
                out[off:, off:] = a
                return out

            SO = pad2(et.SO)
            su = SO[0, 0]
            expect = np.array([[su, 0.0, 0.0], [0.0, 1.0, 0.0]])
            if not np.array_equal(SO, expect):  # pragma: no cover - guards the hard-coded B_e structure
                raise AssertionError("unexpected outboard shape matrix")
            LC[i, L_M] = et.m
            LC[i, L_CS0:L_CS0 + 2] = et.c_s0
            LC[i, L_CS:L_CS + 6] = pad2(et.C_S).ravel()
            LC[i, L_CS0S0] = et.c_s0s0
            LC[i, L_CS0S:L_CS0S + 3] = pad1(et.c_s0S)
            LC[i, L_D1:L_D1 + 3] = pad1(et.d1)
            LC[i, L_D2:L_D2 + 9] = padsq(et.D2).ravel()
            LC[i, L_CSS:L_CSS + 9] = padsq(et.C_SS).ravel()
            LC[i, L_CSES:L_CSES + 9] = padsq(et.C_SES).ravel()
            LC[i, L_K:L_K + 9] = padsq(et.K).ravel()
            LC[i, L_D:L_D + 9] = padsq(et.D).ravel()
            LC[i, L_SO0:L_SO0 + 2] = et.sO0
            LC[i, L_SU] = su
            LC[i, L_MH] = lk.m_hub
            LC[i, L_JH] = lk.M_hub[2, 2]
            LC[i, L_MP] = lk.m_pay
            LC[i, L_JP] = lk.M_pay[2, 2]
            LC[i, L_LEN] = lk.length
            LC[i, L_DUMMY] = 1.0 if off else 0.0
            if et.second_order:
                LC[i, L_SOF] = 1.0
                LC[i, L_EA] = et.EA
                LC[i, L_EL] = et.l
                LC[i, L_IEL] = 1.0 / et.l
                LC[i, L_EAL] = et.EA * et.l
                LC[i, L_G:L_G + 4] = et.G.ravel()
            if np.any(LC[i, _ZERO] != 0.0):  # pragma: no cover - guards the hard-coded sparsity
                raise AssertionError("unexpected element moment pattern")
            LI[i] = (ne, lk.i_alpha, lk.e_slice.start, int(st.motion[i]), off)
            el = np.full((k, ne), 10.0 * lk.length)
            el[:, et.iphi] = 100.0
            lim[lk.e_slice] = el.ravel()
        self.n, self.k, self.N = n, k, n * k
        self.n_dof = st.n_dof
        self.ncuts = n * (k + 1)
        self.LC, self.LI, self.lim = LC, LI, lim
        self.grav = np.ascontiguousarray(st.gravity, dtype=float)
        self.im = np.ascontiguousarray(st.alpha_index[st.motion], dtype=np.int64)
        self.motion = st.motion.copy()
        self.WE = np.zeros((self.N, NWE))
        self.WJ = np.zeros((n, NWJ))
        # plain-sweep workspace (allocated lazily)
        self._plain = None

    def plain_ws(self, need: bool):
        """(cuts (ncuts, 6, 4), Ealls (N, 21), subs (n, 4, 4), slots (n,)) — tiny if not needed."""
        if not need:
            return (np.zeros((1, 6, 4)), np.zeros((1, 21)), np.zeros((1, 4, 4)), np.zeros(1, np.int64))
        if self._plain is None:
            self._plain = (np.zeros((self.ncuts, 6, 4)), np.zeros((self.N, 21)), np.zeros((self.n, 4, 4)),
                           np.zeros(self.n, np.int64))
        return self._plain


def pack(st) -> Packed:
    return Packed(st)


# ---------------------------------------------------------------------------------------------
# Kinematic pass (base -> tip): frame angles, their rates, padded elastic coordinates
PHI_SMALL = 0.1  # |φ| below which cos/sin of the element rotation come from their Taylor series


@njit(cache=True, boundscheck=False, fastmath=_FM)
def _rotate(c, s, th_new, phi):
    """(cos, sin) of θ_new = θ + φ from (cos θ, sin θ): A(θ + φ) = A(θ)A(φ), with cos φ, sin φ
    from their Taylor series for |φ| ≤ PHI_SMALL (truncation < 1e-22, below round-off) and from
    libm on θ_new otherwise. The composition adds ~1 ulp per element (≲ 1e-13 after 1000)."""
    if abs(phi) > PHI_SMALL:
        return math.cos(th_new), math.sin(th_new)
    p2 = phi * phi
    sp = phi * (1.0 + p2 * (-1.0 / 6 + p2 * (1.0 / 120 + p2 * (-1.0 / 5040 + p2 * (1.0 / 362880
                                                                                 - p2 / 39916800)))))
    cp = 1.0 + p2 * (-0.5 + p2 * (1.0 / 24 + p2 * (-1.0 / 720 + p2 * (1.0 / 40320 + p2 * (-1.0 / 3628800
                                                                                       + p2 / 479001600)))))
    return c * cp - s * sp, s * cp + c * sp


@njit(cache=True, boundscheck=False)
def _angles(LC, LI, n, k, q, qd, WE):
    th0 = 0.0
    thd0 = 0.0
    for i in range(n):
        ne = LI[i, I_NE]
        es = LI[i, I_ES]
        off = LI[i, I_OFF]
        th = th0 + q[LI[i, I_IA]]
        thd = thd0 + qd[LI[i, I_IA]]
        cth = math.cos(th)
        sth = math.sin(th)
        b = 0
        for j in range(k):
            g = i * k + j
            if j > 0:
                cth, sth = _rotate(cth, sth, th, q[b + 2])  # b, th: from element j − 1, θ_j
            WE[g, W_C] = cth
            WE[g, W_S] = sth
            WE[g, W_TD] = thd
            b = es + j * ne - off
            if off:
                WE[g, W_E] = 0.0
                WE[g, W_ED] = 0.0
            else:
                WE[g, W_E] = q[b]
                WE[g, W_ED] = qd[b]
            WE[g, W_E + 1] = q[b + 1]
            WE[g, W_ED + 1] = qd[b + 1]
            WE[g, W_E + 2] = q[b + 2]
            WE[g, W_ED + 2] = qd[b + 2]
            th += q[b + 2]
            thd += qd[b + 2]
        th0 = th
        thd0 = thd


@njit(cache=True, boundscheck=False)
def _elastic_known(LC, LI, n, k, qt, qdt, WE):
    """K ê + D ê' of every element (constant during the frozen-coefficient iteration); for a
    link with second-order strain D ê' only, and ê itself in WE[:, W_EH] (its elastic forces
    are linearised at each iterate inside the sweep, see :func:`_so_terms`)."""
    for i in range(n):
        ne = LI[i, I_NE]
        es = LI[i, I_ES]
        off = LI[i, I_OFF]
        so = LC[i, L_SOF] != 0.0
        for j in range(k):
            g = i * k + j
            b = es + j * ne - off
            e0 = 0.0 if off else qt[b]
            d0 = 0.0 if off else qdt[b]
            e1, e2 = qt[b + 1], qt[b + 2]
            d1, d2 = qdt[b + 1], qdt[b + 2]
            if so:
                WE[g, W_EH] = e0
                WE[g, W_EH + 1] = e1
                WE[g, W_EH + 2] = e2
                for r in range(3):
                    WE[g, W_KE + r] = (LC[i, L_D + 3 * r] * d0 + LC[i, L_D + 3 * r + 1] * d1
                                       + LC[i, L_D + 3 * r + 2] * d2)
            else:
                for r in range(3):
                    WE[g, W_KE + r] = (LC[i, L_K + 3 * r] * e0 + LC[i, L_K + 3 * r + 1] * e1
                                       + LC[i, L_K + 3 * r + 2] * e2
                                       + LC[i, L_D + 3 * r] * d0 + LC[i, L_D + 3 * r + 1] * d1
                                       + LC[i, L_D + 3 * r + 2] * d2)


@njit(cache=True, boundscheck=False)
def _eff_mass(LC, n, cq, cv, WJ):
    """M̃_ee = C_SS + c_q K + c_v D per link (+ the unit dummy mass of an inextensible link);
    c_q is kept in WJ[:, J_CQ] for the per-element tangent of second-order links."""
    for i in range(n):
        for r in range(9):
            WJ[i, J_MT + r] = LC[i, L_CSS + r] + cq * LC[i, L_K + r] + cv * LC[i, L_D + r]
        WJ[i, J_MT] += LC[i, L_DUMMY]
        WJ[i, J_CQ] = cq


@njit(cache=True, boundscheck=False, fastmath=_FM, inline="always")
def _so_terms(EA, EAl, il, G00, G01, G10, G11, Kb00, Kb01, Kb10, Kb11, e0, e1, e2):
    """Second-order strain of one element (element.elastic_forces): ε = u/l + ½ wᵀGw,
    w = (v, φ); f_u = EA ε, f_w = EA l ε G w + K_b w. Returns f (3) and the tangent K_T = ∂f/∂e
    as its u–w row (T01, T02) and ΔT = K_T,ww − K_b (2×2, row-major); K_T,uu = EA/l = K_uu."""
    Gw1 = G00 * e1 + G01 * e2
    Gw2 = G10 * e1 + G11 * e2
    eps = e0 * il + 0.5 * (e1 * Gw1 + e2 * Gw2)
    Nl = EAl * eps
    a1 = EAl * Gw1
    a2 = EAl * Gw2
    f0 = EA * eps
    f1 = Nl * Gw1 + (Kb00 * e1 + Kb01 * e2)
    f2 = Nl * Gw2 + (Kb10 * e1 + Kb11 * e2)
    return (f0, f1, f2, EA * Gw1, EA * Gw2, a1 * Gw1 + Nl * G00, a1 * Gw2 + Nl * G01, a2 * Gw1 + Nl * G10,
            a2 * Gw2 + Nl * G11)


# ---------------------------------------------------------------------------------------------
# Riccati sweep
@njit(cache=True, boundscheck=False, fastmath=_FM)
def _riccati(LC, LI, grav, n, k, WE, WJ, tau, acc, xout, torque):
    """Backward (tip -> base) articulated-inertia pass and forward (base -> tip) pass.

    Needs WE[:, W_C..W_KE] (from _angles and _elastic_known) and WJ[:, J_MT] (from _eff_mass).
    Writes q̈ into xout (all entries: α̈ and elastic), the joint torques into torque, and leaves
    in WE / WJ what :func:`_riccati_loads` needs.
    """
    g0 = grav[0]
    g1 = grav[1]
    p00 = p01 = p02 = p11 = p12 = p22 = 0.0
    c0 = c1 = c2 = 0.0
    for i in range(n - 1, -1, -1):
                # payload at the tip of link i
        mp = LC[i, L_MP]
        p00 += mp
        p11 += mp
        p22 += LC[i, L_JP]
        c0 -= mp * g0
        c1 -= mp * g1
        WJ[i, J_PT] = p00
        WJ[i, J_PT + 1] = p01
        WJ[i, J_PT + 2] = p02
        WJ[i, J_PT + 3] = p11
        WJ[i, J_PT + 4] = p12
        WJ[i, J_PT + 5] = p22
        WJ[i, J_CT] = c0
        WJ[i, J_CT + 1] = c1
        WJ[i, J_CT + 2] = c2
        # link constants (the element moments are sparse: u couples to (v, φ) only through
        # D2 and C_SES; Packed checks the pattern)
        m = LC[i, L_M]
        s00 = LC[i, L_CS0]
        C00, C11, C12 = LC[i, L_CS], LC[i, L_CS + 4], LC[i, L_CS + 5]
        css0 = LC[i, L_CS0S0]
        q0 = LC[i, L_CS0S]
        d11, d12 = LC[i, L_D1 + 1], LC[i, L_D1 + 2]
        D01, D02, D10, D20 = LC[i, L_D2 + 1], LC[i, L_D2 + 2], LC[i, L_D2 + 3], LC[i, L_D2 + 6]
        S00, S11, S12, S22 = LC[i, L_CSS], LC[i, L_CSS + 4], LC[i, L_CSS + 5], LC[i, L_CSS + 8]
        E01, E02, E10, E20 = LC[i, L_CSES + 1], LC[i, L_CSES + 2], LC[i, L_CSES + 3], LC[i, L_CSES + 6]
        so00 = LC[i, L_SO0]
        so01 = LC[i, L_SO0 + 1]
        su = LC[i, L_SU]
        M00 = WJ[i, J_MT]
        M11, M12, M22 = WJ[i, J_MT + 4], WJ[i, J_MT + 5], WJ[i, J_MT + 8]
        so = LC[i, L_SOF] != 0.0  # second-order strain (its constants are read in the branch)
        mg0 = m * g0
        mg1 = m * g1
        for j in range(k - 1, -1, -1):
            g = i * k + j
            c = WE[g, W_C]
            s = WE[g, W_S]
            td = WE[g, W_TD]
            e0, e1, e2 = WE[g, W_E], WE[g, W_E + 1], WE[g, W_E + 2]
            f0, f1, f2 = WE[g, W_ED], WE[g, W_ED + 1], WE[g, W_ED + 2]
            # --- element terms (element.element_terms / outboard_maps)
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
            he0 = -td2 * sS0 + tdd * (E01 * f1 + E02 * f2) - C00 * rt0 + WE[g, W_KE]
            he1 = -td2 * sS1 + tdd * (E10 * f0) - C11 * rt1 + WE[g, W_KE + 1]
            he2 = -td2 * sS2 + tdd * (E20 * f0) - C12 * rt1 + WE[g, W_KE + 2]
            so0 = so00 + su * e0
            so1 = so01 + e1
            rx = c * so0 - s * so1
            ry = s * so0 + c * so1
            sf0 = su * f0
            gb0 = -td2 * rx + tdd * (-c * f1 - s * sf0)
            gb1 = -td2 * ry + tdd * (-s * f1 + c * sf0)
            # --- Riccati element step
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
            X00 = A00 + su * a0
            X10 = A10 + su * a1
            X20 = A20 + su * (-ry * a0 + rx * a1 + a2)
            X01 = A01 + b0
            X11 = A11 + b1
            X21 = A21 + (-ry * b0 + rx * b1 + b2)
            X02 = A02 + p02
            X12 = A12 + p12
            X22 = A22 + (-ry * p02 + rx * p12 + p22)
            rho0 = p00 * gb0 + p01 * gb1 + c0
            rho1 = p01 * gb0 + p11 * gb1 + c1
            rho2 = p02 * gb0 + p12 * gb1 + c2
            r0 = -(he0 + su * (c * rho0 + s * rho1))
            r1 = -(he1 + (-s * rho0 + c * rho1))
            r2 = -(he2 + rho2)
            if so:
                # second-order strain at the iterate e (sweeps._elastic_rhs):
                # h̃_e += f(e) + K_T(e)(ê − e), M̃_ee += c_q (K_T(e) − K). The link constants are
                # loaded here, not hoisted: keeps the linear path's register pressure unchanged
                Kb00, Kb01, Kb10, Kb11 = LC[i, L_K + 4], LC[i, L_K + 5], LC[i, L_K + 7], LC[i, L_K + 8]
                fu0, fu1, fu2, T01, T02, dT11, dT12, dT21, dT22 = _so_terms(
                    LC[i, L_EA], LC[i, L_EAL], LC[i, L_IEL], LC[i, L_G], LC[i, L_G + 1], LC[i, L_G + 2],
                    LC[i, L_G + 3], Kb00, Kb01, Kb10, Kb11, e0, e1, e2)
                de0 = WE[g, W_EH] - e0
                de1 = WE[g, W_EH + 1] - e1
                de2 = WE[g, W_EH + 2] - e2
                r0 -= fu0 + (LC[i, L_K] * de0 + T01 * de1 + T02 * de2)
                r1 -= fu1 + (T01 * de0 + (dT11 + Kb00) * de1 + (dT12 + Kb01) * de2)
                r2 -= fu2 + (T02 * de0 + (dT21 + Kb10) * de1 + (dT22 + Kb11) * de2)
                cq = WJ[i, J_CQ]
                H01 += cq * T01
                H02 += cq * T02
                H11 += cq * dT11
                H12 += cq * dT12
                H22 += cq * dT22
            # LDLᵀ of H
            i0 = 1.0 / H00
            l10 = H01 * i0
            l20 = H02 * i0
            dd1 = H11 - l10 * H01
            i1 = 1.0 / dd1
            l21 = (H12 - l20 * H01) * i1
            dd2 = H22 - l20 * H02 - l21 * l21 * dd1
            i2 = 1.0 / dd2
            # Ka[:, a] = H⁻¹(−X[a, :]), k0 = H⁻¹ r
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
            p00, p01, p02, p11, p12, p22 = n00, n01, n02, n11, n12, n22
            WE[g, W_KA] = K00
            WE[g, W_KA + 1] = K01
            WE[g, W_KA + 2] = K02
            WE[g, W_KA + 3] = K10
            WE[g, W_KA + 4] = K11
            WE[g, W_KA + 5] = K12
            WE[g, W_KA + 6] = K20
            WE[g, W_KA + 7] = K21
            WE[g, W_KA + 8] = K22
            WE[g, W_K0] = k0
            WE[g, W_K0 + 1] = k1
            WE[g, W_K0 + 2] = k2
            WE[g, W_P] = p00
            WE[g, W_P + 1] = p01
            WE[g, W_P + 2] = p02
            WE[g, W_P + 3] = p11
            WE[g, W_P + 4] = p12
            WE[g, W_P + 5] = p22
            WE[g, W_CC] = c0
            WE[g, W_CC + 1] = c1
            WE[g, W_CC + 2] = c2
            WE[g, W_RS] = rx
            WE[g, W_RS + 1] = ry
            WE[g, W_GB] = gb0
            WE[g, W_GB + 1] = gb1
        # hub (outboard side of joint i), then the joint condition
        mh = LC[i, L_MH]
        p00 += mh
        p11 += mh
        p22 += LC[i, L_JH]
        c0 -= mh * g0
        c1 -= mh * g1
        WJ[i, J_PP] = p00
        WJ[i, J_PP + 1] = p01
        WJ[i, J_PP + 2] = p02
        WJ[i, J_PP + 3] = p11
        WJ[i, J_PP + 4] = p12
        WJ[i, J_PP + 5] = p22
        WJ[i, J_CP] = c0
        WJ[i, J_CP + 1] = c1
        WJ[i, J_CP + 2] = c2
        if LI[i, I_MOT]:
            gg = acc[i]
            WJ[i, J_G0] = gg
            c0 += p02 * gg
            c1 += p12 * gg
            c2 += p22 * gg
        else:
            ga0 = -p02 / p22
            ga1 = -p12 / p22
            ga2 = -1.0
            gg = (tau[i] - c2) / p22
            WJ[i, J_GA] = ga0
            WJ[i, J_GA + 1] = ga1
            WJ[i, J_GA + 2] = ga2
            WJ[i, J_G0] = gg
            # P + outer(P[:, 2], ga), symmetric
            n00 = p00 + p02 * ga0
            n01 = p01 + p02 * ga1
            n11 = p11 + p12 * ga1
            c0 += p02 * gg
            c1 += p12 * gg
            c2 += p22 * gg
            p00, p01, p11 = n00, n01, n11
            p02 = p12 = p22 = 0.0
    # ---- forward pass
    a0 = a1 = a2 = 0.0
    for i in range(n):
        ne = LI[i, I_NE]
        es = LI[i, I_ES]
        off = LI[i, I_OFF]
        su = LC[i, L_SU]
        if LI[i, I_MOT]:
            add = WJ[i, J_G0]
        else:
            add = WJ[i, J_GA] * a0 + WJ[i, J_GA + 1] * a1 + WJ[i, J_GA + 2] * a2 + WJ[i, J_G0]
        a2 += add
        xout[LI[i, I_IA]] = add
        torque[i] = WJ[i, J_PP + 2] * a0 + WJ[i, J_PP + 4] * a1 + WJ[i, J_PP + 5] * a2 + WJ[i, J_CP + 2]
        for j in range(k):
            g = i * k + j
            WE[g, W_A] = a0
            WE[g, W_A + 1] = a1
            WE[g, W_A + 2] = a2
            q0 = WE[g, W_KA] * a0 + WE[g, W_KA + 1] * a1 + WE[g, W_KA + 2] * a2 + WE[g, W_K0]
            q1 = WE[g, W_KA + 3] * a0 + WE[g, W_KA + 4] * a1 + WE[g, W_KA + 5] * a2 + WE[g, W_K0 + 1]
            q2 = WE[g, W_KA + 6] * a0 + WE[g, W_KA + 7] * a1 + WE[g, W_KA + 8] * a2 + WE[g, W_K0 + 2]
            b = es + j * ne - off
            if not off:
                xout[b] = q0
            xout[b + 1] = q1
            xout[b + 2] = q2
            c = WE[g, W_C]
            s = WE[g, W_S]
            rx = WE[g, W_RS]
            ry = WE[g, W_RS + 1]
            sq0 = su * q0
            a0 = a0 - ry * a2 + c * sq0 - s * q1 + WE[g, W_GB]
            a1 = a1 + rx * a2 + s * sq0 + c * q1 + WE[g, W_GB + 1]
            a2 = a2 + q2
        WJ[i, J_AT] = a0
        WJ[i, J_AT + 1] = a1
        WJ[i, J_AT + 2] = a2


@njit(cache=True, boundscheck=False)
def _riccati_loads(n, k, WE, WJ, loads):
    """Loads (Qx, Qy, M) at every cut from the last Riccati sweep: f = P a + c."""
    ic = 0
    for i in range(n):
        for j in range(k):
            g = i * k + j
            a0, a1, a2 = WE[g, W_A], WE[g, W_A + 1], WE[g, W_A + 2]
            loads[ic, 0] = WE[g, W_P] * a0 + WE[g, W_P + 1] * a1 + WE[g, W_P + 2] * a2 + WE[g, W_CC]
            loads[ic, 1] = WE[g, W_P + 1] * a0 + WE[g, W_P + 3] * a1 + WE[g, W_P + 4] * a2 + WE[g, W_CC + 1]
            loads[ic, 2] = WE[g, W_P + 2] * a0 + WE[g, W_P + 4] * a1 + WE[g, W_P + 5] * a2 + WE[g, W_CC + 2]
            ic += 1
        a0, a1, a2 = WJ[i, J_AT], WJ[i, J_AT + 1], WJ[i, J_AT + 2]
        loads[ic, 0] = WJ[i, J_PT] * a0 + WJ[i, J_PT + 1] * a1 + WJ[i, J_PT + 2] * a2 + WJ[i, J_CT]
        loads[ic, 1] = WJ[i, J_PT + 1] * a0 + WJ[i, J_PT + 3] * a1 + WJ[i, J_PT + 4] * a2 + WJ[i, J_CT + 1]
        loads[ic, 2] = WJ[i, J_PT + 2] * a0 + WJ[i, J_PT + 4] * a1 + WJ[i, J_PT + 5] * a2 + WJ[i, J_CT + 2]
        ic += 1


# ---------------------------------------------------------------------------------------------
# Plain transfer sweep (port of sweeps.plain)
@njit(cache=True, boundscheck=False)
def _full_terms(LC, i, w, grav, Maa, Mae, ha, he, Ba, Be, gb):
    """Dense element terms of one element (for the plain sweep): M_aa, M_ae, h̄_a, h̃_e (with
    K ê + D ê'), B_a, B_e, γ̄_O, all padded to ne = 3."""
    g0, g1 = grav[0], grav[1]
    c, s, td = w[W_C], w[W_S], w[W_TD]
    e = w[W_E:W_E + 3]
    f = w[W_ED:W_ED + 3]
    m = LC[i, L_M]
    ms0 = LC[i, L_CS0]
    ms1 = LC[i, L_CS0 + 1]
    for r in range(3):
        ms0 += LC[i, L_CS + r] * e[r]
        ms1 += LC[i, L_CS + 3 + r] * e[r]
    rem0 = -c * ms1 - s * ms0
    rem1 = -s * ms1 + c * ms0
    sS = np.empty(3)
    for r in range(3):
        sS[r] = LC[i, L_CS0S + r]
        for l in range(3):
            sS[r] += LC[i, L_CSS + 3 * r + l] * e[l]
    Jt = LC[i, L_CS0S0]
    for r in range(3):
        Jt += 2.0 * LC[i, L_CS0S + r] * e[r] + e[r] * (sS[r] - LC[i, L_CS0S + r])
    Maa[:, :] = 0.0
    Maa[0, 0] = m
    Maa[1, 1] = m
    Maa[0, 2] = Maa[2, 0] = rem0
    Maa[1, 2] = Maa[2, 1] = rem1
    Maa[2, 2] = Jt
    for r in range(3):
        Mae[0, r] = c * LC[i, L_CS + r] - s * LC[i, L_CS + 3 + r]
        Mae[1, r] = s * LC[i, L_CS + r] + c * LC[i, L_CS + 3 + r]
        Mae[2, r] = LC[i, L_D1 + r]
        for l in range(3):
            Mae[2, r] += e[l] * LC[i, L_D2 + 3 * l + r]
    v0 = 0.0
    v1 = 0.0
    for r in range(3):
        v0 += LC[i, L_CS + r] * f[r]
        v1 += LC[i, L_CS + 3 + r] * f[r]
    td2 = td * td
    hr0 = -td2 * ms0 - 2.0 * td * v1
    hr1 = -td2 * ms1 + 2.0 * td * v0
    ha[0] = c * hr0 - s * hr1 - m * g0
    ha[1] = s * hr0 + c * hr1 - m * g1
    ha[2] = 2.0 * td * (sS[0] * f[0] + sS[1] * f[1] + sS[2] * f[2]) - (rem0 * g0 + rem1 * g1)
    rt0 = c * g0 + s * g1
    rt1 = -s * g0 + c * g1
    for r in range(3):
        ce = 0.0
        for l in range(3):
            ce += LC[i, L_CSES + 3 * r + l] * f[l]
        he[r] = (-td2 * sS[r] + 2.0 * td * ce - (LC[i, L_CS + r] * rt0 + LC[i, L_CS + 3 + r] * rt1)
                 + w[W_KE + r])
    su = LC[i, L_SU]
    so0 = LC[i, L_SO0] + su * e[0]
    so1 = LC[i, L_SO0 + 1] + e[1]
    rx = c * so0 - s * so1
    ry = s * so0 + c * so1
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
    gb[0] = -td2 * rx + 2.0 * td * (-c * f[1] - s * su * f[0])
    gb[1] = -td2 * ry + 2.0 * td * (-s * f[1] + c * su * f[0])
    gb[2] = 0.0
    w[W_RS] = rx
    w[W_RS + 1] = ry


@njit(cache=True, boundscheck=False)
def _so_dense(LC, cq, i, w, Mt, he):
    """Second-order strain of one element for the plain sweep: h̃_e += f(e) + K_T(e)(ê − e),
    M̃_ee (row-major 3×3) += c_q (K_T(e) − K)."""
    e0, e1, e2 = w[W_E], w[W_E + 1], w[W_E + 2]
    Kb00, Kb01, Kb10, Kb11 = LC[i, L_K + 4], LC[i, L_K + 5], LC[i, L_K + 7], LC[i, L_K + 8]
    fu0, fu1, fu2, T01, T02, dT11, dT12, dT21, dT22 = _so_terms(
        LC[i, L_EA], LC[i, L_EAL], LC[i, L_IEL], LC[i, L_G], LC[i, L_G + 1], LC[i, L_G + 2], LC[i, L_G + 3],
        Kb00, Kb01, Kb10, Kb11, e0, e1, e2)
    de0 = w[W_EH] - e0
    de1 = w[W_EH + 1] - e1
    de2 = w[W_EH + 2] - e2
    he[0] += fu0 + (LC[i, L_K] * de0 + T01 * de1 + T02 * de2)
    he[1] += fu1 + (T01 * de0 + (dT11 + Kb00) * de1 + (dT12 + Kb01) * de2)
    he[2] += fu2 + (T02 * de0 + (dT21 + Kb10) * de1 + (dT22 + Kb11) * de2)
    Mt[1] += cq * T01
    Mt[2] += cq * T02
    Mt[3] += cq * T01
    Mt[6] += cq * T02
    Mt[4] += cq * dT11
    Mt[5] += cq * dT12
    Mt[7] += cq * dT21
    Mt[8] += cq * dT22


@njit(cache=True, boundscheck=False)
def _solve_small(A, B, X):
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


@njit(cache=True, boundscheck=False)
def _equilibrated_cond(A):
    """2-norm condition number after scaling columns, then rows, to unit norm (sweeps.py)."""
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


@njit(cache=True, boundscheck=False)
def _plain(LC, LI, grav, n, k, WE, WJ, tau, acc, xout, torque, loads, cuts, Ealls, subs, slots):
    """The paper's plain transfer sweep (sweeps.plain). Returns (ok, cond of the final 3×3)."""
    g0, g1 = grav[0], grav[1]
    B = np.zeros((6, 4))
    Bn = np.zeros((6, 4))
    S = np.zeros((4, 4))
    Maa = np.zeros((3, 3))
    Mae = np.zeros((3, 3))
    ha = np.zeros(3)
    he = np.zeros(3)
    Ba = np.zeros((3, 3))
    Be = np.zeros((3, 3))
    gb = np.zeros(3)
    T = np.zeros((3, 3))
    BeT = np.zeros((3, 3))
    G = np.zeros((3, 3))
    rhs = np.zeros((3, 7))
    sol = np.zeros((3, 7))
    U = np.zeros((6, 7))
    Mt = np.zeros(9)
    ic = 0
    for i in range(n):
        mot = LI[i, I_MOT]
        if i == 0:
            B[:, :] = 0.0
            if mot:
                B[3, 0] = B[4, 1] = B[5, 2] = 1.0
                B[2, 3] = acc[0]
                slots[0] = -1
            else:
                B[3, 0] = B[4, 1] = 1.0
                B[5, 3] = tau[0]
                B[2, 2] = 1.0
                slots[0] = 2
        else:
            if mot:
                B[2, 3] += acc[i]
                slots[i] = -1
            else:
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
                subs[i, :, :] = S
                slots[i] = 3 + piv  # marks "has substitution", slot = piv
        mh, jh = LC[i, L_MH], LC[i, L_JH]
        for cc in range(4):
            B[3, cc] -= mh * B[0, cc]
            B[4, cc] -= mh * B[1, cc]
            B[5, cc] -= jh * B[2, cc]
        B[3, 3] += mh * g0
        B[4, 3] += mh * g1
        for j in range(k):
            gi = i * k + j
            w = WE[gi]
            cuts[ic, :, :] = B
            ic += 1
            _full_terms(LC, i, w, grav, Maa, Mae, ha, he, Ba, Be, gb)
            for r in range(9):
                Mt[r] = WJ[i, J_MT + r]
            if LC[i, L_SOF] != 0.0:
                _so_dense(LC, WJ[i, J_CQ], i, w, Mt, he)
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
                    acc_ = Mt[3 * r + cc]
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
            if not _solve_small(G, rhs, sol):
                return False, np.inf
            Ealls[gi, :] = sol.ravel()
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
            for r in range(6):
                for cc in range(4):
                    acc_ = 0.0
                    for l in range(6):
                        acc_ += U[r, l] * B[l, cc]
                    Bn[r, cc] = acc_
                Bn[r, 3] += U[r, 6]
            B[:, :] = Bn
        cuts[ic, :, :] = B
        ic += 1
        mp, jp = LC[i, L_MP], LC[i, L_JP]
        for cc in range(4):
            B[3, cc] -= mp * B[0, cc]
            B[4, cc] -= mp * B[1, cc]
            B[5, cc] -= jp * B[2, cc]
        B[3, 3] += mp * g0
        B[4, 3] += mp * g1
    A3 = np.ascontiguousarray(B[3:, :3])
    cond = _equilibrated_cond(A3)
    rhs3 = np.empty((3, 1))
    for r in range(3):
        rhs3[r, 0] = -B[3 + r, 3]
    u = np.zeros((3, 1))
    if not _solve_small(A3.copy(), rhs3, u):
        return False, np.inf
    # back substitution of the joint eliminations: w at every stage
    wst = np.zeros((n, 4))
    wv = np.array([u[0, 0], u[1, 0], u[2, 0], 1.0])
    for i in range(n - 1, -1, -1):
        wst[i, :] = wv
        if slots[i] >= 3:
            wv = subs[i] @ wv
    ic = 0
    z = np.zeros(6)
    for i in range(n):
        wi = wst[i]
        ne = LI[i, I_NE]
        es = LI[i, I_ES]
        off = LI[i, I_OFF]
        if LI[i, I_MOT]:
            xout[LI[i, I_IA]] = acc[i]
        else:
            sl = slots[i] - 3 if slots[i] >= 3 else slots[i]
            xout[LI[i, I_IA]] = wi[sl]
        for j in range(k):
            for r in range(6):
                z[r] = (cuts[ic, r, 0] * wi[0] + cuts[ic, r, 1] * wi[1] + cuts[ic, r, 2] * wi[2]
                        + cuts[ic, r, 3] * wi[3])
            if j == 0:
                torque[i] = z[5] + LC[i, L_JH] * z[2]
            loads[ic, 0] = z[3]
            loads[ic, 1] = z[4]
            loads[ic, 2] = z[5]
            E = Ealls[i * k + j]
            b = es + j * ne - off
            for r in range(off, 3):
                v = E[7 * r + 6]
                for cc in range(3):
                    v += E[7 * r + cc] * z[cc] + E[7 * r + 3 + cc] * z[3 + cc]
                xout[b + r] = v
            ic += 1
        for r in range(3, 6):
            z[r] = (cuts[ic, r, 0] * wi[0] + cuts[ic, r, 1] * wi[1] + cuts[ic, r, 2] * wi[2]
                    + cuts[ic, r, 3] * wi[3])
        loads[ic, 0] = z[3]
        loads[ic, 1] = z[4]
        loads[ic, 2] = z[5]
        ic += 1
    return True, cond


# ---------------------------------------------------------------------------------------------
@njit(cache=True, boundscheck=False)
def _sweep(sweep, LC, LI, grav, n, k, q, qd, WE, WJ, tau, acc, xout, torque, loads, pws):
    """One sweep at the iterate (q, q̇) (WE[:, W_KE] and WJ[:, J_MT] already set). Returns
    (ok, cond) — cond is the plain sweep's final-system condition number (nan for Riccati)."""
    _angles(LC, LI, n, k, q, qd, WE)
    if sweep == SW_RICCATI:
        _riccati(LC, LI, grav, n, k, WE, WJ, tau, acc, xout, torque)
        return True, np.nan
    return _plain(LC, LI, grav, n, k, WE, WJ, tau, acc, xout, torque, loads, pws[0], pws[1], pws[2], pws[3])


@njit(cache=True, boundscheck=False)
def _accel(sweep, LC, LI, grav, n, k, im, q, qd, tau, mot, qs, qds, acc, WE, WJ, xout, torque, loads, pws,
           want_loads):
    """Exact forward dynamics q̈(q, q̇) (motion joints take the law's angle, rate, α̈).
    qs, qds (n_dof) and acc (n) are scratch."""
    qs[:] = q
    qds[:] = qd
    ii = 0
    for i in range(n):
        acc[i] = mot[i, 2]
        if LI[i, I_MOT]:
            qs[im[ii]] = mot[i, 0]
            qds[im[ii]] = mot[i, 1]
            ii += 1
    _elastic_known(LC, LI, n, k, qs, qds, WE)
    _eff_mass(LC, n, 0.0, 0.0, WJ)
    ok, cond = _sweep(sweep, LC, LI, grav, n, k, qs, qds, WE, WJ, tau, acc, xout, torque, loads, pws)
    for i in range(n):
        if not LI[i, I_MOT]:
            torque[i] = tau[i]
    if want_loads and sweep == SW_RICCATI:
        _riccati_loads(n, k, WE, WJ, loads)
    return ok, cond


@njit(cache=True, boundscheck=False)
def _check(q, qd, qdd, lim):
    """Index of the first bad coordinate (non-finite or runaway elastic displacement), or -1."""
    for i in range(q.shape[0]):
        if not (math.isfinite(q[i]) and math.isfinite(qd[i]) and math.isfinite(qdd[i])):
            return i
        if abs(q[i]) > lim[i]:
            return i
    return -1


@njit(cache=True, boundscheck=False)
def _sample(LC, LI, grav, n, k, q, qd, j, root, tip, root_angle, energy, want_energy):
    """Kinematics (link roots, tips, root angles) and the total energy at one state, written to
    row j of the output arrays: the compiled counterpart of structure.kinematics + energy."""
    g0, g1 = grav[0], grav[1]
    px = py = 0.0
    vx = vy = 0.0
    th0 = thd0 = 0.0
    etot = 0.0
    for i in range(n):
        ne = LI[i, I_NE]
        es = LI[i, I_ES]
        off = LI[i, I_OFF]
        m = LC[i, L_M]
        su = LC[i, L_SU]
        th = th0 + q[LI[i, I_IA]]
        thd = thd0 + qd[LI[i, I_IA]]
        root[j, i, 0] = px
        root[j, i, 1] = py
        root_angle[j, i] = th
        if want_energy:
            mh, jh = LC[i, L_MH], LC[i, L_JH]
            etot += 0.5 * (mh * (vx * vx + vy * vy) + jh * thd * thd) - mh * (px * g0 + py * g1)
        c = math.cos(th)
        s = math.sin(th)
        e2 = 0.0
        for jj in range(k):
            if jj > 0:
                c, s = _rotate(c, s, th, e2)  # e2 = φ of element jj − 1, th = θ_jj
            b = es + jj * ne - off
            e0 = 0.0 if off else q[b]
            f0 = 0.0 if off else qd[b]
            e1, e2 = q[b + 1], q[b + 2]
            f1, f2 = qd[b + 1], qd[b + 2]
            so0 = LC[i, L_SO0] + su * e0
            so1 = LC[i, L_SO0 + 1] + e1
            rx = c * so0 - s * so1
            ry = s * so0 + c * so1
            sf0 = su * f0
            dvx = -thd * ry + (c * sf0 - s * f1)
            dvy = thd * rx + (s * sf0 + c * f1)
            if want_energy:
                ms0 = LC[i, L_CS0] + LC[i, L_CS] * e0 + LC[i, L_CS + 1] * e1 + LC[i, L_CS + 2] * e2
                ms1 = LC[i, L_CS0 + 1] + LC[i, L_CS + 3] * e0 + LC[i, L_CS + 4] * e1 + LC[i, L_CS + 5] * e2
                rem0 = -c * ms1 - s * ms0
                rem1 = -s * ms1 + c * ms0
                e = (e0, e1, e2)
                f = (f0, f1, f2)
                Jt = LC[i, L_CS0S0]
                Tee = 0.0
                Vee = 0.0
                Tae = 0.0
                for r in range(3):
                    se = 0.0
                    sf = 0.0
                    ke = 0.0
                    a2r = LC[i, L_D1 + r]
                    for l in range(3):
                        se += LC[i, L_CSS + 3 * r + l] * e[l]
                        sf += LC[i, L_CSS + 3 * r + l] * f[l]
                        ke += LC[i, L_K + 3 * r + l] * e[l]
                        a2r += e[l] * LC[i, L_D2 + 3 * l + r]
                    Jt += 2.0 * LC[i, L_CS0S + r] * e[r] + e[r] * se
                    Tee += f[r] * sf
                    Vee += e[r] * ke
                    a0r = c * LC[i, L_CS + r] - s * LC[i, L_CS + 3 + r]
                    a1r = s * LC[i, L_CS + r] + c * LC[i, L_CS + 3 + r]
                    Tae += (vx * a0r + vy * a1r + thd * a2r) * f[r]
                if LC[i, L_SOF] != 0.0:  # U = ½ EA l ε² + ½ wᵀK_b w (element.strain_energy)
                    Gw1 = LC[i, L_G] * e1 + LC[i, L_G + 1] * e2
                    Gw2 = LC[i, L_G + 2] * e1 + LC[i, L_G + 3] * e2
                    eps = e0 * LC[i, L_IEL] + 0.5 * (e1 * Gw1 + e2 * Gw2)
                    Vee = LC[i, L_EAL] * eps * eps + (e1 * (LC[i, L_K + 4] * e1 + LC[i, L_K + 5] * e2)
                                                      + e2 * (LC[i, L_K + 7] * e1 + LC[i, L_K + 8] * e2))
                # p' = (ṙ_I, θ̇): ½ p'ᵀ M_aa p' + p'ᵀ M_ae ė + ½ ėᵀ C_SS ė + U(e) − g·∫r dm
                Taa = m * (vx * vx + vy * vy) + 2.0 * thd * (rem0 * vx + rem1 * vy) + Jt * thd * thd
                etot += 0.5 * (Taa + 2.0 * Tae + Tee) + 0.5 * Vee
                comx = m * px + (c * ms0 - s * ms1)
                comy = m * py + (s * ms0 + c * ms1)
                etot -= comx * g0 + comy * g1
            px += rx
            py += ry
            vx += dvx
            vy += dvy
            th += e2
            thd += f2
        tip[j, i, 0] = px
        tip[j, i, 1] = py
        if want_energy:
            mp, jp = LC[i, L_MP], LC[i, L_JP]
            etot += 0.5 * (mp * (vx * vx + vy * vy) + jp * thd * thd) - mp * (px * g0 + py * g1)
        th0 = th
        thd0 = thd
    if want_energy:
        energy[j] = etot


@njit(cache=True, boundscheck=False)
def _record(LC, LI, grav, n, k, ia, t0, t1, q0, qd0, tau0, ld0, q1, qd1, tau1, ld1, qs, qds, ptr, rec, stride,
            want_energy):
    """Sample every output time in (t0, t1] (cubic Hermite between the step ends, linear for
    torques and loads), as solver._Recorder.record. Returns the new sample pointer."""
    out_t, angle, rate, torque, root, tip, rang, energy, loads = rec
    nt = out_t.shape[0]
    nd = q0.shape[0]
    ncuts = ld1.shape[0]
    eps = 1e-9 * (t1 - t0)
    h = t1 - t0
    while ptr < nt and out_t[ptr] <= t1 + eps:
        tj = out_t[ptr]
        exact = abs(tj - t1) <= eps
        if exact:
            x = 1.0
            qq = q1
            vv = qd1
        else:
            x = (tj - t0) / h
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
            for r in range(nd):
                qs[r] = h00 * q0[r] + h10 * h * qd0[r] + h01 * q1[r] + h11 * h * qd1[r]
                qds[r] = d00 * q0[r] + d10 * qd0[r] + d01 * q1[r] + d11 * qd1[r]
            qq = qs
            vv = qds
        for i in range(n):
            angle[ptr, i] = qq[ia[i]]
            rate[ptr, i] = vv[ia[i]]
            torque[ptr, i] = tau1[i] if exact else (1 - x) * tau0[i] + x * tau1[i]
        _sample(LC, LI, grav, n, k, qq, vv, ptr, root, tip, rang, energy, want_energy)
        if stride > 0 and ptr % stride == 0:
            jl = ptr // stride
            for c in range(ncuts):
                for r in range(3):
                    v = ld1[c, r] if exact else (1 - x) * ld0[c, r] + x * ld1[c, r]
                    loads[jl, c, (r + 1) % 3] = v  # (Qx, Qy, M) -> (M, Qx, Qy)
        ptr += 1
    return ptr


@njit(cache=True, boundscheck=False)
def run(integ, sweep, itmode, nfix, tol, maxit, auto_frac, fam, LC, LI, grav, n, k, im, ia, lim,
        state, t_end, restart, s_begin, s_end, drv, need_loads, prev, rec, stride, want_energy, WE, WJ, pws,
        stats):
    """Steps s_begin … s_end − 1 of the time loop, recording the output samples on the way.

    state = (q, q̇, q̈, a) (a: the auxiliary acceleration of generalised-α), overwritten;
    drv = (τ left, motion left, τ right, motion right, τ mid, motion mid) per step
    ((n_steps, n) and (n_steps, n, 3): (α, α̇, α̈)); prev = (q, q̇, τ, loads) at the end of
    step s_begin − 1 (loads only where need_loads); rec = output grid and arrays
    (see solver._Recorder); fam = (β, γ, α_m, α_f, |β − 1/6|/β).

    stats (float, ≥ 8), accumulated: [0] total sweeps, [1] max sweeps in a step,
    [2] unconverged steps, [3] max final-system condition number (plain), [4] steps done,
    [5] status (ST_OK, ST_NONFINITE, ST_RUNAWAY, 3 = linear solve failed), [6] index of the
    bad coordinate, [7] output sample pointer.
    """
    q, qd, qdd, aa = state
    TAUL, MOTL, TAUR, MOTR, TAUM, MOTM = drv
    qp, qdp, tp, lp = prev
    nd = q.shape[0]
    ncuts = lp.shape[0]
    beta, gamma, am, af, lte = fam[0], fam[1], fam[2], fam[3], fam[4]
    x = np.empty(nd)
    xn = np.empty(nd)
    qt = np.empty(nd)
    qdt = np.empty(nd)
    qi = np.empty(nd)
    qdi = np.empty(nd)
    torque = np.empty(n)
    loads = np.empty((ncuts, 3))
    torque_r = np.empty(n)         # restart solve: its torques/loads are not recorded
    loads_r = np.empty((ncuts, 3))
    k2v = np.empty(nd)
    k3v = np.empty(nd)
    ka = np.empty(nd)
    qs = np.empty(nd)
    qds = np.empty(nd)
    acc_s = np.empty(n)
    tot_sweeps = 0
    max_sweeps = int(stats[1])
    unconv = 0
    cond_max = stats[3]
    ptr = int(stats[7])
    t0 = 0.0 if s_begin == 0 else t_end[s_begin - 1]
    status = 0
    done = s_begin
    for st in range(s_begin, s_end):
        t1 = t_end[st]
        h = t1 - t0
        tau = TAUL[st]
        mot = MOTL[st]
        if integ == INT_NEWMARK:
            # predictor (integrators.NewmarkFamily.predict)
            hh = h * h
            sc = (1.0 - af) / (1.0 - am)
            cq = beta * hh * sc
            cv = gamma * h * sc
            i1m = 1.0 / (1.0 - am)
            for r in range(nd):
                corr = (af * qdd[r] - am * aa[r]) * i1m
                qt[r] = q[r] + h * qd[r] + hh * (0.5 - beta) * aa[r] + beta * hh * corr
                qdt[r] = qd[r] + h * (1.0 - gamma) * aa[r] + gamma * h * corr
                x[r] = qdd[r]
            ii = 0
            for i in range(n):
                acc_s[i] = mot[i, 2]
                if LI[i, I_MOT]:
                    x[im[ii]] = mot[i, 2]
                    ii += 1
            _elastic_known(LC, LI, n, k, qt, qdt, WE)
            _eff_mass(LC, n, cq, cv, WJ)
            nsw = maxit if itmode != IT_FIXED else nfix + 1
            converged = itmode == IT_FIXED
            prev_dx = np.inf
            used = 0
            for r in range(nd):
                qi[r] = qt[r] + cq * x[r]
                qdi[r] = qdt[r] + cv * x[r]
            for it in range(nsw):
                ii = 0
                for i in range(n):
                    if LI[i, I_MOT]:
                        qi[im[ii]] = mot[i, 0]
                        qdi[im[ii]] = mot[i, 1]
                        ii += 1
                ok, cond = _sweep(sweep, LC, LI, grav, n, k, qi, qdi, WE, WJ, tau, acc_s, xn, torque, loads,
                                  pws)
                used = it + 1
                if not ok:
                    status = 3
                    break
                if sweep == SW_PLAIN and cond > cond_max:
                    cond_max = cond
                # one fused pass: |Δq̈|, max|q̈|, the next iterate's (q, q̇), and for "auto"
                # max|q̈_{n+1} − q̈_n|
                dx = 0.0
                xmax = 0.0
                dq = 0.0
                bad = False
                for r in range(nd):
                    v = xn[r]
                    d = abs(v - x[r])
                    bad |= d != d
                    dx = d if d > dx else dx
                    ax = abs(v)
                    xmax = ax if ax > xmax else xmax
                    x[r] = v
                    qi[r] = qt[r] + cq * v
                    qdi[r] = qdt[r] + cv * v
                if itmode == IT_AUTO:
                    for r in range(nd):
                        d2 = abs(x[r] - qdd[r])
                        dq = d2 if d2 > dq else dq
                if bad:
                    dx = np.nan
                if itmode != IT_FIXED:
                    scale = max(1.0, xmax)
                    if dx <= tol * scale:
                        converged = True
                        break
                    if it >= 3 and dx >= 0.9 * prev_dx and dx <= 1e3 * tol * scale:
                        converged = True  # stagnation at the round-off floor
                        break
                    if not math.isfinite(dx):
                        break
                    if itmode == IT_AUTO and it >= 1 and dx < prev_dx:
                        # the contraction ρ = dx/prev_dx predicts the remaining iteration error
                        # dx·ρ/(1 − ρ); stop once it is below auto_frac × the local truncation
                        # error estimate |β − 1/6|/β · max|q̈_{n+1} − q̈_n| (both scaled by βh²).
                        rr = dx / prev_dx
                        if dx * rr / (1.0 - rr) <= auto_frac * lte * dq:
                            converged = True
                            break
                    prev_dx = dx
            if status == 3:
                break
            tot_sweeps += used
            if used > max_sweeps:
                max_sweeps = used
            if not converged:
                unconv += 1
            for r in range(nd):
                anew = ((1.0 - af) * x[r] + af * qdd[r] - am * aa[r]) * i1m
                q[r] = qt[r] + cq * x[r]
                qd[r] = qdt[r] + cv * x[r]
                aa[r] = anew
                qdd[r] = x[r]
            ii = 0
            for i in range(n):
                if LI[i, I_MOT]:
                    q[im[ii]] = mot[i, 0]
                    qd[im[ii]] = mot[i, 1]
                    aa[im[ii]] = x[im[ii]]
                    ii += 1
                else:
                    torque[i] = tau[i]
            if need_loads[st] and sweep == SW_RICCATI:
                _riccati_loads(n, k, WE, WJ, loads)
        else:
            # classical RK4 on (q, q̇) with the exact acceleration solver
            hf = 0.5 * h
            for r in range(nd):
                qi[r] = q[r] + hf * qd[r]
                qdi[r] = qd[r] + hf * qdd[r]
                k2v[r] = qdi[r]
            ok, cond = _accel(sweep, LC, LI, grav, n, k, im, qi, qdi, TAUM[st], MOTM[st], qs, qds, acc_s,
                              WE, WJ, ka, torque, loads, pws, False)
            if ok:
                for r in range(nd):
                    qi[r] = q[r] + hf * k2v[r]
                    qdi[r] = qd[r] + hf * ka[r]
                    k3v[r] = qdi[r]
                ok, cond = _accel(sweep, LC, LI, grav, n, k, im, qi, qdi, TAUM[st], MOTM[st], qs, qds,
                                  acc_s, WE, WJ, x, torque, loads, pws, False)
            if ok:
                for r in range(nd):
                    qi[r] = q[r] + h * k3v[r]
                    qdi[r] = qd[r] + h * x[r]
                ok, cond = _accel(sweep, LC, LI, grav, n, k, im, qi, qdi, tau, mot, qs, qds, acc_s, WE, WJ,
                                  xn, torque, loads, pws, False)
            if ok:
                # k1 = (q̇, q̈), k2 = (k2v, ka), k3 = (k3v, x), k4 = (qdi, xn)
                for r in range(nd):
                    q[r] = q[r] + h / 6.0 * (qd[r] + 2.0 * k2v[r] + 2.0 * k3v[r] + qdi[r])
                    qd[r] = qd[r] + h / 6.0 * (qdd[r] + 2.0 * ka[r] + 2.0 * x[r] + xn[r])
                ii = 0
                for i in range(n):
                    if LI[i, I_MOT]:
                        q[im[ii]] = mot[i, 0]
                        qd[im[ii]] = mot[i, 1]
                        ii += 1
                ok, cond = _accel(sweep, LC, LI, grav, n, k, im, q, qd, tau, mot, qs, qds, acc_s, WE, WJ, qdd,
                                  torque, loads, pws, need_loads[st])
            if not ok:
                status = 3
                break
            if cond > cond_max:
                cond_max = cond
            tot_sweeps += 4
            max_sweeps = 4
        bad = _check(q, qd, qdd, lim)
        if bad >= 0:
            stats[6] = bad
            status = ST_RUNAWAY if math.isfinite(q[bad] + qd[bad] + qdd[bad]) else ST_NONFINITE
            break
        if restart[st]:  # a drive jumps at t1: restart with the right-hand limit; the
            # recorded sample at t1 keeps the left limit (the step's own solve)
            ok, cond = _accel(sweep, LC, LI, grav, n, k, im, q, qd, TAUR[st], MOTR[st], qs, qds, acc_s,
                              WE, WJ, qdd, torque_r, loads_r, pws, False)
            if not ok:
                status = 3
                break
            if cond > cond_max:
                cond_max = cond
            for r in range(nd):
                aa[r] = qdd[r]
        ptr = _record(LC, LI, grav, n, k, ia, t0, t1, qp, qdp, tp, lp, q, qd, torque, loads, qs, qds, ptr,
                      rec, stride, want_energy)
        qp[:] = q
        qdp[:] = qd
        tp[:] = torque
        if need_loads[st]:
            lp[:, :] = loads
        t0 = t1
        done = st + 1
    stats[0] += tot_sweeps
    stats[1] = max_sweeps
    stats[2] += unconv
    stats[3] = cond_max
    stats[4] = done
    stats[5] = status
    stats[7] = ptr
    return status


@njit(cache=True, boundscheck=False)
def accel(sweep, LC, LI, grav, n, k, im, q, qd, tau, mot, WE, WJ, xout, torque, loads, pws):
    """Compiled acceleration solver: fills xout (q̈), torque and loads (all cuts) at (q, q̇)."""
    nd = q.shape[0]
    qs = np.empty(nd)
    qds = np.empty(nd)
    acc_s = np.empty(n)
    return _accel(sweep, LC, LI, grav, n, k, im, q, qd, tau, mot, qs, qds, acc_s, WE, WJ, xout, torque, loads,
                  pws, True)


@njit(cache=True, boundscheck=False)
def sample_outputs(LC, LI, grav, n, k, Q, QD, root, tip, root_angle, energy, want_energy):
    """Kinematics and energy at many states (rows of Q, QD)."""
    for j in range(Q.shape[0]):
        _sample(LC, LI, grav, n, k, Q[j], QD[j], j, root, tip, root_angle, energy, want_energy)


# ---------------------------------------------------------------------------------------------
_WARM = False


def is_warm() -> bool:
    return _WARM


def warmup() -> float:
    """Compile (or load from the on-disk cache) every kernel entry point on a tiny case and
    return the seconds it took. A no-op returning 0.0 once done in this process."""
    global _WARM
    if _WARM or not HAVE_NUMBA:
        return 0.0
    from .case import Case
    from .drives import Constant, Drive, Sine
    from .model import Hub, Link, Manipulator, Payload, Section
    from .scenario import Scenario
    from .solver import simulate

    t = time.perf_counter()
    _WARM = True  # simulate() below must not recurse into warmup
    try:
        links = (Link(Section(0.5, 2.0, 0.3, 7e6), hub=Hub(0.1, 0.01)),
                 Link(Section(0.5, 2.0, 0.3, None), payload=Payload(0.1, 0.0)))
        drives = (Drive("torque", Sine(1.0, 1.0, until=0.0025)), Drive("motion", Constant(0.0)))
        case = Case(Manipulator(links, gravity=(0.0, -9.81)), Scenario(0.004, 0.002, drives))
        for integ in ("newmark", "rk4"):
            for sw in ("riccati", "plain"):
                simulate(case, elements_per_link=1, h=1e-3, integrator=integ, sweep=sw, engine="numba")
    except BaseException:
        _WARM = False
        raise
    return time.perf_counter() - t
