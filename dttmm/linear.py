"""Linearisation of the DT-TMM forward dynamics and the arm's natural modes.

:func:`linearize` writes the discretised arm near a state (q₀, q̇₀) at time t as

    M δq̈ + D δq̇ + K δq = B δτ,

over the *free* coordinates: the DT-TMM coordinates (:mod:`dttmm.structure`) without the angles
of motion-driven joints, which stay on their law (held). δτ are the torques of the
torque-driven joints (open- or closed-loop: a closed-loop joint is a free joint whose torque is
an input here). Everything comes from the DT-TMM sweep (:func:`dttmm.sweeps.accelerations`):

* M: the sweep's q̈ is affine in applied generalized forces Q, so the response to unit forces,
  differenced against Q = 0, gives M⁻¹ column by column, exactly (to round-off).
* K = −M ∂q̈/∂q and D = −M ∂q̈/∂q̇, the derivatives by an 8th-order central difference
  stencil with steps of 2e-4 (angles in rad, displacements in units of the element length;
  larger steps meet the nonlinearity of the element kinematics, smaller ones round-off).
  Since M(q) q̈ = Q(t) − h(q, q̇) − f(q, q̇), at a general state

      K = ∂f/∂q + ∂h/∂q + (∂M/∂q) q̈₀,    D = ∂f/∂q̇ + ∂h/∂q̇,

  i.e. K holds the elastic tangent stiffness, the gravity and geometric (centrifugal) terms of
  the state, and the change of the inertia forces M q̈₀ with the configuration; D holds the
  material damping and the gyroscopic / Coriolis terms. At rest without gravity, K is the
  elastic stiffness and D the material damping. K need not be symmetric at a general state.
* B = M ∂q̈/∂τ (a unit column on each torque-driven joint's angle).

:func:`modes` solves K φ = ω² M φ with motion-driven joints held and torque-driven joints free.
"""

from __future__ import annotations

import numpy as np

from .case import Case
from .errors import InputError
from .modal import (  # noqa: F401 - _STENCIL and STEP are read as dttmm.linear's too
    _STENCIL,
    MAX_FREE,
    STEP,
    Linearization,
    Modes,
    _damping_ratios,
    _eigen,
    _has_damping,
    check_n,
    derivative,
    eigen_modes,
    modes_of,
    state_pair,
)
from .result import tip_deflection
from .structure import STRAINS, Structure, build_structure, kinematics
from .sweeps import accelerations as sweep_accelerations

__all__ = ["Linearization", "Modes", "frequencies", "linearize", "modes"]


def _drive_inputs(case: Case, st: Structure, t: float, torque) -> tuple[np.ndarray, np.ndarray]:
    """(τ (n,), motion (n, 3)) at t: open-loop torque laws' values (closed-loop joints: 0,
    or the given ``torque``), motion laws' (α, α̇, α̈)."""
    n = st.n_links
    tau, mot = np.zeros(n), np.zeros((n, 3))
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "motion":
            mot[i] = d.motion(t)
        elif not d.closed_loop:
            tau[i] = d.torque(t)
    if torque is not None:
        given = np.asarray(torque, float)
        if given.shape != (n,) or not np.all(np.isfinite(given)):
            raise InputError("torque", torque, f"must be {n} finite joint torques (N·m)")
        tau = np.where(st.motion, 0.0, given)
    return tau, mot


def _point(case: Case, st: Structure, mot: np.ndarray, state) -> tuple[np.ndarray, np.ndarray]:
    """Full (q, q̇) of the linearisation point; motion-driven joints on their law."""
    if state is None:
        q, qd = np.zeros(st.n_dof), np.zeros(st.n_dof)
        for i, d in enumerate(case.scenario.drives):
            q[st.links[i].i_alpha] = d.initial_angle
    else:
        q, qd = state_pair(state, st.n_dof)
    im = st.alpha_index[st.motion]
    q[im], qd[im] = mot[st.motion, 0], mot[st.motion, 1]
    return q, qd


def _scales(st: Structure) -> np.ndarray:
    """Scale of each coordinate for the difference steps: 1 for angles (α, φ), the element
    length for displacements (u, v)."""
    s = np.ones(st.n_dof)
    for lk in st.links:
        et = lk.et
        blk = np.ones(et.ne)
        blk[[i for i in (et.iu, et.iv) if i >= 0]] = et.l
        s[lk.e_slice] = np.tile(blk, lk.k)
    return s


def _spatial(case) -> bool:
    """Whether ``case`` is a spatial arm (a SpatialCase or a (SpatialManipulator, Scenario)
    pair): :mod:`dttmm.spatial.linear` linearises it."""
    from .spatial.case import SpatialCase
    from .spatial.model import SpatialManipulator

    if isinstance(case, SpatialCase):
        return True
    return isinstance(case, tuple) and len(case) == 2 and isinstance(case[0], SpatialManipulator)


def _check(case, elements_per_link, t, strain) -> tuple[Structure, float]:
    if not isinstance(case, Case):
        raise InputError("case", case, "must be a dttmm.Case or a spatial case")
    if strain not in STRAINS:
        raise InputError("strain", strain, f"unknown (one of: {', '.join(STRAINS)})")
    try:
        t = float(t)
    except (TypeError, ValueError):
        raise InputError("t", t, "must be a time in s") from None
    if not np.isfinite(t):
        raise InputError("t", t, "must be finite")
    st = build_structure(case, elements_per_link, strain)
    st.require_flexible("the planar linearisation (dttmm.linear, natural modes)")
    return st, t


def linearize(
    case: Case,
    elements_per_link: int,
    t: float = 0.0,
    state=None,
    *,
    strain: str = "linear",
    torque=None,
    step: float = STEP,
) -> Linearization:
    """Linearise the DT-TMM forward dynamics of ``case`` about a state (see the module doc).

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
        Elements per link k.
    t : float
        Time (s) at which the drives' laws are evaluated (motion joints' α, α̇, α̈; open-loop
        torques).
    state : None or (q, qd)
        None: rest — torque-driven joints at their initial angles, zero rates, undeformed links.
        Else full (n_dof,) coordinate and rate vectors (order of :mod:`dttmm.structure`);
        entries of motion-driven joints are replaced by their law's values.
    strain : "linear" or "second-order"
        The elements' axial strain measure.
    torque : None or (n,) array
        Nominal joint torques (N·m) of the torque-driven joints at the point; default: the
        open-loop laws' values at t and 0 for closed-loop joints.

    Returns
    -------
    Linearization

    A spatial case goes to :func:`dttmm.spatial.linear.linearize` (the same record; there
    ``state`` may also be ``"equilibrium"``).
    """
    if _spatial(case):
        from .spatial.linear import linearize as spatial_linearize

        return spatial_linearize(case, elements_per_link, t, state, strain=strain, torque=torque, step=step)
    if isinstance(state, str):
        raise InputError("state", state, "must be None or a pair (q, qd) for a planar arm")
    st, t = _check(case, elements_per_link, t, strain)
    if not (isinstance(step, (int, float)) and 0.0 < step < 0.1):
        raise InputError("step", step, "must be a relative difference step in (0, 0.1)")
    tau, mot = _drive_inputs(case, st, t, torque)
    q0, qd0 = _point(case, st, mot, state)
    free = np.flatnonzero(~np.isin(np.arange(st.n_dof), st.alpha_index[st.motion]))
    if free.size > MAX_FREE:
        raise InputError(
            "elements_per_link",
            elements_per_link,
            f"gives {free.size} free coordinates (dense limit {MAX_FREE})",
        )
    acc = lambda q, qd, Q=None, tq=tau: sweep_accelerations(st, q, qd, tq, mot, forces=Q).qdd[free]
    a0 = acc(q0, qd0)
    # M⁻¹ from unit generalized forces (q̈ is affine in Q: the difference is exact)
    eye = np.zeros((free.size, st.n_dof))
    eye[np.arange(free.size), free] = 1.0
    Minv = np.column_stack([acc(q0, qd0, Q) - a0 for Q in eye])
    M = np.linalg.inv(Minv)
    M = 0.5 * (M + M.T)
    scale = _scales(st)
    Jq = derivative(lambda q: acc(q, qd0), q0, free, scale, step)  # ∂q̈/∂q
    Jv = derivative(lambda qd: acc(q0, qd), qd0, free, scale, step)  # ∂q̈/∂q̇
    tj = tuple(int(i) for i in np.flatnonzero(~st.motion))
    Jt = np.zeros((free.size, len(tj)))  # ∂q̈/∂τ
    for c, i in enumerate(tj):
        Jt[:, c] = acc(q0, qd0, tq=tau + np.eye(st.n_links)[i]) - a0
    # M · J as a solve with the computed M⁻¹ keeps the inversion's round-off out of K, D, B
    K, D, B = (np.linalg.solve(Minv, J) for J in (-Jq, -Jv, Jt))
    Z = np.zeros((free.size, free.size))
    A = np.block([[Z, np.eye(free.size)], [Jq, Jv]])
    B_ss = np.vstack([np.zeros_like(Jt), Jt])
    names = st.coordinate_names()
    qdd = sweep_accelerations(st, q0, qd0, tau, mot).qdd
    return Linearization(
        M=M,
        D=D,
        K=K,
        B=B,
        A=A,
        B_ss=B_ss,
        coordinates=tuple(names[j] for j in free),
        free=free,
        torque_joints=tj,
        q=q0,
        qd=qd0,
        qdd=qdd,
        t=t,
        elements_per_link=st.k,
        strain=strain,
    )


def _deflections(st: Structure, lin: Linearization, shapes: np.ndarray) -> tuple:
    """Per link (n_modes, k + 1) transverse node deflections in the clamped-root frame, by a
    central difference of the kinematics along each shape (linear in the amplitude)."""

    def nodes(q):
        kin = kinematics(st, q, np.zeros(st.n_dof), with_terms=False)
        out = []
        for lkn in kin.links:
            pts = np.vstack([lkn.r, lkn.tip])
            out.append(tip_deflection(lkn.r[0], lkn.theta[0], pts))
        return out

    per_link = [np.empty((shapes.shape[1], st.k + 1)) for _ in st.links]
    for m in range(shapes.shape[1]):
        dq = np.zeros(st.n_dof)
        dq[lin.free] = shapes[:, m]
        eps = 1e-7 / max(np.abs(dq).max(), 1e-300)
        plus, minus = nodes(lin.q + eps * dq), nodes(lin.q - eps * dq)
        for i in range(st.n_links):
            per_link[i][m] = (plus[i] - minus[i]) / (2 * eps)
    return tuple(per_link)


def modes(
    case: Case,
    elements_per_link: int,
    t: float = 0.0,
    state=None,
    n: int | None = None,
    *,
    strain: str = "linear",
    torque=None,
    zero_tol: float = 1e-13,
) -> Modes:
    """Natural modes of ``case`` about a state: motion-driven joints held, torque-driven free.

    Parameters
    ----------
    case, elements_per_link, t, state, strain, torque
        As in :func:`linearize`.
    n : int or None
        Number of lowest modes to return (None: all n_free).
    zero_tol : float
        Eigenvalues with |ω²| ≤ zero_tol · max|ω²| are rigid-body modes, reported at 0 Hz.

    Returns
    -------
    Modes
        Frequencies from K φ = ω² M φ (scipy.linalg.eigh when K is symmetric, else eig);
        damping ratios when D ≠ 0. A spatial case goes to :func:`dttmm.spatial.linear.modes`.
    """
    if _spatial(case):
        from .spatial.linear import modes as spatial_modes

        return spatial_modes(
            case, elements_per_link, t, state, n, strain=strain, torque=torque, zero_tol=zero_tol
        )
    lin = linearize(case, elements_per_link, t, state, strain=strain, torque=torque)
    st = build_structure(case, elements_per_link, strain)
    check_n(n)
    s_nodes = tuple(np.linspace(0.0, lk.length, lk.k + 1) for lk in st.links)
    return modes_of(lin, n, zero_tol, s_nodes, lambda V: (_deflections(st, lin, V), None))


def frequencies(case: Case, elements_per_link: int, n: int | None = None) -> np.ndarray:
    """Lowest ``n`` natural frequencies (Hz, ascending) of ``case`` at rest: :func:`modes`'s
    frequencies, the common natural-frequency call of the suite's methods (planar or spatial)."""
    return np.asarray(modes(case, elements_per_link, n=n).frequencies, float)
