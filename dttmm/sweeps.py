"""The two DT-TMM sweeps for one linear(ised) step system — the readable one-step reference.

At a cut the state is z = (a, f): a = (ẍ, ÿ, θ̈) the acceleration of the point and of the
cross-section, f = (Qx, Qy, M) the load the inboard part exerts on the outboard part.
An element with inboard state (a_I, f_I) obeys

    rigid rows    M_aa a_I + M_ae ë + h̄_a = f_I − B_aᵀ f_O
    elastic rows  M_ea a_I + M̃_ee ë + h̃_e = −B_eᵀ f_O
    kinematics    a_O = B_a a_I + B_e ë + γ̄_O

with M̃_ee = M_ee + c_q K + c_v D and h̃_e = h_e − Q_e + K ê + D ê' (Newmark: ê, ê' the
predictors and c_q = βh², c_v = γh; acceleration solver: ê = e, ê' = ė, c_q = c_v = 0).

* ``riccati``: sweep tip → base the affine relation f = P a + c, then base → tip. O(N), stable.
* ``plain``: the paper's transfer form z_O = U z_I carried as z = B w with three base unknowns,
  closed by a 3×3 solve at the tip. Loses digits exponentially with mesh refinement.

Both return the same :class:`SweepOut`. :func:`accelerations` is the forward dynamics at one
state built on them: the reference that the kernel (:mod:`dttmm.kernel`) is checked against.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .element import damping_tangent, elastic_forces
from .structure import Kinematics, Structure, kinematics

__all__ = ["SWEEPS", "SweepOut", "accelerations", "plain", "riccati"]

E3 = np.array([0.0, 0.0, 1.0])


@dataclass
class SweepOut:
    qdd: np.ndarray  # (n_dof,)
    loads: np.ndarray  # (n_cuts, 3): (Qx, Qy, M) at each element root and each link tip
    torque: np.ndarray  # (n,) joint torques (law value or computed for motion joints)
    cond: float = np.nan  # condition number of the final 3×3 system (plain sweep)
    final_system: np.ndarray | None = None  # the plain sweep's final matrix (always 3×3)


def _elastic_rhs(lk, lkn, cq, cv, e_hat, ed_hat):
    """Per element M̃_ee (k, ne, ne) and h̃_e (k, ne). The elastic forces are linearised at the
    iterate e_i (Newton): f(e) ≈ f(e_i) + K_T(e_i)(ẽ + c_q ë − e_i); for the linear element
    this is exactly K ẽ + c_q K ë. The damping force D(e) ė is linear in ė; its matrix is
    taken at the iterate: D(e_i)(ẽ' + c_v ë) (D = μK for the linear element)."""
    et = lk.et
    f, KT = elastic_forces(et, lkn.e)
    if et.second_order and et.mu != 0.0:
        Dt = damping_tangent(et, lkn.e)
        Mt = et.C_SS + cq * KT + cv * Dt
        ht = lkn.hbar_e + f + np.einsum("kij,kj->ki", KT, e_hat - lkn.e) + np.einsum("kij,kj->ki", Dt, ed_hat)
        return Mt, ht
    Mt = et.C_SS + cq * KT + cv * et.D
    ht = lkn.hbar_e + f + np.einsum("kij,kj->ki", KT, e_hat - lkn.e) + ed_hat @ et.D.T
    return Mt, ht


def riccati(st: Structure, kin: Kinematics, cq: float, cv: float, e_hat, ed_hat, tau, acc_presc) -> SweepOut:
    """Articulated-inertia (Riccati) sweep. ``e_hat``/``ed_hat``: per link (k, ne) arrays;
    ``tau`` (n,) torques of torque joints; ``acc_presc`` (n,) α̈ of motion joints."""
    n = st.n_links
    Q_g = lambda m: np.array([m * st.gravity[0], m * st.gravity[1], 0.0])
    store = []
    P = np.zeros((3, 3))
    c = np.zeros(3)
    for i in range(n - 1, -1, -1):
        lk, lkn = st.links[i], kin.links[i]
        et = lk.et
        # payload at the tip, then the link tip cut
        P = P + lk.M_pay
        c = c - Q_g(lk.m_pay)
        P_tip, c_tip = P, c
        Mt, ht = _elastic_rhs(lk, lkn, cq, cv, e_hat[i], ed_hat[i])
        k = lk.k
        Ka = np.empty((k, et.ne, 3))
        k0 = np.empty((k, et.ne))
        Ps = np.empty((k, 3, 3))
        cs = np.empty((k, 3))
        for j in range(k - 1, -1, -1):
            Ba, Be = lkn.B_a[j], lkn.B_e[j]
            PBe = P @ Be
            H = Mt[j] + Be.T @ PBe
            X = lkn.M_ae[j] + Ba.T @ PBe
            rho = P @ lkn.gbar[j] + c
            sol = np.linalg.solve(H, -np.column_stack([X.T, ht[j] + Be.T @ rho]))
            Ka[j], k0[j] = sol[:, :3], sol[:, 3]
            P = lkn.M_aa[j] + Ba.T @ P @ Ba + X @ Ka[j]
            P = 0.5 * (P + P.T)
            c = lkn.hbar_a[j] + Ba.T @ rho + X @ k0[j]
            Ps[j], cs[j] = P, c
        # hub (outboard side of joint i), then the joint condition
        Pp = P + lk.M_hub
        cp = c - Q_g(lk.m_hub)
        if st.motion[i]:
            ga, g0 = None, acc_presc[i]
            P, c = Pp, cp + Pp[:, 2] * g0
        else:
            ga = -Pp[2, :] / Pp[2, 2]
            g0 = (tau[i] - cp[2]) / Pp[2, 2]
            P = Pp + np.outer(Pp[:, 2], ga)
            P = 0.5 * (P + P.T)
            c = cp + Pp[:, 2] * g0
        store.append((Ka, k0, Ps, cs, P_tip, c_tip, Pp, cp, ga, g0))
    store.reverse()

    qdd = np.empty(st.n_dof)
    loads = np.empty((st.n_elements + n, 3))
    torque = np.empty(n)
    a = np.zeros(3)
    ic = 0
    for i in range(n):
        lk, lkn = st.links[i], kin.links[i]
        Ka, k0, Ps, cs, P_tip, c_tip, Pp, cp, ga, g0 = store[i]
        alpha_dd = g0 if ga is None else ga @ a + g0
        a = a + E3 * alpha_dd
        qdd[lk.i_alpha] = alpha_dd
        torque[i] = Pp[2] @ a + cp[2]
        edd = qdd[lk.e_slice].reshape(lk.k, lk.et.ne)
        for j in range(lk.k):
            loads[ic] = Ps[j] @ a + cs[j]
            ic += 1
            edd[j] = Ka[j] @ a + k0[j]
            a = lkn.B_a[j] @ a + lkn.B_e[j] @ edd[j] + lkn.gbar[j]
        loads[ic] = P_tip @ a + c_tip
        ic += 1
    return SweepOut(qdd, loads, torque)


def _equilibrated_cond(A):
    """2-norm condition number after scaling rows and columns to unit norm (the unknowns are
    forces and accelerations of very different size; plain cond would measure units)."""
    if not np.all(np.isfinite(A)):
        return np.inf
    c = np.linalg.norm(A, axis=0)
    As = A / np.where(c > 0, c, 1.0)
    r = np.linalg.norm(As, axis=1)
    As = As / np.where(r > 0, r, 1.0)[:, None]
    return float(np.linalg.cond(As))


def plain(st: Structure, kin: Kinematics, cq: float, cv: float, e_hat, ed_hat, tau, acc_presc) -> SweepOut:
    """The paper's plain transfer sweep with a constant 3×3 final system."""
    n = st.n_links
    Q_g = lambda m: np.array([m * st.gravity[0], m * st.gravity[1], 0.0])
    # z = B w, B (6, 4): rows (a, f), columns (u1, u2, u3, 1)
    B = np.zeros((6, 4))
    subs = []  # per joint: (substitution S or None, slot of α̈ or None)
    cuts = []  # per cut: (stage, B)
    elem = []  # per link: (Ea, Ef, E0) arrays
    for i in range(n):
        lk, lkn = st.links[i], kin.links[i]
        et = lk.et
        if i == 0:
            B[:] = 0.0
            if st.motion[0]:  # u = (Fx, Fy, τ1), α̈ known
                B[3, 0] = B[4, 1] = B[5, 2] = 1.0
                B[2, 3] = acc_presc[0]
                subs.append((None, None))
            else:  # u = (Fx, Fy, α̈1), τ1 known
                B[3, 0] = B[4, 1] = 1.0
                B[5, 3] = tau[0]
                B[2, 2] = 1.0
                subs.append((None, 2))
        else:
            if st.motion[i]:
                B[2, 3] += acc_presc[i]
                subs.append((None, None))
            else:
                cm, d = B[5, :3], B[5, 3]
                score = np.abs(cm) / np.maximum(np.linalg.norm(B[:, :3], axis=0), 1e-300)
                piv = int(np.argmax(score))
                S = np.eye(4)
                S[piv, :] = 0.0
                for m in range(3):
                    if m != piv:
                        S[piv, m] = -cm[m] / cm[piv]
                S[piv, 3] = (tau[i] - d) / cm[piv]
                B = B @ S
                B[2, piv] += 1.0
                subs.append((S, piv))
        # hub: f⁺ = f⁻ − M_h a⁺ + Q_h
        B[3:] -= lk.M_hub @ B[:3]
        B[3:, 3] += Q_g(lk.m_hub)
        Mt, ht = _elastic_rhs(lk, lkn, cq, cv, e_hat[i], ed_hat[i])
        Ea = np.empty((lk.k, et.ne, 3))
        Ef = np.empty((lk.k, et.ne, 3))
        E0 = np.empty((lk.k, et.ne))
        for j in range(lk.k):
            cuts.append((i, B.copy()))
            Ba, Be, Maa, Mae = lkn.B_a[j], lkn.B_e[j], lkn.M_aa[j], lkn.M_ae[j]
            T = np.linalg.inv(Ba).T
            BeT = Be.T @ T
            G = Mt[j] - BeT @ Mae
            rhs = np.column_stack([-Mae.T + BeT @ Maa, -BeT, -ht[j] + BeT @ lkn.hbar_a[j]])
            sol = np.linalg.solve(G, rhs)
            Ea[j], Ef[j], E0[j] = sol[:, :3], sol[:, 3:6], sol[:, 6]
            # linear map (a_I, f_I, 1) -> (a_O, f_O)
            U = np.zeros((6, 7))
            U[:3, :3] = Ba + Be @ Ea[j]
            U[:3, 3:6] = Be @ Ef[j]
            U[:3, 6] = Be @ E0[j] + lkn.gbar[j]
            U[3:, :3] = T @ (-Maa - Mae @ Ea[j])
            U[3:, 3:6] = T @ (np.eye(3) - Mae @ Ef[j])
            U[3:, 6] = T @ (-lkn.hbar_a[j] - Mae @ E0[j])
            Bn = U[:, :6] @ B
            Bn[:, 3] += U[:, 6]
            B = Bn
        cuts.append((i, B.copy()))  # link tip cut
        elem.append((Ea, Ef, E0))
        # payload: f beyond = f_tip − M_p a + Q_p
        B[3:] -= lk.M_pay @ B[:3]
        B[3:, 3] += Q_g(lk.m_pay)
    A3 = B[3:, :3]
    cond = _equilibrated_cond(A3)
    u = np.linalg.solve(A3, -B[3:, 3])
    w = np.append(u, 1.0)
    # back-substitution of the joint eliminations: w at every stage
    ws = [None] * n
    for i in range(n - 1, -1, -1):
        ws[i] = w
        S, _ = subs[i]
        if S is not None:
            w = S @ w
    qdd = np.empty(st.n_dof)
    loads = np.empty((len(cuts), 3))
    torque = np.empty(n)
    ic = 0
    for i in range(n):
        lk = st.links[i]
        S, slot = subs[i]
        wi = ws[i]
        qdd[lk.i_alpha] = acc_presc[i] if st.motion[i] else wi[slot]
        Ea, Ef, E0 = elem[i]
        edd = qdd[lk.e_slice].reshape(lk.k, lk.et.ne)
        for j in range(lk.k):
            z = cuts[ic][1] @ wi
            if j == 0:  # torque at the joint: f⁻_θ = f⁺_θ + (M_h a⁺)_θ
                torque[i] = z[5] + lk.M_hub[2] @ z[:3]
            loads[ic] = z[3:]
            edd[j] = Ea[j] @ z[:3] + Ef[j] @ z[3:] + E0[j]
            ic += 1
        loads[ic] = (cuts[ic][1] @ wi)[3:]
        ic += 1
    return SweepOut(qdd, loads, torque, cond, A3)


SWEEPS = {"riccati": riccati, "plain": plain}


def accelerations(
    st: Structure,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray,
    mot: np.ndarray,
    sweep: str = "riccati",
    forces: np.ndarray | None = None,
) -> SweepOut:
    """Forward dynamics at one state: q̈ (n_dof,), cut loads and joint torques at (q, q̇).

    ``tau`` (n,) torques of the torque-driven joints (N·m); ``mot`` (n, 3) (α, α̇, α̈) of the
    motion-driven joints, which override the given q, q̇ entries. ``sweep``: "riccati" or "plain".
    ``forces`` (n_dof,), optional: generalized forces Q applied on the coordinates besides the
    drives (N or N·m per coordinate; virtual work Qᵀδq). On a joint angle it adds to the joint's
    torque (ignored on a motion-driven joint, whose angle is prescribed); on an elastic
    coordinate it enters the element's elastic rows (h̃_e − Q_e). q̈ is affine in Q.
    Raises numpy.linalg.LinAlgError when a step system is singular.
    """
    q, qd = np.array(q, float), np.array(qd, float)
    im = st.alpha_index[st.motion]
    q[im], qd[im] = mot[st.motion, 0], mot[st.motion, 1]
    split = lambda x: [x[lk.e_slice].reshape(lk.k, lk.et.ne) for lk in st.links]
    kin = kinematics(st, q, qd)
    tau_in = np.array(tau, float)
    if forces is not None:
        forces = np.asarray(forces, float)
        tau_in = tau_in + np.where(st.motion, 0.0, forces[st.alpha_index])
        for lk, lkn in zip(st.links, kin.links):
            lkn.hbar_e = lkn.hbar_e - forces[lk.e_slice].reshape(lk.k, lk.et.ne)
    out = SWEEPS[sweep](st, kin, 0.0, 0.0, split(q), split(qd), tau_in, mot[:, 2])
    out.torque[~st.motion] = tau_in[~st.motion]
    return out
