"""Driver of the spatial global-equation solver (:mod:`reference_models.spatial_global`): the
closed-loop drive laws, the Newmark-family step iteration (with closures by Newton on (q̈, λ)),
RK4, the output recorder and the run; the mechanics at a state are
:mod:`reference_models._spatial_numpy` (readable) or :mod:`reference_models._spatial_numba`
(compiled)."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import numpy as np

from dttmm import plumbing
from dttmm.control import pd_torque, time_tables
from dttmm.control_state import ControlState
from dttmm.drives import UserLaw
from dttmm.errors import InputError, SimulationError
from dttmm.iteration import stop_rule
from dttmm.jit import HAVE_NUMBA
from dttmm.spatial import SpatialResult
from dttmm.timegrid import step_schedule

from . import _checks
from . import _spatial_numba as _sn
from ._global_driver import convergence
from ._spatial_numpy import (
    _EPS,
    _assemble,
    _closure_gaps,
    _closure_loads,
    _constraints,
    _cut_loads,
    _damping,
    _elastic,
    _energy,
    _forward,
    _forward_constrained,
    _initial_state,
    _joint_torques,
    _Layout,
    _link_frames,
    _link_shapes,
    _load_forces,
    _prescribed,
    _solve,
    _tip_frames,
    _tip_loads,
    _torques,
)

INTEGRATORS = ("newmark", "generalized-alpha", "rk4")
#: "numba": the compiled mechanics (:mod:`reference_models._spatial_numba`, O(N²) per state);
#: "numpy": the readable dense-Jacobian mechanics (:mod:`reference_models._spatial_numpy`, its check)
ENGINES = ("numba", "numpy")
_STEPPED = ("newmark", "generalized-alpha")


# ----------------------------------------------------------------------------------------------
# Closed-loop drive laws
# ----------------------------------------------------------------------------------------------


class _Control:
    """The closed-loop joints of a case: their laws, integral states z and errors α_ref − α,
    and the torques the user laws applied in their last solve."""

    def __init__(self, case, lay: _Layout):
        drives = case.scenario.drives
        self.case, self.lay = case, lay
        self.joints = [j for j, d in enumerate(drives) if d.closed_loop]
        self.links = lay.joints[self.joints]
        self.rows = lay.alpha_idx[self.links]
        self.laws = [drives[j].law for j in self.joints]
        self.user = np.array([isinstance(law, UserLaw) for law in self.laws], bool)
        nc = len(self.joints)
        self.z, self.e, self.used = np.zeros(nc), np.zeros(nc), np.zeros(nc)
        self.unconverged_solves = 0

    def __bool__(self):
        return bool(self.joints)

    def tables(self, times, left):
        """Feedforward (nt, nc) and reference (nt, nc, 2) of the closed-loop joints."""
        ff, ref = time_tables(self.case, np.atleast_1d(times), left)
        return ff[:, self.joints], ref[:, self.joints]

    def hub(self, q, qd):
        """(h (nc, N), h₀ (nc,)): H = h q̈ + h₀ of every closed-loop joint at (q, q̇)."""
        lay = self.lay
        fr = _tip_frames(lay, q, qd)
        rows, h0 = np.zeros((len(self.joints), lay.n_dof)), np.zeros(len(self.joints))
        for c, i in enumerate(self.links):
            Jw = fr.Jw_link[i].real
            Jd = (fr.Jw_link[i] @ qd).imag / _EPS  # J̇_ω q̇
            R = fr.R_link[i].real
            a = R @ lay.axis[i]
            I = R @ lay.hub_J[i] @ R.T
            w = Jw @ qd
            rows[c] = a @ I @ Jw
            h0[c] = a @ (I @ Jd + np.cross(w, I @ w))
        return rows, h0

    def laws_at(self, t, left, q, qd, x, ff, ref, zc, dz, cq, cv, A=None, rhs=None):
        """The laws at the iterate x (q, q̇ its coordinates) at time t: torques (nc,) and, with
        A, their linearisation added to A q̈ = rhs (the slope in α̈ through α, α̇ and
        z = zc + dz·α on the diagonal, ∂τ/∂H along the row h). Also returns the user laws'
        slopes (nc,)."""
        hrow, h0 = self.hub(q, qd)
        tau, slope = np.zeros(len(self.joints)), np.zeros(len(self.joints))
        tips = None
        for c, (r, law) in enumerate(zip(self.rows, self.laws)):
            H = float(hrow[c] @ x + h0[c])
            if not self.user[c]:
                z = zc[c] + dz[c] * q[r]
                t_c, da, dv, dzz, dw = pd_torque(
                    law.kp, law.kd, law.gain_integral, law.moment_gain, law.limit, 1.0,
                    ff[c], ref[c, 0], ref[c, 1], z, q[r], qd[r], H,
                )  # fmt: skip
                tau[c] = t_c
                if A is not None:
                    s = da * cq + dv * cv + dzz * dz[c] * cq
                    A[r, r] -= s
                    A[r] -= dw * hrow[c]
                    rhs[r] += t_c - s * x[r] - dw * (hrow[c] @ x)
                continue
            if tips is None:
                tips = tuple(float(v) for v in _link_frames(self.lay, q)["tip_deflection"][:, 0])
            a = self.lay.alpha_idx[self.lay.joints]
            state = ControlState(
                joint=self.joints[c],
                angle=float(q[r]),
                rate=float(qd[r]),
                moment=float(self.used[c] - H),
                integral=0.0,
                angles=tuple(float(v) for v in q[a]),
                rates=tuple(float(v) for v in qd[a]),
                tip_deflections=tips,
            )
            tau[c], da, dv, _ = law.evaluate(float(t), state, left)
            slope[c] = da * cq + dv * cv
            if A is not None:
                A[r, r] -= slope[c]
                rhs[r] += tau[c] - slope[c] * x[r]
        return tau, slope

    def applied(self, tau, slope, new, x):
        """The torques the user laws applied in a solve that moved the iterate from x to new."""
        for c, r in enumerate(self.rows):
            if self.user[c]:
                self.used[c] = tau[c] + slope[c] * (new[r] - x[r])

    def full(self, tau_c):
        """(n_joints,) with the closed-loop joints' torques ``tau_c`` (nc,), 0 elsewhere."""
        out = np.zeros(self.lay.joints.size)
        out[self.joints] = tau_c
        return out


def _solve_closed(lay, ctl, A, rhs, x, P, F, t, left, q, qd, ff, ref, zc, dz, cq, cv, con=None):
    """One solve of A q̈ = rhs with the laws linearised at x (motion joints prescribed in x),
    with the closures ``con`` of :func:`_solve`. Returns (new q̈, the laws' τ at x, λ)."""
    A, rhs = A.copy(), rhs.copy()
    tau, slope = ctl.laws_at(t, left, q, qd, x, ff, ref, zc, dz, cq, cv, A, rhs)
    if con is None:
        new = x.copy()
        new[F] = np.linalg.solve(A[np.ix_(F, F)], rhs[F] - A[np.ix_(F, P)] @ x[P])
        lam = np.zeros(0)
    else:
        new, lam = _solve(A, rhs, x, P, F, con)
    ctl.applied(tau, slope, new, x)
    return new, tau, lam


def _forward_closed(case, lay, ctl, q, qd, t, left, opt):
    """:func:`_forward` with the closed-loop laws at time t and the integral states ctl.z: the
    laws' dependence on q̈ (through H; user laws: also their moment) is iterated until
    :func:`dttmm.iteration.stop_rule` holds. Returns (q̈, τ_p, τ of the closed-loop joints
    (n_joints,), converged, the closure multipliers λ (m,))."""
    P, F = lay.presc, lay.free
    pres = _prescribed(case, t, left)
    M, f = _assemble(lay, q, qd)
    rhs = f + _torques(case, lay, t, left) - _elastic(lay, q)[1] - _damping(lay, q, qd)[0]
    rhs += _load_forces(case, lay, q, t, left)
    ff, ref = ctl.tables([t], left)
    zc, dz = ctl.z.copy(), np.zeros(ctl.z.size)
    x = np.zeros(lay.n_dof)
    x[P] = pres[:, 2]
    prev, converged = math.inf, False
    ctl.used[:] = 0.0
    con, lam = None, np.zeros(0)
    if lay.closures:
        _, J, Jdqd = _constraints(lay, q, qd)
        con = (J, -Jdqd - J[:, P] @ x[P])
    for i in range(opt["max_iterations"]):
        new, _, lam = _solve_closed(
            lay, ctl, M, rhs, x, P, F, t, left, q, qd, ff[0], ref[0], zc, dz, 0.0, 0.0, con
        )
        delta = float(np.max(np.abs(new - x)))
        x = new
        if i > 0:
            stop, converged = stop_rule(i, delta, prev, float(np.max(np.abs(x))), opt["tol"])
            if stop:
                break
            prev = delta
    tau_c, _ = ctl.laws_at(t, left, q, qd, x, ff[0], ref[0], zc, dz, 0.0, 0.0)
    full = ctl.full(tau_c)
    rhs2 = rhs.copy()
    rhs2[ctl.rows] += tau_c
    if con is not None:
        rhs2 += con[0].T @ lam
    return x, M[P] @ x - rhs2[P], full, converged, lam


# ----------------------------------------------------------------------------------------------
# Time integration
# ----------------------------------------------------------------------------------------------


@dataclass
class _State:
    t: float
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    a: np.ndarray
    tau: np.ndarray
    lam: np.ndarray = None  # closure multipliers


def _iterate(case, lay, opt, t1, qt, qtd, qdd0, cq, cv, ctl=None, h=0.0):
    """The step's iteration (left-limit drive values at t1); returns (q̈, τ_p, solves, ok, τ of
    the closed-loop joints (n_joints,) or None, λ). Closed-loop laws (``ctl``) at t1 with the
    iterate's state, z_{n+1} = z_n + h/2 (e_n + α_ref(t1) − α_{n+1}); ctl.z, ctl.e move to t1.
    Closures (index 3): the step's equations carry Jᵀλ and g(q_{n+1}) = 0, linearised at the
    iterate as J_F q̈_F = J_F q̈_F⁽ⁱ⁾ − g/c_q; Newton on (q̈, λ) stopped on q̈ by the stop rule."""
    P, F = lay.presc, lay.free
    pres = _prescribed(case, t1, True)
    Qt = _torques(case, lay, t1, True)
    qdd = qdd0.copy()
    qdd[P] = pres[:, 2]
    prev = math.inf
    converged = False
    if ctl:
        ff, ref = ctl.tables([t1], True)
        ff, ref = ff[0], ref[0]
        zc = ctl.z + 0.5 * h * (ctl.e + ref[:, 0])
        dz = np.full(zc.size, -0.5 * h)
        ctl.used[:] = 0.0
    for i in range(opt["max_iterations"]):
        q = qt + cq * qdd
        qd = qtd + cv * qdd
        q[P], qd[P] = pres[:, 0], pres[:, 1]
        M, f = _assemble(lay, q, qd)
        _, fi, KT = _elastic(lay, q)
        fd, Dt = _damping(lay, q, qd)
        B = cq * KT + cv * Dt
        A = M + B
        rhs = f + Qt - fi - fd + B @ qdd + _load_forces(case, lay, q, t1, True)
        con = None
        if lay.closures:
            g, J, _ = _constraints(lay, q)
            con = (J, J[:, F] @ qdd[F] - g / cq)
        if ctl:
            new, _, lam = _solve_closed(
                lay, ctl, A, rhs, qdd, P, F, t1, True, q, qd, ff, ref, zc, dz, cq, cv, con
            )
        elif con is not None:
            new, lam = _solve(A, rhs, qdd, P, F, con)
        else:
            new = qdd.copy()
            new[F] = np.linalg.solve(A[np.ix_(F, F)], rhs[F] - A[np.ix_(F, P)] @ qdd[P])
        delta = float(np.max(np.abs(new[F] - qdd[F]))) if F.size else 0.0
        qdd = new
        stop, converged = stop_rule(i, delta, prev, float(np.max(np.abs(new))), opt["tol"])
        if stop:
            break
        prev = delta
    # the motion joints' torques: the residual of their rows at the converged state; the
    # closed-loop joints' torques: their laws there
    q = qt + cq * qdd
    qd = qtd + cv * qdd
    q[P], qd[P] = pres[:, 0], pres[:, 1]
    tau_p = np.zeros(P.size)
    full = None
    tau_c = np.zeros(0)
    if not lay.closures:
        lam = np.zeros(0)
    if ctl:
        tau_c, _ = ctl.laws_at(t1, True, q, qd, qdd, ff, ref, zc, dz, cq, cv)
        full = ctl.full(tau_c)
        pd_ = ~ctl.user
        ctl.z[pd_] = (zc + dz * q[ctl.rows])[pd_]
        ctl.e[pd_] = (ref[:, 0] - q[ctl.rows])[pd_]
    if P.size:
        M, f = _assemble(lay, q, qd)
        rhs = f + Qt - _elastic(lay, q)[1] - _damping(lay, q, qd)[0] + _load_forces(case, lay, q, t1, True)
        if ctl:
            rhs[ctl.rows] += tau_c
        if lay.closures:
            rhs += _constraints(lay, q)[1].T @ lam
        tau_p = M[P] @ qdd - rhs[P]
    return qdd, tau_p, i + 1, converged, full, lam


def _initial(case, lay, ctl=None, opt=None) -> _State:
    q, qd = _initial_state(case, lay)
    pres = _prescribed(case, 0.0, False)
    q[lay.presc], qd[lay.presc] = pres[:, 0], pres[:, 1]
    if ctl:
        qdd, tau_p, tau_c, ok, lam = _forward_closed(case, lay, ctl, q, qd, 0.0, False, opt)
        if not ok:
            ctl.unconverged_solves += 1
        _, ref = ctl.tables([0.0], False)
        ctl.e[:] = np.where(ctl.user, 0.0, ref[0, :, 0] - q[ctl.rows])
        return _State(0.0, q, qd, qdd, qdd.copy(), _joint_torques(case, lay, 0.0, False, tau_p, tau_c), lam)
    if lay.closures:
        qdd, tau_p, lam = _forward_constrained(case, lay, q, qd, 0.0, False)
        return _State(0.0, q, qd, qdd, qdd.copy(), _joint_torques(case, lay, 0.0, False, tau_p), lam)
    qdd, tau_p = _forward(case, lay, q, qd, 0.0, False)
    return _State(0.0, q, qd, qdd, qdd.copy(), _joint_torques(case, lay, 0.0, False, tau_p))


def _newmark_run(case, lay, h, opt, coef, rec, ctl=None):
    beta, gamma, am, af = coef.beta, coef.gamma, coef.alpha_m, coef.alpha_f
    t_end, restart = step_schedule(case.scenario.duration, h, case.scenario.breakpoints)
    st = _initial(case, lay, ctl, opt)
    rec.start(st)
    solves, unconverged = [], []
    for n, t1 in enumerate(t_end):
        dt = t1 - st.t
        mix = (af * st.qdd - am * st.a) / (1 - am)
        qt = st.q + dt * st.qd + dt * dt * (0.5 - beta) * st.a + beta * dt * dt * mix
        qtd = st.qd + dt * (1 - gamma) * st.a + gamma * dt * mix
        cq = beta * dt * dt * (1 - af) / (1 - am)
        cv = gamma * dt * (1 - af) / (1 - am)
        qdd, tau_p, n_solves, ok, tau_c, lam = _iterate(case, lay, opt, t1, qt, qtd, st.qdd, cq, cv, ctl, dt)
        solves.append(n_solves)
        if not ok:
            unconverged.append(n)
        q, qd = qt + cq * qdd, qtd + cv * qdd
        a = ((1 - af) * qdd + af * st.qdd - am * st.a) / (1 - am)
        pres = _prescribed(case, t1, True)
        P = lay.presc
        q[P], qd[P], a[P] = pres[:, 0], pres[:, 1], pres[:, 2]
        new = _State(t1, q, qd, qdd, a, _joint_torques(case, lay, t1, True, tau_p, tau_c), lam)
        rec.check(new, n)
        rec.emit(st, new)
        if restart[n]:
            if ctl:
                qdd_r, _, _, ok_r, _ = _forward_closed(case, lay, ctl, new.q, new.qd, t1, False, opt)
                if not ok_r:
                    ctl.unconverged_solves += 1
            else:
                qdd_r, _ = _forward(case, lay, new.q, new.qd, t1, False)
            new = _State(t1, new.q, new.qd, qdd_r, qdd_r.copy(), new.tau, new.lam)
        st = new
    return {
        "n_steps": len(t_end),
        "iterations_mean": float(np.mean(solves)),
        "iterations_max": int(np.max(solves)),
        "unconverged": unconverged,
        "t_end": t_end,
    }


def _rk4_run(case, lay, h, opt, rec):
    t_end, restart = step_schedule(case.scenario.duration, h, case.scenario.breakpoints)
    P = lay.presc

    def acc(t, left, q, qd):
        q, qd = q.copy(), qd.copy()
        pres = _prescribed(case, t, left)
        q[P], qd[P] = pres[:, 0], pres[:, 1]
        return _forward(case, lay, q, qd, t, left)

    st = _initial(case, lay)
    rec.start(st)
    q, qd = st.q, st.qd
    for n, t1 in enumerate(t_end):
        t0 = st.t
        dt = t1 - t0
        tm = t0 + 0.5 * dt
        a1 = st.qdd
        q2, v2 = q + 0.5 * dt * qd, qd + 0.5 * dt * a1
        a2 = acc(tm, False, q2, v2)[0]
        q3, v3 = q + 0.5 * dt * v2, qd + 0.5 * dt * a2
        a3 = acc(tm, False, q3, v3)[0]
        q4, v4 = q + dt * v3, qd + dt * a3
        a4 = acc(t1, True, q4, v4)[0]
        q = q + (dt / 6) * (qd + 2 * v2 + 2 * v3 + v4)
        qd = qd + (dt / 6) * (a1 + 2 * a2 + 2 * a3 + a4)
        pres = _prescribed(case, t1, True)
        q[P], qd[P] = pres[:, 0], pres[:, 1]
        qdd, tau_p = acc(t1, True, q, qd)
        new = _State(t1, q, qd, qdd, qdd, _joint_torques(case, lay, t1, True, tau_p))
        rec.check(new, n)
        rec.emit(st, new)
        if restart[n]:
            qdd_r, _ = acc(t1, False, q, qd)
            new = _State(t1, q, qd, qdd_r, qdd_r, new.tau)
        st = new
    return {
        "n_steps": len(t_end),
        "iterations_mean": None,
        "iterations_max": None,
        "unconverged": [],
        "t_end": t_end,
    }


class _Recorder:
    """(q, q̇, τ) at the output times; the step-end state on a step end, else cubic Hermite."""

    def __init__(self, case, lay, h):
        self.case, self.lay = case, lay
        self.t = case.scenario.output_times
        nt = self.t.size
        self.q = np.zeros((nt, lay.n_dof))
        self.qd = np.zeros((nt, lay.n_dof))
        self.tau = np.zeros((nt, lay.joints.size))
        self.lam = np.zeros((nt, sum(cl.n_eq for cl in lay.closures)))
        self.count = 0
        self.tol_t = 1e-9 * h
        self.meta = {}
        self.want_loads = False
        self.shape_points = 0
        self.wall0 = time.perf_counter()

    @property
    def next_time(self):
        return self.t[self.count] if self.count < self.t.size else math.inf

    def add(self, q, qd, tau, lam=None):
        i = self.count
        self.q[i], self.qd[i], self.tau[i] = q, qd, tau
        if self.lam.shape[1]:
            self.lam[i] = lam
        self.count += 1

    def start(self, st):
        if self.next_time <= self.tol_t:
            self.add(st.q, st.qd, st.tau, st.lam)

    def emit(self, s0: _State, s1: _State):
        lay = self.lay
        while self.next_time <= s1.t + self.tol_t:
            t = self.next_time
            if abs(t - s1.t) <= self.tol_t:
                self.add(s1.q, s1.qd, s1.tau, s1.lam)
                continue
            y, yd = plumbing.hermite_sample(t, [s0.t, s1.t], [s0.q, s1.q], [s0.qd, s1.qd], derivative=True)
            q, qd = y[0], yd[0]
            if lay.presc.size:
                pres = _prescribed(self.case, t, False)
                q[lay.presc], qd[lay.presc] = pres[:, 0], pres[:, 1]
            s = (t - s0.t) / (s1.t - s0.t)
            tau = (1 - s) * s0.tau + s * s1.tau
            for j, d in enumerate(self.case.scenario.drives):
                if d.kind == "torque" and not d.closed_loop:  # closed loop: linear, as DT-TMM
                    tau[j] = d.torque(t, False)
            lam = (1 - s) * s0.lam + s * s1.lam if self.lam.shape[1] else None  # linear, as τ
            self.add(q, qd, tau, lam)

    def check(self, st: _State, n: int):
        x = np.concatenate([st.q, st.qd, st.qdd])
        if np.all(np.isfinite(x)):
            return
        bad = int(np.flatnonzero(~np.isfinite(x))[0])
        names = self.lay.names
        comp = (names + [f"rate of {c}" for c in names] + [f"acceleration of {c}" for c in names])[bad]
        partial = self.result(time.perf_counter() - self.wall0, n, {**self.meta, "success": False}, "failed")
        raise SimulationError("non-finite state", t=st.t, step=n, component=comp, partial=partial)

    def result(self, wall, n_steps, meta, status="ok", warnings=()) -> SpatialResult:
        lay, n = self.lay, self.count
        nl = lay.n_links
        root, tip = np.zeros((n, nl, 3)), np.zeros((n, nl, 3))
        defl, twist, en = np.zeros((n, nl, 2)), np.zeros((n, nl)), np.zeros(n)
        Rl, Rt = np.zeros((n, nl, 3, 3)), np.zeros((n, nl, 3, 3))
        for i in range(n):
            fr = _link_frames(lay, self.q[i])
            root[i], tip[i], defl[i], twist[i] = fr["root"], fr["tip"], fr["tip_deflection"], fr["twist"]
            Rl[i], Rt[i] = fr["root_rotation"], fr["tip_rotation"]
            e = _energy(lay, self.q[i], self.qd[i])
            en[i] = e["kinetic"] + e["elastic"] + e["gravity"]
        a = lay.alpha_idx[lay.joints]
        meta = {**meta, "q": self.q[:n].copy(), "qd": self.qd[:n].copy()}
        loads = None
        nc = len(lay.closures)
        closure = {}
        if nc:
            cl_loads, gaps, angles = np.zeros((n, nc, 6)), np.zeros((n, nc)), np.zeros((n, nc))
            for i in range(n):
                cl_loads[i] = _closure_loads(lay, self.q[i], self.lam[i])[0]
                gaps[i], angles[i] = _closure_gaps(lay, self.q[i])
            closure = {"closure_loads": cl_loads, "closure_residual": gaps, "closure_angle_residual": angles}
        if self.want_loads:
            loads = np.zeros((n, nl * (lay.k + 1), 6))
            for i in range(n):
                t = float(self.t[i])
                lam = self.lam[i] if nc else None
                qdd = _forward(self.case, lay, self.q[i], self.qd[i], t, t > 0.0, self.tau[i], lam)[0]
                ext = _tip_loads(self.case, lay, _tip_frames(lay, self.q[i]), t, t > 0.0)
                points = _closure_loads(lay, self.q[i], lam)[1] if nc else ()
                loads[i] = _cut_loads(lay, self.q[i], self.qd[i], qdd, ext, points)
        shapes = _link_shapes(self.case, lay, self.q[:n], self.shape_points) if self.shape_points else None
        return SpatialResult(
            t=self.t[:n].copy(),
            link_shapes=shapes,
            joint_angle=self.q[:n, a],
            joint_rate=self.qd[:n, a],
            joint_torque=self.tau[:n].copy(),
            link_root=root,
            link_tip=tip,
            tip_deflection=defl,
            end_effector=tip[:, lay.end_effector].copy(),
            wall_time=float(wall),
            n_steps=int(n_steps),
            meta=meta,
            energy=en,
            status=status,
            warnings=tuple(warnings),
            cut_loads=loads,
            cut_load_t=self.t[:n].copy() if loads is not None else None,
            twist=twist,
            link_rotation=Rl,
            tip_rotation=Rt,
            **_result_closure_fields(closure, meta),
        )


def _result_closure_fields(closure: dict, meta: dict) -> dict:
    """The closure outputs as :class:`SpatialResult` fields (in ``meta`` where it has none)."""
    fields = {f.name for f in dataclasses.fields(SpatialResult)}
    out = {k: v for k, v in closure.items() if k in fields}
    meta.update({k: v for k, v in closure.items() if k not in fields})
    return out


def check_engine(engine) -> str:
    """The engine (None: "numba" where numba is installed, else "numpy")."""
    if engine is None:
        return "numba" if HAVE_NUMBA else "numpy"
    plumbing.choice("engine", engine, ENGINES)
    if engine == "numba" and not HAVE_NUMBA:
        raise InputError("engine", engine, "numba is not installed; use engine='numpy'")
    return engine


def check_options(integrator, tol, max_iterations, options: dict) -> dict:
    """The integrator's options with their defaults (None: the Newmark family's defaults)."""
    _checks.integrator(integrator, INTEGRATORS)
    allowed = {"newmark": ("beta", "gamma"), "generalized-alpha": ("rho_inf",), "rk4": ()}[integrator]
    _checks.integrator_options(integrator, options, allowed)
    opt = {"beta": None, "gamma": None, "rho_inf": None, **options}
    opt["tol"] = plumbing.positive_number("tol", tol)
    opt["max_iterations"] = plumbing.positive_integer("max_iterations", max_iterations)
    return opt


def check_closed_loop(case, integrator: str) -> None:
    """Refuse the closed-loop drives this solver cannot run: any with RK4 (the laws are solved
    implicitly with a Newmark step). A ``computed_torque`` feedforward is tabulated by
    :func:`dttmm.control.computed_torque` (the spatial rigid recursive Newton–Euler)."""
    for j, d in enumerate(case.scenario.drives):
        if not d.closed_loop:
            continue
        if integrator not in _STEPPED:
            raise InputError(
                f"scenario.drives[{j}].law",
                d.law.name,
                f"closed-loop drive on joint {j + 1}: integrator {integrator!r} of the spatial global "
                f"solver cannot run it (its integrators {' and '.join(map(repr, _STEPPED))} can)",
            )


def run(case, lay, h: float, integrator: str, opt: dict, engine: str, cut_loads: bool, shape_points: int):
    """The run of :func:`reference_models.spatial_global.simulate`, its settings checked there."""
    if engine == "numba":
        lay.compiled = _sn.pack(lay)
    if lay.closures and integrator not in _STEPPED:
        raise InputError(
            "integrator",
            integrator,
            f"the spatial global solver holds closed loops (model.closures: {len(lay.closures)}) with "
            f"{' and '.join(map(repr, _STEPPED))} only (index-3 multipliers)",
        )
    ctl = _Control(case, lay)
    meta = {
        "method": "spatial-global",
        "elements_per_link": lay.k,
        "h": float(h),
        "integrator": integrator,
        "strain": lay.strain,
        "engine": engine,
        "n_dof": lay.n_dof,
        "coordinates": list(lay.names),
        "versions": plumbing.versions(),
    }
    rec = _Recorder(case, lay, h)
    rec.meta = meta
    rec.want_loads = cut_loads
    rec.shape_points = shape_points
    wall0 = time.perf_counter()
    with np.errstate(over="ignore", invalid="ignore"):  # non-finite states are caught and reported
        if integrator == "rk4":
            stats = _rk4_run(case, lay, h, opt, rec)
        else:
            coef = plumbing.newmark_family(
                integrator, beta=opt["beta"], gamma=opt["gamma"], rho_inf=opt["rho_inf"]
            )
            meta.update(beta=coef.beta, gamma=coef.gamma, alpha_m=coef.alpha_m, alpha_f=coef.alpha_f)
            meta.update(tol=opt["tol"], max_iterations=opt["max_iterations"])
            stats = _newmark_run(case, lay, h, opt, coef, rec, ctl if ctl else None)
    wall = time.perf_counter() - wall0
    meta.update(
        iterations_mean=stats["iterations_mean"],
        iterations_max=stats["iterations_max"],
        time_per_step=wall / stats["n_steps"],
    )
    solves = ctl.unconverged_solves if ctl else 0
    status, warns = convergence(meta, stats["unconverged"], stats["t_end"], opt, solves)
    return rec.result(wall, stats["n_steps"], meta, status, warns)
