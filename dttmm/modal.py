"""The linearisation record and the eigen-analysis shared by the planar and the spatial
kernels' linearisations (:mod:`dttmm.linear`, :mod:`dttmm.spatial.linear`): the equations
M δq̈ + D δq̇ + K δq = B δτ, their modes, and the difference stencil both use."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

__all__ = ["MAX_FREE", "STEP", "Linearization", "Modes", "derivative"]

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


def check_n(n) -> None:
    """InputError unless ``n`` (number of modes) is None or an integer ≥ 1."""
    from .errors import InputError

    if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1):
        raise InputError("n", n, "must be an integer ≥ 1 (number of modes)")


def eigen_modes(lin: Linearization, n, zero_tol: float):
    """The first ``n`` (None: all) modes of ``lin``: (frequencies (Hz; NaN where unstable),
    eigenvalues ω² (rad²/s², |ω²| ≤ zero_tol·max set to 0), shapes (columns, largest entry
    positive), damping ratios or None, warnings)."""
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
    return freq, lam, V, zeta, warn


def modes_of(lin: Linearization, n, zero_tol: float, s: tuple, deflect) -> Modes:
    """The :class:`Modes` of ``lin``: its first ``n`` modes (:func:`eigen_modes`), the nodes'
    arc lengths ``s`` per link and ``deflect(V)`` → (deflections, twists or None) of the shapes V
    (planar and spatial arms alike)."""
    freq, lam, V, zeta, warn = eigen_modes(lin, n, zero_tol)
    deflections, twists = deflect(V)
    return Modes(freq, lam, V, s, deflections, zeta, lin, warn, twists)


def state_pair(state, n_dof: int) -> tuple[np.ndarray, np.ndarray]:
    """A user's linearisation point ``state = (q, qd)`` as two float arrays of ``n_dof`` finite
    numbers (copies); InputError naming the part otherwise."""
    from .errors import InputError

    try:
        q, qd = (np.array(x, float) for x in state)
    except (TypeError, ValueError):
        raise InputError("state", type(state).__name__, "must be a pair (q, qd) of arrays") from None
    for name, x in (("state[0] (q)", q), ("state[1] (qd)", qd)):
        if x.shape != (n_dof,) or not np.all(np.isfinite(x)):
            raise InputError(name, f"shape {x.shape}", f"must be {n_dof} finite numbers")
    return q, qd
