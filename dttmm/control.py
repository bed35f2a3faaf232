"""Closed-loop drives as the engines execute them: per-joint gains, per-step tables of the laws
of time, the PD/PID torque with its algebraic moment loop solved, and the rigid-model inverse
dynamics behind the ``computed_torque`` feedforward.

The law of a ``pd``/``pid`` joint i (see :class:`dttmm.drives.PD`) is

    τ = clip(L0 − g_M M_root, ±limit),  L0 = τ_ff(t) + kp (α_ref − α) + kd (α̇_ref − α̇) + ki z.

The hub is a rigid body at the joint that turns with the root cross-section of the link, so its
moment balance about the joint gives the root bending moment exactly: M_root = τ − J_hub ω̇
(ω̇: the absolute angular acceleration of the link root). The loop τ ↔ M_root therefore has the
closed-form solution

    τ = clip((L0 + g_M J_hub ω̇) / (1 + g_M), ±limit),

valid saturated or not (g_M > −1), which :func:`pd_torque` evaluates with its slopes. Every
engine that integrates the flexible arm (DT-TMM, the global solver) solves this equation
implicitly at the step end; docs/control.md gives the time discretisation.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .control_state import ControlState, JitState
from .drives import PD, ComputedTorque, UserLaw, reference_of
from .errors import InputError

__all__ = [
    "CODE_OPEN",
    "CODE_PD",
    "CODE_USER",
    "Gains",
    "computed_torque",
    "gains",
    "pd_torque",
    "rigid_inverse_dynamics",
    "time_tables",
]

#: law codes of :class:`Gains`: open-loop torque or motion drive, pd/pid, user law
CODE_OPEN, CODE_PD, CODE_USER = 0, 1, 2


class Gains(NamedTuple):
    """Per-joint constants of the drive laws, (n,) arrays (zeros where not applicable)."""

    code: np.ndarray  # int64: CODE_OPEN, CODE_PD or CODE_USER
    kp: np.ndarray  # N·m/rad
    kd: np.ndarray  # N·m·s/rad
    ki: np.ndarray  # N·m/(rad·s), 0 for pd
    moment_gain: np.ndarray  # 1
    limit: np.ndarray  # N·m, inf where none
    j_hub: np.ndarray  # kg·m², hub inertia of the link (0 without hub)


def gains(case) -> Gains:
    """The :class:`Gains` of every joint of ``case``."""
    drives = case.scenario.drives
    n = len(drives)
    g = Gains(
        code=np.zeros(n, np.int64),
        kp=np.zeros(n),
        kd=np.zeros(n),
        ki=np.zeros(n),
        moment_gain=np.zeros(n),
        limit=np.full(n, np.inf),
        j_hub=np.array([lk.hub_inertia for lk in case.model.links], float),
    )
    for i, d in enumerate(drives):
        law = d.law
        if isinstance(law, UserLaw):
            g.code[i] = CODE_USER
        elif isinstance(law, PD):  # PID is a PD
            g.code[i] = CODE_PD
            g.kp[i], g.kd[i], g.ki[i] = law.kp, law.kd, law.gain_integral
            g.moment_gain[i], g.limit[i] = law.moment_gain, law.limit
    return g


def time_tables(case, times, left: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The laws of time of every joint on ``times`` (nt,), left limits if ``left``.

    Returns
    -------
    ff : (nt, n)
        pd/pid joints: the feedforward torque τ_ff(t) (0 without one; the rigid inverse dynamics
        for ``computed_torque``); open-loop torque joints: their torque τ(t); else 0.
    ref : (nt, n, 2)
        pd/pid joints: (α_ref, α̇_ref); else 0.
    """
    times = np.asarray(times, float).reshape(-1)
    drives = case.scenario.drives
    nt, n = times.size, len(drives)
    ff, ref = np.zeros((nt, n)), np.zeros((nt, n, 2))
    ct = None
    for i, d in enumerate(drives):
        law = d.law
        if d.kind == "motion" or isinstance(law, UserLaw):
            continue
        if not isinstance(law, PD):
            ff[:, i] = [law(t, left) for t in times]
            continue
        ref[:, i] = [law.reference.motion(t, left)[:2] for t in times]
        if isinstance(law.feedforward, ComputedTorque):
            if ct is None:
                ct = computed_torque(case, times, left)
            ff[:, i] = ct[:, i]
        elif law.feedforward is not None:
            ff[:, i] = [law.feedforward(t, left) for t in times]
    return ff, ref


def pd_torque(kp, kd, ki, gm, limit, j_hub, ff, a_ref, r_ref, z, alpha, rate, omega_dot):
    """The pd/pid torque with its moment loop solved, and its slopes.

    τ = clip((τ_ff + kp (α_ref − α) + kd (α̇_ref − α̇) + ki z + g_M J_hub ω̇) / (1 + g_M), ±limit).

    Returns (τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂z, ∂τ/∂ω̇); beyond the limit the slopes are 0 (at exactly
    ±limit the unsaturated ones). Plain scalar arithmetic: numba compiles it as it is.
    """
    inv = 1.0 / (1.0 + gm)
    gj = gm * j_hub
    u = (ff + kp * (a_ref - alpha) + kd * (r_ref - rate) + ki * z + gj * omega_dot) * inv
    if abs(u) > limit:
        return (limit if u > 0.0 else -limit), 0.0, 0.0, 0.0, 0.0
    return u, -kp * inv, -kd * inv, ki * inv, gj * inv


def correct_torques(md, drv, w):
    """The sweep torques of the closed-loop (pd/pid) joints that satisfy their laws linearised
    about a base sweep: w.taul ← B + δ with (I − D A) δ = T − B + D (H_B − H_k), from
    τ' = T + D (H(τ') − H_k) and H(τ') = H_B + A (τ' − B) (T in w.taul, B in w.tb, H_B in w.yb,
    H_k in w.yk, D = ∂τ/∂H in w.dw, A = ∂H/∂τ in w.amat; H the law's sweep input, the root
    moment for moment feedback). Gaussian elimination with partial pivoting in w.gmat
    (n, n + 1). ``md.n``: the joints; ``drv.code``: CODE_PD marks the joints it acts on. Plain
    loops over arrays: both kernels compile it as it is (docs/control.md)."""
    n = md.n
    g = w.gmat
    for i in range(n):
        cl = drv.code[i] == CODE_PD
        for j in range(n):
            g[i, j] = 1.0 if i == j else 0.0
            if cl and drv.code[j] == CODE_PD:
                g[i, j] -= w.dw[i] * w.amat[i, j]
        g[i, n] = w.taul[i] - w.tb[i] + w.dw[i] * (w.yb[i] - w.yk[i]) if cl else 0.0
    for c in range(n):
        p = c
        for r in range(c + 1, n):
            if abs(g[r, c]) > abs(g[p, c]):
                p = r
        if p != c:
            for j in range(n + 1):
                g[c, j], g[p, j] = g[p, j], g[c, j]
        piv = g[c, c]
        for r in range(c + 1, n):
            f = g[r, c] / piv
            if f != 0.0:
                for j in range(c, n + 1):
                    g[r, j] -= f * g[c, j]
    for r in range(n - 1, -1, -1):
        v = g[r, n]
        for j in range(r + 1, n):
            v -= g[r, j] * g[j, n]
        g[r, n] = v / g[r, r]
    for i in range(n):
        if drv.code[i] == CODE_PD:
            w.taul[i] = w.tb[i] + g[i, n]


def rk4_integral(n, code, ia, z, ref, q, w, c, zsum, zs):
    """The integral states of the pd/pid joints (``code`` CODE_PD; α of joint i at q[ia[i]]) at
    an RK4 stage: ż = α_ref − α of the stage state q (its reference ``ref`` (n, 2)) enters the
    sum ``zsum`` with weight w, and the next stage's zs = z_n + c ż. Plain loops over arrays:
    both kernels compile it as it is."""
    for i in range(n):
        if code[i] == CODE_PD:
            zd = ref[i, 0] - q[ia[i]]
            zsum[i] += w * zd
            zs[i] = z[i] + c * zd


def jit_user_torque(fn, t, joint, moment, angles, rates, tips, cq, cv):
    """(τ, s) of the numba-jitted user law ``fn`` at time t as the compiled kernels evaluate
    it: it sees the :class:`JitState` of ``joint`` (root moment ``moment``, integral 0, the
    arrays of every joint's angle and rate and every link's tip deflection); s = ∂τ/∂α c_q +
    ∂τ/∂α̇ c_v is its slope along the step's α̈. Plain code: both kernels compile it as it is."""
    tau, d_a, d_r = fn(
        t, JitState(joint, angles[joint], rates[joint], moment, 0.0, angles, rates, tips, np.nan)
    )
    return tau, d_a * cq + d_r * cv


# --- the rigid model -------------------------------------------------------------------------
def user_law_torque(law, t, joint, angles, rates, tips, moment, cq, cv):
    """(τ, s) of the user law ``law`` at time t as the uncompiled kernels evaluate it: it sees a
    :class:`dttmm.control_state.ControlState` of ``joint`` (a numba-jitted law its
    :class:`JitState`) with the root moment ``moment``, integral 0, every joint's angle and rate
    and every link's tip deflection ``tips``; s = ∂τ/∂α c_q + ∂τ/∂α̇ c_v is its slope along the
    step's α̈ (c_q, c_v: the integrator's dα/dα̈, dα̇/dα̈)."""
    state = ControlState(
        joint=joint,
        angle=angles[joint],
        rate=rates[joint],
        moment=float(moment),
        integral=0.0,
        angles=angles,
        rates=rates,
        tip_deflections=tips,
    )
    tau, d_a, d_r, _ = law.evaluate(float(t), state)
    return tau, d_a * cq + d_r * cv


def _rigid_links(case):
    """Per link: length L, mass m, first moment about the joint along the link s and across it
    s_y, and inertia I about the joint of the rigid link (hub + uniform rod or the rigid link's
    body + payload, its centre of mass offset in the tip frame)."""
    rows = []
    for lk in case.model.links:
        L, m_p = lk.beam.length, lk.payload_mass
        ox, oy = lk.payload_offset
        if lk.rigid:
            b = lk.beam
            cx, cy = b.com
            m = lk.hub_mass + b.mass + m_p
            s = b.mass * cx + m_p * (L + ox)
            sy = b.mass * cy + m_p * oy
            inertia = (
                lk.hub_inertia
                + b.inertia
                + b.mass * (cx * cx + cy * cy)
                + lk.payload_inertia
                + m_p * ((L + ox) ** 2 + oy * oy)
            )
            rows.append((L, m, s, inertia, sy))
            continue
        m_rod = lk.beam.mass
        m = lk.hub_mass + m_rod + m_p
        s = m_rod * L / 2.0 + m_p * L
        inertia = lk.hub_inertia + m_rod * L * L / 3.0 + m_p * L * L + lk.payload_inertia
        sy = 0.0
        if ox or oy:
            s += m_p * ox
            sy = m_p * oy
            inertia += m_p * (2.0 * L * ox + ox * ox + oy * oy)
        rows.append((L, m, s, inertia, sy))
    return np.array(rows, float)


def rigid_inverse_dynamics(case, q, qd, qdd) -> np.ndarray:
    """Joint torques (..., n) of the rigid arm (every link a rigid uniform rod with its hub and
    payload, the case's gravity) at joint angles, rates and accelerations (..., n): the
    recursive Newton–Euler equations of a planar serial chain, vectorised over leading axes."""
    q, qd, qdd = (np.asarray(x, float) for x in (q, qd, qdd))
    par = _rigid_links(case)
    n = par.shape[0]
    shape = np.broadcast_shapes(q.shape, qd.shape, qdd.shape)
    if shape[-1:] != (n,):
        raise InputError("q", q.shape, f"must end with the number of joints, {n}")
    lead = shape[:-1]
    th = np.cumsum(np.broadcast_to(q, shape), axis=-1)
    w = np.cumsum(np.broadcast_to(qd, shape), axis=-1)
    wd = np.cumsum(np.broadcast_to(qdd, shape), axis=-1)
    g = np.asarray(case.model.gravity, float)
    a = np.broadcast_to(-g, (*lead, 2)).copy()  # joint-origin acceleration, gravity as a base acceleration
    acc_origin, e_axis = [], []
    for i in range(n):
        L = par[i, 0]
        e = np.stack([np.cos(th[..., i]), np.sin(th[..., i])], axis=-1)
        ep = np.stack([-e[..., 1], e[..., 0]], axis=-1)
        acc_origin.append(a)
        e_axis.append(e)
        a = a + L * (wd[..., i, None] * ep - (w[..., i] ** 2)[..., None] * e)
    cross = lambda u, v: u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    f_out = np.zeros((*lead, 2))  # force on the outboard link through the next joint
    n_out = np.zeros(lead)  # moment on it
    tau = np.zeros((*lead, n))
    for i in range(n - 1, -1, -1):
        L, m, s, inertia, sy = par[i]
        e, a0 = e_axis[i], acc_origin[i]
        ep = np.stack([-e[..., 1], e[..., 0]], axis=-1)
        # m × the acceleration of the centre of mass (at s/m along the link)
        f_in = m * a0 + (s * wd[..., i, None]) * ep - (s * w[..., i] ** 2)[..., None] * e + f_out
        # moments about joint i: I ω̇ + s e × a_0 + L e × f_out + n_out
        n_in = inertia * wd[..., i] + s * cross(e, a0) + L * cross(e, f_out) + n_out
        if sy:  # the part s_y e⊥ of the first moment across the link
            f_in = f_in - (sy * wd[..., i, None]) * e - (sy * w[..., i] ** 2)[..., None] * ep
            n_in = n_in + sy * cross(ep, a0)
        tau[..., i] = n_in
        f_out, n_out = f_in, n_in
    return tau


def computed_torque(case, t, left: bool = False) -> np.ndarray:
    """The ``computed_torque`` feedforward: rigid inverse dynamics along the references of all
    joints (a motion drive's law, a pd/pid law's reference) at time(s) ``t``. A spatial case
    (one drive per unlocked joint) takes the spatial rigid arm's recursive Newton–Euler
    (:func:`dttmm.spatial.inverse_dynamics.rigid_inverse_dynamics`).

    Returns (n,) for a scalar t, (nt, n) for an array.
    """
    refs = [reference_of(d) for d in case.scenario.drives]
    for i, r in enumerate(refs):
        if r is None:
            d = case.scenario.drives[i]
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.name,
                "the computed_torque feedforward needs a reference motion on every joint "
                "(a motion drive or a pd/pid drive)",
            )
    ts = np.asarray(t, float)
    flat = ts.reshape(-1)
    m = np.array([[r.motion(float(tt), left) for r in refs] for tt in flat]).reshape(flat.size, len(refs), 3)
    if _is_spatial(case):
        from .spatial.inverse_dynamics import rigid_inverse_dynamics as spatial_rnea

        tau = spatial_rnea(case.model, m[..., 0], m[..., 1], m[..., 2])
    else:
        tau = rigid_inverse_dynamics(case, m[..., 0], m[..., 1], m[..., 2])
    return tau[0] if ts.ndim == 0 else tau


def _is_spatial(case) -> bool:
    """A spatial arm (its model lists its unlocked joints): the feedforward is the spatial
    recursive Newton–Euler of :mod:`dttmm.spatial.inverse_dynamics`."""
    return hasattr(case.model, "unlocked")
