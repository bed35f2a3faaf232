"""DT-TMM simulation: the time loop around the sweeps (METHOD.md §4).

Public: :func:`simulate` (Newmark family or RK4) and :func:`accelerations`
(positions, velocities → accelerations).
"""
from __future__ import annotations

import math
import time

import numpy as np

from .case import Case
from .errors import InputError, SimulationError
from .integrators import newmark_family
from .result import make_result
from .structure import Structure, build_structure, energy, kinematics
from .sweeps import SWEEPS
from .timegrid import step_schedule, versions

__all__ = ["simulate", "accelerations"]

INTEGRATORS = ("newmark", "generalized-alpha", "rk4")


class _Drives:
    """Torques and prescribed motions of all joints at an instant."""

    def __init__(self, st: Structure):
        self.drives = st.case.scenario.drives
        self.motion = st.motion

    def torques(self, t, left=False):
        return np.array([0.0 if m else d.torque(t, left) for d, m in zip(self.drives, self.motion)])

    def motions(self, t, left=False):
        out = np.zeros((len(self.drives), 3))
        for i, (d, m) in enumerate(zip(self.drives, self.motion)):
            if m:
                out[i] = d.motion(t, left)
        return out


class _System:
    """One discretised case with its sweep; solves the step system at a given iterate."""

    def __init__(self, case: Case, k, sweep: str, strain: str = "linear"):
        if sweep not in SWEEPS:
            raise InputError("sweep", sweep, f"unknown (one of: {', '.join(SWEEPS)})")
        self.st = build_structure(case, k, strain)
        self.sweep = SWEEPS[sweep]
        self.drv = _Drives(self.st)
        self.ia = self.st.alpha_index
        self.im = self.ia[self.st.motion]
        self.cond_max = 0.0

    def elastic_split(self, x):
        st = self.st
        return [x[lk.e_slice].reshape(lk.k, lk.et.ne) for lk in st.links]

    def solve(self, q, qd, cq, cv, e_hat, ed_hat, tau, acc):
        kin = kinematics(self.st, q, qd)
        out = self.sweep(self.st, kin, cq, cv, e_hat, ed_hat, tau, acc)
        if not math.isnan(out.cond):
            self.cond_max = max(self.cond_max, out.cond)
        return out

    def accelerations(self, q, qd, t, left=False):
        tau = self.drv.torques(t, left)
        mot = self.drv.motions(t, left)
        q, qd = q.copy(), qd.copy()
        q[self.im] = mot[self.st.motion, 0]
        qd[self.im] = mot[self.st.motion, 1]
        es, eds = self.elastic_split(q), self.elastic_split(qd)
        out = self.solve(q, qd, 0.0, 0.0, es, eds, tau, mot[:, 2])
        out.torque[~self.st.motion] = tau[~self.st.motion]
        return out

    def initial_state(self):
        st = self.st
        q = np.zeros(st.n_dof)
        qd = np.zeros(st.n_dof)
        for i, d in enumerate(st.case.scenario.drives):
            q[self.ia[i]], qd[self.ia[i]] = d.initial_angle, d.initial_rate
        return q, qd


ENGINES = ("numba", "numpy")


def _engine(engine) -> str:
    """Resolve ``engine``: None → "numba" when numba imports, else "numpy"."""
    from . import _kernel

    if engine is None:
        return "numba" if _kernel.HAVE_NUMBA else "numpy"
    if engine not in ENGINES:
        raise InputError("engine", engine, f"unknown (one of: {', '.join(ENGINES)})")
    if engine == "numba" and not _kernel.HAVE_NUMBA:
        raise InputError("engine", engine,
                         "numba is not installed (pip install 'dttmm[fast]'); use engine='numpy'")
    return engine


def accelerations(case: Case, elements_per_link: int, q, qd, t: float = 0.0, *, sweep: str = "riccati",
                  engine: str | None = None, strain: str = "linear"):
    """Forward dynamics of the discretised arm: q̈ from (q, q̇) at time t.

    Coordinates as in :mod:`dttmm.structure` (``[α_1, e_11, …, α_2, …]``). Motion-driven joints
    take their angle, rate and acceleration from the law (the given values are overridden).
    ``engine``: "numba" (compiled, the default when numba is installed) or "numpy" (the
    readable reference). Returns q̈ (n_dof,).
    """
    if not isinstance(case, Case):
        raise InputError("case", case, "must be a dttmm.Case")
    engine = _engine(engine)
    sysm = _System(case, elements_per_link, sweep, strain)
    q = np.asarray(q, float)
    qd = np.asarray(qd, float)
    if q.shape != (sysm.st.n_dof,) or qd.shape != (sysm.st.n_dof,):
        raise InputError("q/qd", (q.shape, qd.shape), f"must both have shape ({sysm.st.n_dof},)")
    if engine == "numpy":
        return sysm.accelerations(q, qd, t).qdd
    from . import _kernel as K

    K.warmup()
    pk = K.pack(sysm.st)
    n = pk.n
    qdd = np.empty(pk.n_dof)
    ok, _ = K.accel(_SWEEP_CODE[sweep], pk.LC, pk.LI, pk.grav, n, pk.k, pk.im, np.ascontiguousarray(q),
                    np.ascontiguousarray(qd), sysm.drv.torques(t), sysm.drv.motions(t), pk.WE, pk.WJ, qdd,
                    np.empty(n), np.empty((pk.ncuts, 3)), pk.plain_ws(sweep == "plain"))
    if not ok:
        raise np.linalg.LinAlgError("singular matrix")
    return qdd


_SWEEP_CODE = {"riccati": 0, "plain": 1}


class _Recorder:
    """Samples the state on the output grid (cubic Hermite between step ends when needed)."""

    def __init__(self, sysm: _System, times, want_loads: bool, want_energy: bool):
        st = sysm.st
        self.sysm, self.t = sysm, times
        nt, n = times.size, st.n_links
        self.i = 0
        self.angle = np.full((nt, n), np.nan)
        self.rate = np.full((nt, n), np.nan)
        self.torque = np.full((nt, n), np.nan)
        self.root = np.full((nt, n, 2), np.nan)
        self.tip = np.full((nt, n, 2), np.nan)
        self.root_angle = np.full((nt, n), np.nan)
        self.energy = np.full(nt, np.nan) if want_energy else None
        ncuts = st.n_elements + n
        self.load_stride = max(1, int(math.ceil(nt * ncuts / 2.0e6))) if want_loads else 0
        self.loads = np.full(((nt - 1) // self.load_stride + 1, ncuts, 3), np.nan) if want_loads else None

    def _put(self, j, q, qd, torque, loads):
        st = self.sysm.st
        kin = kinematics(st, q, qd, with_terms=self.energy is not None)
        ia = self.sysm.ia
        self.angle[j], self.rate[j], self.torque[j] = q[ia], qd[ia], torque
        for i, lkn in enumerate(kin.links):
            self.root[j, i] = lkn.r[0]
            self.tip[j, i] = lkn.tip
            self.root_angle[j, i] = lkn.theta[0]
        if self.energy is not None:
            self.energy[j] = energy(st, kin)
        if self.loads is not None and j % self.load_stride == 0:
            self.loads[j // self.load_stride] = loads[:, [2, 0, 1]]

    def record(self, t0, s0, t1, s1):
        """s = (q, qd, torque, loads) at the step ends t0 < t1; sample every output time in (t0, t1]."""
        eps = 1e-9 * (t1 - t0)
        while self.i < self.t.size and self.t[self.i] <= t1 + eps:
            tj = self.t[self.i]
            if abs(tj - t1) <= eps:
                self._put(self.i, *s1)
            else:
                h = t1 - t0
                x = (tj - t0) / h
                h00, h10, h01, h11 = 2 * x**3 - 3 * x**2 + 1, x**3 - 2 * x**2 + x, -2 * x**3 + 3 * x**2, x**3 - x**2
                d00, d10, d01, d11 = (6 * x**2 - 6 * x) / h, 3 * x**2 - 4 * x + 1, (-6 * x**2 + 6 * x) / h, 3 * x**2 - 2 * x
                q = h00 * s0[0] + h10 * h * s0[1] + h01 * s1[0] + h11 * h * s1[1]
                qd = d00 * s0[0] + d10 * s0[1] + d01 * s1[0] + d11 * s1[1]
                lin = lambda a, b: (1 - x) * a + x * b
                self._put(self.i, q, qd, lin(s0[2], s1[2]), lin(s0[3], s1[3]))
            self.i += 1

    def result(self, wall, n_steps, meta, upto=None):
        m = self.i if upto is None else upto
        sl = slice(0, m)
        loads = self.loads[: (m - 1) // self.load_stride + 1] if self.loads is not None and m else None
        lt = self.t[sl][:: self.load_stride] if self.loads is not None else None
        return make_result(t=self.t[sl], joint_angle=self.angle[sl], joint_rate=self.rate[sl],
                           joint_torque=self.torque[sl], link_root=self.root[sl], link_root_angle=self.root_angle[sl],
                           link_tip=self.tip[sl], wall_time=wall, n_steps=n_steps, meta=meta, cut_loads=loads,
                           cut_load_t=lt, energy=None if self.energy is None else self.energy[sl])


def _check_state(sysm, q, qd, qdd, t, step, rec, meta, wall0):
    """Stop a diverging run: NaN/inf, or elastic displacements beyond 10 link lengths."""
    bad = ~np.isfinite(q) | ~np.isfinite(qd) | ~np.isfinite(qdd)
    st = sysm.st
    for lk in st.links:
        e = q[lk.e_slice].reshape(lk.k, lk.et.ne)
        lim = np.full(lk.et.ne, 10.0 * lk.length)
        lim[lk.et.iphi] = 100.0
        run = np.abs(e) > lim
        bad[lk.e_slice] |= run.ravel()
    if bad.any():
        idx = int(np.flatnonzero(bad)[0])
        why = "non-finite state" if not np.isfinite(q[idx] + qd[idx] + qdd[idx]) else "runaway elastic displacement"
        meta = dict(meta, success=False, failure=why)
        partial = rec.result(time.perf_counter() - wall0, step, meta)
        raise SimulationError(f"simulation diverged ({why})", t=t, step=step,
                              component=st.coordinate_names()[idx], partial=partial)


def _base_meta(st, h, integrator, sweep, iterations, tol, auto_fraction, engine, strain) -> dict:
    meta = {"method": "dttmm", "sweep": sweep, "elements_per_link": st.k, "h": float(h),
            "integrator": integrator, "iterations": iterations, "tol": tol, "n_dof": st.n_dof,
            "final_system_size": 3, "versions": versions(), "success": True, "engine": engine,
            "strain": strain}
    if iterations == "auto":
        meta["auto_fraction"] = auto_fraction
    return meta


def _progress(total, enabled):
    if not enabled:
        return None
    try:
        from tqdm import tqdm
    except ImportError:
        return None
    return tqdm(total=total, unit="step", desc="dttmm", leave=False)


def simulate(case: Case, *, elements_per_link: int, h: float, integrator: str = "newmark",
             sweep: str = "riccati", iterations: int | str | None = None, tol: float = 1e-10,
             max_iterations: int = 50, beta: float | None = None, gamma: float | None = None,
             rho_inf: float | None = None, cut_loads: bool = True, energy: bool = True,
             progress: bool | None = None, engine: str | None = None, auto_fraction: float = 0.1,
             strain: str = "linear"):
    """Simulate ``case`` by DT-TMM with k = ``elements_per_link`` elements per link and step ``h``.

    Parameters
    ----------
    integrator : "newmark" (β = ¼, γ = ½ unless given), "generalized-alpha" (``rho_inf``,
        default 0.9) or "rk4" (explicit, on the acceleration solver).
    sweep : "riccati" (stable, default) or "plain" (the paper's transfer form).
    iterations : None → iterate each step until max|Δq̈| ≤ tol·max(1, max|q̈|) (at most
        ``max_iterations`` sweeps); m ≥ 0 → exactly m + 1 sweeps per step (0 = the paper's
        one-shot linearisation); "auto" → at least 2 sweeps, then stop as soon as the iteration
        error predicted from the contraction ρ = |Δq̈_m|/|Δq̈_{m−1}|, |Δq̈_m|·ρ/(1 − ρ), is below
        ``auto_fraction`` × the local truncation error estimate |β − 1/6|/β · max|q̈_{n+1} − q̈_n|
        (both measured in q̈; multiplied by βh² they are displacement errors), or the
        ``tol`` rule is met.
    engine : "numba" (compiled kernel, default when numba is installed) or "numpy" (the
        readable reference implementation; same results to round-off).
    strain : the elements' axial strain, "linear" (default: u/l, unconditionally stable with
        the trapezoidal rule) or "second-order" (u/l + ½ wᵀGw: the chord shortens as the element
        bends; converges much faster in k for extensible links, but with the trapezoidal rule
        it needs h small enough to resolve the axial-bending coupling — measured on single_link:
        h = 4e-3 diverged at k = 2 and 8, h ≤ 2e-3 ran; use generalised-α for large steps).
        See docs/method.md §2. Inextensible links are unaffected.
    cut_loads, energy : record the loads at every cut and the total energy on the output grid.
    progress : show a progress bar (default: on for runs of more than 20 000 element-steps × 1000).

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``.

    Raises
    ------
    InputError for bad settings; SimulationError (with ``.partial``) when the run diverges.
    """
    if not isinstance(case, Case):
        raise InputError("case", case, "must be a dttmm.Case")
    if integrator not in INTEGRATORS:
        raise InputError("integrator", integrator, f"unknown (one of: {', '.join(INTEGRATORS)})")
    if iterations is not None and iterations != "auto" and (
            isinstance(iterations, bool) or not isinstance(iterations, (int, np.integer)) or iterations < 0):
        raise InputError("iterations", iterations, "must be None, \"auto\" or an integer ≥ 0")
    if not (isinstance(tol, (int, float)) and 0 < tol < 1):
        raise InputError("tol", tol, "must lie in (0, 1)")
    if isinstance(auto_fraction, bool) or not isinstance(auto_fraction, (int, float)) \
            or not auto_fraction > 0:
        raise InputError("auto_fraction", auto_fraction, "must be positive")
    if isinstance(max_iterations, bool) or not isinstance(max_iterations, (int, np.integer)) \
            or max_iterations < 1:
        raise InputError("max_iterations", max_iterations, "must be an integer ≥ 1")
    engine = _engine(engine)
    fam = None if integrator == "rk4" else newmark_family(integrator, beta=beta, gamma=gamma, rho_inf=rho_inf)
    if engine == "numba":
        return _simulate_numba(case, elements_per_link, h, integrator, sweep, iterations, tol, max_iterations,
                               fam, cut_loads, energy, progress, auto_fraction, strain)
    scen = case.scenario
    t_end, restart = step_schedule(scen.duration, h, scen.breakpoints)
    sysm = _System(case, elements_per_link, sweep, strain)
    st = sysm.st
    meta = _base_meta(st, h, integrator, sweep, iterations, tol, auto_fraction, "numpy", strain)
    rec = _Recorder(sysm, scen.output_times, cut_loads, energy)
    n_steps = t_end.size
    if progress is None:
        progress = n_steps * max(st.n_elements, 1) > 2e7
    bar = _progress(n_steps, progress)
    wall0 = time.perf_counter()

    q, qd = sysm.initial_state()
    try:
        out = sysm.accelerations(q, qd, 0.0)
    except np.linalg.LinAlgError as exc:
        meta.update(success=False, failure=str(exc))
        raise SimulationError(f"initial acceleration solve failed ({exc})", t=0.0, step=0,
                              component="step system", partial=rec.result(0.0, 0, meta, upto=0)) from None
    qdd = out.qdd
    q[sysm.im], qd[sysm.im] = sysm.drv.motions(0.0)[st.motion, 0], sysm.drv.motions(0.0)[st.motion, 1]
    s_prev = (q.copy(), qd.copy(), out.torque.copy(), out.loads.copy())
    rec.record(-1.0, s_prev, 0.0, s_prev)
    if integrator == "rk4":
        stepper = _rk4_stepper(sysm)
    else:
        stepper = _newmark_stepper(sysm, fam, iterations, tol, max_iterations, auto_fraction)
    state = stepper.init(q, qd, qdd)
    t0 = 0.0
    for n in range(n_steps):
        t1 = t_end[n]
        try:
            state, out = stepper.step(state, t0, t1)
        except (np.linalg.LinAlgError, FloatingPointError) as exc:
            meta.update(success=False, failure=str(exc))
            raise SimulationError(f"linear solve failed ({exc})", t=t1, step=n, component="step system",
                                  partial=rec.result(time.perf_counter() - wall0, n, meta)) from None
        q, qd, qdd = state[0], state[1], state[2]
        _check_state(sysm, q, qd, qdd, t1, n, rec, meta, wall0)
        if restart[n]:  # a drive jumps at t1: restart with the right-hand limit; the sample
            # recorded at t1 keeps the left limit (the torques and loads of the step's own solve)
            state = stepper.restart(state, sysm.accelerations(q, qd, t1, left=False).qdd)
        s_cur = (q.copy(), qd.copy(), out.torque.copy(), out.loads.copy())
        rec.record(t0, s_prev, t1, s_cur)
        s_prev, t0 = s_cur, t1
        if bar is not None:
            bar.update(1)
    wall = time.perf_counter() - wall0
    if bar is not None:
        bar.close()
    meta.update(stepper.stats(n_steps))
    if sweep == "plain":
        meta["final_system_cond"] = sysm.cond_max
    meta["time_per_step"] = wall / n_steps
    return rec.result(wall, n_steps, meta)


def _lte_factor(fam) -> float:
    """|β − 1/6|/β: the Newmark local truncation error in q, (β − 1/6)h²(q̈_{n+1} − q̈_n),
    expressed like an acceleration error (divided by the βh² that maps q̈ errors to q)."""
    return abs(fam.beta - 1.0 / 6.0) / fam.beta


class _newmark_stepper:
    """Newmark / generalised-α with the frozen-coefficient iteration of METHOD.md §4."""

    def __init__(self, sysm, fam, iterations, tol, max_iterations, auto_fraction=0.1):
        self.s, self.fam = sysm, fam
        self.auto = iterations == "auto"
        self.fixed = None if self.auto else iterations
        self.tol, self.maxit = tol, max_iterations
        self.auto_fraction = auto_fraction
        self.lte = _lte_factor(fam)
        self.sweeps = 0
        self.max_sweeps = 0
        self.unconverged = 0

    def init(self, q, qd, qdd):
        return q, qd, qdd, qdd.copy()

    def restart(self, state, qdd):
        return state[0], state[1], qdd, qdd.copy()

    def step(self, state, t0, t1):
        s, st = self.s, self.s.st
        q, qd, qdd, a = state
        h = t1 - t0
        qt, qdt, cq, cv = self.fam.predict(h, q, qd, qdd, a)
        tau = s.drv.torques(t1, left=True)
        mot = s.drv.motions(t1, left=True)
        mm = st.motion
        e_hat, ed_hat = s.elastic_split(qt), s.elastic_split(qdt)
        x = qdd.copy()
        x[s.im] = mot[mm, 2]
        nsweep = self.maxit if self.fixed is None else self.fixed + 1
        prev_dx = np.inf
        converged = self.fixed is not None
        for it in range(nsweep):
            qi = qt + cq * x
            qdi = qdt + cv * x
            qi[s.im], qdi[s.im] = mot[mm, 0], mot[mm, 1]
            out = s.solve(qi, qdi, cq, cv, e_hat, ed_hat, tau, mot[:, 2])
            dx = np.max(np.abs(out.qdd - x))
            x = out.qdd
            if self.fixed is None:
                scale = max(1.0, np.max(np.abs(x)))
                if dx <= self.tol * scale:
                    converged = True
                    break
                if it >= 3 and dx >= 0.9 * prev_dx and dx <= 1e3 * self.tol * scale:
                    converged = True  # stagnation at the round-off floor
                    break
                if not np.isfinite(dx):
                    break
                if self.auto and it >= 1 and dx < prev_dx:
                    rr = dx / prev_dx  # contraction → remaining iteration error dx·ρ/(1 − ρ)
                    if dx * rr / (1.0 - rr) <= self.auto_fraction * self.lte * np.max(np.abs(x - qdd)):
                        converged = True
                        break
                prev_dx = dx
        n_used = it + 1
        self.sweeps += n_used
        self.max_sweeps = max(self.max_sweeps, n_used)
        self.unconverged += not converged
        qn = qt + cq * x
        qdn = qdt + cv * x
        qn[s.im], qdn[s.im] = mot[mm, 0], mot[mm, 1]
        an = self.fam.aux(x, qdd, a)
        an[s.im] = x[s.im]
        out.torque[~mm] = tau[~mm]
        return (qn, qdn, x, an), out

    def stats(self, n_steps):
        return {"iterations_mean": self.sweeps / max(n_steps, 1), "iterations_max": self.max_sweeps,
                "unconverged_steps": self.unconverged}


class _rk4_stepper:
    """Classical RK4 on (q, q̇) with the exact acceleration solver; motion joints follow the law."""

    def __init__(self, sysm):
        self.s = sysm
        self.calls = 0

    def init(self, q, qd, qdd):
        return q, qd, qdd

    def restart(self, state, qdd):
        return state[0], state[1], qdd

    def step(self, state, t0, t1):
        s = self.s
        q, qd, qdd = state
        h = t1 - t0
        f = lambda qq, vv, t, left=False: s.accelerations(qq, vv, t, left)
        k1v, k1a = qd, qdd
        o2 = f(q + 0.5 * h * k1v, qd + 0.5 * h * k1a, t0 + 0.5 * h)
        k2v, k2a = qd + 0.5 * h * k1a, o2.qdd
        o3 = f(q + 0.5 * h * k2v, qd + 0.5 * h * k2a, t0 + 0.5 * h)
        k3v, k3a = qd + 0.5 * h * k2a, o3.qdd
        o4 = f(q + h * k3v, qd + h * k3a, t1, True)
        k4v, k4a = qd + h * k3a, o4.qdd
        qn = q + h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v)
        qdn = qd + h / 6 * (k1a + 2 * k2a + 2 * k3a + k4a)
        mot = s.drv.motions(t1, left=True)
        qn[s.im], qdn[s.im] = mot[s.st.motion, 0], mot[s.st.motion, 1]
        out = f(qn, qdn, t1, True)
        self.calls += 4
        return (qn, qdn, out.qdd), out

    def stats(self, n_steps):
        return {"iterations_mean": 4.0, "iterations_max": 4, "unconverged_steps": 0}


# ---------------------------------------------------------------------------------------------
# Compiled engine (dttmm._kernel): the same time loop, run inside numba.

def _drive_tables(sysm: _System, t_end, restart, rk4: bool):
    """Drive values the kernel needs, per step: torques and motion (α, α̇, α̈) at the step end
    (left limits), at restart steps also the right limits, and for RK4 at the mid-step."""
    st = sysm.st
    n, ns = st.n_links, t_end.size
    t_start = np.concatenate(([0.0], t_end[:-1]))
    t_mid = t_start + 0.5 * (t_end - t_start)
    taul, motl = np.zeros((ns, n)), np.zeros((ns, n, 3))
    taur, motr = np.zeros((ns, n)), np.zeros((ns, n, 3))
    taum, motm = (np.zeros((ns, n)), np.zeros((ns, n, 3))) if rk4 else (np.zeros((1, n)), np.zeros((1, n, 3)))
    rs = np.flatnonzero(restart)
    for i, (d, m) in enumerate(zip(sysm.drv.drives, st.motion)):
        if m:
            motl[:, i] = [d.motion(t, True) for t in t_end]
            if rs.size:
                motr[rs, i] = [d.motion(t, False) for t in t_end[rs]]
            if rk4:
                motm[:, i] = [d.motion(t, False) for t in t_mid]
        else:
            taul[:, i] = [d.torque(t, True) for t in t_end]
            if rs.size:
                taur[rs, i] = [d.torque(t, False) for t in t_end[rs]]
            if rk4:
                taum[:, i] = [d.torque(t, False) for t in t_mid]
    return taul, motl, taur, motr, taum, motm


def _load_plan(rec: _Recorder, t_end, i0: int):
    """Step ends whose cut loads the recorder needs (samples j ≡ 0 mod load_stride, and the
    step end before a sample that is interpolated)."""
    need = np.zeros(t_end.size, np.bool_)
    if rec.loads is None:
        return need
    stride = rec.load_stride
    j = np.arange(((i0 + stride - 1) // stride) * stride, rec.t.size, stride)
    t_start = np.concatenate(([0.0], t_end[:-1]))
    eps = 1e-9 * (t_end - t_start)
    nj = np.searchsorted(t_end + eps, rec.t[j], side="left")
    ok = nj < t_end.size
    j, nj = j[ok], nj[ok]
    need[nj] = True
    inexact = np.abs(rec.t[j] - t_end[nj]) > eps[nj]
    prev = nj[inexact] - 1
    need[prev[prev >= 0]] = True
    return need


def _simulate_numba(case, k, h, integrator, sweep, iterations, tol, max_iterations, fam, cut_loads,
                    want_energy, progress, auto_fraction, strain="linear"):
    from . import _kernel as K

    sysm = _System(case, k, sweep, strain)  # validates strain before any compile
    compile_time = K.warmup() if not K.is_warm() else None
    scen = case.scenario
    t_end, restart = step_schedule(scen.duration, h, scen.breakpoints)
    st = sysm.st
    pk = K.pack(st)
    n, nd = pk.n, pk.n_dof
    meta = _base_meta(st, h, integrator, sweep, iterations, tol, auto_fraction, "numba", strain)
    if compile_time is not None:
        meta["compile_time"] = compile_time
    rec = _Recorder(sysm, scen.output_times, cut_loads, want_energy)
    n_steps = t_end.size
    if progress is None:
        progress = n_steps * max(st.n_elements, 1) > 2e8
    bar = _progress(n_steps, progress)
    wall0 = time.perf_counter()
    rk4 = integrator == "rk4"
    drv = _drive_tables(sysm, t_end, restart, rk4)
    sw = _SWEEP_CODE[sweep]
    pws = pk.plain_ws(sweep == "plain")

    # initial state and accelerations (as the numpy path)
    q, qd = sysm.initial_state()
    mot0 = sysm.drv.motions(0.0)
    qdd, torque, loads = np.empty(nd), np.empty(n), np.empty((pk.ncuts, 3))
    ok, cond0 = K.accel(sw, pk.LC, pk.LI, pk.grav, n, pk.k, pk.im, q, qd, sysm.drv.torques(0.0), mot0, pk.WE,
                        pk.WJ, qdd, torque, loads, pws)
    if not ok:
        meta.update(success=False, failure="Singular matrix")
        raise SimulationError("initial acceleration solve failed (Singular matrix)", t=0.0, step=0,
                              component="step system", partial=rec.result(0.0, 0, meta, upto=0))
    q[sysm.im], qd[sysm.im] = mot0[st.motion, 0], mot0[st.motion, 1]
    s_prev = (q.copy(), qd.copy(), torque.copy(), loads.copy())
    recarr = (rec.t, rec.angle, rec.rate, rec.torque, rec.root, rec.tip, rec.root_angle,
              rec.energy if rec.energy is not None else np.zeros(0),
              rec.loads if rec.loads is not None else np.zeros((0, pk.ncuts, 3)))
    stride = rec.load_stride if rec.loads is not None else 0
    ia = sysm.ia.astype(np.int64)
    # the samples at t = 0 (compiled recorder, as rec.record(-1, s, 0, s))
    rec.i = K._record(pk.LC, pk.LI, pk.grav, n, pk.k, ia, -1.0, 0.0, *s_prev, *s_prev, np.empty(nd),
                      np.empty(nd), rec.i, recarr, stride, want_energy)

    if rk4:
        famv, itmode, nfix = np.zeros(5), K.IT_FIXED, 3
    else:
        famv = np.array([fam.beta, fam.gamma, fam.alpha_m, fam.alpha_f, _lte_factor(fam)])
        if iterations is None:
            itmode, nfix = K.IT_TOL, 0
        elif iterations == "auto":
            itmode, nfix = K.IT_AUTO, 0
        else:
            itmode, nfix = K.IT_FIXED, int(iterations)
    state = (q, qd, qdd, qdd.copy())
    prev = s_prev
    need = _load_plan(rec, t_end, rec.i)
    stats = np.zeros(8)
    stats[3] = 0.0 if math.isnan(cond0) else cond0
    stats[7] = rec.i
    chunk = n_steps if bar is None else max(1, n_steps // 200)
    status = 0
    for a in range(0, n_steps, chunk):
        b = min(n_steps, a + chunk)
        status = K.run(1 if rk4 else 0, sw, itmode, nfix, float(tol), int(max_iterations),
                       float(auto_fraction), famv, pk.LC, pk.LI, pk.grav, n, pk.k, pk.im, ia, pk.lim, state,
                       t_end, restart, a, b, drv, need, prev, recarr, stride, want_energy, pk.WE, pk.WJ, pws, stats)
        if bar is not None:
            bar.update(int(stats[4]) - a)
        if status:
            break
    rec.i = int(stats[7])
    wall = time.perf_counter() - wall0
    if bar is not None:
        bar.close()
    done = int(stats[4])
    if status:
        step = done
        if status == 3:
            why = "linear solve failed (Singular matrix)"
            meta.update(success=False, failure="Singular matrix")
            raise SimulationError(why, t=float(t_end[step]), step=step, component="step system",
                                  partial=rec.result(wall, step, meta))
        why = "non-finite state" if status == K.ST_NONFINITE else "runaway elastic displacement"
        meta = dict(meta, success=False, failure=why)
        raise SimulationError(f"simulation diverged ({why})", t=float(t_end[step]), step=step,
                              component=st.coordinate_names()[int(stats[6])],
                              partial=rec.result(wall, step, meta))
    meta.update({"iterations_mean": stats[0] / max(n_steps, 1), "iterations_max": int(stats[1]),
                 "unconverged_steps": int(stats[2])})
    if rk4:
        meta.update({"iterations_mean": 4.0, "iterations_max": 4, "unconverged_steps": 0})
    if sweep == "plain":
        meta["final_system_cond"] = float(stats[3])
    meta["time_per_step"] = wall / n_steps
    return rec.result(wall, n_steps, meta)
