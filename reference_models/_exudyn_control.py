"""Closed-loop drive laws (``pd``, ``pid``, user laws) in the Exudyn reference models.

How the law enters Exudyn: every closed-loop joint i gets an
``ObjectConnectorCoordinateSpringDamper`` between the rotation coordinate of the tip node of link
i−1 (a ground coordinate for joint 1) and that of the hub node of link i, whose
``springForceUserFunction`` returns −τ. Exudyn applies −f to the hub coordinate and +f to the tip
coordinate of link i−1, i.e. +τ on the hub and the reaction −τ on the link before; the
connector's ``Force`` sensor is the reported torque. Exudyn calls the user function at every
residual evaluation of the generalized-α Newton iteration, at the step end time t_{n+1}, with the
current iterate of the joint angle (the connector's displacement, + α(0)) and rate (its
velocity), and it builds the connector's Jacobian by numerical differentiation of that function
(a connector with a user function has no analytic Jacobian): kp, kd, the integral's −h/2·ki and
the saturation are seen by Newton. So the law is **implicit at t_{n+1}**, like a spring-damper,
with no lag; the converged step satisfies it exactly.

* Law of the pd/pid joints (closed form of the algebraic loop with the moment feedback)::

      L0 = τ_ff(t) + kp (α_ref(t) − α) + kd (α̇_ref(t) − α̇) + ki z
      τ  = clip((L0 + g_M J_hub ω̇) / (1 + g_M), ±limit)

  which is τ = clip(L0 − g_M M_root) with **M_root = τ − J_hub ω̇**: the moment the hub exerts
  on the beam at its root cross-section, from the moment balance of the hub body (a point mass
  with inertia J_hub rotating with the root section); ω̇ is the angular acceleration of the hub
  node. While unsaturated, τ = L0/(1 + g_M) + c J_hub ω̇ (c = g_M/(1 + g_M)): the second term is
  linear in the accelerations, so it goes into the model as constant mass-matrix entries of an
  ``ObjectGenericODE2`` (−c J_hub on the hub rotation, +c J_hub coupling the reaction on the tip
  body of link i−1 to ω̇; non-symmetric, which the sparse LU takes), exact and in the Jacobian,
  and the user function returns L0/(1 + g_M). While saturated the user function returns
  ±limit − c J_hub ω̇ with ω̇ read from Exudyn's current acceleration vector (the Newton
  iterate): the converged step satisfies the law either way. The reported torque is the
  connector force plus c J_hub ω̇ (a hub acceleration sensor).
* Laws of time (reference, feedforward, ``computed_torque`` through
  :func:`dttmm.control.computed_torque`) at the step end with the left limit; at a segment start
  (t = 0 and every restart at a breakpoint) with the right limit.
* Integral state of a ``pid`` law: the trapezoidal rule
  z_{n+1} = z_n + h/2 ((α_ref − α)_n + (α_ref − α)_{n+1}), z_0 = 0, evaluated inside the user
  function with the current iterate (so ∂z/∂α = −h/2 is in the Jacobian) and committed by a
  PostStepUserFunction after every converged step.
* User laws: ``fn(t, state)`` with a :class:`dttmm.drives.ControlState` of the current iterate
  (every joint's angle and rate, every link's tip deflection in its clamped-root frame, and the
  moment τ_last − J_hub ω̇ with τ_last the law's latest value; integral 0). The slopes the law
  returns are not used: Exudyn differentiates the user function numerically.
* Initial accelerations (t = 0 and each restart): Exudyn solves M q̈ = f once, with ω̇ in f read
  from the initial state. Where a user function reads ω̇ (user laws; moment feedback with a
  finite limit) the start is made consistent by Newton's method on the hub accelerations, each
  evaluation one Exudyn initial-acceleration solve (``MainSolverImplicitSecondOrder.
  InitializeSolver``) with the hub accelerations of the initial state set to the iterate.
"""

from __future__ import annotations

import math

import numpy as np

from dttmm.control import time_tables
from dttmm.drives import ControlState, UserLaw

__all__ = ["ClosedLoop"]


class ClosedLoop:
    """The closed-loop joints of one Exudyn model: connectors, user functions, integral states.

    Use: :meth:`add_joint` while building (for every closed-loop joint), :meth:`assembled` after
    ``mbs.Assemble()``, :meth:`start_segment` before every integration segment, and
    :meth:`post_step` from the PostStepUserFunction.
    """

    def __init__(self, case, alpha0, hub_nodes, tip_nodes):
        self.case = case
        self.drives = case.scenario.drives
        self.n = len(self.drives)
        self.joints = [i for i, d in enumerate(self.drives) if d.closed_loop]
        self.alpha0 = [float(a) for a in alpha0]
        self.j_hub = [float(link.hub_inertia) for link in case.model.links]
        self.hub_nodes, self.tip_nodes = list(hub_nodes), list(tip_nodes)
        self.connectors: dict[int, int] = {}
        self.sensors: dict[int, int] = {}
        self.acc_sensors: dict[int, int] = {}
        self.seg_start = 0.0
        self.t_n = 0.0
        self.z = np.zeros(self.n)  # integral states at t_n
        self.e_n = np.zeros(self.n)  # α_ref − α at t_n
        self.tau_last = np.zeros(self.n)
        self.error: BaseException | None = None  # first exception raised in a user function
        self._cache: tuple | None = None  # ((t, left), ff (n,), ref (n, 2)) of the last time
        self.hub_idx = self.tip_idx = None

    # --- building ----------------------------------------------------------------------------
    def _loop_joints(self) -> list[int]:
        """Joints whose user function reads ω̇: user laws, and moment feedback that may saturate."""
        return [
            i
            for i in self.joints
            if isinstance(self.drives[i].law, UserLaw)
            or (self._mass_coupled(i) and math.isfinite(self.drives[i].law.limit))
        ]

    @property
    def needs_consistent_start(self) -> bool:
        """True when a user function reads ω̇: the initial accelerations then need the fixed
        point of :meth:`consistent_start`."""
        return bool(self._loop_joints())

    def torque(self, i: int, force: np.ndarray, hub_acc: np.ndarray | None) -> np.ndarray:
        """The law's τ of joint i from its connector force rows and, with mass coupling, the hub
        angular acceleration rows (the same output times)."""
        tau = -np.asarray(force, float)
        if self._mass_coupled(i):
            g = self.drives[i].law.moment_gain
            tau = tau + g / (1.0 + g) * self.j_hub[i] * np.asarray(hub_acc, float)
        return tau

    def add_joint(self, mbs, exu, ii, i: int, m_in: int, m_out: int) -> int:
        """Add the law's connector between the coordinate markers m_in (rotation of the tip
        node of link i−1, or ground) and m_out (rotation of hub node i); returns its number."""
        fn = self._user_law_force(i) if isinstance(self.drives[i].law, UserLaw) else self._pd_force(i)

        def force(mbs_, t, item, u, v, k, d, off):
            if self.error is not None:
                return math.nan  # stop the Newton iteration; the error is raised after the solve
            try:
                return fn(mbs_, t, u, v)
            except Exception as exc:  # Exudyn would only print it; keep it for the caller
                self.error = exc
                return math.nan

        if self._mass_coupled(i):
            # τ = L0/(1+g) + c·J_h·ω̇ (unsaturated): the second term as constant mass entries,
            # −c·J_h on the hub rotation and +c·J_h coupling the reaction on the tip body of
            # link i−1 to ω̇ (a non-symmetric mass matrix; EigenSparse's LU takes it)
            cj = self.drives[i].law.moment_gain / (1.0 + self.drives[i].law.moment_gain) * self.j_hub[i]
            nodes = ([self.tip_nodes[i - 1]] if i else []) + [self.hub_nodes[i]]
            m = np.zeros((3 * len(nodes), 3 * len(nodes)))
            m[-1, -1] = -cj
            if i:
                m[2, -1] = cj
            mbs.AddObject(ii.ObjectGenericODE2(nodeNumbers=nodes, massMatrix=m))
            self.acc_sensors[i] = mbs.AddSensor(
                ii.SensorNode(
                    nodeNumber=self.hub_nodes[i],
                    outputVariableType=exu.OutputVariableType.AngularAcceleration,
                    storeInternal=True,
                    writeToFile=False,
                )
            )
        c = mbs.AddObject(
            ii.ObjectConnectorCoordinateSpringDamper(
                markerNumbers=[m_in, m_out], stiffness=0.0, damping=0.0, springForceUserFunction=force
            )
        )
        self.connectors[i] = c
        self.sensors[i] = mbs.AddSensor(
            ii.SensorObject(
                objectNumber=c,
                outputVariableType=exu.OutputVariableType.Force,
                storeInternal=True,
                writeToFile=False,
            )
        )
        return c

    def assembled(self, mbs) -> None:
        """Global indices of the hub and tip rotation coordinates (after ``mbs.Assemble()``)."""
        ltg = mbs.systemData.GetNodeLTGODE2
        self.hub_idx = [int(ltg(nd)[2]) for nd in self.hub_nodes]
        self.tip_idx = [int(ltg(nd)[2]) for nd in self.tip_nodes]

    # --- laws of time ------------------------------------------------------------------------
    def _time_laws(self, i: int, t: float, left: bool) -> tuple[float, float, float]:
        """(α_ref, α̇_ref, τ_ff) of pd/pid joint i at t (:func:`dttmm.control.time_tables`, the
        feedforward incl. the computed torque), cached per (t, left)."""
        if self._cache is None or self._cache[0] != (t, left):
            ff, ref = time_tables(self.case, [t], left)
            self._cache = ((t, left), ff[0], ref[0])
        _, ff, ref = self._cache
        return float(ref[i, 0]), float(ref[i, 1]), float(ff[i])

    # --- the laws ----------------------------------------------------------------------------
    def _mass_coupled(self, i: int) -> bool:
        """True for a pd/pid joint whose law depends on ω̇ (moment feedback and a hub inertia)."""
        law = self.drives[i].law
        return not isinstance(law, UserLaw) and law.moment_gain != 0.0 and self.j_hub[i] != 0.0

    def _pd_force(self, i: int):
        """The user function of a pd/pid joint. With moment feedback the share c·J_h·ω̇ of τ
        (c = g/(1 + g)) is carried by the mass coupling of :meth:`add_joint` (exact, in the
        Jacobian); the function returns the rest: L0/(1 + g) while unsaturated (no ω̇), and
        ±limit − c·J_h·ω̇ while saturated (ω̇ the Newton iterate)."""
        law = self.drives[i].law
        kp, kd, ki = float(law.kp), float(law.kd), float(law.gain_integral)
        gm, lim, jh, a0 = float(law.moment_gain), float(law.limit), self.j_hub[i], self.alpha0[i]
        cj = gm / (1.0 + gm) * jh if self._mass_coupled(i) else 0.0

        def fn(mbs_, t, u, v):
            left = t > self.seg_start
            a_ref, r_ref, tff = self._time_laws(i, t, left)
            alpha = a0 + u
            l0 = tff + kp * (a_ref - alpha) + kd * (r_ref - v)
            if ki != 0.0:
                l0 += ki * (self.z[i] + 0.5 * (t - self.t_n) * (self.e_n[i] + a_ref - alpha))
            base = l0 / (1.0 + gm)
            if cj == 0.0:
                tau = base if abs(base) <= lim else math.copysign(lim, base)
                self.tau_last[i] = tau
                return -tau
            coupled = cj * mbs_.systemData.GetODE2Coordinates_tt()[self.hub_idx[i]]
            tau = base + coupled
            if abs(tau) <= lim:
                self.tau_last[i] = tau
                return -base
            tau = math.copysign(lim, tau)
            self.tau_last[i] = tau
            return -(tau - coupled)

        return fn

    def _user_law_force(self, i: int):
        drive, jh, a0 = self.drives[i], self.j_hub[i], self.alpha0[i]

        def fn(mbs_, t, u, v):
            left = t > self.seg_start
            sd = mbs_.systemData
            q, qd = sd.GetODE2Coordinates(), sd.GetODE2Coordinates_t()
            angles, rates = self._joint_states(q, qd)
            angles[i], rates[i] = a0 + u, v
            wd = sd.GetODE2Coordinates_tt()[self.hub_idx[i]]
            state = ControlState(
                joint=i,
                angle=a0 + u,
                rate=v,
                moment=float(self.tau_last[i] - jh * wd),
                integral=0.0,
                angles=tuple(angles),
                rates=tuple(rates),
                tip_deflections=tuple(self._tip_deflections(mbs_)),
                computed_torque=None,
            )
            tau = float(drive.evaluate(t, state, left)[0])
            self.tau_last[i] = tau
            return -tau

        return fn

    def _joint_states(self, q, qd) -> tuple[list, list]:
        """Every joint's angle and rate from the coordinate vectors (relative rotations)."""
        angles, rates = [], []
        for j in range(self.n):
            h, p = self.hub_idx[j], (self.tip_idx[j - 1] if j else None)
            angles.append(self.alpha0[j] + q[h] - (q[p] if j else 0.0))
            rates.append(qd[h] - (qd[p] if j else 0.0))
        return angles, rates

    def _tip_deflections(self, mbs_) -> list:
        """Transverse tip deflection of every link in its clamped-root frame (m), current state."""
        import exudyn as exu

        out = []
        pos, rot = exu.OutputVariableType.Position, exu.OutputVariableType.Rotation
        for hn, tn in zip(self.hub_nodes, self.tip_nodes):
            r, p = np.asarray(mbs_.GetNodeOutput(hn, pos)), np.asarray(mbs_.GetNodeOutput(tn, pos))
            th = float(np.asarray(mbs_.GetNodeOutput(hn, rot)).ravel()[-1])
            out.append(float(-math.sin(th) * (p[0] - r[0]) + math.cos(th) * (p[1] - r[1])))
        return out

    # --- integration hooks -------------------------------------------------------------------
    def _errors(self, mbs, t: float, left: bool) -> np.ndarray:
        """α_ref(t) − α of every pid joint (0 elsewhere) at the current state."""
        e = np.zeros(self.n)
        q, qd = mbs.systemData.GetODE2Coordinates(), mbs.systemData.GetODE2Coordinates_t()
        angles, _ = self._joint_states(q, qd)
        for i in self.joints:
            law = self.drives[i].law
            if not isinstance(law, UserLaw) and law.gain_integral != 0.0:
                e[i] = self._time_laws(i, t, left)[0] - angles[i]
        return e

    def start_segment(self, mbs, t: float) -> None:
        """Before a segment that starts at t: right limits of the laws, integral state kept."""
        self.seg_start = self.t_n = float(t)
        self.e_n = self._errors(mbs, t, False)

    def post_step(self, mbs, t: float) -> None:
        """After a converged step ending at t: commit the trapezoidal integral states."""
        e = self._errors(mbs, t, True)
        self.z += 0.5 * (t - self.t_n) * (self.e_n + e)
        self.t_n, self.e_n = float(t), e

    def consistent_start(self, mbs, exu, settings, tol=1e-10, max_iterations=8) -> int:
        """Make the initial accelerations of the segment satisfy the laws' ω̇ dependence.

        Newton's method on w (the hub angular accelerations of the closed-loop joints whose
        law reads ω̇): F(w) = the hub accelerations of Exudyn's initial-acceleration solve with
        w in the initial state; solve F(w) = w with a difference Jacobian (F is affine while no
        law saturates). Leaves w in the initial state; returns the number of solves.
        """
        sel = self._loop_joints()
        if not sel:
            return 0
        idx = [self.hub_idx[i] for i in sel]
        init = exu.ConfigurationType.Initial
        solver = exu.MainSolverImplicitSecondOrder()

        def F(w):
            a = np.asarray(mbs.systemData.GetODE2Coordinates_tt(init), float).copy()
            a[idx] = w
            mbs.systemData.SetODE2Coordinates_tt(a, init)
            solver.InitializeSolver(mbs, settings)
            out = np.asarray(mbs.systemData.GetODE2Coordinates_tt(), float)[idx]
            return out

        w = np.asarray(mbs.systemData.GetODE2Coordinates_tt(init), float)[idx]
        calls = 0
        for _ in range(max_iterations):
            f0 = F(w)
            calls += 1
            r = f0 - w
            if np.max(np.abs(r)) <= tol * max(1.0, float(np.max(np.abs(w)))):
                break
            jac = np.empty((len(idx), len(idx)))
            for j in range(len(idx)):
                dw = 1e-4 * max(1.0, abs(w[j]))
                wp = w.copy()
                wp[j] += dw
                jac[:, j] = (F(wp) - f0) / dw
                calls += 1
            w = w - np.linalg.solve(jac - np.eye(len(idx)), r)
        # leave the fixed point in the initial state
        a = np.asarray(mbs.systemData.GetODE2Coordinates_tt(init), float).copy()
        a[idx] = w
        mbs.systemData.SetODE2Coordinates_tt(a, init)
        solver.FinalizeSolver(mbs, settings)
        if self.error is not None:
            raise self.error
        return calls
