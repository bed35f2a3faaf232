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

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from .case import Case
from .errors import InputError
from .result import tip_deflection
from .structure import STRAINS, Structure, build_structure, kinematics
from .sweeps import accelerations as sweep_accelerations

__all__ = ["Linearization", "Modes", "frequencies", "linearize", "modes"]

#: 8th-order central difference of a first derivative: f' ≈ Σ c_m (f(x + m h) − f(x − m h)) / h.
_STENCIL = ((1, 4.0 / 5.0), (2, -1.0 / 5.0), (3, 4.0 / 105.0), (4, -1.0 / 280.0))
#: Relative step of the stencil (times the coordinate's scale).
STEP = 2e-4
#: Most free coordinates linearised (dense matrices, O(n²) sweeps).
MAX_FREE = 2500


@dataclass(frozen=True)
class Linearization:
    """Linear(ised) equations M δq̈ + D δq̇ + K δq = B δτ of the arm about a state.

    Attributes
    ----------
    M, D, K : (n_free, n_free) ndarrays
        Mass (kg, kg·m, kg·m²), damping and stiffness matrices over the free coordinates.
    B : (n_free, n_torque) ndarray
        Input matrix of the torque-driven joints' torques (N·m).
    A, B_ss : (2 n_free, 2 n_free), (2 n_free, n_torque) ndarrays
        First-order form ẋ = A x + B_ss δτ with x = (δq, δq̇).
    coordinates : tuple of str
        Names of the free coordinates (order of the rows).
    free : (n_free,) int ndarray
        Their indices in the full DT-TMM coordinate vector.
    torque_joints : tuple of int
        Joint numbers (0-based) of the columns of B.
    q, qd : (n_dof,) ndarrays
        The linearisation point (full vectors; motion-driven joints at their law's values).
    qdd : (n_dof,) ndarray
        Accelerations at the point.
    t : float
        Time of the point (s); the drives' laws are evaluated there.
    elements_per_link : int
    strain : str
    """

    M: np.ndarray
    D: np.ndarray
    K: np.ndarray
    B: np.ndarray
    A: np.ndarray
    B_ss: np.ndarray
    coordinates: tuple
    free: np.ndarray
    torque_joints: tuple
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    t: float
    elements_per_link: int
    strain: str

    @property
    def n_free(self) -> int:
        return len(self.free)


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
        try:
            q, qd = (np.array(x, float) for x in state)
        except (TypeError, ValueError):
            raise InputError("state", type(state).__name__, "must be a pair (q, qd) of arrays") from None
        for name, x in (("state[0] (q)", q), ("state[1] (qd)", qd)):
            if x.shape != (st.n_dof,) or not np.all(np.isfinite(x)):
                raise InputError(name, f"shape {x.shape}", f"must be {st.n_dof} finite numbers")
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


def derivative(f, x: np.ndarray, idx: np.ndarray, scale: np.ndarray, step: float) -> np.ndarray:
    """∂f/∂x_j for j in ``idx`` by the 8th-order central stencil; columns (len(f(x)), len(idx))."""
    cols = []
    for j in idx:
        hj = step * scale[j]
        col = 0.0
        for m, c in _STENCIL:
            xp, xm = x.copy(), x.copy()
            xp[j] += m * hj
            xm[j] -= m * hj
            col = col + c * (f(xp) - f(xm))
        cols.append(col / hj)
    return np.column_stack(cols)


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
    return build_structure(case, elements_per_link, strain), t


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


@dataclass(frozen=True)
class Modes:
    """Natural modes of the arm linearised about a state (see :func:`modes`).

    Attributes
    ----------
    frequencies : (n_modes,) ndarray
        Undamped natural frequencies (Hz), ascending; rigid-body modes of free joints are 0;
        NaN for an unstable direction (ω² < 0, see ``eigenvalues``).
    eigenvalues : (n_modes,) ndarray
        ω² (rad²/s²) of K φ = ω² M φ (real parts when K is not symmetric).
    shapes : (n_free, n_modes) ndarray
        Mode shapes over the free coordinates, M-normalised (φᵀ M φ = 1), each signed so that
        its largest entry is positive.
    s : tuple of (k + 1,) ndarrays
        Per link, the arc length (m) of the element nodes from the link root.
    deflections : tuple of (n_modes, k + 1) ndarrays
        Per link, the transverse deflection of the element nodes in the link's clamped-root
        frame (normal to the root cross-section) for each M-normalised shape (m per unit modal
        amplitude).
    damping_ratios : (n_modes,) ndarray or None
        ζ of each mode from the damped state-space eigenvalues s₁, s₂ assigned to it
        (ζ = −(s₁ + s₂) / (2 √(s₁ s₂))); None when D = 0. NaN for rigid-body modes.
    linearization : Linearization
    warnings : tuple of str
    twists : None or tuple of (n_modes, k + 1) ndarrays
        Spatial arms only: per link, the twist (rad per unit modal amplitude) of the element
        nodes' sections about the link's x axis; their ``deflections`` are then
        (n_modes, k + 1, 2), the offsets along the link frame's y and z axes. None for a planar
        arm.
    """

    frequencies: np.ndarray
    eigenvalues: np.ndarray
    shapes: np.ndarray
    s: tuple
    deflections: tuple
    damping_ratios: np.ndarray | None
    linearization: Linearization
    warnings: tuple = ()
    twists: tuple | None = None


def _eigen(K: np.ndarray, M: np.ndarray):
    """(ω² ascending, shapes M-normalised, symmetric?) of K φ = ω² M φ."""
    scale = max(np.abs(K).max(), 1e-300)
    if np.abs(K - K.T).max() <= 1e-9 * scale:
        Ks = 0.5 * (K + K.T)
        try:
            # flexibility form M φ = ω⁻² K φ when K is positive definite: the lowest ω² are
            # then the largest eigenvalues, not round-off-sized ones next to ω²_max
            mu, V = scipy.linalg.eigh(M, Ks)
            lam, V = 1.0 / mu[::-1], V[:, ::-1]
            V = V / np.sqrt(np.einsum("im,ij,jm->m", V, M, V))
        except np.linalg.LinAlgError:
            lam, V = scipy.linalg.eigh(Ks, M)
        return lam, V, True
    lam, V = scipy.linalg.eig(K, M)
    order = np.argsort(lam.real)
    lam, V = lam[order].real, V[:, order].real
    V = V / np.sqrt(np.abs(np.einsum("im,ij,jm->m", V, M, V)))
    return lam, V, False


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


def _has_damping(lin: Linearization) -> bool:
    """D ≠ 0 beyond the difference round-off: max|D| against the critical-damping scale
    √(max|K| max|M|)."""
    crit = np.sqrt(np.abs(lin.K).max() * np.abs(lin.M).max())
    return bool(np.abs(lin.D).max() > 1e-10 * crit)


def _damping_ratios(lin: Linearization, shapes: np.ndarray) -> np.ndarray:
    """ζ per undamped mode from the state-space eigenvalues, each assigned to the mode its
    displacement part projects on most (in the M inner product)."""
    nf = lin.n_free
    s, X = scipy.linalg.eig(lin.A)
    P = X[:nf]
    proj = np.abs(shapes.T @ lin.M @ P)
    owner = np.argmax(proj, axis=0)
    zeta = np.full(shapes.shape[1], np.nan)
    for m in range(shapes.shape[1]):
        sm = s[owner == m]
        if sm.size != 2:
            continue
        wn2 = (sm[0] * sm[1]).real
        if wn2 > 0:
            zeta[m] = -(sm[0] + sm[1]).real / (2 * np.sqrt(wn2))
    return zeta


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
    if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1):
        raise InputError("n", n, "must be an integer ≥ 1 (number of modes)")
    lam, V, _ = _eigen(lin.K, lin.M)
    lam = np.where(np.abs(lam) <= zero_tol * np.abs(lam).max(), 0.0, lam)
    zeta = _damping_ratios(lin, V) if _has_damping(lin) else None
    nm = lin.n_free if n is None else min(int(n), lin.n_free)
    lam, V = lam[:nm], V[:, :nm]
    zeta = None if zeta is None else zeta[:nm]
    big = np.argmax(np.abs(V), axis=0)
    V = V * np.sign(V[big, np.arange(nm)])
    warn = tuple(
        f"mode {m + 1} is unstable at this state (ω² = {lam[m]:.6g} rad²/s²)" for m in np.flatnonzero(lam < 0)
    )
    freq = np.where(lam >= 0, np.sqrt(np.abs(lam)), np.nan) / (2 * np.pi)
    s_nodes = tuple(np.linspace(0.0, lk.length, lk.k + 1) for lk in st.links)
    return Modes(
        frequencies=freq,
        eigenvalues=lam,
        shapes=V,
        s=s_nodes,
        deflections=_deflections(st, lin, V),
        damping_ratios=zeta,
        linearization=lin,
        warnings=warn,
    )


def frequencies(case: Case, elements_per_link: int, n: int | None = None) -> np.ndarray:
    """Lowest ``n`` natural frequencies (Hz, ascending) of ``case`` at rest: :func:`modes`'s
    frequencies, the common natural-frequency call of the suite's methods (planar or spatial)."""
    return np.asarray(modes(case, elements_per_link, n=n).frequencies, float)
