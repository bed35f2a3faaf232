"""Closed-loop drive laws in the global-equation solver (numpy engine).

A closed-loop joint i adds its law's torque τ_i to the generalized force of α_i. The law is
evaluated implicitly at the step end t_{n+1} with the state there, through the law objects of
:mod:`dttmm.drives`:

* ``pd``/``pid``: τ = clip(L0 − g_M M_root, ±limit) with L0 = τ_ff + kp (α_ref − α)
  + kd (α̇_ref − α̇) + ki z and the root bending moment M_root = τ − J_hub ω̇_i (moment balance
  of the hub, a point mass with inertia J_hub rotating with the link root), ω̇_i the absolute
  angular acceleration of link i's root cross-section: a fixed 0/1 row of q̈ (the joint angles
  up to i and the element rotations φ of every inboard link). The algebraic loop in τ is
  solved in closed form, τ = clip((L0 + g_M J_hub ω̇_i)/(1 + g_M), ±limit).
* the integral state of ``pid`` by the trapezoidal rule,
  z_{n+1} = z_n + (h/2)(α_ref(t_n) − α_n + α_ref(t_{n+1}) − α_{n+1}), z(0) = 0;
* a user law at the latest iterate, seeing M_root = τ_used − J_hub ω̇_i of that iterate.

The step iteration adds the law's linearisation in q̈ to the iteration matrix: the slope in
α̈_i (through α, α̇ and z) on the diagonal and the slope in ω̇_i along its exact row, so the
matrix is not symmetric (the dense LU solve does not mind).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from dttmm.drives import PID, ComputedTorque, ControlState, UserLaw
from dttmm.errors import InputError

STEPPED = ("newmark", "generalized-alpha")


def require_stepped(case, what: str) -> None:
    """Refuse a closed-loop case for ``what`` (an integrator or a function) that cannot solve
    the laws implicitly.

    Raises
    ------
    InputError
        Naming ``scenario.drives[i].law`` and the integrators that can.
    """
    for i, d in enumerate(case.scenario.drives):
        if d.closed_loop:
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.name,
                f"closed-loop drive on joint {i + 1}: {what} of the global solver cannot run it "
                f"(its integrators {' and '.join(map(repr, STEPPED))} can)",
            )


def require_python_engine(case) -> None:
    """Refuse a user law (a Python callable) for the compiled engine."""
    for i, d in enumerate(case.scenario.drives):
        if isinstance(d.law, UserLaw):
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.label,
                f"a Python user law on joint {i + 1} cannot run in the compiled engine; use engine='numpy'",
            )


def omega_rows(lay) -> np.ndarray:
    """(n, N) 0/1 rows W with ω̇_i = W[i] @ q̈: the absolute angular acceleration of link i's
    root cross-section is the sum of the joint accelerations α̈_j (j ≤ i) and of the element
    rotations φ̈ of every element inboard of link i."""
    W = np.zeros((lay.n_links, lay.n_dof))
    for i in range(lay.n_links):
        W[i, lay.alpha_idx[: i + 1]] = 1.0
        phi = lay.e_idx[: lay.first_el[i], 2]
        W[i, phi[phi >= 0]] = 1.0
    return W


@dataclass
class Loop:
    """The closed-loop joints of a case on a layout and what their laws need."""

    case: object
    lay: object
    joints: np.ndarray  # (nc,) closed-loop joints
    rows: np.ndarray  # (nc,) q index of their α
    omega: np.ndarray  # (nc, N) ω̇ rows
    j_hub: np.ndarray  # (nc,) hub inertia of the driven link (kg·m²)
    pid: np.ndarray  # (nc,) bool: has an integral state
    bare: list  # per joint: the pd/pid law without moment feedback and limit (gives L0); None for a user law
    user: bool  # some law is a user law (needs tip deflections)
    tips: object  # q -> (n,) tip deflections in the clamped-root frames (m)
    _ct: dict = field(default_factory=dict)

    def computed_torque(self, t: float, left: bool) -> np.ndarray | None:
        """Rigid inverse dynamics of the references at t (n,), cached per (t, left)."""
        key = (float(t), bool(left))
        if key not in self._ct:
            from dttmm.control import computed_torque

            if len(self._ct) > 8:
                self._ct.clear()
            self._ct[key] = np.asarray(computed_torque(self.case, t, left), float)
        return self._ct[key]


def loop_of(case, lay, tips) -> Loop | None:
    """The :class:`Loop` of ``case``, or None without closed-loop drives. ``tips``: q ↦ the
    links' tip deflections in their clamped-root frames (n,) (m), for user laws."""
    drives = case.scenario.drives
    joints = np.array([i for i, d in enumerate(drives) if d.closed_loop], int)
    if joints.size == 0:
        return None
    bare, pid, ct = [], [], False
    for i in joints:
        law = drives[i].law
        if isinstance(law, UserLaw):
            bare.append(None)
            pid.append(False)
            continue
        bare.append(dataclasses.replace(law, moment_gain=0.0, limit=math.inf))
        pid.append(isinstance(law, PID))
        ct |= isinstance(law.feedforward, ComputedTorque)
    return Loop(
        case=case,
        lay=lay,
        joints=joints,
        rows=lay.alpha_idx[joints],
        omega=omega_rows(lay)[joints],
        j_hub=np.array([case.model.links[i].hub_inertia for i in joints], float),
        pid=np.array(pid, bool),
        bare=bare,
        user=any(b is None for b in bare),
        tips=tips,
    )


def reference_angles(loop: Loop, t: float) -> np.ndarray:
    """α_ref(t) (nc,) of the pd/pid joints (0 for user laws); the references are continuous."""
    out = np.zeros(loop.joints.size)
    for c, law in enumerate(loop.bare):
        if law is not None:
            out[c] = law.reference.motion(t, False)[0]
    return out


def evaluate(loop: Loop, t, left, q, qd, qdd, z, tau_used):
    """The laws at one iterate.

    Parameters
    ----------
    loop : Loop
    t : float
        Time (s); ``left`` picks the left limit of the laws of time.
    q, qd, qdd : (N,) arrays
        The iterate's coordinates, rates and accelerations (ω̇ = W q̈).
    z : (nc,) array
        Integral states at this iterate (rad·s; used by ``pid`` only).
    tau_used : (nc,) array
        Torques of the solve that produced the iterate (N·m): a user law's M_root.

    Returns
    -------
    tau, d_alpha, d_rate, d_z, d_omega : (nc,) arrays
        Torques (N·m) and their total slopes with the moment loop closed.
    """
    nc = loop.joints.size
    out = np.zeros((5, nc))
    lay = loop.lay
    a = lay.alpha_idx
    angles, rates = tuple(q[a].tolist()), tuple(qd[a].tolist())
    tips = tuple(np.asarray(loop.tips(q), float).tolist()) if loop.user else ()
    wdot = loop.omega @ qdd
    drives = loop.case.scenario.drives
    for c, i in enumerate(loop.joints):
        d, J, r = drives[i], loop.j_hub[c], loop.rows[c]
        base = ControlState(i, float(q[r]), float(qd[r]), 0.0, 0.0, angles, rates, tips)
        if loop.bare[c] is None:
            st = dataclasses.replace(base, moment=float(tau_used[c] - J * wdot[c]))
            tau, da, dv, _ = d.evaluate(t, st, left)
            out[:, c] = tau, da, dv, 0.0, 0.0
            continue
        law = d.law
        ct = None
        if isinstance(law.feedforward, ComputedTorque):
            ct = float(loop.computed_torque(t, left)[i])
        base = dataclasses.replace(base, integral=float(z[c]), computed_torque=ct)
        L0 = loop.bare[c].evaluate(t, base, left)[0]
        gm = law.moment_gain
        tau = min(max((L0 + gm * J * wdot[c]) / (1.0 + gm), -law.limit), law.limit)
        tau, da, dv, dm = d.evaluate(t, dataclasses.replace(base, moment=float(tau - J * wdot[c])), left)
        saturated = da == 0.0 and dv == 0.0 and dm == 0.0 and abs(tau) >= law.limit
        den = 1.0 - dm  # τ = g(α, α̇, z, τ − J ω̇) solved for τ
        out[:, c] = tau, da / den, dv / den, (0.0 if saturated else law.gain_integral) / den, -dm * J / den
    return tuple(out)


def linearise(loop: Loop, A, rhs, x, laws, cq: float, cv: float, dz) -> None:
    """Add the laws' torques and their linearisation in q̈ at the iterate x to A q̈ = rhs.

    With s = ∂τ/∂α c_q + ∂τ/∂α̇ c_v + ∂τ/∂z dz c_q (dz (nc,) = ∂z/∂α) and s_ω = ∂τ/∂ω̇:
    A[α_i, α_i] −= s, A[α_i, :] −= s_ω W_i, rhs[α_i] += τ − s x[α_i] − s_ω W_i x.
    """
    tau, da, dv, dzt, dw = laws
    for c, r in enumerate(loop.rows):
        s = da[c] * cq + dv[c] * cv + dzt[c] * dz[c] * cq
        A[r, r] -= s
        A[r] -= dw[c] * loop.omega[c]
        rhs[r] += tau[c] - s * x[r] - dw[c] * (loop.omega[c] @ x)


def applied(loop: Loop, laws, dx, cq: float, cv: float, dz) -> np.ndarray:
    """Torques (nc,) the linearised laws applied in a solve that changed q̈ by dx: the
    τ that a user law's next M_root = τ − J_hub ω̇ refers to."""
    tau, da, dv, dzt, dw = laws
    s = da * cq + dv * cv + dzt * dz * cq
    return tau + s * dx[loop.rows] + dw * (loop.omega @ dx)
