"""Closed-loop (pd/pid) joint torques inside the time loop.

A closed-loop joint i has the torque

    τ = clip((L0 + g_M J_hub ω̇_i) / (1 + g_M), ±limit),
    L0 = τ_ff + kp (α_ref − α) + kd (α̇_ref − α̇) + ki z,

the law τ = clip(L0 − g_M M_root) with the root bending moment M_root = τ − J_hub ω̇_i of the
hub's moment balance solved for τ (ω̇_i: absolute angular acceleration of link i's root).

A Newmark step evaluates it implicitly at t_{n+1}: α = α̃ + c_q α̈, α̇ = α̃' + c_v α̈, the
integral state by the trapezoidal rule z_{n+1} = z_n + h/2 (e_n + e_{n+1}), e = α_ref − α. Each
sweep of the step sees the law linearised at the latest iterate k in the joint's own α̈,

    τ ≈ τ_k + s (α̈ − α̈_k),  s = ∂τ/∂α c_q + ∂τ/∂α̇ c_v − ∂τ/∂z h c_q / 2 + ∂τ/∂ω̇,

(the inboard part of ω̇_i held at the iterate): the Riccati sweep takes it as an extra joint
stiffness (:func:`dttmm.kernel.riccati._joint`, slope passed in ``acc[i]``, τ_k − s α̈_k in
``tau[i]``). The converged step satisfies the law exactly. The forward dynamics at a given
state (t = 0, restarts, RK4 stages) iterate sweeps the same way with s = ∂τ/∂ω̇ only.

Per-joint constants, columns of ``Drives.gain`` (n, 6): kp, kd, ki, g_M, limit, J_hub; a
joint's ``Drives.code`` is 1 for pd/pid and 0 otherwise.
"""

from __future__ import annotations

from .. import control
from ._jit import PURE, njit

#: columns of Drives.gain
KP, KD, KI, GM, LIMIT, JHUB = range(6)
#: Drives.code of a pd/pid joint, of a user law (engine "python" only)
CODE_PD = control.CODE_PD
CODE_USER = control.CODE_USER

#: the law itself, compiled from dttmm.control (its source is part of the kernel's cache key)
_pd_torque = njit(nrt=False, inline="always")(control.pd_torque)


@njit(nrt=False, inline="always")
def pd_torque(gain, i, ff, a_ref, r_ref, z, alpha, rate, omega_dot):
    """(τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂z, ∂τ/∂ω̇) of the pd/pid law of joint i (row i of ``gain``)
    with the moment feedback solved in closed form (:func:`dttmm.control.pd_torque`)."""
    return _pd_torque(
        gain[i, KP],
        gain[i, KD],
        gain[i, KI],
        gain[i, GM],
        gain[i, LIMIT],
        gain[i, JHUB],
        ff,
        a_ref,
        r_ref,
        z,
        alpha,
        rate,
        omega_dot,
    )


@njit(nrt=False, inline="always")
def root_omega_dot(md, data, i):
    """ω̇ of link i's root cross-section from the last Riccati sweep."""
    return data.a[i * md.k, 2]


@njit(nrt=False, inline="always")
def inboard(md, data, x, i):
    """y_i = ω̇_i − α̈_i of the last sweep (x: its q̈)."""
    return data.a[i * md.k, 2] - x[md.i_alpha[i]]


@njit(nrt=False, inline="always")
def step_law(md, data, drv, s, state, ws, h, cq, cv, i, final):
    """Law of closed-loop joint i at the Newmark iterate (ws.qi, ws.qdi, ws.x) of step s (size
    h) with ω̇ from the last sweep. Sets the sweep's inputs ws.taul[i] = τ_k − s α̈_k and
    ws.acc[i] = s; with ``final``, the law's τ into ws.torque[i] and (z, e) of t_{n+1} into
    (ws.zs[i], ws.zsum[i]). Returns τ_k."""
    ia = md.i_alpha[i]
    err = drv.ref_left[s, i, 0] - ws.qi[ia]
    z = state.z[i] + 0.5 * h * (state.zerr[i] + err)
    tau, d_a, d_r, d_z, d_w = pd_torque(
        drv.gain,
        i,
        drv.ff_left[s, i],
        drv.ref_left[s, i, 0],
        drv.ref_left[s, i, 1],
        z,
        ws.qi[ia],
        ws.qdi[ia],
        root_omega_dot(md, data, i),
    )
    slope = d_a * cq + d_r * cv - d_z * (0.5 * h * cq) + d_w
    ws.acc[i] = slope
    ws.taul[i] = tau - slope * ws.x[ia]
    ws.dw[i] = d_w
    ws.yk[i] = inboard(md, data, ws.x, i)
    if final:
        ws.torque[i] = tau
        ws.zs[i] = z
        ws.zsum[i] = err
    return tau


@njit(nrt=False, inline="always")
def step_laws(md, data, drv, s, state, ws, h, cq, cv, final):
    """:func:`step_law` for every closed-loop joint (the others keep ws.taul = their τ)."""
    for i in range(md.n):
        if drv.code[i] == CODE_PD:
            step_law(md, data, drv, s, state, ws, h, cq, cv, i, final)
    out = ws.torque if final else ws.torque_r  # ws.torque: the last sweep's, the moments
    user_laws(md, data, drv, drv.t_end[s], ws.qi, ws.qdi, ws.x, cq, cv, ws, ws.torque, out, False)


@njit(nrt=False, inline="always")
def state_laws(md, data, drv, t, ff, ref, z, q, qd, x, ws, first, torque):
    """Laws of the closed-loop joints at the state (q, q̇) with integral states z (n,) and the
    laws of time ``ff`` (n,), ``ref`` (n, 2), linearised in α̈ through ω̇ only (the forward
    dynamics). ``first``: no sweep at this state yet, ω̇ and α̈ of the iterate taken as 0.
    Sets ws.taul, ws.acc and the law's τ in ``torque`` of those joints; returns whether any
    law depends on ω̇ (user laws: on the moment). ``t``: the time (user laws)."""
    loop = user_laws(md, data, drv, t, q, qd, x, 0.0, 0.0, ws, torque, torque, first)
    for i in range(md.n):
        if drv.code[i] != CODE_PD:
            continue
        ia = md.i_alpha[i]
        wd = 0.0 if first else root_omega_dot(md, data, i)
        ak = 0.0 if first else x[ia]
        tau, _da, _dr, _dz, d_w = pd_torque(drv.gain, i, ff[i], ref[i, 0], ref[i, 1], z[i], q[ia], qd[ia], wd)
        ws.acc[i] = d_w
        ws.taul[i] = tau - d_w * ak
        ws.dw[i] = d_w
        ws.yk[i] = 0.0 if first else inboard(md, data, x, i)
        torque[i] = tau
        loop |= drv.gain[i, GM] * drv.gain[i, JHUB] != 0.0
    return loop


# --- moment feedback through the inboard link ----------------------------------------------
# ω̇_i = y_i + α̈_i, where y_i (the tip of link i − 1) responds strongly to τ_i itself (the
# reaction on the light tip element of the inboard link): holding y_i at the iterate diverges
# (measured: a factor −6.7 per sweep on the closed-loop three-link arm at g_M = 0.5, k = 2).
# The sweep is affine in its joint torques τ' at fixed gains, y = y_B + A (τ' − B) about a base
# input B with output y_B; the law τ' = T + D (y − y_k) (T = τ_k − s α̈_k, D = diag ∂τ/∂ω̇) then
# gives (I − D A)(τ' − B) = T − B + D (y_B − y_k), an n × n solve per sweep. A is measured by
# n_closed + 1 sweeps at the first sweep of a step (and at every forward-dynamics solve).


#: a Newmark step measures A anew every this many steps (and after a restart); in between
#: the A of an earlier step serves (it only sets the rate of convergence, not the solution)
A_EVERY = 8


@njit(nrt=False, inline="always")
def n_sensitivity(md, drv):
    """Sweeps that measuring A takes: one per closed-loop joint, and the base."""
    m = 1
    for i in range(md.n):
        if drv.code[i] == CODE_PD:
            m += 1
    return m


#: the closed-loop correction of the sweep torques (:func:`dttmm.control.correct_torques`, on ws)
correct = njit(nrt=False, inline="always")(control.correct_torques)


# --- user laws: Python callables (engine "python"), numba-jitted laws (both engines) ----------------------------------------------------
if PURE:

    def user_laws(md, data, drv, t, q, qd, x, cq, cv, ws, tsweep, torque, first):
        """User laws (code CODE_USER) at the iterate (q, q̇, q̈ = x) at time t: each law sees a
        :class:`dttmm.drives.ControlState` (a numba-jitted law: a
        :class:`dttmm.kernel.userlaw.JitState`) (its moment: M_root = τ − J_hub ω̇ of the last sweep,
        τ from ``tsweep``, 0 before the first; integral 0; every joint's angle and rate; every link's tip
        deflection in its clamped-root frame) and is linearised with s = ∂τ/∂α c_q + ∂τ/∂α̇ c_v
        into ws.acc, ws.taul = τ − s α̈_k; its τ goes to ``torque``. Returns whether there is
        one (its moment dependence is resolved by repeating the sweeps)."""
        import numpy as np

        from ..result import tip_deflection
        from .recorder import sample

        if not any(drv.code[i] == CODE_USER for i in range(md.n)):
            return False
        ia = md.i_alpha
        n = md.n
        scratch = _Sample(np.zeros((1, n, 2)), np.zeros((1, n, 2)), np.zeros((1, n)), np.zeros(0))
        sample(md, q, qd, 0, scratch)
        tips = tuple(float(v) for v in tip_deflection(scratch.root[0], scratch.root_angle[0], scratch.tip[0]))
        angles = tuple(float(q[j]) for j in ia)
        rates = tuple(float(qd[j]) for j in ia)
        for i in range(n):
            if drv.code[i] != CODE_USER:
                continue
            wd = 0.0 if first else root_omega_dot(md, data, i)
            moment = 0.0 if first else tsweep[i] - drv.gain[i, JHUB] * wd
            tau, slope = control.user_law_torque(drv.user[i], t, i, angles, rates, tips, moment, cq, cv)
            ws.acc[i] = slope
            ws.taul[i] = tau - slope * (0.0 if first else x[ia[i]])
            ws.dw[i] = 0.0
            torque[i] = tau
        return True

    class _Sample:
        """The rows of a Record that :func:`dttmm.kernel.recorder.sample` writes."""

        def __init__(self, root, tip, root_angle, energy):
            self.root, self.tip, self.root_angle, self.energy = root, tip, root_angle, energy

else:
    import math

    from numba import types
    from numba.extending import overload

    from .recorder import sample

    #: a jitted law's torque and slope (:func:`dttmm.control.jit_user_torque`)
    _jit_user = njit(nrt=False, inline="always")(control.jit_user_torque)

    def user_laws(md, data, drv, t, q, qd, x, cq, cv, ws, tsweep, torque, first):
        """The user laws of the compiled kernel (numba-jitted laws in ``drv.user``, a
        :class:`dttmm.kernel.userlaw.UserTables`), as in the uncompiled kernel; compiled by the
        overload below, a no-op returning False where ``drv.user`` is an array (no user law)."""
        raise NotImplementedError  # pragma: no cover - only ever compiled

    @overload(user_laws, jit_options={"_nrt": False, "boundscheck": False})
    def _user_laws(md, data, drv, t, q, qd, x, cq, cv, ws, tsweep, torque, first):
        if isinstance(drv.types[drv.fields.index("user")], types.Array):
            # open-loop and pd/pid runs: their kernel has no user-law code at all

            def none(md, data, drv, t, q, qd, x, cq, cv, ws, tsweep, torque, first):
                return False

            return none

        def laws(md, data, drv, t, q, qd, x, cq, cv, ws, tsweep, torque, first):
            u = drv.user
            ia = md.i_alpha
            sample(md, q, qd, 0, u)
            for j in range(md.n):
                th = u.root_angle[0, j]
                dx = u.tip[0, j, 0] - u.root[0, j, 0]
                dy = u.tip[0, j, 1] - u.root[0, j, 1]
                u.tips[j] = -math.sin(th) * dx + math.cos(th) * dy
                u.angles[j] = q[ia[j]]
                u.rates[j] = qd[ia[j]]
            for i in range(md.n):
                if drv.code[i] != CODE_USER:
                    continue
                moment = 0.0
                ak = 0.0
                if not first:
                    moment = tsweep[i] - drv.gain[i, JHUB] * root_omega_dot(md, data, i)
                    ak = x[ia[i]]
                tau, slope = _jit_user(u.fns[u.slot[i]], t, i, moment, u.angles, u.rates, u.tips, cq, cv)
                ws.acc[i] = slope
                ws.taul[i] = tau - slope * ak
                ws.dw[i] = 0.0
                torque[i] = tau
            return True

        return laws
