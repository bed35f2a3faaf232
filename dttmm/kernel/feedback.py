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

import math

from ._jit import njit

#: columns of Drives.gain
KP, KD, KI, GM, LIMIT, JHUB = range(6)
#: Drives.code of a pd/pid joint
CODE_PD = 1


@njit(nrt=False, inline="always")
def pd_torque(gain, i, ff, a_ref, r_ref, z, alpha, rate, omega_dot):
    """(τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂z, ∂τ/∂ω̇) of the pd/pid law of joint i (row i of ``gain``)
    with the moment feedback solved in closed form; all slopes zero beyond the limit."""
    kp = gain[i, KP]
    kd = gain[i, KD]
    ki = gain[i, KI]
    gm = gain[i, GM]
    jh = gain[i, JHUB]
    l0 = ff + kp * (a_ref - alpha) + kd * (r_ref - rate) + ki * z
    inv = 1.0 / (1.0 + gm)
    tau = (l0 + gm * jh * omega_dot) * inv
    lim = gain[i, LIMIT]
    if abs(tau) > lim:
        return math.copysign(lim, tau), 0.0, 0.0, 0.0, 0.0
    return tau, -kp * inv, -kd * inv, ki * inv, gm * jh * inv


@njit(nrt=False, inline="always")
def root_omega_dot(md, dt, i):
    """ω̇ of link i's root cross-section from the last Riccati sweep."""
    return dt.a[i * md.k, 2]


@njit(nrt=False, inline="always")
def step_law(md, dt, drv, s, st, ws, h, cq, cv, i, final):
    """Law of closed-loop joint i at the Newmark iterate (ws.qi, ws.qdi, ws.x) of step s (size
    h) with ω̇ from the last sweep. Sets the sweep's inputs ws.taul[i] = τ_k − s α̈_k and
    ws.acc[i] = s; with ``final``, the law's τ into ws.torque[i] and (z, e) of t_{n+1} into
    (ws.zs[i], ws.zsum[i]). Returns τ_k."""
    ia = md.i_alpha[i]
    err = drv.ref_left[s, i, 0] - ws.qi[ia]
    z = st.z[i] + 0.5 * h * (st.zerr[i] + err)
    tau, d_a, d_r, d_z, d_w = pd_torque(
        drv.gain,
        i,
        drv.ff_left[s, i],
        drv.ref_left[s, i, 0],
        drv.ref_left[s, i, 1],
        z,
        ws.qi[ia],
        ws.qdi[ia],
        root_omega_dot(md, dt, i),
    )
    slope = d_a * cq + d_r * cv - d_z * (0.5 * h * cq) + d_w
    ws.acc[i] = slope
    ws.taul[i] = tau - slope * ws.x[ia]
    if final:
        ws.torque[i] = tau
        ws.zs[i] = z
        ws.zsum[i] = err
    return tau


@njit(nrt=False, inline="always")
def step_laws(md, dt, drv, s, st, ws, h, cq, cv, final):
    """:func:`step_law` for every closed-loop joint (the others keep ws.taul = their τ)."""
    for i in range(md.n):
        if drv.code[i] == CODE_PD:
            step_law(md, dt, drv, s, st, ws, h, cq, cv, i, final)


@njit(nrt=False, inline="always")
def state_laws(md, dt, drv, ff, ref, z, q, qd, x, ws, first, torque):
    """Laws of the closed-loop joints at the state (q, q̇) with integral states z (n,) and the
    laws of time ``ff`` (n,), ``ref`` (n, 2), linearised in α̈ through ω̇ only (the forward
    dynamics). ``first``: no sweep at this state yet, ω̇ and α̈ of the iterate taken as 0.
    Sets ws.taul, ws.acc and the law's τ in ``torque`` of those joints; returns whether any
    law depends on ω̇."""
    loop = False
    for i in range(md.n):
        if drv.code[i] != CODE_PD:
            continue
        ia = md.i_alpha[i]
        wd = 0.0 if first else root_omega_dot(md, dt, i)
        ak = 0.0 if first else x[ia]
        tau, _da, _dr, _dz, d_w = pd_torque(drv.gain, i, ff[i], ref[i, 0], ref[i, 1], z[i], q[ia], qd[ia], wd)
        ws.acc[i] = d_w
        ws.taul[i] = tau - d_w * ak
        torque[i] = tau
        loop |= drv.gain[i, GM] * drv.gain[i, JHUB] != 0.0
    return loop
