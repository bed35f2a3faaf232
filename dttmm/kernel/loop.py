"""The time loop: Newmark family (with the frozen-coefficient iteration) and RK4, stepping
the state and recording outputs on the way. The one implementation of the DT-TMM time loop,
compiled by numba or run as plain Python (see :mod:`dttmm.kernel._jit`).

Each Newmark step solves the equations of motion at t_{n+1} with q = q̃ + c_q q̈ and
q̇ = q̃' + c_v q̈ (:func:`predict`): sweeps at the latest iterate until the stop rule of
:func:`_stop` holds (or a fixed number of sweeps): the suite's one stop rule,
:func:`dttmm.iteration.stop_rule`, and for ``iterations="auto"`` the contraction test.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .. import control, iteration
from ._jit import njit

# The loop's functions allocate nothing and are compiled without reference counting
# (nrt=False): with it, every call or inlined call touches the count of every array of its
# named-tuple arguments, which costs more than a small model's sweep. They are inlined into
# `run` (a real call would pass every array of the tuples as separate arguments).
from .element import angles, effective_mass, elastic_known
from .feedback import A_EVERY, CODE_PD, correct, inboard, n_sensitivity, state_laws, step_laws
from .layout import (
    INT_NEWMARK,
    IT_AUTO,
    IT_FIXED,
    ST_NONFINITE,
    ST_OK,
    ST_RUNAWAY,
    ST_SINGULAR,
    SW_PLAIN,
    SW_RICCATI,
)
from .plain import plain
from .recorder import record
from .riccati import riccati, riccati_loads

# the suite's one stop rule of a tolerance-driven iteration, inlined
_stop_rule = njit(nrt=False, inline="always")(iteration.stop_rule)
_change_and_size = njit(nrt=False, inline="always")(iteration.change_and_size)
_residual_ratio = njit(nrt=False, inline="always")(iteration.residual_ratio)


class Options(NamedTuple):
    """Run settings (codes from :mod:`dttmm.kernel.layout`)."""

    integrator: int  # INT_NEWMARK or INT_RK4
    sweep: int  # SW_RICCATI or SW_PLAIN
    iteration: int  # IT_FIXED, IT_TOL or IT_AUTO
    n_fixed: int  # IT_FIXED: sweeps per step − 1
    tol: float
    max_iterations: int
    auto_fraction: float
    beta: float  # Newmark family (β, γ, α_m, α_f) and |β − 1/6|/β
    gamma: float
    alpha_m: float
    alpha_f: float
    lte: float
    check_every: int  # fixed/"auto" sweeps: residual check every this many steps (0: never)
    closed: bool  # some joint has a closed-loop (pd/pid) law
    coupled: bool  # some joint past the first has moment feedback (feedback.correct)


class Drives(NamedTuple):
    """Drive values per step (the drive laws are Python objects, evaluated beforehand):
    torques (n_steps, n) and motions (n_steps, n, 3) = (α, α̇, α̈) at the step end (left
    limits), the right limits at restart steps, the mid-step values (RK4).

    Closed-loop joints (``code`` 1; 0 elsewhere) have the constants ``gain`` (n, 6) of
    :mod:`dttmm.kernel.feedback` and, at the same instants, the feedforward torque ``ff_*``
    (n_steps, n) and the reference (α_ref, α̇_ref) ``ref_*`` (n_steps, n, 2); without closed-loop
    joints these tables have one row of zeros."""

    t_end: np.ndarray
    restart: np.ndarray  # (n_steps,) bool: a drive jumps at the step end
    need_loads: np.ndarray  # (n_steps,) bool: the recorder needs the cut loads of this step
    tau_left: np.ndarray
    mot_left: np.ndarray
    tau_right: np.ndarray
    mot_right: np.ndarray
    tau_mid: np.ndarray
    mot_mid: np.ndarray
    code: np.ndarray
    user: object  # engine "python": the user laws (tuple, None where not); else np.zeros(0)
    gain: np.ndarray
    ff_left: np.ndarray
    ref_left: np.ndarray
    ff_right: np.ndarray
    ref_right: np.ndarray
    ff_mid: np.ndarray
    ref_mid: np.ndarray


class State(NamedTuple):
    """(q, q̇, q̈, a) now (a: the auxiliary acceleration of generalised-α) and the last
    recorded step end (q, q̇, torques, cut loads), all overwritten as the run goes; per joint
    the integral state z of a closed-loop law and its error α_ref − α now."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    aux: np.ndarray
    q_prev: np.ndarray
    qd_prev: np.ndarray
    torque_prev: np.ndarray
    loads_prev: np.ndarray
    z: np.ndarray
    zerr: np.ndarray


class Stats(NamedTuple):
    """Counters of a run, one-element arrays accumulated across calls of :func:`run`."""

    sweeps: np.ndarray  # total sweeps
    max_sweeps: np.ndarray  # most sweeps in one step
    unconverged: np.ndarray  # steps that stopped before the tolerance
    cond_max: np.ndarray  # largest final-system condition number (plain sweep)
    steps_done: np.ndarray
    status: np.ndarray  # ST_* code
    bad_index: np.ndarray  # coordinate that failed the state check
    bad_value: np.ndarray  # its value
    ptr: np.ndarray  # next output sample
    checks: np.ndarray  # residual checks done (fixed sweep counts and "auto")
    flagged: np.ndarray  # checks whose iteration error exceeded the truncation error
    first_flag: np.ndarray  # step of the first flagged check (-1: none)
    worst_step: np.ndarray  # step of the largest ratio (-1: none)
    worst_ratio: np.ndarray  # largest ratio iteration error / truncation error
    worst_resid: np.ndarray  # max|Δq̈|/max(1, max|q̈|) of that check


def new_stats() -> Stats:
    i = lambda: np.zeros(1, np.int64)
    return Stats(
        sweeps=i(),
        max_sweeps=i(),
        unconverged=i(),
        cond_max=np.zeros(1),
        steps_done=i(),
        status=i(),
        bad_index=i(),
        bad_value=np.zeros(1),
        ptr=i(),
        checks=i(),
        flagged=i(),
        first_flag=np.full(1, -1, np.int64),
        worst_step=np.full(1, -1, np.int64),
        worst_ratio=np.zeros(1),
        worst_resid=np.zeros(1),
    )


class Work(NamedTuple):
    """Scratch arrays of the time loop."""

    x: np.ndarray  # (n_dof,) q̈ iterates
    xn: np.ndarray
    qt: np.ndarray  # predictors q̃, q̃'
    qdt: np.ndarray
    qi: np.ndarray  # iterate (q, q̇)
    qdi: np.ndarray
    k2: np.ndarray  # RK4 stages
    k3: np.ndarray
    ka: np.ndarray
    qs: np.ndarray  # (q, q̇) with the motion laws applied / interpolated samples
    qds: np.ndarray
    acc: np.ndarray  # (n,) prescribed α̈
    torque: np.ndarray  # (n,) and (n_cuts, 3): of the step's solve
    loads: np.ndarray
    torque_r: np.ndarray  # of a restart solve (not recorded)
    loads_r: np.ndarray
    taul: np.ndarray  # (n,) closed loop: torques of the sweep (τ_k − s α̈_k at such joints)
    zs: np.ndarray  # (n,) closed loop: z of an RK4 stage; z_{n+1} of a Newmark step
    zsum: np.ndarray  # (n,) closed loop: RK4's weighted sum of ż; e_{n+1} of a Newmark step
    xc: np.ndarray  # (n_dof,) closed loop: previous iterate of the forward dynamics
    xs: np.ndarray  # (n_dof,) closed loop: q̈ of the sensitivity sweeps
    dw: np.ndarray  # (n,) closed loop: ∂τ/∂ω̇ at the iterate
    yk: np.ndarray  # (n,) closed loop: inboard part of ω̇ at the iterate, of the base sweep,
    yb: np.ndarray
    tb: np.ndarray  # (n,) closed loop: the base sweep's torques
    amat: np.ndarray  # (n, n) closed loop: ∂y/∂τ' of the sweep
    gmat: np.ndarray  # (n, n + 1) closed loop: scratch of the solve
    fd_unconverged: np.ndarray  # (1,) closed loop: forward-dynamics solves out of sweeps
    fd_sweeps: np.ndarray  # (1,) closed loop: sweeps of the forward-dynamics solves


def new_work(n_dof: int, n: int, n_cuts: int) -> Work:
    v = lambda: np.empty(n_dof)
    return Work(
        x=v(),
        xn=v(),
        qt=v(),
        qdt=v(),
        qi=v(),
        qdi=v(),
        k2=v(),
        k3=v(),
        ka=v(),
        qs=v(),
        qds=v(),
        acc=np.empty(n),
        torque=np.empty(n),
        loads=np.empty((n_cuts, 3)),
        torque_r=np.empty(n),
        loads_r=np.empty((n_cuts, 3)),
        taul=np.zeros(n),
        zs=np.zeros(n),
        zsum=np.zeros(n),
        xc=np.empty(n_dof),
        xs=np.empty(n_dof),
        dw=np.zeros(n),
        yk=np.zeros(n),
        yb=np.zeros(n),
        tb=np.zeros(n),
        amat=np.zeros((n, n)),
        gmat=np.zeros((n, n + 1)),
        fd_unconverged=np.zeros(1, np.int64),
        fd_sweeps=np.zeros(1, np.int64),
    )


@njit(nrt=False, inline="always")
def copy(src, dst):
    """dst[:] = src for 1-d arrays (a slice assignment would need reference counting)."""
    for r in range(src.shape[0]):
        dst[r] = src[r]


@njit(nrt=False, inline="always")
def sweep(md, data, code, q, qd, tau, acc, xout, torque, loads):
    """One sweep at the iterate (q, q̇) (data.f_known and data.Mt already set). Returns
    (ok, cond): cond is the plain sweep's final-system condition number (nan for Riccati)."""
    angles(md, q, qd, data)
    if code == SW_RICCATI:
        riccati(md, data, tau, acc, xout, torque)
        return True, np.nan
    return plain(md, data, tau, acc, xout, torque, loads)


@njit(nrt=False, inline="always")
def apply_motion(motion, im, mot, q, qd):
    """Motion-driven joints (``motion`` (n,) bool, their angles at ``im`` in q) take the law's
    angle and rate from ``mot`` (n, 3)."""
    ii = 0
    for i in range(motion.shape[0]):
        if motion[i]:
            q[im[ii]] = mot[i, 0]
            qd[im[ii]] = mot[i, 1]
            ii += 1


@njit(nrt=False, inline="always")
def accel(md, data, code, q, qd, tau, mot, ws, xout, torque, loads, want_loads):
    """Exact forward dynamics q̈(q, q̇) into xout (motion joints take the law's angle, rate,
    α̈), with the joint torques and, if ``want_loads``, the cut loads. Returns (ok, cond)."""
    copy(q, ws.qs)
    copy(qd, ws.qds)
    for i in range(md.n):
        ws.acc[i] = mot[i, 2]
    apply_motion(md.motion, md.im, mot, ws.qs, ws.qds)
    elastic_known(md, ws.qs, ws.qds, data)
    effective_mass(md, 0.0, 0.0, data)
    ok, cond = sweep(md, data, code, ws.qs, ws.qds, tau, ws.acc, xout, torque, loads)
    for i in range(md.n):
        if not md.motion[i]:
            torque[i] = tau[i]
    if want_loads and code == SW_RICCATI:
        riccati_loads(md, data, loads)
    return ok, cond


@njit(nrt=False)  # a real call: closed-loop runs only
def sensitivity(md, data, opts, q, qd, drv, ws, columns):
    """Base sweep at (q, q̇) with the torques ws.taul (its y into ws.yb, the torques copied to
    ws.tb) and, with ``columns``, one sweep per closed-loop joint j with τ'_j + 1:
    ws.amat[:, j] = ∂y/∂τ'_j (the sweep is affine in its torques). Outputs go to scratch
    (ws.xs, restart arrays). Returns ok."""
    ok, _c = sweep(md, data, opts.sweep, q, qd, ws.taul, ws.acc, ws.xs, ws.torque_r, ws.loads_r)
    for i in range(md.n):
        ws.yb[i] = inboard(md, data, ws.xs, i)
        ws.tb[i] = ws.taul[i]
    for j in range(md.n):
        if drv.code[j] != CODE_PD or not ok or not columns:
            continue
        ws.taul[j] = ws.tb[j] + 1.0
        ok, _c = sweep(md, data, opts.sweep, q, qd, ws.taul, ws.acc, ws.xs, ws.torque_r, ws.loads_r)
        ws.taul[j] = ws.tb[j]
        for i in range(md.n):
            ws.amat[i, j] = inboard(md, data, ws.xs, i) - ws.yb[i]
    return ok


@njit(nrt=False, inline="always")
def _flag(value):
    """``value`` as a run-time bool. numba types a literal ``False`` passed to a compiled call as
    its own type and compiles one more version of the callee per combination of literal flags:
    the callers of :func:`accel_closed` pass their flags through this, so one version serves all."""
    return bool(value)


# a real call: closed-loop runs only, and inlining it four times into `run` costs compile time;
# its flags arrive as run-time bools (:func:`_flag`)
@njit(nrt=False)
def accel_closed(
    md, data, opts, t, q, qd, tau, mot, drv, ff, ref, z, ws, xout, torque, loads, want_loads, fresh
):
    """:func:`accel` with closed-loop joints: their laws at (q, q̇) and time t, integral states z (n,),
    feedforward ``ff`` (n,) and reference ``ref`` (n, 2). A law with moment feedback depends on
    ω̇ of its link root, itself a result of the sweep: the sweeps repeat, each with the laws
    linearised in α̈ at the last one, until :func:`dttmm.iteration.stop_rule` holds, as in a
    step (at most ``max_iterations``; a solve that stops there
    counts in ws.fd_unconverged). With moment
    feedback past the first joint the sensitivity A is measured anew if ``fresh``, else the
    last one serves. The torques of closed-loop joints are the laws' τ. Returns (ok, cond)."""
    copy(q, ws.qs)
    copy(qd, ws.qds)
    for i in range(md.n):
        ws.acc[i] = mot[i, 2]
        ws.taul[i] = tau[i]
    apply_motion(md.motion, md.im, mot, ws.qs, ws.qds)
    elastic_known(md, ws.qs, ws.qds, data)
    effective_mass(md, 0.0, 0.0, data)
    ok = True
    cond = np.nan
    converged = False
    prev_dx = np.inf
    for it in range(opts.max_iterations):
        if it > 0:
            copy(ws.taul, ws.tb)
        loop = state_laws(md, data, drv, t, ff, ref, z, ws.qs, ws.qds, xout, ws, it == 0, torque)
        if opts.coupled:
            if it == 0:
                if not sensitivity(md, data, opts, ws.qs, ws.qds, drv, ws, fresh):
                    return False, cond
                ws.fd_sweeps[0] += n_sensitivity(md, drv) if fresh else 1
            else:
                copy(ws.yk, ws.yb)
            correct(md, drv, ws)
        ok, cond = sweep(md, data, opts.sweep, ws.qs, ws.qds, ws.taul, ws.acc, xout, torque, loads)
        ws.fd_sweeps[0] += 1
        if not ok:
            return ok, cond
        if not loop:
            converged = True
            break
        if it > 0:
            dx, xmax = _change_and_size(xout, ws.xc, xout)
            stop, converged = _stop_rule(it, dx, prev_dx, xmax, opts.tol)
            if stop:
                break
            prev_dx = dx
        copy(xout, ws.xc)
    if not converged:
        ws.fd_unconverged[0] += 1
    for i in range(md.n):
        if not md.motion[i] and drv.code[i] == 0:  # closed loop: the sweep's τ until the laws
            torque[i] = tau[i]
    state_laws(md, data, drv, t, ff, ref, z, ws.qs, ws.qds, xout, ws, False, torque)  # τ at the final ω̇
    if want_loads and opts.sweep == SW_RICCATI:
        riccati_loads(md, data, loads)
    return ok, cond


@njit(nrt=False, inline="always")
def predict(beta, gamma, alpha_m, alpha_f, h, q, qd, qdd, a, qt, qdt):
    """Newmark-family predictor: fills q̃, q̃' (so that q_{n+1} = q̃ + c_q q̈_{n+1},
    q̇_{n+1} = q̃' + c_v q̈_{n+1}) and returns (c_q, c_v)."""
    hh = h * h
    sc = (1.0 - alpha_f) / (1.0 - alpha_m)
    cq = beta * hh * sc
    cv = gamma * h * sc
    i1m = 1.0 / (1.0 - alpha_m)
    for r in range(q.shape[0]):
        corr = (alpha_f * qdd[r] - alpha_m * a[r]) * i1m
        qt[r] = q[r] + h * qd[r] + hh * (0.5 - beta) * a[r] + beta * hh * corr
        qdt[r] = qd[r] + h * (1.0 - gamma) * a[r] + gamma * h * corr
    return cq, cv


@njit(nrt=False, inline="always")
def _stop(opts, it, dx, prev_dx, xmax, dq):
    """Stop rule of the tolerance-driven iteration after sweep ``it``: returns (stop,
    converged). dx = max|Δq̈|, xmax = max|q̈|, dq = max|q̈_{n+1} − q̈_n| ("auto" only).
    The rule of :func:`dttmm.iteration.stop_rule`, then for "auto" the contraction test."""
    stop, converged = _stop_rule(it, dx, prev_dx, xmax, opts.tol)
    if stop:
        return stop, converged
    if opts.iteration == IT_AUTO and it >= 1 and dx < prev_dx:
        # the contraction ρ = dx/prev_dx predicts the remaining iteration error dx·ρ/(1 − ρ);
        # stop once it is below auto_fraction × the local truncation error estimate
        # |β − 1/6|/β · max|q̈_{n+1} − q̈_n| (both scaled by βh²)
        rr = dx / prev_dx
        if dx * rr / (1.0 - rr) <= opts.auto_fraction * opts.lte * dq:
            return True, True
    return False, False


@njit(nrt=False, inline="always")
def _update_iterate(x, xn, qt, qdt, qi, qdi, qdd, cq, cv, want_dq):
    """x ← xn, the next iterate (qi, qdi) = (q̃ + c_q x, q̃' + c_v x). Returns (max|Δq̈| (nan if
    not finite), max|q̈|, max|q̈ − q̈_n| if ``want_dq``, q̈_n = qdd)."""
    dx = 0.0
    xmax = 0.0
    dq = 0.0
    bad = False
    for r in range(x.shape[0]):
        v = xn[r]
        d = abs(v - x[r])
        bad |= d != d  # noqa: PLR0124 - NaN test without a call
        dx = max(dx, d)
        ax = abs(v)
        xmax = max(xmax, ax)
        x[r] = v
        qi[r] = qt[r] + cq * v
        qdi[r] = qdt[r] + cv * v
    if want_dq:
        for r in range(x.shape[0]):
            d2 = abs(x[r] - qdd[r])
            dq = max(dq, d2)
    if bad:
        dx = np.nan
    return dx, xmax, dq


@njit(nrt=False, inline="always")
def _iterate(md, data, opts, state, ws, cq, cv, tau, mot, stats, drv, s, h):
    """Sweeps of one Newmark step (step s of ``drv``, size h) from the iterate x = ws.x; the
    closed-loop laws linearised at each iterate (:func:`dttmm.kernel.feedback.step_laws`).
    Returns (ok, sweeps used, converged)."""
    nsw = opts.max_iterations if opts.iteration != IT_FIXED else opts.n_fixed + 1
    converged = opts.iteration == IT_FIXED
    prev_dx = np.inf
    used = 0
    for r in range(ws.x.shape[0]):
        ws.qi[r] = ws.qt[r] + cq * ws.x[r]
        ws.qdi[r] = ws.qdt[r] + cv * ws.x[r]
    tv = tau
    if opts.closed:
        copy(tau, ws.taul)
        tv = ws.taul
    for it in range(nsw):
        apply_motion(md.motion, md.im, mot, ws.qi, ws.qdi)
        if opts.closed:
            copy(ws.taul, ws.tb)  # the last sweep's torques (it ≥ 1)
            step_laws(md, data, drv, s, state, ws, h, cq, cv, False)
            if opts.coupled:
                if it == 0:
                    # a base sweep about this very iterate (y of the last step's is a poor
                    # guess: measured), with A anew every A_EVERY steps and after a restart
                    fresh = s % A_EVERY == 0 or (s > 0 and drv.restart[s - 1])
                    if not sensitivity(md, data, opts, ws.qi, ws.qdi, drv, ws, fresh):
                        return False, used, False
                    used += n_sensitivity(md, drv) if fresh else 1
                else:
                    copy(ws.yk, ws.yb)
                correct(md, drv, ws)
        ok, cond = sweep(md, data, opts.sweep, ws.qi, ws.qdi, tv, ws.acc, ws.xn, ws.torque, ws.loads)
        used += 1
        if not ok:
            return False, used, False
        if opts.sweep == SW_PLAIN and cond > stats.cond_max[0]:
            stats.cond_max[0] = cond
        dx, xmax, dq = _update_iterate(
            ws.x, ws.xn, ws.qt, ws.qdt, ws.qi, ws.qdi, state.qdd, cq, cv, opts.iteration == IT_AUTO
        )
        if opts.iteration != IT_FIXED:
            stop, converged = _stop(opts, it, dx, prev_dx, xmax, dq)
            if stop:
                break
            prev_dx = dx
    return True, used, converged


@njit(nrt=False)  # a real call: inlining a third sweep into `run` slowed every step (measured)
def _residual_check(md, data, opts, ws, tau, mot, dq, d2q, s, stats):
    """Residual of the step equations at the accepted iterate x = ws.x of step s: one more
    sweep, not applied (its q̈ into ws.k2, torques and loads into the restart scratch), gives
    the correction d = max|Δq̈| it would make. An error d in q̈ moves q by βh²·d and q̇ by
    γh·d; the Newmark truncation errors are (β − 1/6)h²·Δq̈ in q and
    h·(|γ − ½|·Δq̈ + Δ²q̈/12) in q̇ (dq = max|q̈_{n+1} − q̈_n|, d2q = max|q̈_{n+1} − 2q̈_n +
    q̈_{n−1}|). The check's ratio is the larger of the two error ratios; it passes at ≤ 1 (a tol
    term admits what a converged step leaves). Updates the counters of ``stats``."""
    apply_motion(md.motion, md.im, mot, ws.qi, ws.qdi)
    ok, _cond = sweep(md, data, opts.sweep, ws.qi, ws.qdi, tau, ws.acc, ws.k2, ws.torque_r, ws.loads_r)
    d, xmax = _change_and_size(ws.k2, ws.x, ws.x)
    if not ok:
        d = np.inf
    ratio = _residual_ratio(d, xmax, dq, d2q, opts.tol, opts.lte, opts.gamma)
    scale = max(1.0, xmax)
    stats.checks[0] += 1
    if not ratio <= 1.0:  # NaN counts as flagged
        stats.flagged[0] += 1
        if stats.first_flag[0] < 0:
            stats.first_flag[0] = s
    if stats.worst_step[0] < 0 or not ratio <= stats.worst_ratio[0]:
        stats.worst_step[0] = s
        stats.worst_ratio[0] = ratio
        stats.worst_resid[0] = d / scale


@njit(nrt=False, inline="always")
def newmark_step(md, data, opts, state, ws, h, tau, mot, want_loads, stats, check, keep, s, drv):
    """One Newmark-family step s of ``drv``, of size h, to the end values (tau, mot); with
    ``check``, the residual check after it (:func:`_residual_check`); with ``keep``, q̈_n is
    kept in ws.ka for the next step's check. Closed-loop joints: the law's τ of the converged
    iterate is the step's torque, and z, α_ref − α move to t_{n+1}. Returns ok."""
    cq, cv = predict(
        opts.beta,
        opts.gamma,
        opts.alpha_m,
        opts.alpha_f,
        h,
        state.q,
        state.qd,
        state.qdd,
        state.aux,
        ws.qt,
        ws.qdt,
    )
    copy(state.qdd, ws.x)
    ii = 0
    for i in range(md.n):
        ws.acc[i] = mot[i, 2]
        if md.motion[i]:
            ws.x[md.im[ii]] = mot[i, 2]
            ii += 1
    elastic_known(md, ws.qt, ws.qdt, data)
    effective_mass(md, cq, cv, data)
    ok, used, converged = _iterate(md, data, opts, state, ws, cq, cv, tau, mot, stats, drv, s, h)
    if not ok:
        return False
    stats.sweeps[0] += used
    stats.max_sweeps[0] = max(stats.max_sweeps[0], used)
    if not converged:
        stats.unconverged[0] += 1
    dq = 0.0
    d2q = 0.0
    if check:
        for r in range(state.q.shape[0]):
            dq = max(dq, abs(ws.x[r] - state.qdd[r]))
            d2q = max(d2q, abs(ws.x[r] - 2.0 * state.qdd[r] + ws.ka[r]))
    if keep:
        copy(state.qdd, ws.ka)
    am, af = opts.alpha_m, opts.alpha_f
    i1m = 1.0 / (1.0 - am)
    for r in range(state.q.shape[0]):
        anew = ((1.0 - af) * ws.x[r] + af * state.qdd[r] - am * state.aux[r]) * i1m
        state.q[r] = ws.qt[r] + cq * ws.x[r]
        state.qd[r] = ws.qdt[r] + cv * ws.x[r]
        state.aux[r] = anew
        state.qdd[r] = ws.x[r]
    apply_motion(md.motion, md.im, mot, state.q, state.qd)
    ii = 0
    for i in range(md.n):
        if md.motion[i]:
            state.aux[md.im[ii]] = ws.x[md.im[ii]]
            ii += 1
        elif drv.code[i] == 0:  # closed loop: the law's τ, below
            ws.torque[i] = tau[i]
    if want_loads and opts.sweep == SW_RICCATI:
        riccati_loads(md, data, ws.loads)
    if opts.closed:  # the laws at the converged iterate (ws.qi, ws.qdi, ω̇ of its sweep)
        step_laws(md, data, drv, s, state, ws, h, cq, cv, True)
        tau = ws.taul
    if check:  # after the loads: the extra sweep overwrites the workspace they are read from
        _residual_check(md, data, opts, ws, tau, mot, dq, d2q, s, stats)
    if opts.closed:
        for i in range(md.n):
            if drv.code[i] == CODE_PD:
                state.z[i] = ws.zs[i]
                state.zerr[i] = ws.zsum[i]
    return True


@njit(nrt=False, inline="always")
def _accel_at(md, data, opts, q, qd, drv, s, h, stage, ws, xout, want_loads, fresh):
    """Forward dynamics at an RK4 stage of step s of size h (``stage`` 1: mid-step laws of
    time, 2: the step end) into xout; closed-loop laws with the stage's integral states ws.zs
    (``fresh``: measure the sensitivity A, :func:`accel_closed`)."""
    if stage == 1:
        tau, mot = drv.tau_mid[s], drv.mot_mid[s]
    else:
        tau, mot = drv.tau_left[s], drv.mot_left[s]
    if not opts.closed:
        return accel(md, data, opts.sweep, q, qd, tau, mot, ws, xout, ws.torque, ws.loads, want_loads)
    t = drv.t_end[s]
    if stage == 1:
        ff, ref = drv.ff_mid[s], drv.ref_mid[s]
        t -= 0.5 * h
    else:
        ff, ref = drv.ff_left[s], drv.ref_left[s]
    return accel_closed(
        md,
        data,
        opts,
        t,
        q,
        qd,
        tau,
        mot,
        drv,
        ff,
        ref,
        ws.zs,
        ws,
        xout,
        ws.torque,
        ws.loads,
        want_loads,
        fresh,
    )


#: the closed-loop integral states at an RK4 stage (:func:`dttmm.control.rk4_integral`)
_rk4_z = njit(nrt=False, inline="always")(control.rk4_integral)


@njit(nrt=False, inline="always")
def _rk4_stage(md, data, opts, state, ws, drv, s, h, c, stage, kq, kqd, keep, kout, xout):
    """An inner RK4 stage of step s: the integral states advanced by c ż (ż at the last stage,
    :func:`_rk4_z`), the stage state (q + c kq, q̇ + c kqd) into ws.qi, ws.qdi (its rates into
    ``kout`` where ``keep``), its acceleration into ``xout``. Returns (ok, cond)."""
    qi, qdi = ws.qi, ws.qdi
    if opts.closed:
        _rk4_z(md.n, drv.code, md.i_alpha, state.z, drv.ref_mid[s], qi, 2.0, c, ws.zsum, ws.zs)
    for r in range(qi.shape[0]):
        qi[r] = state.q[r] + c * kq[r]
        qdi[r] = state.qd[r] + c * kqd[r]
        if keep:
            kout[r] = qdi[r]
    return _accel_at(md, data, opts, qi, qdi, drv, s, h, stage, ws, xout, _flag(False), _flag(False))


@njit(nrt=False, inline="always")
def rk4_step(md, data, opts, state, ws, h, drv, s, stats):
    """Classical RK4 on (q, q̇) (and the integral states z of closed-loop laws, ż = α_ref − α)
    with the exact acceleration solver (step s of ``drv``)."""
    q, qd, qdd = state.q, state.qd, state.qdd
    qi, qdi, k2v, k3v, ka, x, xn = ws.qi, ws.qdi, ws.k2, ws.k3, ws.ka, ws.x, ws.xn
    hf = 0.5 * h
    fd0 = ws.fd_sweeps[0]
    if opts.closed:  # stage 1: ż = e_n
        for i in range(md.n):
            ws.zsum[i] = state.zerr[i]
            ws.zs[i] = state.z[i] + hf * state.zerr[i]
    for r in range(q.shape[0]):
        qi[r] = q[r] + hf * qd[r]
        qdi[r] = qd[r] + hf * qdd[r]
        k2v[r] = qdi[r]
    fresh = s % A_EVERY == 0 or (s > 0 and drv.restart[s - 1])  # else the A of an earlier stage
    ok, cond = _accel_at(md, data, opts, qi, qdi, drv, s, h, 1, ws, ka, _flag(False), fresh)
    if ok:
        ok, cond = _rk4_stage(md, data, opts, state, ws, drv, s, h, hf, 1, k2v, ka, True, k3v, x)
    if ok:
        ok, cond = _rk4_stage(md, data, opts, state, ws, drv, s, h, h, 2, k3v, x, False, k3v, xn)
    if ok:
        if opts.closed:
            _rk4_z(md.n, drv.code, md.i_alpha, state.z, drv.ref_left[s], qi, 1.0, 0.0, ws.zsum, ws.zs)
            for i in range(md.n):
                if drv.code[i] == CODE_PD:
                    state.z[i] += h / 6.0 * ws.zsum[i]
                    ws.zs[i] = state.z[i]
        # k1 = (q̇, q̈), k2 = (k2v, ka), k3 = (k3v, x), k4 = (qdi, xn)
        for r in range(q.shape[0]):
            q[r] = q[r] + h / 6.0 * (qd[r] + 2.0 * k2v[r] + 2.0 * k3v[r] + qdi[r])
            qd[r] = qd[r] + h / 6.0 * (qdd[r] + 2.0 * ka[r] + 2.0 * x[r] + xn[r])
        apply_motion(md.motion, md.im, drv.mot_left[s], q, qd)
        ok, cond = _accel_at(md, data, opts, q, qd, drv, s, h, 2, ws, qdd, drv.need_loads[s], _flag(False))
        if opts.closed:
            for i in range(md.n):
                if drv.code[i] == CODE_PD:
                    state.zerr[i] = drv.ref_left[s, i, 0] - q[md.i_alpha[i]]
    if not ok:
        return False
    if cond > stats.cond_max[0]:  # noqa: PLR1730 - cond is NaN for the Riccati sweep: keep the max
        stats.cond_max[0] = cond
    used = ws.fd_sweeps[0] - fd0 if opts.closed else 4
    stats.sweeps[0] += used
    stats.max_sweeps[0] = max(stats.max_sweeps[0], used)
    return True


@njit(nrt=False, inline="always")
def check_state(md, q, qd, qdd):
    """Index of the first bad coordinate (non-finite, or an elastic displacement beyond its
    runaway bound), or -1."""
    for i in range(q.shape[0]):
        if not (math.isfinite(q[i]) and math.isfinite(qd[i]) and math.isfinite(qdd[i])):
            return i
        if abs(q[i]) > md.lim[i]:
            return i
    return -1


@njit(nrt=False, inline="always")
def _finish_step(md, data, opts, state, ws, drv, s, t0, rec, stats):
    """After step s: check the state, restart at a drive jump, record. Returns the status."""
    t1 = drv.t_end[s]
    bad = check_state(md, state.q, state.qd, state.qdd)
    if bad >= 0:
        stats.bad_index[0] = bad
        stats.bad_value[0] = state.q[bad]
        finite = math.isfinite(state.q[bad] + state.qd[bad] + state.qdd[bad])
        return ST_RUNAWAY if finite else ST_NONFINITE
    if drv.restart[s]:  # a drive jumps at t1: restart with the right-hand limit; the
        # recorded sample at t1 keeps the left limit (the step's own solve)
        if opts.closed:
            ok, cond = accel_closed(
                md,
                data,
                opts,
                t1,
                state.q,
                state.qd,
                drv.tau_right[s],
                drv.mot_right[s],
                drv,
                drv.ff_right[s],
                drv.ref_right[s],
                state.z,
                ws,
                state.qdd,
                ws.torque_r,
                ws.loads_r,
                _flag(False),
                _flag(True),
            )
        else:
            ok, cond = accel(
                md,
                data,
                opts.sweep,
                state.q,
                state.qd,
                drv.tau_right[s],
                drv.mot_right[s],
                ws,
                state.qdd,
                ws.torque_r,
                ws.loads_r,
                False,
            )
        if not ok:
            return ST_SINGULAR
        if cond > stats.cond_max[0]:  # noqa: PLR1730 - cond is NaN for the Riccati sweep
            stats.cond_max[0] = cond
        copy(state.qdd, state.aux)
    s0 = (state.q_prev, state.qd_prev, state.torque_prev, state.loads_prev)
    s1 = (state.q, state.qd, ws.torque, ws.loads)
    stats.ptr[0] = record(md, t0, t1, s0, s1, (ws.qs, ws.qds), stats.ptr[0], rec)
    copy(state.q, state.q_prev)
    copy(state.qd, state.qd_prev)
    copy(ws.torque, state.torque_prev)
    if drv.need_loads[s]:
        for c in range(ws.loads.shape[0]):
            for r in range(3):
                state.loads_prev[c, r] = ws.loads[c, r]
    return ST_OK


@njit(nrt=False)
def run(md, data, opts, drv, state, rec, stats, ws, s_begin, s_end):
    """Steps s_begin … s_end − 1 of the time loop, recording the output samples on the way;
    ``state`` holds the state at the end of step s_begin − 1 and is overwritten. Returns the
    status (also in stats.status; stats.steps_done: steps completed)."""
    t0 = 0.0 if s_begin == 0 else drv.t_end[s_begin - 1]
    status = ST_OK
    done = s_begin
    last = drv.t_end.shape[0] - 1
    every = opts.check_every
    for s in range(s_begin, s_end):
        t1 = drv.t_end[s]
        if opts.integrator == INT_NEWMARK:
            check = every > 0 and (s % every == 0 or s == last)
            keep = every > 0 and ((s + 1) % every == 0 or s + 1 == last)
            if check and s == 0:  # no q̈_{−1}: the first check uses Δq̈ for Δ²q̈
                copy(state.qdd, ws.ka)
            ok = newmark_step(
                md,
                data,
                opts,
                state,
                ws,
                t1 - t0,
                drv.tau_left[s],
                drv.mot_left[s],
                drv.need_loads[s],
                stats,
                check,
                keep,
                s,
                drv,
            )
        else:
            ok = rk4_step(md, data, opts, state, ws, t1 - t0, drv, s, stats)
        status = _finish_step(md, data, opts, state, ws, drv, s, t0, rec, stats) if ok else ST_SINGULAR
        if status != ST_OK:
            break
        t0 = t1
        done = s + 1
    stats.steps_done[0] = done
    stats.status[0] = status
    return status
