"""The time loop of the spatial kernel: Newmark family (generalised-α in the Arnold–Brüls form)
on q with implicit elastic and damping forces and the suite's stop rule (``iterations="auto"``:
with the planar kernel's contraction test), or RK4 on the acceleration solver; closed-loop
drive laws (pd, pid, user laws) solved with the step as in the planar kernel
(:mod:`dttmm.kernel.feedback`); output sampling on the grid by cubic Hermite interpolation
between step ends (q from (q, q̇), q̇ from (q̇, q̈), torques linear).

**Closed-loop joints.** The law of joint i is τ = clip(L0 − g_M M_root, ±limit) (docs/control.md)
with M_root the component along the joint axis a of the moment the hub exerts on the beam at
the link's root cross-section. The hub's moment balance about the root point gives it exactly,
M_root = τ − H, H = a·(J_h ω̇ + ω × J_h ω) (root element-frame components, ω̇ the angular
acceleration of the link root), so τ = clip((L0 + g_M H)/(1 + g_M), ±limit)
(:func:`dttmm.control.pd_torque` with J_hub = 1 and ω̇ → H). A Newmark step evaluates it at
t_{n+1} with the state there (z by the trapezoidal rule); each sweep sees the law linearised
at the latest iterate, τ ≈ τ_k + s (α̈ − α̈_k) + ∂τ/∂H (H − H_k), s = ∂τ/∂α c_q + ∂τ/∂α̇ c_v −
∂τ/∂z h c_q/2, which the sweep takes as a joint stiffness (``ws.slope``). H responds to the
joint torques themselves (the joint's own and, through the inboard links, the others'); the
sweep is affine in its torques, so with moment feedback the torques of every sweep are
corrected through the measured sensitivity ∂H/∂τ (:func:`correct`, the planar kernel's scheme
for its inboard part; here for the whole H, whose own-α̈ part as a slope would make the
articulated inertia of the inboard link indefinite at the acceleration level). The converged
step satisfies the law exactly. User laws see a
:class:`dttmm.drives.ControlState` (a numba-jitted law a :class:`dttmm.drives.JitState`):
``joint`` the drive's index, ``angles``/``rates`` of every unlocked joint, ``tip_deflections``
of every link (the component along the link frame's y axis), ``moment`` = τ_sweep − H of the
last sweep, ``integral`` 0.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ... import control
from ...iteration import change_and_size, residual_ratio, stop_rule
from ._jit import PURE, njit
from .core import LOAD_COL, cross, kinematics, mv, set_rates, sweep, tip_frames

_stop_rule = njit(inline="always")(stop_rule)
_change_and_size = njit(inline="always")(change_and_size)
_residual_ratio = njit(inline="always")(residual_ratio)
#: the law itself, compiled from dttmm.control (its source is part of the kernel's cache key)
_pd_torque = njit(inline="always")(control.pd_torque)

INT_NEWMARK, INT_RK4 = 0, 1
IT_TOL, IT_FIXED, IT_AUTO = 0, 1, 2
ST_OK, ST_NONFINITE, ST_SINGULAR, ST_RUNAWAY = 0, 1, 2, 3
#: an elastic rotation beyond this (rad) or a displacement beyond this many element lengths
#: stops the run: the state is diverging
RUNAWAY_ANGLE, RUNAWAY_LENGTHS = 2.0 * np.pi, 10.0
#: law codes per link (dttmm.control): open loop, pd/pid, user law
CODE_OPEN, CODE_PD, CODE_USER = control.CODE_OPEN, control.CODE_PD, control.CODE_USER
#: columns of Drives.gain: kp, kd, ki, g_M, limit, 1 where the hub has an inertia
KP, KD, KI, GM, LIMIT, HASJ = range(6)
#: a Newmark step measures the sensitivity ∂H/∂τ anew every this many steps (and after a restart)
A_EVERY = 8
#: the closures' W anew every this many steps (and after a restart); between, W is extrapolated
#: from the last two measurements (:func:`closure_predict`). Measured on the four-bar (sweeps
#: per step, k = 2 over 200 steps / k = 8 over 100): every 8: 4.42 / 4.27, 16: 4.22 / 4.06,
#: 24: 4.24, 32: 4.30
W_EVERY = 16
#: with loop closures, W is measured anew at the next iteration of a step whose iterates stop
#: contracting by this factor (max|Δq̈| above W_STALE × the previous one's, above the round-off
#: floor of the stop rule)
W_STALE = 0.5
#: with loop closures, iterates contracting by this factor or more (max|Δq̈| of the iteration
#: against the previous one's, from the third sweep on) stop once the change still to come is
#: within the round-off floor (:func:`closure_left`). Sweeps per step on the four-bar, k = 2,
#: 200 steps: 4.22 without, 3.40 with; five-bar 100 steps: 5.15, 3.94
CONTRACTED = 0.1
#: a closure gap within this many units of round-off (of the coordinates of its points; of 1
#: for the angle rows) counts as closed: the position-level condition amplifies a gap by 1/c_q
#: in q̈, and chasing the round-off holds the iteration above the stop rule's floor. 0: off (1
#: saves a fifth of the four-bar's sweeps but leaves its closure loads 1.4e-8 of their largest
#: from the global solver's, against 3.8e-9 at 0)
GAP_ULPS = 0.0
EPS = np.finfo(np.float64).eps
#: stats slots (int64): sweeps, max sweeps, unconverged steps, status, failed step, samples
#: written, forward-dynamics solves out of sweeps, residual checks, flagged checks, step of the
#: first flag, step of the worst ratio; fstats (float): worst ratio, its relative residual
S_SWEEPS, S_MAX, S_UNCONV, S_STATUS, S_FAILED, S_SAMPLES = range(6)
S_FD_UNCONV, S_CHECKS, S_FLAGGED, S_FIRST_FLAG, S_WORST = range(6, 11)
N_STATS = 11


class Options(NamedTuple):
    """Run settings."""

    integrator: int  # INT_NEWMARK or INT_RK4
    beta: float
    gamma: float
    alpha_m: float
    alpha_f: float
    tol: float
    max_it: int
    iteration: int  # IT_TOL, IT_FIXED or IT_AUTO
    n_fixed: int  # IT_FIXED: sweeps per step − 1
    auto_fraction: float
    lte: float  # |β − 1/6|/β
    check_every: int  # fixed counts and "auto": residual check every this many steps (0: never)
    closed: bool  # some joint has a closed-loop law
    coupled: bool  # some pd/pid joint has moment feedback on a hub inertia (:func:`correct`)


class Drives(NamedTuple):
    """Drive values per step, per link (the laws are Python objects, evaluated beforehand):
    torques (n_steps, n) and motions (n_steps, n, 3) at the step end (left limits), the right
    limits at restart steps (row n_steps: t = 0), the mid-step values (RK4). Closed-loop links
    have ``code`` CODE_PD or CODE_USER, the constants ``gain`` (n, 7) and, at the same instants,
    the feedforward ``ff_*`` (·, n) and the reference (α_ref, α̇_ref) ``ref_*`` (·, n, 2);
    ``user``: the user laws (engine "python": a tuple, None where not; compiled: a
    :class:`dttmm.kernel.userlaw.UserTables`), else an empty array."""

    t_end: np.ndarray
    restart: np.ndarray
    tau_l: np.ndarray
    mot_l: np.ndarray
    tau_r: np.ndarray
    mot_r: np.ndarray
    tau_m: np.ndarray
    mot_m: np.ndarray
    code: np.ndarray
    gain: np.ndarray
    ff_l: np.ndarray
    ref_l: np.ndarray
    ff_r: np.ndarray
    ref_r: np.ndarray
    ff_m: np.ndarray
    ref_m: np.ndarray
    user: object


class Closures(NamedTuple):
    """The loop closures (docs/spatial.md "Trees and closed loops"), nc of them with m
    equations in all: their data fixed at the initial state (dttmm.spatial.topology) and the
    scratch of their solve; λ (6 per closure: force, moment about the closure point, world
    components) is what `to` exerts on `link`."""

    a: np.ndarray  # (nc,) link
    b: np.ndarray  # (nc,) to (−1: the ground)
    kind: np.ndarray  # (nc,) 0 spherical, 1 revolute, 2 weld
    pa: np.ndarray  # (nc, 3) point in a's tip frame
    pb: np.ndarray  # (nc, 3) point in b's tip frame (world for the ground)
    ua: np.ndarray  # (nc, 3) revolute axis, a's tip frame
    ub: np.ndarray  # (nc, 3) its image in b's tip frame
    R0: np.ndarray  # (nc, 3, 3) weld: R_aᵀ R_b at the initial state
    lam: np.ndarray  # (6 nc,) λ of the current iterate
    lamh: np.ndarray  # (n_steps, 6 nc) λ at each step end
    g: np.ndarray  # (m,) the constraint residual at the sweep's q̈ (round-off gaps 0)
    B: np.ndarray  # (6 nc, m) the load directions of the m unknowns
    W: np.ndarray  # (m, m) relative accelerations along the constraints per unit load (kept)
    Wi: np.ndarray  # (m, m) its inverse
    dmu: np.ndarray  # (m,) Δμ (and μ of the re-expression)
    X: np.ndarray  # (m, n_dof) q̈ per unit load of each unknown, measured with W (kept)
    T: np.ndarray  # (m, n) the joints' sweep torques (ws.acc[:, 1]) per unit load (kept)
    tq: np.ndarray  # (n,) those of the sweep with the current λ
    qp: np.ndarray  # (n_dof,) q at the sweep's q̈
    lam1: np.ndarray  # (6 nc,) scratch: λ of a column sweep
    Wlu: np.ndarray  # (m, m) scratch of the inversion
    fr: np.ndarray  # (2, 3, 3) scratch: the two bodies' frames
    v: np.ndarray  # (8, 3) scratch: their origins, points, axes
    state: np.ndarray  # (7,) int64: W is of a Newmark step (1) or not (0); sweeps of the last
    # solve; secant updates of W on (1) or off (0); a previous iterate of this step in gp, dmp (1);
    # measurements kept in Ca… (0, 1, 2); the step of the last (a) and of the one before (b)
    rel0: np.ndarray  # (6 nc,) relative accelerations of the base sweep
    rel: np.ndarray  # (6 nc,)
    motc: np.ndarray  # (n, INPUT_COLS) the inputs with the closure loads
    xs: np.ndarray  # (n_dof,) q̈ of the column sweeps
    gp: np.ndarray  # (m,) the gap of the previous iterate of the step (before its Δμ)
    dmp: np.ndarray  # (m,) its Δμ
    W2: np.ndarray  # (m, m) scratch: W's secant update
    Ca: np.ndarray  # (6 nc, 6 nc) the last measured W in world components, B W Bᵀ
    Cb: np.ndarray  # (6 nc, 6 nc) the one measured before it
    Xa: np.ndarray  # (6 nc, n_dof) the last measured X in world components, B X
    Xb: np.ndarray
    Ta: np.ndarray  # (6 nc, n) the last measured T in world components, B T
    Tb: np.ndarray
    gf: np.ndarray  # (m,) the round-off of each row of g: one unit of its points' coordinates
    nb: np.ndarray  # (1,) the q̈ change a gap of gf moves through the update (the noise floor)


def new_closures(n, ndof, cols, n_steps, a, b, kind, pa, pb, ua, ub, R0, m):
    nc = a.shape[0]
    z = np.zeros
    return Closures(
        a=a, b=b, kind=kind, pa=pa, pb=pb, ua=ua, ub=ub, R0=R0,
        lam=z(6 * nc), lamh=z((n_steps, 6 * nc)), g=z(m), B=z((6 * nc, m)), W=z((m, m)),
        Wi=z((m, m)), dmu=z(m), X=z((m, ndof)), T=z((m, n)), tq=z(n), qp=z(ndof),
        lam1=z(6 * nc), Wlu=z((m, m)), fr=z((2, 3, 3)), v=z((8, 3)),
        state=np.zeros(7, np.int64),
        rel0=z(6 * nc), rel=z(6 * nc), motc=z((n, cols)), xs=z(ndof), gp=z(m), dmp=z(m), W2=z((m, m)),
        Ca=z((6 * nc, 6 * nc)), Cb=z((6 * nc, 6 * nc)), Xa=z((6 * nc, ndof)), Xb=z((6 * nc, ndof)),
        Ta=z((6 * nc, n)), Tb=z((6 * nc, n)), gf=z(m), nb=z(1),
    )  # fmt: skip


def no_closures(n, ndof, cols):
    e = np.zeros((0, 3))
    ei = np.zeros(0, np.int64)
    return new_closures(n, ndof, cols, 0, ei, ei, ei, e, e, e, e, np.zeros((0, 3, 3)), 0)


class Loop(NamedTuple):
    """Scratch of the closed-loop laws, (n,) per link unless stated."""

    taul: np.ndarray  # the sweep's torques (τ_k − s α̈_k at closed-loop joints)
    torque: np.ndarray  # the laws' τ (final evaluation of a step or solve)
    scratch: np.ndarray  # the laws' τ of an intermediate evaluation (not recorded)
    zs: np.ndarray  # z of an RK4 stage; z_{n+1} of a Newmark step
    zsum: np.ndarray  # RK4's weighted sum of ż; e_{n+1} of a Newmark step
    dw: np.ndarray  # ∂τ/∂H at the iterate
    yk: np.ndarray  # H at the iterate, of the base sweep
    yb: np.ndarray
    tb: np.ndarray  # the base sweep's torques
    amat: np.ndarray  # (n, n) ∂y/∂τ' of the sweep
    gmat: np.ndarray  # (n, n + 1) scratch of the solve
    xs: np.ndarray  # (n_dof,) q̈ of the sensitivity sweeps
    xc: np.ndarray  # (n_dof,) previous iterate of the forward dynamics
    fd: np.ndarray  # (2,) forward-dynamics solves out of sweeps, their sweeps
    qddm: np.ndarray  # (n_dof,) q̈ at the start of the previous step (the residual check)
    cl: Closures  # the loop closures (none: a chain or a tree)


def new_loop(n: int, ndof: int, closures: Closures | None = None, cols: int = 15) -> Loop:
    per_link = ("taul", "torque", "scratch", "zs", "zsum", "dw", "yk", "yb", "tb")
    return Loop(
        cl=no_closures(n, ndof, cols) if closures is None else closures,
        amat=np.zeros((n, n)),
        gmat=np.zeros((n, n + 1)),
        fd=np.zeros(2, np.int64),
        **{name: np.zeros(n) for name in per_link},
        **{name: np.zeros(ndof) for name in ("xs", "xc", "qddm")},
    )


# ------------------------------------------------------------------ closed-loop laws --------


@njit()
def hub_moment(md, ws, i):
    """H_i = a·(J_h ω̇ + ω × J_h ω): the hub's inertial moment about link i's joint axis, ω from
    the kinematics in ``ws``, ω̇ from the last sweep (root element-frame components)."""
    el0 = md.el0[i]
    J = md.hub_J[i]
    w = ws.wl[el0]
    Jw = mv(J, w)
    g = cross(w, Jw) + mv(J, ws.wdF[i])
    a = md.aF[i]
    return a[0] * g[0] + a[1] * g[1] + a[2] * g[2]


@njit()
def pd_law(drv, i, ff, a_ref, r_ref, z, alpha, rate, hub):
    """(τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂z, ∂τ/∂H) of the pd/pid law of link i's joint with the moment
    feedback solved in closed form (:func:`dttmm.control.pd_torque`, J_hub ω̇ → H)."""
    g = drv.gain
    return _pd_torque(
        g[i, KP], g[i, KD], g[i, KI], g[i, GM], g[i, LIMIT], 1.0, ff, a_ref, r_ref, z, alpha, rate, hub
    )


@njit()
def link_tips(md, ws, out):
    """Every link's tip deflection along its link frame's y axis (R_link = R_root Rx(roll)ᵀ)
    from the kinematics in ``ws`` into ``out`` (n,)."""
    for i in range(md.n):
        el0 = md.el0[i]
        R = ws.Rw[el0]
        Qi = md.Q[i]
        v = 0.0
        for r in range(3):
            y = R[r, 0] * Qi[1, 0] + R[r, 1] * Qi[1, 1] + R[r, 2] * Qi[1, 2]
            v += (ws.pT[i + 1, r] - ws.pw[el0, r]) * y
        out[i] = v


@njit()
def drive_index(md, i):
    """The index of link i's drive (unlocked joints in order)."""
    j = 0
    for r in range(i):
        if md.locked[r] == 0:
            j += 1
    return j


if PURE:

    def user_laws(md, ws, drv, cw, t, q, qd, x, cq, cv, torque, first):
        """User laws (code CODE_USER) at the iterate (q, q̇, q̈ = x) at time t, the kinematics
        in ``ws`` at (q, q̇): each sees a ControlState (a numba-jitted law a JitState; its moment
        τ_sweep − H of the last sweep, 0 before the first) and is linearised with s = ∂τ/∂α c_q +
        ∂τ/∂α̇ c_v into ws.slope, cw.taul = τ − s α̈_k; its τ goes to ``torque``. Returns whether
        there is one (its moment dependence is resolved by repeating the sweeps)."""
        if not any(drv.code[i] == CODE_USER for i in range(md.n)):
            return False
        tips_a = np.zeros(md.n)
        link_tips(md, ws, tips_a)
        unl = [i for i in range(md.n) if md.locked[i] == 0]
        angles = tuple(float(q[md.ia[i]]) for i in unl)
        rates = tuple(float(qd[md.ia[i]]) for i in unl)
        tips = tuple(float(v) for v in tips_a)
        for i in range(md.n):
            if drv.code[i] != CODE_USER:
                continue
            moment = 0.0 if first else ws.acc[i, 1] - hub_moment(md, ws, i)
            tau, slope = control.user_law_torque(
                drv.user[i], t, drive_index(md, i), angles, rates, tips, moment, cq, cv
            )
            ws.slope[i] = slope
            cw.taul[i] = tau - slope * (0.0 if first else x[md.ia[i]])
            cw.dw[i] = 0.0
            torque[i] = tau
        return True

else:
    from numba import types
    from numba.extending import overload

    #: a jitted law's torque and slope (:func:`dttmm.control.jit_user_torque`)
    _jit_user = njit(inline="always")(control.jit_user_torque)

    def user_laws(md, ws, drv, cw, t, q, qd, x, cq, cv, torque, first):
        """The user laws of the compiled kernel (numba-jitted laws in ``drv.user``, a
        :class:`dttmm.kernel.userlaw.UserTables`), as in the uncompiled kernel; compiled by the
        overload below, a no-op returning False where ``drv.user`` is an array (no user law)."""
        raise NotImplementedError  # pragma: no cover - only ever compiled

    @overload(user_laws)
    def _user_laws(md, ws, drv, cw, t, q, qd, x, cq, cv, torque, first):
        if isinstance(drv.types[drv.fields.index("user")], types.Array):

            def none(md, ws, drv, cw, t, q, qd, x, cq, cv, torque, first):
                return False

            return none

        def laws(md, ws, drv, cw, t, q, qd, x, cq, cv, torque, first):
            u = drv.user
            link_tips(md, ws, u.tips)
            j = 0
            for i in range(md.n):
                if md.locked[i] == 0:
                    u.angles[j] = q[md.ia[i]]
                    u.rates[j] = qd[md.ia[i]]
                    j += 1
            for i in range(md.n):
                if drv.code[i] != CODE_USER:
                    continue
                moment = 0.0
                ak = 0.0
                if not first:
                    moment = ws.acc[i, 1] - hub_moment(md, ws, i)
                    ak = x[md.ia[i]]
                jd = drive_index(md, i)
                tau, slope = _jit_user(u.fns[u.slot[i]], t, jd, moment, u.angles, u.rates, u.tips, cq, cv)
                ws.slope[i] = slope
                cw.taul[i] = tau - slope * ak
                cw.dw[i] = 0.0
                torque[i] = tau
            return True

        return laws


@njit()
def step_laws(md, ws, drv, cw, s, z, zerr, h, cq, cv, qi, qdi, x, final):
    """The laws of the closed-loop joints at the Newmark iterate (qi, q̇i, x) of step s (size h),
    the kinematics in ``ws`` at it and H from the last sweep: ws.slope[i] = s_i,
    cw.taul[i] = τ_k − s_i α̈_k (the sweep's inputs); with ``final`` the laws' τ into cw.torque
    and (z, e) of t_{n+1} into (cw.zs, cw.zsum)."""
    for i in range(md.n):
        if drv.code[i] != CODE_PD:
            continue
        ia = md.ia[i]
        err = drv.ref_l[s, i, 0] - qi[ia]
        zz = z[i] + 0.5 * h * (zerr[i] + err)
        tau, d_a, d_r, d_z, d_w = pd_law(
            drv, i, drv.ff_l[s, i], drv.ref_l[s, i, 0], drv.ref_l[s, i, 1], zz, qi[ia], qdi[ia],
            hub_moment(md, ws, i),
        )  # fmt: skip
        slope = d_a * cq + d_r * cv - d_z * (0.5 * h * cq)
        ws.slope[i] = slope
        cw.taul[i] = tau - slope * x[ia]
        cw.dw[i] = d_w
        cw.yk[i] = hub_moment(md, ws, i)
        if final:
            cw.torque[i] = tau
            cw.zs[i] = zz
            cw.zsum[i] = err
    out = cw.torque if final else cw.scratch
    user_laws(md, ws, drv, cw, drv.t_end[s], qi, qdi, x, cq, cv, out, _flag(False))


@njit()
def state_laws(md, ws, drv, cw, t, ff, ref, z, q, qd, x, first, torque):
    """The laws of the closed-loop joints at the state (q, q̇) (kinematics in ``ws``) with
    integral states z (n,) and the laws of time ``ff`` (n,), ``ref`` (n, 2), linearised in α̈
    through H only (the forward dynamics; :func:`correct` takes it). ``first``: no sweep at this
    state yet, H taken as 0. Sets ws.slope, cw.taul and the laws' τ in ``torque``; returns
    whether any law depends on the sweep (moment feedback, user laws)."""
    loop = user_laws(md, ws, drv, cw, t, q, qd, x, 0.0, 0.0, torque, first)
    for i in range(md.n):
        if drv.code[i] != CODE_PD:
            continue
        ia = md.ia[i]
        hub = 0.0 if first else hub_moment(md, ws, i)
        tau, _da, _dr, _dz, d_w = pd_law(drv, i, ff[i], ref[i, 0], ref[i, 1], z[i], q[ia], qd[ia], hub)
        ws.slope[i] = 0.0
        cw.taul[i] = tau
        cw.dw[i] = d_w
        cw.yk[i] = hub
        torque[i] = tau
        loop |= drv.gain[i, GM] != 0.0 and drv.gain[i, HASJ] != 0.0
    return loop


@njit()
def n_sensitivity(md, drv):
    """Sweeps that measuring ∂H/∂τ takes: one per pd/pid joint, and the base."""
    m = 1
    for i in range(md.n):
        if drv.code[i] == CODE_PD:
            m += 1
    return m


@njit()
def sensitivity(md, ws, drv, cw, cq, cv, qhat, qdhat, mot, zero_f, columns):
    """Base sweep with the torques cw.taul at the kinematics in ``ws`` (its H into cw.yb, the
    torques into cw.tb) and, with ``columns``, one sweep per pd/pid joint j with τ'_j + 1:
    cw.amat[:, j] = ∂H/∂τ'_j (the sweep is affine in its torques). Returns ok."""
    noload = np.zeros((0, 6))
    ok = sweep(md, ws, cq, cv, qhat, qdhat, cw.taul, mot, zero_f, cw.xs, False, noload)
    for i in range(md.n):
        cw.yb[i] = hub_moment(md, ws, i) if md.locked[i] == 0 else 0.0
        cw.tb[i] = cw.taul[i]
    for j in range(md.n):
        if drv.code[j] != CODE_PD or not ok or not columns:
            continue
        cw.taul[j] = cw.tb[j] + 1.0
        ok = sweep(md, ws, cq, cv, qhat, qdhat, cw.taul, mot, zero_f, cw.xs, False, noload)
        cw.taul[j] = cw.tb[j]
        for i in range(md.n):
            y = hub_moment(md, ws, i) if md.locked[i] == 0 else 0.0
            cw.amat[i, j] = y - cw.yb[i]
    return ok


#: the closed-loop correction of the sweep torques, the planar kernel's
#: (:func:`dttmm.control.correct_torques`, on cw)
correct = njit()(control.correct_torques)


@njit(inline="always")
def closure_left(it, dx, prev, prev2):
    """What an iteration with loop closures has still to change q̈ by: from the third sweep on,
    with the iterates contracting at ρ ≤ CONTRACTED, the larger of the last two ratios of
    changes (dx/prev, prev/prev2), the sum of the changes to come, dx·ρ/(1 − ρ); else the
    change dx itself. The closures converge linearly (ρ 1e-4 to 1e-2 on the four-bar and the
    five-bar: the closure loads turn with the kinematics, which the W of fixed kinematics
    misses), so the change that would show the round-off floor is one sweep late; ρ is not
    constant (five-bar: 3e-4, then 6e-3), hence the larger of two."""
    if it >= 2 and dx <= CONTRACTED * prev and prev <= CONTRACTED * prev2:
        r = max(dx / prev, prev / prev2)
        return dx * r / (1.0 - r)
    return dx


@njit(inline="always")
def _flag(value):
    """``value`` as a run-time bool: numba types a literal bool passed to a compiled call as its
    own type and would compile one more version of the callee per literal (the planar kernel's
    :func:`dttmm.kernel.loop._flag`)."""
    return bool(value)


# ------------------------------------------------------------------ forward dynamics --------


@njit()
def accel(md, ws, q, qd, tau, mot, forces, out, torque):
    """q̈ at (q, q̇) with the motion joints' α, α̇ from ``mot`` (q, q̇ are updated in place);
    torques into ``torque``. Returns ok."""
    for i in range(md.n):
        ws.slope[i] = 0.0
        if md.motion[i] == 1:
            q[md.ia[i]] = mot[i, 0]
            qd[md.ia[i]] = mot[i, 1]
    kinematics(md, ws, q, qd)
    set_rates(md, ws, qd)
    ok = sweep(md, ws, 0.0, 0.0, q, qd, tau, mot, forces, out, False, np.zeros((0, 6)))
    joint_torques(md, ws, tau, torque)
    return ok


@njit()
def accel_closed(md, ws, opts, drv, cw, t, q, qd, tau, mot, ff, ref, z, out, torque, fresh):
    """:func:`accel` with closed-loop joints: their laws at (q, q̇) and time t, integral states
    z (n,), feedforward ``ff`` (n,) and reference ``ref`` (n, 2). A law with moment feedback
    (or a user law) depends on the sweep: the sweeps repeat, each with the laws linearised in α̈
    at the last one, until :func:`dttmm.iteration.stop_rule` holds (at most max_it; a solve
    that stops there counts in cw.fd[0]); with moment feedback past the first joint the
    sensitivity is measured anew if ``fresh``. Torques into ``torque`` (closed-loop joints: the
    laws' τ at the final sweep). Returns ok."""
    nd = q.shape[0]
    zero_f = np.zeros(nd)
    noload = np.zeros((0, 6))
    for i in range(md.n):
        cw.taul[i] = tau[i]
        if md.motion[i] == 1:
            q[md.ia[i]] = mot[i, 0]
            qd[md.ia[i]] = mot[i, 1]
    kinematics(md, ws, q, qd)
    set_rates(md, ws, qd)
    ok = True
    converged = False
    prev = np.inf
    for it in range(opts.max_it):
        if it > 0:
            for i in range(md.n):
                cw.tb[i] = cw.taul[i]
        loop = state_laws(md, ws, drv, cw, t, ff, ref, z, q, qd, out, it == 0, cw.scratch)
        if opts.coupled:
            if it == 0:
                if not sensitivity(md, ws, drv, cw, 0.0, 0.0, q, qd, mot, zero_f, fresh):
                    return False
                cw.fd[1] += n_sensitivity(md, drv) if fresh else 1
            else:
                for i in range(md.n):
                    cw.yb[i] = cw.yk[i]
            correct(md, drv, cw)
        ok = sweep(md, ws, 0.0, 0.0, q, qd, cw.taul, mot, zero_f, out, False, noload)
        cw.fd[1] += 1
        if not ok:
            return False
        if not loop:
            converged = True
            break
        if it > 0:
            dx, xmax = _change_and_size(out, cw.xc, out)
            stop, converged = _stop_rule(it, dx, prev, xmax, opts.tol)
            if stop:
                break
            prev = dx
        for r in range(nd):
            cw.xc[r] = out[r]
    if not converged:
        cw.fd[0] += 1
    joint_torques(md, ws, tau, torque)
    state_laws(md, ws, drv, cw, t, ff, ref, z, q, qd, out, _flag(False), torque)  # τ at the final H
    return ok


@njit()
def joint_torques(md, ws, tau, torque):
    """Per joint: the law's torque (torque joints) or the sweep's (motion joints); 0 if locked."""
    for i in range(md.n):
        if md.locked[i] == 1:
            torque[i] = 0.0
        elif md.motion[i] == 1:
            torque[i] = ws.acc[i, 1]
        else:
            torque[i] = tau[i]


@njit()
def start(md, ws, opts, drv, cw, q, qd, qdd, torque, z, zerr):
    """The state at t = 0 (right limits of the drives, integral states 0): q̈ into ``qdd``, the
    joint torques into ``torque``, α_ref − α of the pd/pid joints into ``zerr``. Returns ok."""
    ns = drv.t_end.shape[0]
    nd = q.shape[0]
    if opts.closed:
        ok = accel_closed(
            md, ws, opts, drv, cw, 0.0, q, qd, drv.tau_r[ns], drv.mot_r[ns], drv.ff_r[ns],
            drv.ref_r[ns], z, qdd, torque, _flag(True),
        )  # fmt: skip
    else:
        ok = accel(md, ws, q, qd, drv.tau_r[ns], drv.mot_r[ns], np.zeros(nd), qdd, torque)
    if ok and cw.cl.a.shape[0] > 0:
        ok = closure_start(md, ws, opts, drv, cw, q, qd, drv.tau_r[ns], drv.mot_r[ns], qdd, torque)
    for i in range(md.n):
        zerr[i] = drv.ref_r[ns, i, 0] - q[md.ia[i]] if drv.code[i] == CODE_PD else 0.0
    return ok


# ------------------------------------------------------------------ loop closures -----------


@njit()
def closure_start(md, ws, opts, drv, cw, q, qd, tau, mot, qdd, torque):
    """The forward dynamics of a closed mechanism at the state (q, q̇), after :func:`accel` or
    :func:`accel_closed` (their kinematics in ``ws``): the accelerations that keep it closed
    (acceleration level) and the closure loads λ into ``qdd`` and cl.lam, the joint torques
    into ``torque``. With closed-loop laws (pd/pid without moment feedback: their torques do
    not depend on the sweep) the sweep takes the laws' torques cw.taul, which the torque output
    keeps. Returns ok."""
    nd = q.shape[0]
    noload = np.zeros((0, 6))
    tv = cw.taul if opts.closed else tau
    ok = closure_sweep(md, ws, cw.cl, 0.0, 0.0, q, qd, tv, mot, np.zeros(nd), qdd, noload, True, -1, False)
    joint_torques(md, ws, tv, torque)
    return ok


@njit(inline="always", nrt=False)
def _tip(ws, cl, j, second, R, x, p):
    """Closure j's body a (``second``: b; the ground: identity, 0) in world: its tip frame
    into R, its origin into x, the closure point into p."""
    i = cl.b[j] if second else cl.a[j]
    loc = cl.pb[j] if second else cl.pa[j]
    for r in range(3):
        for c in range(3):
            R[r, c] = (1.0 if r == c else 0.0) if i < 0 else ws.RT[i + 1, r, c]
        x[r] = 0.0 if i < 0 else ws.pT[i + 1, r]
    for r in range(3):
        p[r] = x[r] + R[r, 0] * loc[0] + R[r, 1] * loc[1] + R[r, 2] * loc[2]


@njit(inline="always", nrt=False)
def _cross_into(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@njit(inline="always", nrt=False)
def _mv_into(R, x, out):
    for r in range(3):
        out[r] = R[r, 0] * x[0] + R[r, 1] * x[1] + R[r, 2] * x[2]


@njit(nrt=False)
def closure_geometry(ws, cl):
    """The constraint residual cl.g and the load directions cl.B at the kinematics in ``ws``:
    position p_a − p_b (3 rows, world); revolute: t_k·(u_b × u_a) for two unit t_k ⊥ u_a;
    weld: the axial vector of R_a R0 R_bᵀ (3 rows). To first order each row moves by the
    relative displacement (point, rotation) of a against b along its direction in cl.B. A row
    within GAP_ULPS units of round-off is 0. Allocates nothing (scratch cl.fr, cl.v)."""
    for r in range(cl.B.shape[0]):
        for c in range(cl.B.shape[1]):
            cl.B[r, c] = 0.0
    Ra = cl.fr[0]
    Rb = cl.fr[1]
    v = cl.v
    row = 0
    for j in range(cl.a.shape[0]):
        _tip(ws, cl, j, False, Ra, v[0], v[1])
        _tip(ws, cl, j, True, Rb, v[2], v[3])
        pa = v[1]
        pb = v[3]
        # a gap at the round-off of the points' coordinates counts as none
        floor = GAP_ULPS * EPS * (abs(pa[0]) + abs(pa[1]) + abs(pa[2]) + abs(pb[0]) + abs(pb[1]) + abs(pb[2]))
        ulp = EPS * (abs(pa[0]) + abs(pa[1]) + abs(pa[2]) + abs(pb[0]) + abs(pb[1]) + abs(pb[2]))
        for d in range(3):
            gd = pa[d] - pb[d]
            cl.g[row + d] = gd if abs(gd) > floor else 0.0
            cl.gf[row + d] = ulp
            cl.B[6 * j + d, row + d] = 1.0
        row += 3
        if cl.kind[j] == 1:
            ua = v[4]
            ub = v[5]
            t1 = v[6]
            t2 = v[7]
            _mv_into(Ra, cl.ua[j], ua)
            _mv_into(Rb, cl.ub[j], ub)
            k = 0  # the axis component least in magnitude (the first of equals)
            for d in range(1, 3):
                if abs(ua[d]) < abs(ua[k]):
                    k = d
            # t1 = ua × e_k
            t1[0] = ua[1] if k == 2 else (-ua[2] if k == 1 else 0.0)
            t1[1] = ua[2] if k == 0 else (-ua[0] if k == 2 else 0.0)
            t1[2] = ua[0] if k == 1 else (-ua[1] if k == 0 else 0.0)
            nt = math.sqrt(t1[0] ** 2 + t1[1] ** 2 + t1[2] ** 2)
            for d in range(3):
                t1[d] /= nt
            _cross_into(ua, t1, t2)
            c0 = ub[1] * ua[2] - ub[2] * ua[1]
            c1 = ub[2] * ua[0] - ub[0] * ua[2]
            c2 = ub[0] * ua[1] - ub[1] * ua[0]
            g1 = t1[0] * c0 + t1[1] * c1 + t1[2] * c2
            g2 = t2[0] * c0 + t2[1] * c1 + t2[2] * c2
            cl.g[row] = g1 if abs(g1) > GAP_ULPS * EPS else 0.0
            cl.g[row + 1] = g2 if abs(g2) > GAP_ULPS * EPS else 0.0
            cl.gf[row] = EPS
            cl.gf[row + 1] = EPS
            for d in range(3):
                cl.B[6 * j + 3 + d, row] = t1[d]
                cl.B[6 * j + 3 + d, row + 1] = t2[d]
            row += 2
        elif cl.kind[j] == 2:
            R0 = cl.R0[j]
            for d in range(3):
                # the axial vector of M = R_a R0 R_bᵀ: ½ (M[d2, d1] − M[d1, d2])
                d1 = (d + 1) % 3
                d2 = (d + 2) % 3
                m21 = 0.0
                m12 = 0.0
                for u in range(3):
                    for w in range(3):
                        m21 += Ra[d2, u] * R0[u, w] * Rb[d1, w]
                        m12 += Ra[d1, u] * R0[u, w] * Rb[d2, w]
                gd = 0.5 * (m21 - m12)
                cl.g[row + d] = gd if abs(gd) > GAP_ULPS * EPS else 0.0
                cl.gf[row + d] = EPS
            for d in range(3):
                cl.B[6 * j + 3 + d, row + d] = 1.0
            row += 3


@njit(nrt=False)
def closure_inputs(ws, cl, mot, lam):
    """The inputs ``mot`` with the closure loads λ added to the world tip loads: λ_j = (F, M)
    on link a at its point, −λ_j on b (moments moved to the tip points)."""
    for r in range(mot.shape[0]):
        for c in range(mot.shape[1]):
            cl.motc[r, c] = mot[r, c]
    k = LOAD_COL
    R = cl.fr[0]
    x = cl.v[0]
    pt = cl.v[1]
    for j in range(cl.a.shape[0]):
        f0 = lam[6 * j]
        f1 = lam[6 * j + 1]
        f2 = lam[6 * j + 2]
        for second in range(2):
            i = cl.b[j] if second else cl.a[j]
            if i < 0:
                continue
            _tip(ws, cl, j, second == 1, R, x, pt)
            sg = -1.0 if second else 1.0
            s0 = pt[0] - x[0]
            s1 = pt[1] - x[1]
            s2 = pt[2] - x[2]
            cl.motc[i, k] += sg * f0
            cl.motc[i, k + 1] += sg * f1
            cl.motc[i, k + 2] += sg * f2
            cl.motc[i, k + 3] += sg * (lam[6 * j + 3] + s1 * f2 - s2 * f1)
            cl.motc[i, k + 4] += sg * (lam[6 * j + 4] + s2 * f0 - s0 * f2)
            cl.motc[i, k + 5] += sg * (lam[6 * j + 5] + s0 * f1 - s1 * f0)


@njit(nrt=False)
def closure_accelerations(ws, cl, out):
    """Per closure the relative acceleration of a's point against b's (world, 3) and of their
    frames' angular accelerations (3), from the last sweep's tip accelerations."""
    R = cl.fr[0]
    x = cl.v[0]
    pt = cl.v[1]
    aw = cl.v[2]
    bw = cl.v[3]
    for j in range(cl.a.shape[0]):
        for d in range(6):
            out[6 * j + d] = 0.0
        for second in range(2):
            i = cl.b[j] if second else cl.a[j]
            if i < 0:
                continue
            _tip(ws, cl, j, second == 1, R, x, pt)
            A = ws.Atip[i + 1]
            for r in range(3):
                aw[r] = R[r, 0] * A[0] + R[r, 1] * A[1] + R[r, 2] * A[2]
                bw[r] = R[r, 0] * A[3] + R[r, 1] * A[4] + R[r, 2] * A[5]
            s0 = pt[0] - x[0]
            s1 = pt[1] - x[1]
            s2 = pt[2] - x[2]
            ap0 = aw[0] + bw[1] * s2 - bw[2] * s1
            ap1 = aw[1] + bw[2] * s0 - bw[0] * s2
            ap2 = aw[2] + bw[0] * s1 - bw[1] * s0
            sg = -1.0 if second else 1.0
            out[6 * j] += sg * ap0
            out[6 * j + 1] += sg * ap1
            out[6 * j + 2] += sg * ap2
            for d in range(3):
                out[6 * j + 3 + d] += sg * bw[d]


@njit(nrt=False)
def invert(A, Ai, S):
    """Ai = A⁻¹ by Gauss–Jordan elimination with partial pivoting in the scratch S (m, m).
    Returns False for a singular A."""
    m = A.shape[0]
    for r in range(m):
        for c in range(m):
            S[r, c] = A[r, c]
            Ai[r, c] = 1.0 if r == c else 0.0
    for c in range(m):
        piv = c
        for r in range(c + 1, m):
            if abs(S[r, c]) > abs(S[piv, c]):
                piv = r
        if not abs(S[piv, c]) > 0.0:
            return False
        if piv != c:
            for u in range(m):
                t = S[c, u]
                S[c, u] = S[piv, u]
                S[piv, u] = t
                t = Ai[c, u]
                Ai[c, u] = Ai[piv, u]
                Ai[piv, u] = t
        d = 1.0 / S[c, c]
        for u in range(m):
            S[c, u] *= d
            Ai[c, u] *= d
        for r in range(m):
            if r != c and S[r, c] != 0.0:
                f = S[r, c]
                for u in range(m):
                    S[r, u] -= f * S[c, u]
                    Ai[r, u] -= f * Ai[c, u]
    return True


@njit(nrt=False)
def closure_record(cl, s):
    """Keep W, X, T just measured at step ``s`` of a Newmark run in world components (with
    the load directions B of this iterate: C = B W Bᵀ, B X, B T) as the last measurement; the
    one kept before moves back (a second measurement in the same step replaces the last)."""
    ml = cl.B.shape[0]
    m = cl.B.shape[1]
    st = cl.state
    if st[4] >= 1 and st[5] != s:
        for d in range(ml):
            for e in range(ml):
                cl.Cb[d, e] = cl.Ca[d, e]
            for r in range(cl.Xa.shape[1]):
                cl.Xb[d, r] = cl.Xa[d, r]
            for r in range(cl.Ta.shape[1]):
                cl.Tb[d, r] = cl.Ta[d, r]
        st[6] = st[5]
        st[4] = 2
    elif st[4] == 0:
        st[4] = 1
    st[5] = s
    for d in range(ml):
        for e in range(ml):
            t = 0.0
            for c in range(m):
                if cl.B[e, c] != 0.0:
                    u = 0.0
                    for r in range(m):
                        u += cl.B[d, r] * cl.W[r, c]
                    t += u * cl.B[e, c]
            cl.Ca[d, e] = t
        for r in range(cl.Xa.shape[1]):
            t = 0.0
            for c in range(m):
                t += cl.B[d, c] * cl.X[c, r]
            cl.Xa[d, r] = t
        for r in range(cl.Ta.shape[1]):
            t = 0.0
            for c in range(m):
                t += cl.B[d, c] * cl.T[c, r]
            cl.Ta[d, r] = t


@njit(nrt=False)
def closure_predict(cl, s):
    """W, X, T at step ``s`` in the load directions B of this iterate from the measurements
    kept: extrapolated linearly in the step from the last two (one kept: the last, turned into
    these directions). W changes with the configuration from step to step (on the four-bar
    about 1e-5 of itself per step); the extrapolation halves what the last measurement misses
    (measured: 1.0e-5 against 2.3e-5 one step after it). Returns whether W could be inverted."""
    ml = cl.B.shape[0]
    m = cl.B.shape[1]
    st = cl.state
    f = 0.0
    if st[4] >= 2 and st[5] != st[6]:
        f = (s - st[5]) / (st[5] - st[6])
    for r in range(m):
        for c in range(m):
            t = 0.0
            for d in range(ml):
                if cl.B[d, r] != 0.0:
                    u = 0.0
                    for e in range(ml):
                        u += (cl.Ca[d, e] + f * (cl.Ca[d, e] - cl.Cb[d, e])) * cl.B[e, c]
                    t += cl.B[d, r] * u
            cl.W[r, c] = t
        for q in range(cl.Xa.shape[1]):
            cl.X[r, q] = 0.0
        for q in range(cl.Ta.shape[1]):
            cl.T[r, q] = 0.0
        for d in range(ml):
            b = cl.B[d, r]
            if b != 0.0:  # B is sparse: a direction has 1 or 3 components
                for q in range(cl.Xa.shape[1]):
                    cl.X[r, q] += b * (cl.Xa[d, q] + f * (cl.Xa[d, q] - cl.Xb[d, q]))
                for q in range(cl.Ta.shape[1]):
                    cl.T[r, q] += b * (cl.Ta[d, q] + f * (cl.Ta[d, q] - cl.Tb[d, q]))
    return invert(cl.W, cl.Wi, cl.Wlu)


@njit(nrt=False)
def closure_noise(cl, cq):
    """The round-off floor of the iteration: the largest change of a q̈ component that gaps
    of one unit of round-off per row (cl.gf) move through the update, max_r Σ_c |(Xᵀ W⁻¹)[r, c]|
    gf[c] / c_q. An iterate's change below it is the round-off of the gaps, not progress."""
    m = cl.g.shape[0]
    nb = 0.0
    for r in range(cl.X.shape[1]):
        t = 0.0
        for c in range(m):
            z = 0.0
            for k in range(m):
                z += cl.X[k, r] * cl.Wi[k, c]
            t += abs(z) * cl.gf[c]
        nb = max(nb, t)
    return nb / cq


@njit(nrt=False)
def closure_sweep(md, ws, cl, cq, cv, qt, qdt, tv, mot, zero_f, xn, noload, fresh, s, first):
    """One iteration of a Newmark step with loop closures, at the iterate's kinematics in
    ``ws``: the sweep with the current λ gives q̈⁰ into ``xn``; the closures' position-level
    condition at the step end, g(q̂ + c_q q̈) = 0, linearised about q̈⁰, g⁰ + c_q W Δμ = 0 with
    g⁰ the gap at q̂ + c_q q̈⁰ and W the relative accelerations along the constraints per unit
    load, fixes Δμ; λ += B Δμ and ``xn`` += X Δμ (the accelerations are affine in λ: X the
    q̈ per unit load). W and X are measured (one sweep per unknown at this kinematics) when
    ``fresh`` or when cl.state[0] holds none of a Newmark step, else those of an earlier
    iterate serve (a quasi-Newton step on μ: the fixed point, g = 0 with the step's equations,
    is the same); at the first iterate of step ``s`` (``first``) those extrapolated from the
    measurements kept (:func:`closure_predict`). cl.nb[0] gets the iteration's round-off floor
    (:func:`closure_noise`). At the initial state and a restart (c_q = 0) the condition is at
    acceleration level, Bᵀ rel(λ) = 0, and the last sweep is the one with the corrected λ.
    The sweeps taken go to cl.state[1]; ``ws`` ends with the link tip frames of q̂ + c_q q̈⁰
    (c_q ≠ 0; :func:`tip_frames`, the rest of its kinematics those of the iterate) and the
    joints' sweep torques ws.acc[:, 1] of the new λ (affine: T). Returns ok."""
    m = cl.g.shape[0]
    nd = xn.shape[0]
    closure_geometry(ws, cl)
    # λ in the directions of this iterate (orthonormal per closure): a revolute closure's
    # moment stays perpendicular to its current axis (no moment about it)
    mu = cl.dmu
    for c in range(m):
        t = 0.0
        for r in range(cl.B.shape[0]):
            t += cl.B[r, c] * cl.lam[r]
        mu[c] = t
    for r in range(cl.lam.shape[0]):
        t = 0.0
        for c in range(m):
            t += cl.B[r, c] * mu[c]
        cl.lam[r] = t
    measure = fresh or cq == 0.0 or cl.state[0] == 0
    if not measure and first and cl.state[4] >= 1:
        measure = not closure_predict(cl, s)
    # the round-off floor anew with W, X measured or updated (an extrapolation moves it by
    # about what it moves W: 1e-5)
    changed = measure
    closure_inputs(ws, cl, mot, cl.lam)
    ok = sweep(md, ws, cq, cv, qt, qdt, tv, cl.motc, zero_f, xn, False, noload)
    for i in range(md.n):
        cl.tq[i] = ws.acc[i, 1]
    if measure:
        closure_accelerations(ws, cl, cl.rel0)
        lam1 = cl.lam1
        for c in range(m):
            for r in range(lam1.shape[0]):
                lam1[r] = cl.lam[r] + cl.B[r, c]
            closure_inputs(ws, cl, mot, lam1)
            ok = sweep(md, ws, cq, cv, qt, qdt, tv, cl.motc, zero_f, cl.xs, False, noload) and ok
            closure_accelerations(ws, cl, cl.rel)
            for r in range(m):
                t = 0.0
                for d in range(cl.B.shape[0]):
                    t += cl.B[d, r] * (cl.rel[d] - cl.rel0[d])
                cl.W[r, c] = t
            for r in range(nd):
                cl.X[c, r] = cl.xs[r] - xn[r]
            for i in range(md.n):
                cl.T[c, i] = ws.acc[i, 1] - cl.tq[i]
        ok = ok and invert(cl.W, cl.Wi, cl.Wlu)
        cl.state[0] = 1 if ok and cq != 0.0 else 0
        cl.state[1] = m + 1
        if cl.state[0] == 1 and s >= 0:
            closure_record(cl, s)
        else:
            cl.state[4] = 0
    else:
        cl.state[1] = 1
    for r in range(nd):
        if not math.isfinite(xn[r]):
            ok = False
    if not ok:
        return False
    if cq == 0.0:
        # the forward dynamics (the initial state, a restart): the relative accelerations
        # vanish, Bᵀ rel(λ) = 0, in place of the position condition
        for r in range(m):
            t = 0.0
            for d in range(cl.B.shape[0]):
                t += cl.B[d, r] * cl.rel0[d]
            cl.g[r] = t
    else:
        # the gap at the positions of the sweep's q̈ (motion-driven joints at their law)
        for r in range(nd):
            cl.qp[r] = qt[r] + cq * xn[r]
        for i in range(md.n):
            if md.motion[i] == 1:
                cl.qp[md.ia[i]] = mot[i, 0]
        tip_frames(md, ws, cl.qp)
        closure_geometry(ws, cl)
        if cl.state[2] == 1 and cl.state[3] == 1:
            # a secant (Broyden) update of W from the previous iterate's gap g_p and its Δμ, s,
            # against this gap g: W += ((g − g_p)/c_q − W s) sᵀ / (sᵀ s). W measured
            # at fixed kinematics misses the loads' change with the kinematics (their moment
            # arms and directions), which with large closure loads near a singular
            # configuration turns the fixed point away; the secant sees it
            ss = 0.0
            for c in range(m):
                ss += cl.dmp[c] * cl.dmp[c]
            if ss > 0.0:
                for r in range(m):
                    wsc = 0.0
                    for c in range(m):
                        wsc += cl.W[r, c] * cl.dmp[c]
                    f = ((cl.g[r] - cl.gp[r]) / cq - wsc) / ss
                    for c in range(m):
                        cl.W2[r, c] = cl.W[r, c] + f * cl.dmp[c]
                if invert(cl.W2, cl.Wi, cl.Wlu):
                    changed = True
                    for r in range(m):
                        for c in range(m):
                            cl.W[r, c] = cl.W2[r, c]
                else:
                    invert(cl.W, cl.Wi, cl.Wlu)
    if changed:
        cl.nb[0] = closure_noise(cl, cq) if cq != 0.0 else 0.0
    dmu = cl.dmu
    for r in range(m):
        t = 0.0
        for c in range(m):
            t -= cl.Wi[r, c] * cl.g[c]
        dmu[r] = t if cq == 0.0 else t / cq
    for r in range(cl.lam.shape[0]):
        t = 0.0
        for c in range(m):
            t += cl.B[r, c] * dmu[c]
        cl.lam[r] += t
    if cq == 0.0:
        closure_inputs(ws, cl, mot, cl.lam)
        ok = sweep(md, ws, cq, cv, qt, qdt, tv, cl.motc, zero_f, xn, False, noload)
        cl.state[1] += 1
    else:
        for r in range(m):
            cl.gp[r] = cl.g[r]
            cl.dmp[r] = dmu[r]
        cl.state[3] = 1
        # q̈ and the motion-driven joints' torques (:func:`joint_torques`) with the new λ
        for c in range(m):
            for r in range(nd):
                xn[r] += cl.X[c, r] * dmu[c]
        for i in range(md.n):
            t = cl.tq[i]
            for c in range(m):
                t += cl.T[c, i] * dmu[c]
            ws.acc[i, 1] = t
    for r in range(nd):
        if not math.isfinite(xn[r]):
            ok = False
    return ok


# ------------------------------------------------------------------ the time loop -----------


@njit()
def check_state(md, q):
    """ST_OK, or ST_NONFINITE / ST_RUNAWAY for a diverging state."""
    for r in range(q.shape[0]):
        if not math.isfinite(q[r]):
            return ST_NONFINITE
    for i in range(md.n):
        off = 0 if md.ext[i] == 1 else -1
        for j in range(md.k[i] * (1 - md.rigid[i])):  # a rigid link has no coordinates
            r0 = md.ie[md.el0[i] + j]
            for c in range(6):
                if c + off < 0:
                    continue
                v = abs(q[r0 + c + off])
                lim = RUNAWAY_ANGLE if c >= 3 else RUNAWAY_LENGTHS * md.l[i]
                if v > lim:
                    return ST_RUNAWAY
    return ST_OK


@njit()
def hermite(x, h):
    x2 = x * x
    x3 = x2 * x
    return 2 * x3 - 3 * x2 + 1, (x3 - 2 * x2 + x) * h, -2 * x3 + 3 * x2, (x3 - x2) * h


@njit()
def residual_check(md, ws, opts, cq, cv, qt, qdt, tv, mot, x, k2, dq, d2q, s, stats, fstats):
    """The planar kernel's residual check (docs/kernel.md, "Residual check"): one more sweep
    at the accepted iterate (kinematics in ``ws``), not applied, gives the correction
    d = max|Δq̈| it would make; the step is flagged when the iteration error exceeds the
    Newmark truncation error in q or q̇, ratio = max(d / (lte·Δq̈ + tol_q̈), γ d / (|γ − ½| Δq̈ +
    Δ²q̈/12 + γ tol_q̈)) > 1 (Δq̈ = ``dq``, Δ²q̈ = ``d2q``)."""
    ok = sweep(md, ws, cq, cv, qt, qdt, tv, mot, np.zeros(x.shape[0]), k2, False, np.zeros((0, 6)))
    d, xmax = _change_and_size(k2, x, x)
    if not ok:
        d = np.inf
    ratio = _residual_ratio(d, xmax, dq, d2q, opts.tol, opts.lte, opts.gamma)
    stats[S_CHECKS] += 1
    if not ratio <= 1.0:  # NaN counts as flagged
        stats[S_FLAGGED] += 1
        if stats[S_FIRST_FLAG] < 0:
            stats[S_FIRST_FLAG] = s
    if stats[S_WORST] < 0 or not ratio <= fstats[0]:
        stats[S_WORST] = s
        fstats[0] = ratio
        fstats[1] = d / max(1.0, xmax)


class Step(NamedTuple):
    """The arrays a time step works on (:func:`newmark_step`, :func:`accept_newmark`,
    :func:`rk4_step`): the state (q, q̇, q̈, aux (n_dof,); joint torques, integral states z and
    their errors (n,)), q̈ of the step before (the residual check) and the step's scratch."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    aux: np.ndarray
    torque: np.ndarray
    z: np.ndarray
    zerr: np.ndarray
    qddm: np.ndarray
    qt: np.ndarray  # the Newmark predictors
    qdt: np.ndarray
    x: np.ndarray  # the iterate q̈ and the sweep's
    xn: np.ndarray
    qi: np.ndarray  # the iterate's (stage's) q, q̇
    qdi: np.ndarray
    k2: np.ndarray  # RK4 stages (k2: the residual check's scratch too)
    k3: np.ndarray
    ka: np.ndarray
    kb: np.ndarray
    kc: np.ndarray
    zero_f: np.ndarray  # no generalized forces
    noload: np.ndarray  # (0, 6): no cut loads


@njit()
def accept_newmark(md, ws, opts, drv, cw, st, s, h, last, ok, cq, cv, i1m, tv, stats, fstats):
    """The end of Newmark step s with the iterate x (q̈ at the step end; ``ok``: the iteration's
    outcome): the joint torques and closure loads kept, the state (q, q̇, q̈, aux) updated,
    the laws' final evaluation at it (closed loops) and the residual check every
    opts.check_every steps (and at the ``last``)."""
    q, qd, qdd, aux, torque, z, zerr = st.q, st.qd, st.qdd, st.aux, st.torque, st.z, st.zerr
    qddm, qt, qdt, x, k2 = st.qddm, st.qt, st.qdt, st.x, st.k2
    tau, mot = drv.tau_l[s], drv.mot_l[s]
    n = md.n
    nd = q.shape[0]
    check = ok and opts.check_every > 0 and (s % opts.check_every == 0 or s == last)
    dqc = 0.0
    d2q = 0.0
    if check:
        for r in range(nd):
            dqc = max(dqc, abs(x[r] - qdd[r]))
            d2q = max(d2q, abs(x[r] - 2.0 * qdd[r] + qddm[r]))
    joint_torques(md, ws, tau, torque)
    for r in range(cw.cl.lam.shape[0]):
        cw.cl.lamh[s, r] = cw.cl.lam[r]
    for r in range(nd):
        qddm[r] = qdd[r]
        anew = ((1.0 - opts.alpha_f) * x[r] + opts.alpha_f * qdd[r] - opts.alpha_m * aux[r]) * i1m
        q[r] = qt[r] + cq * x[r]
        qd[r] = qdt[r] + cv * x[r]
        aux[r] = anew
        qdd[r] = x[r]
    for i in range(n):
        if md.motion[i] == 1:
            q[md.ia[i]] = mot[i, 0]
            qd[md.ia[i]] = mot[i, 1]
            qdd[md.ia[i]] = mot[i, 2]
    if ok and (opts.closed or check):
        # the accepted iterate's kinematics (the laws' final evaluation, the check)
        kinematics(md, ws, q, qd)
        set_rates(md, ws, qd)
    if ok and opts.closed:
        step_laws(md, ws, drv, cw, s, z, zerr, h, cq, cv, q, qd, x, _flag(True))
        for i in range(n):
            if drv.code[i] != CODE_OPEN:
                torque[i] = cw.torque[i]
    if check:
        residual_check(md, ws, opts, cq, cv, qt, qdt, tv, mot, x, k2, dqc, d2q, s, stats, fstats)
    if ok and opts.closed:
        for i in range(n):
            if drv.code[i] == CODE_PD:
                z[i] = cw.zs[i]
                zerr[i] = cw.zsum[i]


@njit()
def newmark_step(md, ws, opts, drv, cw, st, s, h, last, stats, fstats):
    """Newmark step s (length h) from the state (q, q̇, q̈, aux) in place: the predictors, the
    iteration to the stop rule (sweeps, closed-loop laws and their correction, loop closures),
    the accepted state, the laws' final evaluation and the residual check (``last``: the last
    step index). Counts into stats, fstats (see N_STATS). Returns ok."""
    q, qd, qdd, aux, z, zerr = st.q, st.qd, st.qdd, st.aux, st.z, st.zerr
    qt, qdt, x, xn, qi, qdi = st.qt, st.qdt, st.x, st.xn, st.qi, st.qdi
    zero_f, noload = st.zero_f, st.noload
    n = md.n
    nd = q.shape[0]
    tau = drv.tau_l[s]
    mot = drv.mot_l[s]
    hh = h * h
    sc = (1.0 - opts.alpha_f) / (1.0 - opts.alpha_m)
    cq = opts.beta * hh * sc
    cv = opts.gamma * h * sc
    i1m = 1.0 / (1.0 - opts.alpha_m)
    for r in range(nd):
        corr = (opts.alpha_f * qdd[r] - opts.alpha_m * aux[r]) * i1m
        qt[r] = q[r] + h * qd[r] + hh * (0.5 - opts.beta) * aux[r] + opts.beta * hh * corr
        qdt[r] = qd[r] + h * (1.0 - opts.gamma) * aux[r] + opts.gamma * h * corr
        x[r] = qdd[r]
    for i in range(n):
        ws.slope[i] = 0.0
        cw.taul[i] = tau[i]
        if md.motion[i] == 1:
            x[md.ia[i]] = mot[i, 2]
    tv = cw.taul if opts.closed else tau
    prev = np.inf
    prev2 = np.inf  # that of the iteration before
    used = 0
    nclose = cw.cl.a.shape[0]
    ok = True
    stale = False
    measured = False  # W was measured in this step
    bro = False  # secant updates of W in this step
    converged = False
    fixed = opts.iteration == IT_FIXED
    nmax = opts.n_fixed + 1 if fixed else opts.max_it
    for it in range(nmax):
        for r in range(nd):
            qi[r] = qt[r] + cq * x[r]
            qdi[r] = qdt[r] + cv * x[r]
        for i in range(n):
            if md.motion[i] == 1:
                qi[md.ia[i]] = mot[i, 0]
                qdi[md.ia[i]] = mot[i, 1]
        kinematics(md, ws, qi, qdi)
        set_rates(md, ws, qdi)
        if opts.closed:
            for i in range(n):
                cw.tb[i] = cw.taul[i]  # the last sweep's torques (it ≥ 1)
            step_laws(md, ws, drv, cw, s, z, zerr, h, cq, cv, qi, qdi, x, _flag(False))
            if opts.coupled:
                if it == 0:
                    # a base sweep about this very iterate, with the sensitivity anew
                    # every A_EVERY steps and after a restart
                    fresh = s % A_EVERY == 0 or (s > 0 and drv.restart[s - 1])
                    ok = sensitivity(md, ws, drv, cw, cq, cv, qt, qdt, mot, zero_f, fresh)
                    used += n_sensitivity(md, drv) if fresh else 1
                    if not ok:
                        break
                else:
                    for i in range(n):
                        cw.yb[i] = cw.yk[i]
                correct(md, drv, cw)
        if cw.cl.a.shape[0] > 0:
            if it == 0 and s >= 2 and not drv.restart[s - 1] and not drv.restart[s - 2]:
                # λ extrapolated from the last two step ends (the iteration's start)
                for r in range(cw.cl.lam.shape[0]):
                    cw.cl.lam[r] = 2.0 * cw.cl.lamh[s - 1, r] - cw.cl.lamh[s - 2, r]
            # W anew every W_EVERY steps, after a restart, and once the iterates stop
            # contracting (else the W of an earlier iterate: one sweep per iteration)
            wnew = stale
            if it == 0:
                wnew = s % W_EVERY == 0 or (s > 0 and drv.restart[s - 1])
                cw.cl.state[2] = 0
                cw.cl.state[3] = 0
            elif bro:
                cw.cl.state[2] = 1
            ok = closure_sweep(md, ws, cw.cl, cq, cv, qt, qdt, tv, mot, zero_f, xn, noload, wnew, s, it == 0)
            used += cw.cl.state[1]
            measured = measured or cw.cl.state[1] > 1
        else:
            ok = sweep(md, ws, cq, cv, qt, qdt, tv, mot, zero_f, xn, False, noload)
            used += 1
        dx = 0.0
        xmax = 0.0
        dq = 0.0
        for r in range(nd):
            dx = max(dx, abs(xn[r] - x[r]))
            xmax = max(xmax, abs(xn[r]))
            dq = max(dq, abs(xn[r] - qdd[r]))
            x[r] = xn[r]
        if not ok:
            break
        if fixed:
            converged = it == nmax - 1
            continue
        stop, converged = _stop_rule(it, dx, prev, xmax, opts.tol)
        if (
            not stop
            and nclose > 0
            and it >= 1
            and closure_left(it, dx, prev, prev2) <= min(cw.cl.nb[0], 1e3 * opts.tol * max(1.0, xmax))
        ):
            # the change, or the change still to come, is within the round-off floor
            # of the closures' gaps (which the position condition divides by c_q): what
            # is left is round-off (the stop rule's stagnation, without the iterations
            # that show it)
            stop = True
            converged = True
        if stop:
            break
        # iterates that stop contracting above the round-off floor: W anew
        stalled = it >= 1 and dx > W_STALE * prev and dx > 1e3 * opts.tol * max(1.0, xmax)
        stale = stalled and not measured
        # iterates that stop contracting with a W of this step: secant updates of W for
        # the rest of the step (the loads' change with the kinematics, which a measured
        # W misses, holds the fixed point back)
        bro = bro or (stalled and measured)
        if opts.iteration == IT_AUTO and it >= 1 + opts.closed and dx < prev:
            # the contraction ρ = dx/prev predicts the iteration error left, dx·ρ/(1 − ρ);
            # stop once it is below auto_fraction × the local truncation error estimate
            # |β − 1/6|/β · max|q̈_{n+1} − q̈_n| (the planar kernel's rule). Closed-loop
            # laws are linearised at the previous iterate, so their torques lag a sweep:
            # the contraction is judged from the third sweep on (measured on the
            # closed-loop arm: two sweeps left 10× the discretisation error with moment
            # feedback, 2.7 % of it without)
            rr = dx / prev
            if dx * rr / (1.0 - rr) <= opts.auto_fraction * opts.lte * dq:
                converged = True
                break
        prev2 = prev
        prev = dx
    stats[S_SWEEPS] += used
    stats[S_MAX] = max(stats[S_MAX], used)
    if not converged and not fixed:
        stats[S_UNCONV] += 1
    accept_newmark(md, ws, opts, drv, cw, st, s, h, last, ok, cq, cv, i1m, tv, stats, fstats)
    return ok


@njit()
def rk4_step(md, ws, opts, drv, cw, st, s, h, stats):
    """RK4 step s (length h) from the state (q, q̇, q̈) in place, closed-loop laws' integral
    states included (stage states in qi, qdi; stage accelerations in k2, k3, ka, kb, kc).
    Counts the forward-dynamics solves into stats. Returns ok."""
    q, qd, qdd, torque, z, zerr = st.q, st.qd, st.qdd, st.torque, st.z, st.zerr
    qi, qdi, k2, k3, ka, kb, kc = st.qi, st.qdi, st.k2, st.k3, st.ka, st.kb, st.kc
    n = md.n
    nd = q.shape[0]
    ok = True
    hf = 0.5 * h
    if opts.closed:  # stage 1: ż = e_n
        for i in range(n):
            cw.zsum[i] = zerr[i]
            cw.zs[i] = z[i] + hf * zerr[i]
    fresh = s % A_EVERY == 0 or (s > 0 and drv.restart[s - 1])
    fd0 = cw.fd[1]
    for r in range(nd):
        qi[r] = q[r] + hf * qd[r]
        qdi[r] = qd[r] + hf * qdd[r]
    ok = rk4_accel(md, ws, opts, drv, cw, s, h, 1, qi, qdi, ka, torque, fresh)
    for r in range(nd):
        k2[r] = qdi[r]
    if ok:
        ok = rk4_stage(md, ws, opts, drv, cw, st, s, h, hf, 1, k2, ka, kb)
        for r in range(nd):
            k3[r] = qdi[r]
    if ok:
        ok = rk4_stage(md, ws, opts, drv, cw, st, s, h, h, 2, k3, kb, kc)
    if ok:
        if opts.closed:
            rk4_z(n, drv.code, md.ia, z, drv.ref_l[s], qi, 1.0, 0.0, cw.zsum, cw.zs)
            for i in range(n):
                if drv.code[i] == CODE_PD:
                    z[i] += h / 6.0 * cw.zsum[i]
                    cw.zs[i] = z[i]
        for r in range(nd):
            q[r] = q[r] + h / 6.0 * (qd[r] + 2.0 * k2[r] + 2.0 * k3[r] + qdi[r])
            qd[r] = qd[r] + h / 6.0 * (qdd[r] + 2.0 * ka[r] + 2.0 * kb[r] + kc[r])
        ok = rk4_accel(md, ws, opts, drv, cw, s, h, 2, q, qd, qdd, torque, _flag(False))
        if opts.closed:
            for i in range(n):
                if drv.code[i] == CODE_PD:
                    zerr[i] = drv.ref_l[s, i, 0] - q[md.ia[i]]
    used = cw.fd[1] - fd0 if opts.closed else 4
    stats[S_SWEEPS] += used
    stats[S_MAX] = max(stats[S_MAX], used)
    return ok


@njit()
def run(
    md, ws, opts, drv, cw, q, qd, qdd, aux, torque, z, zerr, ts, oq, oqd, otau, stats, fstats, first, until
):
    """Steps ``first`` ≤ s < ``until`` of the time loop from the state (q, q̇, q̈, aux, joint
    torques, integral states z and errors α_ref − α) at the start of step ``first`` (t = 0 for
    0), sampling the state on the grid ``ts`` into oq, oqd (nt, n_dof) and otau (nt, n). Each
    Newmark step iterates to the stop rule (``iterations="auto"``: or the contraction test), or
    takes n_fixed + 1 sweeps. stats, fstats: see N_STATS (stats[S_SAMPLES]: the samples taken
    so far, where the next call goes on). Calls over consecutive ranges of steps give the run of
    one call over all of them, bit for bit (the progress bar's chunks). Returns the number of
    steps taken by the end of this call (``until``, or the failed step)."""
    n = md.n
    nd = q.shape[0]
    ns = drv.t_end.shape[0]
    zero_f = np.zeros(nd)
    tq0 = np.zeros(n)
    q0 = q.copy()
    qd0 = qd.copy()
    qdd0 = qdd.copy()
    qddm = cw.qddm  # q̈_{n−1} (the residual check), kept between calls
    qt = np.zeros(nd)
    qdt = np.zeros(nd)
    x = np.zeros(nd)
    xn = np.zeros(nd)
    qi = np.zeros(nd)
    qdi = np.zeros(nd)
    k2 = np.zeros(nd)
    k3 = np.zeros(nd)
    ka = np.zeros(nd)
    kb = np.zeros(nd)
    kc = np.zeros(nd)
    noload = np.zeros((0, 6))
    st = Step(
        q, qd, qdd, aux, torque, z, zerr, qddm, qt, qdt, x, xn, qi, qdi, k2, k3, ka, kb, kc, zero_f, noload
    )
    nt = ts.shape[0]
    if first == 0:
        js = 0
        for r in range(nd):
            qddm[r] = qdd[r]
        while js < nt and ts[js] <= 1e-12:
            for r in range(nd):
                oq[js, r] = q[r]
                oqd[js, r] = qd[r]
            for i in range(n):
                otau[js, i] = torque[i]
            js += 1
        t0 = 0.0
    else:
        js = stats[S_SAMPLES]
        t0 = drv.t_end[first - 1]
    s = first
    last = ns - 1
    ok = True
    while s < until:
        t1 = drv.t_end[s]
        h = t1 - t0
        for r in range(nd):
            q0[r] = q[r]
            qd0[r] = qd[r]
            qdd0[r] = qdd[r]
        for i in range(n):
            tq0[i] = torque[i]
        if opts.integrator == INT_NEWMARK:
            ok = newmark_step(md, ws, opts, drv, cw, st, s, h, last, stats, fstats)
        else:
            ok = rk4_step(md, ws, opts, drv, cw, st, s, h, stats)
        status = check_state(md, q) if ok else ST_SINGULAR
        if status == ST_OK:
            for r in range(nd):
                if not math.isfinite(qd[r]):
                    status = ST_NONFINITE
        for i in range(n):  # a law that returned a non-finite torque
            if not (math.isfinite(torque[i]) and math.isfinite(cw.taul[i])):
                status = ST_NONFINITE
        if status != ST_OK:
            stats[S_STATUS] = status
            stats[S_FAILED] = s
            stats[S_SAMPLES] = js
            return s
        # samples in (t0, t1]
        eps = 1e-9 * h
        while js < nt and ts[js] <= t1 + eps:
            xx = (ts[js] - t0) / h
            if abs(ts[js] - t1) <= eps:
                xx = 1.0
            w0, w1, w2, w3 = hermite(xx, h)
            for r in range(nd):
                oq[js, r] = w0 * q0[r] + w1 * qd0[r] + w2 * q[r] + w3 * qd[r]
                oqd[js, r] = w0 * qd0[r] + w1 * qdd0[r] + w2 * qd[r] + w3 * qdd[r]
            for i in range(n):
                otau[js, i] = (1.0 - xx) * tq0[i] + xx * torque[i]
            js += 1
        # a drive jumps at t1: restart from the right limits (the recorded torque at t1 keeps
        # the left limit: the step's own)
        if drv.restart[s]:
            if opts.closed:
                ok = accel_closed(
                    md, ws, opts, drv, cw, t1, q, qd, drv.tau_r[s], drv.mot_r[s], drv.ff_r[s],
                    drv.ref_r[s], z, qdd, torque, _flag(True),
                )  # fmt: skip
            else:
                ok = accel(md, ws, q, qd, drv.tau_r[s], drv.mot_r[s], zero_f, qdd, torque)
            if ok and cw.cl.a.shape[0] > 0:
                ok = closure_start(md, ws, opts, drv, cw, q, qd, drv.tau_r[s], drv.mot_r[s], qdd, torque)
            for r in range(nd):
                aux[r] = qdd[r]
            if not ok:
                stats[S_STATUS] = ST_SINGULAR
                stats[S_FAILED] = s
                stats[S_SAMPLES] = js
                return s
        t0 = t1
        s += 1
    stats[S_SAMPLES] = js
    return until


@njit()
def rk4_accel(md, ws, opts, drv, cw, s, h, stage, q, qd, out, torque, fresh):
    """Forward dynamics at an RK4 stage of step s (``stage`` 1: mid-step laws of time, 2: the
    step end) into ``out``; closed-loop laws with the stage's integral states cw.zs."""
    if stage == 1:
        tau, mot = drv.tau_m[s], drv.mot_m[s]
    else:
        tau, mot = drv.tau_l[s], drv.mot_l[s]
    if not opts.closed:
        return accel(md, ws, q, qd, tau, mot, np.zeros(q.shape[0]), out, torque)
    t = drv.t_end[s]
    if stage == 1:
        ff, ref = drv.ff_m[s], drv.ref_m[s]
        t -= 0.5 * h
    else:
        ff, ref = drv.ff_l[s], drv.ref_l[s]
    return accel_closed(md, ws, opts, drv, cw, t, q, qd, tau, mot, ff, ref, cw.zs, out, torque, fresh)


#: the closed-loop integral states at an RK4 stage (:func:`dttmm.control.rk4_integral`)
rk4_z = njit()(control.rk4_integral)


@njit(inline="always")
def rk4_stage(md, ws, opts, drv, cw, st, s, h, c, stage, kq, kqd, out):
    """An inner RK4 stage of step s: the integral states advanced by c ż (ż at the last stage,
    :func:`rk4_z`), the stage state (q + c kq, q̇ + c kqd) into st.qi, st.qdi, its acceleration
    into ``out`` (:func:`rk4_accel`). Returns ok."""
    qi, qdi = st.qi, st.qdi
    if opts.closed:
        rk4_z(md.n, drv.code, md.ia, st.z, drv.ref_m[s], qi, 2.0, c, cw.zsum, cw.zs)
    for r in range(qi.shape[0]):
        qi[r] = st.q[r] + c * kq[r]
        qdi[r] = st.qd[r] + c * kqd[r]
    return rk4_accel(md, ws, opts, drv, cw, s, h, stage, qi, qdi, out, st.torque, _flag(False))
