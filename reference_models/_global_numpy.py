"""The readable numpy mechanics of the global-equation solver (see
:mod:`reference_models.global_newmark`): layout, mass matrix from dense recursive Jacobians,
elastic and damping forces, kinematics, energy and the forward dynamics at one state. No time
loop: the time loop is :mod:`reference_models._global_numba` (compiled, and uncompiled as
:mod:`reference_models._global_python`), checked against these one-step quantities."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dttmm import plumbing
from dttmm.case import Case
from dttmm.drives import Constant, Drive
from dttmm.errors import InputError
from dttmm.model import Link, Manipulator, Section
from dttmm.result import tip_deflection
from dttmm.scenario import Scenario

from . import _checks
from . import _global_control as gc

# The public names are re-exported by reference_models.global_newmark (the facade).

STRAINS = _checks.STRAINS
_N_GAUSS = 4  # exact for the degree-6 polynomials of the mass matrix and velocity terms

_XG, _WG = np.polynomial.legendre.leggauss(_N_GAUSS)
_XG = 0.5 * (_XG + 1.0)
_WG = 0.5 * _WG


# ----------------------------------------------------------------------------------------------
# Layout: coordinates, elements, constant matrices
# ----------------------------------------------------------------------------------------------


@dataclass
class _Layout:
    """Index tables and constant data of one (case, k) discretisation."""

    n_links: int
    k: int
    n_dof: int
    names: list
    alpha_idx: np.ndarray  # (n,) index of α_i in q
    first_el: np.ndarray  # (n,) first element of each link
    last_el: np.ndarray  # (n,) last element of each link
    link_of: np.ndarray  # (Nel,) link of each element
    length: np.ndarray  # (Nel,) element length l
    rhoA: np.ndarray  # (Nel,)
    e_idx: np.ndarray  # (Nel, 3) q index of (u, v, φ); −1 where absent
    is_rot: np.ndarray  # (N,) angle-type coordinate (α or φ)
    f_pos: np.ndarray  # (N,) first chain position the coordinate moves
    owner: np.ndarray  # (N,) element whose frame gives pivot/direction (−1 for α)
    kind: np.ndarray  # (N,) 0 = α, 1 = u, 2 = v, 3 = φ
    K: np.ndarray  # (N, N)
    D: np.ndarray  # (N, N)
    sigma0: np.ndarray  # (Nel, 2) ∫ρA s0 dx (first moment of the undeformed element)
    Sbar: np.ndarray  # (Nel, 2, 3) ∫ρA S dx
    c0: np.ndarray  # (Nel,) ∫ρA s0·s0 dx
    b0: np.ndarray  # (Nel, 3) ∫ρA Sᵀ s0 dx
    c1: np.ndarray  # (Nel, 3) ∫ρA s0ᵀ E S dx
    SS: np.ndarray  # (Nel, 3, 3) ∫ρA SᵀS dx
    H: np.ndarray  # (Nel, 3, 3) ∫ρA Sᵀ E S dx (antisymmetric)
    mass: np.ndarray  # (Nel,) element beam mass
    hub_m: np.ndarray  # (Nel,) hub mass on the element's inboard frame
    hub_J: np.ndarray  # (Nel,) hub inertia on the element's inboard frame
    payloads: list  # [(link, mass, inertia)]: inertia about the payload's centre of mass
    gravity: np.ndarray  # (2,)
    motion: np.ndarray  # (n,) bool, motion-driven joints
    free: np.ndarray  # indices of free coordinates
    presc: np.ndarray  # indices of prescribed coordinates (α of motion joints)
    strain: str = "linear"  # "linear" | "second-order"
    nonlinear: bool = False  # some element has a second-order axial strain
    EA: np.ndarray | None = None  # (Nel,) axial stiffness, 0 for an inextensible link
    EI: np.ndarray | None = None  # (Nel,)
    second: np.ndarray | None = None  # (Nel,) bool: element uses the second-order strain
    mu: np.ndarray | None = None  # (Nel,) Kelvin-Voigt damping coefficient μ (s)
    shape_points: int = 0  # points per link of Result.link_shapes (0: none)
    pay_offset: list | None = None  # [(x, y)] per payload: its centre of mass in the tip frame


def _shape_matrices(length: float) -> tuple[np.ndarray, np.ndarray]:
    """S(ξ) (ng, 2, 3) on (u, v, φ) and s0(ξ) (ng, 2) at the Gauss points."""
    xi = _XG
    S = np.zeros((xi.size, 2, 3))
    S[:, 0, 0] = xi
    S[:, 1, 1] = 3 * xi**2 - 2 * xi**3
    S[:, 1, 2] = length * (xi**3 - xi**2)
    s0 = np.zeros((xi.size, 2))
    s0[:, 0] = xi * length
    return S, s0


def _moments(length: np.ndarray, rhoA: np.ndarray) -> dict:
    """Element mass moments (exact Gauss quadrature of the cubic shapes), per element.

    With s(ξ) = s0(ξ) + S(ξ) e the element's mass matrix and velocity terms are polynomials
    in e whose coefficients are these constant integrals.
    """
    E = np.array([[0.0, -1.0], [1.0, 0.0]])
    out = {key: [] for key in ("sigma0", "Sbar", "c0", "b0", "c1", "SS", "H")}
    for l, ra in zip(length, rhoA):
        S, s0 = _shape_matrices(l)
        w = ra * l * _WG
        out["sigma0"].append(np.einsum("g,gi->i", w, s0))
        out["Sbar"].append(np.einsum("g,gij->ij", w, S))
        out["c0"].append(np.einsum("g,gi,gi->", w, s0, s0))
        out["b0"].append(np.einsum("g,gki,gk->i", w, S, s0))
        out["c1"].append(np.einsum("g,gk,kl,glj->j", w, s0, E, S))
        out["SS"].append(np.einsum("g,gki,gkj->ij", w, S, S))
        out["H"].append(np.einsum("g,gki,kl,glj->ij", w, S, E, S))
    return {key: np.array(val, float) for key, val in out.items()}


def _element_stiffness(beam, l: float) -> np.ndarray:
    """3×3 stiffness on (u, v, φ); the u entry is zero for an inextensible link."""
    Ke = np.zeros((3, 3))
    if beam.EA is not None:
        Ke[0, 0] = beam.EA / l
    c = beam.EI / l**3
    Ke[1:, 1:] = c * np.array([[12.0, -6 * l], [-6 * l, 4 * l * l]])
    return Ke


def _check_k(k) -> int:
    return plumbing.elements_per_link(k)


def _check_case(case) -> Case:
    return plumbing.check_case(case)


def _coordinates(links, k) -> dict:
    """Coordinate tables: per coordinate its name, kind (0 = α, 1 = u, 2 = v, 3 = φ), owning
    element and first moved chain position; per element the q index of (u, v, φ).

    Chain positions: element e's inboard frame sits at e, a link tip at (last element) + ½.
    α_i moves everything from its link's first element on; an elastic coordinate of element e
    moves everything outboard of e's outboard node (from e + ½ on).
    """
    names, kind, owner, f_pos, alpha_idx = [], [], [], [], []
    e_idx = -np.ones((len(links) * k, 3), int)
    for i, link in enumerate(links):
        alpha_idx.append(len(names))
        names.append(f"alpha_{i + 1}")
        kind.append(0)
        owner.append(-1)
        f_pos.append(float(i * k))
        if link.rigid:
            slots = ()  # a rigid link: no elastic coordinates
        else:
            slots = (0, 1, 2) if link.beam.EA is not None else (1, 2)
        for j in range(k):
            el = i * k + j
            for slot in slots:
                e_idx[el, slot] = len(names)
                names.append(f"{('u', 'v', 'phi')[slot]}_{i + 1}_{j + 1}")
                kind.append(slot + 1)
                owner.append(el)
                f_pos.append(el + 0.5)
    kind = np.array(kind, int)
    return {
        "names": names,
        "kind": kind,
        "is_rot": (kind == 0) | (kind == 3),
        "owner": np.array(owner, int),
        "f_pos": np.array(f_pos, float),
        "alpha_idx": np.array(alpha_idx, int),
        "e_idx": e_idx,
    }


def _stiffness(links, k, e_idx, n_dof) -> tuple[np.ndarray, np.ndarray]:
    """Stiffness K and Kelvin-Voigt damping D = μK, block diagonal per element."""
    K = np.zeros((n_dof, n_dof))
    D = np.zeros((n_dof, n_dof))
    for i, link in enumerate(links):
        if link.rigid:
            continue
        Ke = _element_stiffness(link.beam, link.beam.length / k)
        for el in range(i * k, (i + 1) * k):
            slots = np.flatnonzero(e_idx[el] >= 0)
            idx = np.ix_(e_idx[el, slots], e_idx[el, slots])
            K[idx] += Ke[np.ix_(slots, slots)]
            D[idx] += link.beam.damping * Ke[np.ix_(slots, slots)]
    return K, D


def _layout(case, k, strain="linear") -> _Layout:
    """Build the coordinate and element tables of ``case`` with k elements per link."""
    case = _check_case(case)
    k = _check_k(k)
    strain = _checks.strain(strain)
    links = case.model.links
    n = len(links)
    nel = n * k
    co = _coordinates(links, k)
    N = len(co["names"])
    K, D = _stiffness(links, k, co["e_idx"], N)
    length = np.repeat([lk.beam.length / k for lk in links], k).astype(float)
    rhoA = np.repeat([0.0 if lk.rigid else lk.beam.rhoA for lk in links], k).astype(float)
    hub_m, hub_J = np.zeros(nel), np.zeros(nel)
    hub_m[::k] = [lk.hub_mass for lk in links]
    hub_J[::k] = [lk.hub_inertia for lk in links]
    payloads = [
        (i, lk.payload_mass, lk.payload_inertia) for i, lk in enumerate(links) if lk.payload is not None
    ]
    pay_offset = [tuple(lk.payload_offset) for lk in links if lk.payload is not None]
    motion = np.array([d.kind == "motion" for d in case.scenario.drives], bool)
    presc = co["alpha_idx"][motion]
    EA = np.repeat([0.0 if lk.rigid or lk.beam.EA is None else float(lk.beam.EA) for lk in links], k)
    EI = np.repeat([0.0 if lk.rigid else float(lk.beam.EI) for lk in links], k)
    second = np.repeat(
        [strain == "second-order" and not lk.rigid and lk.beam.EA is not None for lk in links], k
    )
    moments = _moments(length, rhoA)
    mass = rhoA * length
    for i, lk in enumerate(links):
        if lk.rigid:  # the body of a rigid link: on the frame of its first (massless) segment
            b, el = lk.beam, i * k
            d = np.array(b.com, float)
            mass[el] = b.mass
            moments["sigma0"][el] = b.mass * d
            moments["c0"][el] = b.inertia + b.mass * float(d @ d)
    return _Layout(
        n_links=n,
        k=k,
        n_dof=N,
        **co,
        first_el=np.arange(n) * k,
        last_el=np.arange(n) * k + k - 1,
        link_of=np.repeat(np.arange(n), k),
        length=length,
        rhoA=rhoA,
        K=K,
        D=D,
        **moments,
        mass=mass,
        hub_m=hub_m,
        hub_J=hub_J,
        payloads=payloads,
        gravity=np.array(case.model.gravity, float),
        motion=motion,
        free=np.setdiff1d(np.arange(N), presc),
        presc=presc,
        strain=strain,
        nonlinear=bool(second.any()),
        EA=EA,
        EI=EI,
        second=second,
        mu=np.repeat([0.0 if lk.rigid else float(lk.beam.damping) for lk in links], k),
        pay_offset=pay_offset,
    )


# ----------------------------------------------------------------------------------------------
# Elastic forces (linear or second-order axial strain)
# ----------------------------------------------------------------------------------------------


def _chord_matrix(length: np.ndarray) -> np.ndarray:
    """G = ∫₀¹ N'ᵀN' dξ (Nel, 2, 2) on w = (v, φ), N' = (dN3/dx, dN4/dx), in closed form:
    N3' = 6(ξ − ξ²)/l, N4' = 3ξ² − 2ξ give G = [[6/(5l²), −1/(10l)], [−1/(10l), 2/15]]
    (l·G is the familiar geometric stiffness block of the Hermite beam per unit axial force)."""
    l = np.asarray(length, float)
    G = np.empty(l.shape + (2, 2))
    G[..., 0, 0] = 6.0 / (5.0 * l * l)
    G[..., 0, 1] = G[..., 1, 0] = -1.0 / (10.0 * l)
    G[..., 1, 1] = 2.0 / 15.0
    return G


def _element_elastic(lay: _Layout, e: np.ndarray):
    """Per-element strain energy U (Nel,), internal force f (Nel, 3) and tangent K_T (Nel, 3, 3)
    on (u, v, φ) (rows/columns of absent coordinates are zero).

    U = ½ EA l ε² + ½ wᵀK_b w with w = (v, φ), K_b = EI/l³ [[12, −6l], [−6l, 4l²]] and
    ε = u/l (linear) or ε = u/l + ½ wᵀGw (second order, extensible links). Hence
    f_u = EA ε, f_w = EA l ε Gw + K_b w and
    K_T = [[EA/l, EA (Gw)ᵀ], [EA Gw, EA l (Gw)(Gw)ᵀ + EA l ε G + K_b]].
    """
    l, EA, EI = lay.length, lay.EA, lay.EI
    nel = l.size
    Kb = np.empty((nel, 2, 2))
    c = EI / l**3
    Kb[:, 0, 0] = 12.0 * c
    Kb[:, 0, 1] = Kb[:, 1, 0] = -6.0 * c * l
    Kb[:, 1, 1] = 4.0 * c * l * l
    w = e[:, 1:]
    G = _chord_matrix(l)
    Gw = _matvec(G, w) * lay.second[:, None]  # zero for linear elements
    eps = e[:, 0] / l + 0.5 * np.sum(w * Gw, axis=1)
    Kbw = _matvec(Kb, w)
    U = 0.5 * EA * l * eps**2 + 0.5 * np.sum(w * Kbw, axis=1)
    f = np.empty((nel, 3))
    f[:, 0] = EA * eps
    f[:, 1:] = (EA * l * eps)[:, None] * Gw + Kbw
    KT = np.empty((nel, 3, 3))
    KT[:, 0, 0] = EA / l
    KT[:, 0, 1:] = KT[:, 1:, 0] = EA[:, None] * Gw
    epsG = (EA * l * eps * lay.second)[:, None, None] * G
    KT[:, 1:, 1:] = (
        (EA * l)[:, None, None] * (Gw[:, :, None] * Gw[:, None, :]) + epsG + Kb
    )  # exactly symmetric
    return U, f, KT


def _element_damping(lay: _Layout, e: np.ndarray, ed: np.ndarray):
    """Per-element Kelvin-Voigt damping force f_d (Nel, 3) and its rate tangent D_t (Nel, 3, 3)
    on (u, v, φ), acting on the rate of the element's own strain measure.

    Dissipation R = ½ μ [EA l ε̇² + ẇᵀK_b ẇ] with ε̇ = u̇/l (+ wᵀGẇ, second order), so
    f_d,u = μ EA ε̇, f_d,w = μ (EA l ε̇ Gw + K_b ẇ) and D_t = ∂f_d/∂ė = μ (K_T without its
    ε G term). For the linear element f_d = μK ė and D_t = μK. The dependence of f_d on e
    (through Gw) stays out of D_t: it keeps the iteration matrix symmetric, and the residual
    is exact, so the converged step does not depend on it.
    """
    l, EA, EI, mu = lay.length, lay.EA, lay.EI, lay.mu
    nel = l.size
    c = EI / l**3
    Kb = np.empty((nel, 2, 2))
    Kb[:, 0, 0] = 12.0 * c
    Kb[:, 0, 1] = Kb[:, 1, 0] = -6.0 * c * l
    Kb[:, 1, 1] = 4.0 * c * l * l
    w, wd = e[:, 1:], ed[:, 1:]
    Gw = _matvec(_chord_matrix(l), w) * lay.second[:, None]
    epsd = ed[:, 0] / l + np.sum(wd * Gw, axis=1)
    fd = np.empty((nel, 3))
    fd[:, 0] = mu * EA * epsd
    fd[:, 1:] = mu[:, None] * ((EA * l * epsd)[:, None] * Gw + _matvec(Kb, wd))
    Dt = np.empty((nel, 3, 3))
    Dt[:, 0, 0] = mu * EA / l
    Dt[:, 0, 1:] = Dt[:, 1:, 0] = (mu * EA)[:, None] * Gw
    Dt[:, 1:, 1:] = mu[:, None, None] * ((EA * l)[:, None, None] * (Gw[:, :, None] * Gw[:, None, :]) + Kb)
    return fd, Dt


def _scatter(lay: _Layout, f_el: np.ndarray, K_el: np.ndarray):
    """Element vectors (Nel, 3) and blocks (Nel, 3, 3) into (N,) and (N, N)."""
    have = lay.e_idx >= 0
    f = np.zeros(lay.n_dof)
    f[lay.e_idx[have]] = f_el[have]
    el, a, b = np.nonzero(have[:, :, None] & have[:, None, :])
    K = np.zeros((lay.n_dof, lay.n_dof))
    K[lay.e_idx[el, a], lay.e_idx[el, b]] = K_el[el, a, b]
    return f, K


def _damping(lay: _Layout, q: np.ndarray, qd: np.ndarray):
    """Damping force f_d(q, q̇) (N,) and its rate tangent D_t (N, N); D q̇ and D (= μK) for
    the linear element."""
    if not lay.nonlinear:
        return lay.D @ qd, lay.D
    fd, Dt = _element_damping(lay, _elastic(lay, q), _elastic(lay, qd))
    return _scatter(lay, fd, Dt)


def _internal(lay: _Layout, q: np.ndarray):
    """Internal elastic force f_int(q) (N,) and its Jacobian K_T(q) (N, N).

    For the linear element f_int = K q and K_T = K exactly (the constant matrix)."""
    if not lay.nonlinear:
        return lay.K @ q, lay.K
    _, f_el, KT_el = _element_elastic(lay, _elastic(lay, q))
    return _scatter(lay, f_el, KT_el)


def _strain_energy(lay: _Layout, q: np.ndarray) -> float:
    """Σ U over the elements; ½qᵀKq for the linear element."""
    if not lay.nonlinear:
        return 0.5 * q @ lay.K @ q
    return float(np.sum(_element_elastic(lay, _elastic(lay, q))[0]))


# ----------------------------------------------------------------------------------------------
# Kinematics
# ----------------------------------------------------------------------------------------------


def _rot(theta: np.ndarray) -> np.ndarray:
    """Rotation matrices A(θ) (..., 2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    A = np.empty(np.shape(theta) + (2, 2))
    A[..., 0, 0] = A[..., 1, 1] = c
    A[..., 0, 1] = -s
    A[..., 1, 0] = s
    return A


def _perp(x: np.ndarray) -> np.ndarray:
    """E x with E the rotation by +90°: (x, y) → (−y, x)."""
    out = np.empty_like(x)
    out[..., 0] = -x[..., 1]
    out[..., 1] = x[..., 0]
    return out


def _matvec(A: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Batched matrix-vector product (..., m, n) @ (..., n) -> (..., m)."""
    return (A @ x[..., None])[..., 0]


def _elastic(lay: _Layout, q: np.ndarray) -> np.ndarray:
    """(Nel, 3) elastic coordinates (u, v, φ), zero where a coordinate is absent."""
    e = np.zeros(lay.e_idx.shape)
    have = lay.e_idx >= 0
    e[have] = q[lay.e_idx[have]]
    return e


def _angles(lay: _Layout, q: np.ndarray, e: np.ndarray) -> np.ndarray:
    """Cross-section angle θ at every element's inboard node (Nel,)."""
    inc = np.zeros(e.shape[0])
    inc[1:] = e[:-1, 2]
    inc[lay.first_el] += q[lay.alpha_idx]
    return np.cumsum(inc)


@dataclass
class _Frames:
    """Positions and angles of the chain: element inboard frames and link tips."""

    e: np.ndarray  # (Nel, 3)
    theta: np.ndarray  # (Nel,)
    A: np.ndarray  # (Nel, 2, 2)
    d: np.ndarray  # (Nel, 2) local outboard offset (l + u, v)
    rI: np.ndarray  # (Nel, 2)
    rO: np.ndarray  # (Nel, 2)


def _frames(lay: _Layout, q: np.ndarray) -> _Frames:
    e = _elastic(lay, q)
    theta = _angles(lay, q, e)
    A = _rot(theta)
    d = np.stack([lay.length + e[:, 0], e[:, 1]], -1)
    delta = _matvec(A, d)
    rO = np.cumsum(delta, axis=0)
    rI = np.zeros_like(rO)
    rI[1:] = rO[:-1]
    return _Frames(e, theta, A, d, rI, rO)


def _jacobians(lay: _Layout, fr: _Frames, r_frame: np.ndarray, pos: np.ndarray):
    """Jacobians of frame positions (nF, 2, N) and angles (nF, N) with respect to q.

    A frame at chain position ``pos`` is moved by every coordinate whose first moved
    position ``f_pos`` is ≤ pos: an angle-type coordinate turns it about its pivot,
    an axial/transverse coordinate translates it along its element's axes.
    """
    N = lay.n_dof
    pivot = np.zeros((N, 2))
    direc = np.zeros((N, 2))
    a = lay.alpha_idx
    pivot[a] = fr.rI[lay.first_el]
    own = lay.owner
    phi = lay.kind == 3
    pivot[phi] = fr.rO[own[phi]]
    for kd, col in ((1, 0), (2, 1)):
        sel = lay.kind == kd
        direc[sel] = fr.A[own[sel], :, col]
    mask = (lay.f_pos[None, :] <= pos[:, None]).astype(float)
    turn = _perp(r_frame[:, None, :] - pivot[None, :, :])
    vec = np.where(lay.is_rot[None, :, None], turn, direc[None, :, :])
    Jr = np.transpose(vec * mask[:, :, None], (0, 2, 1))
    Jt = mask * lay.is_rot[None, :]
    return Jr, Jt


def _bias(lay: _Layout, fr: _Frames, qd: np.ndarray):
    """Velocity-dependent accelerations (q̈ = 0) of every inboard frame and of the outboard nodes.

    Returns (bI, bO, thd, ed): (Nel, 2), (Nel, 2), angular rates (Nel,), elastic rates (Nel, 3).
    """
    ed = _elastic(lay, qd)
    thd = _angles(lay, qd, ed)
    local = -(thd[:, None] ** 2) * fr.d + 2 * thd[:, None] * _perp(ed[:, :2])
    beta = _matvec(fr.A, local)
    bO = np.cumsum(beta, axis=0)
    bI = np.zeros_like(bO)
    bI[1:] = bO[:-1]
    return bI, bO, thd, ed


# ----------------------------------------------------------------------------------------------
# Element terms and assembly
# ----------------------------------------------------------------------------------------------


def _element_terms(lay: _Layout, fr: _Frames, thd: np.ndarray, ed: np.ndarray):
    """Element mass matrices (Nel, 6, 6), velocity terms and gravity forces (Nel, 6)
    in the element coordinates p = (r_I, θ, u, v, φ), hubs included.

    Mass: ∫ρA J_pᵀJ_p dx with J_p = [I, E A s, A S]; velocity terms ∫ρA J_pᵀ A w dx with
    w = −θ̇² s + 2θ̇ E S ė; gravity ∫ρA J_pᵀ g dx — all from the element moments.
    """
    A, g, e = fr.A, lay.gravity, fr.e
    sigma = lay.sigma0 + _matvec(lay.Sbar, e)  # ∫ρA s dx
    Asig_perp = _perp(_matvec(A, sigma))  # E A ∫ρA s dx
    be = lay.b0 + _matvec(lay.SS, e)  # ∫ρA Sᵀ s dx
    nel = e.shape[0]
    m = lay.mass + lay.hub_m
    Mel = np.zeros((nel, 6, 6))
    Mel[:, 0, 0] = Mel[:, 1, 1] = m
    Mel[:, 0:2, 2] = Asig_perp
    Mel[:, 0:2, 3:] = A @ lay.Sbar
    Mel[:, 2, 2] = lay.c0 + np.sum((lay.b0 + be) * e, axis=1) + lay.hub_J
    Mel[:, 2, 3:] = -(lay.c1 + _matvec(np.transpose(lay.H, (0, 2, 1)), e))
    Mel[:, 3:, 3:] = lay.SS
    Mel[:, 2:, 0:2] = np.transpose(Mel[:, 0:2, 2:], (0, 2, 1))
    Mel[:, 3:, 2] = Mel[:, 2, 3:]
    th2 = thd * thd
    hel = np.empty((nel, 6))
    hel[:, 0:2] = _matvec(A, -th2[:, None] * sigma + 2 * thd[:, None] * _perp(_matvec(lay.Sbar, ed)))
    hel[:, 2] = 2 * thd * np.sum(be * ed, axis=1)
    hel[:, 3:] = -th2[:, None] * be + 2 * thd[:, None] * _matvec(lay.H, ed)
    gel = np.empty((nel, 6))
    gel[:, 0:2] = m[:, None] * g
    gel[:, 2] = Asig_perp @ g
    gel[:, 3:] = _matvec(np.transpose(lay.Sbar, (0, 2, 1)), g @ A)
    return Mel, hel, gel


def _element_selector(lay: _Layout) -> np.ndarray:
    """(Nel, 3, N) map from q to each element's own elastic coordinates."""
    nel = lay.e_idx.shape[0]
    sel = np.zeros((nel, 3, lay.n_dof))
    el, slot = np.nonzero(lay.e_idx >= 0)
    sel[el, slot, lay.e_idx[el, slot]] = 1.0
    return sel


@dataclass
class _Bodies:
    """Jacobians and inertia data of every body at one state."""

    J: np.ndarray  # (Nel, 6, N) element coordinates p = (r_I, θ, u, v, φ) w.r.t. q
    Mel: np.ndarray  # (Nel, 6, 6) element mass matrices (hubs included)
    fel: np.ndarray  # (Nel, 6) gravity − velocity terms − M_el·(bias accel. of p)
    Jpay: list  # [(3, N)] payload frames (r_tip, θ_tip)
    Mpay: list  # [(3,)] payload inertia diagonals
    fpay: list  # [(3,)] payload gravity − inertia of the bias acceleration


def _bodies(lay: _Layout, q: np.ndarray, qd: np.ndarray) -> _Bodies:
    fr = _frames(lay, q)
    bI, bO, thd, ed = _bias(lay, fr, qd)
    nel = fr.theta.size
    tips = np.array([lay.last_el[i] for i, _, _ in lay.payloads], int)
    r_frame = np.concatenate([fr.rI, fr.rO[tips]]) if tips.size else fr.rI
    pos = np.concatenate([np.arange(nel, dtype=float), tips + 0.5])
    Jr, Jt = _jacobians(lay, fr, r_frame, pos)
    J = np.concatenate([Jr[:nel], Jt[:nel, None, :], _element_selector(lay)], axis=1)
    Mel, hel, gel = _element_terms(lay, fr, thd, ed)
    fel = gel - hel - _matvec(Mel[:, :, 0:2], bI)
    Jpay, Mpay, fpay = [], [], []
    for p, (_, mp, Jp) in enumerate(lay.payloads):
        Jpay.append(np.vstack([Jr[nel + p], Jt[nel + p]]))
        d = lay.pay_offset[p]
        if d[0] == 0.0 and d[1] == 0.0:
            Mpay.append(np.array([mp, mp, Jp]))
            fpay.append(np.concatenate([mp * (lay.gravity - bO[tips[p]]), [0.0]]))
        else:  # centre of mass at ρ = A(θ_tip) d: M = [[m I, m Eρ], [m (Eρ)ᵀ, J + m ρ·ρ]]
            el = tips[p]
            th, w = fr.theta[el] + fr.e[el, 2], thd[el] + ed[el, 2]
            rho = _matvec(_rot(np.array([th]))[0], np.array(d, float))
            Erho = np.array([-rho[1], rho[0]])
            M3 = np.zeros((3, 3))
            M3[0, 0] = M3[1, 1] = mp
            M3[0:2, 2] = M3[2, 0:2] = mp * Erho
            M3[2, 2] = Jp + mp * float(rho @ rho)
            F = mp * (lay.gravity - bO[el] + w * w * rho)
            Mpay.append(M3)
            fpay.append(np.array([F[0], F[1], float(Erho @ F)]))
    return _Bodies(J, Mel, fel, Jpay, Mpay, fpay)


def _assemble(lay: _Layout, q: np.ndarray, qd: np.ndarray):
    """M(q) (N, N) and f = Q_gravity − h(q, q̇) (N,) (no joint torques, no elastic forces).

    M = Σ J_elᵀ M_el J_el, f = Σ J_elᵀ (g_el − h_el − M_el J̇_el q̇), payloads alike.
    """
    b = _bodies(lay, q, qd)
    nel = b.J.shape[0]
    Jf = b.J.reshape(nel * 6, -1)
    M = Jf.T @ (b.Mel @ b.J).reshape(nel * 6, -1)
    f = Jf.T @ b.fel.reshape(-1)
    for Jb, Mp, fb in zip(b.Jpay, b.Mpay, b.fpay):
        M += Jb.T @ (Mp[:, None] * Jb if Mp.ndim == 1 else Mp @ Jb)
        f += Jb.T @ fb
    return 0.5 * (M + M.T), f


def _kinetic(lay: _Layout, q: np.ndarray, qd: np.ndarray) -> float:
    """½q̇ᵀM(q)q̇ from the body velocities, without forming M."""
    b = _bodies(lay, q, np.zeros_like(qd))
    pd = _matvec(b.J, qd)
    T = 0.5 * np.einsum("ei,eij,ej->", pd, b.Mel, pd)
    for Jb, Mp in zip(b.Jpay, b.Mpay):
        v = Jb @ qd
        T += 0.5 * v @ (Mp * v if Mp.ndim == 1 else Mp @ v)
    return float(T)


# ----------------------------------------------------------------------------------------------
# Drives
# ----------------------------------------------------------------------------------------------


def _torques(case, lay: _Layout, t: float, left: bool) -> np.ndarray:
    """Generalized joint torques (N,): τ_i on α_i of open-loop torque-driven joints (the
    closed-loop ones are added by the step iteration)."""
    Q = np.zeros(lay.n_dof)
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and not d.closed_loop:
            Q[lay.alpha_idx[i]] = d.torque(t, left)
    return Q


def _prescribed(case, lay: _Layout, t: float, left: bool) -> np.ndarray:
    """(n_motion, 3): (α, α̇, α̈) of the motion-driven joints at t."""
    rows = [d.motion(t, left) for d in case.scenario.drives if d.kind == "motion"]
    return np.array(rows, float).reshape(-1, 3)


def _initial_state(case, lay: _Layout):
    q = np.zeros(lay.n_dof)
    qd = np.zeros(lay.n_dof)
    for i, d in enumerate(case.scenario.drives):
        q[lay.alpha_idx[i]] = d.initial_angle
        qd[lay.alpha_idx[i]] = d.initial_rate
    return q, qd


# ----------------------------------------------------------------------------------------------
# Forward dynamics
# ----------------------------------------------------------------------------------------------


def _forward(case, lay, q, qd, t, left):
    """q̈ from M q̈ = Q − h − f_int(q) − Dq̇ (f_int = Kq for the linear element) with motion
    joints prescribed; also the joint torques of the motion-driven joints (n_motion,).
    ``q``, ``qd`` must hold the prescribed values."""
    P, F = lay.presc, lay.free
    pres = _prescribed(case, lay, t, left)
    M, f = _assemble(lay, q, qd)
    if lay.nonlinear:
        rhs = f + _torques(case, lay, t, left) - _internal(lay, q)[0] - _damping(lay, q, qd)[0]
    else:
        rhs = f + _torques(case, lay, t, left) - lay.K @ q - lay.D @ qd
    qdd = np.zeros(lay.n_dof)
    qdd[P] = pres[:, 2]
    qdd[F] = np.linalg.solve(M[np.ix_(F, F)], rhs[F] - M[np.ix_(F, P)] @ qdd[P])
    tau_p = M[P] @ qdd - rhs[P]
    return qdd, tau_p


# ----------------------------------------------------------------------------------------------
# Public helpers
# ----------------------------------------------------------------------------------------------


def coordinate_names(case, k) -> list[str]:
    """Names of the minimal coordinates, in the order of q.

    Parameters
    ----------
    case : dttmm.Case
    k : int
        Elements per link.

    Returns
    -------
    list of str
        Per link i: ``alpha_i``, then per element j ``u_i_j`` (extensible links only),
        ``v_i_j``, ``phi_i_j`` (1-based).
    """
    return list(_layout(case, k).names)


def _as_state(lay: _Layout, x, field: str) -> np.ndarray:
    arr = np.asarray(x, float)
    if arr.shape != (lay.n_dof,):
        raise InputError(field, f"shape {arr.shape}", f"must have shape ({lay.n_dof},)")
    if not np.all(np.isfinite(arr)):
        raise InputError(field, "non-finite entries", "must be finite")
    return arr


def mass_matrix(case, elements_per_link, q) -> np.ndarray:
    """Mass matrix of the minimal coordinates.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
    q : (N,) array_like
        Coordinates in the order of :func:`coordinate_names`.

    Returns
    -------
    (N, N) ndarray
        M(q) = Σ J_elᵀ M_el J_el (+ hubs and payloads), symmetric.
    """
    lay = _layout(case, elements_per_link)
    q = _as_state(lay, q, "q")
    return _assemble(lay, q, np.zeros(lay.n_dof))[0]


def stiffness_matrix(case, elements_per_link) -> np.ndarray:
    """Stiffness matrix of the minimal coordinates.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int

    Returns
    -------
    (N, N) ndarray
        Constant, block diagonal per element; zero rows and columns on the joint angles.
    """
    return _layout(case, elements_per_link).K.copy()


def elastic_forces(case, elements_per_link, q, strain="linear"):
    """Internal elastic force and its tangent at a configuration.

    Per element, with w = (v, φ) and K_b = EI/l³ [[12, −6l], [−6l, 4l²]], the strain energy is
    U = ½ EA l ε² + ½ wᵀK_b w with the axial strain ε = u/l (``"linear"``) or
    ε = u/l + ½ wᵀGw (``"second-order"``, extensible links only: the chord shortens as the
    element bends), G = ∫₀¹ N'ᵀN' dξ, N' = (dN3/dx, dN4/dx). Inextensible links keep
    U = ½ wᵀK_b w either way.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
    q : (N,) array_like
    strain : {"linear", "second-order"}

    Returns
    -------
    f_int : (N,) ndarray
        ∂U/∂q (K q for the linear element).
    K_T : (N, N) ndarray
        ∂f_int/∂q (the constant K for the linear element), symmetric, block diagonal per element.
    """
    lay = _layout(case, elements_per_link, strain)
    f, KT = _internal(lay, _as_state(lay, q, "q"))
    return f.copy(), KT.copy()


def damping_forces(case, elements_per_link, q, qd, strain="linear"):
    """Kelvin-Voigt damping force and its rate tangent at a state.

    Per element the dissipation function is R = ½ μ [EA l ε̇² + ẇᵀK_b ẇ], with w = (v, φ),
    K_b as in :func:`elastic_forces` and ε̇ the rate of the element's strain measure:
    ε̇ = u̇/l (``"linear"``) or ε̇ = u̇/l + wᵀGẇ (``"second-order"``, extensible links). So
    f_d,u = μ EA ε̇ and f_d,w = μ (EA l ε̇ Gw + K_b ẇ); for the linear element f_d = μK q̇.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
    q, qd : (N,) array_like
    strain : {"linear", "second-order"}

    Returns
    -------
    f_d : (N,) ndarray
        ∂R/∂q̇ (N or N·m per coordinate).
    D_t : (N, N) ndarray
        ∂f_d/∂q̇, symmetric, block diagonal per element.
    """
    lay = _layout(case, elements_per_link, strain)
    fd, Dt = _damping(lay, _as_state(lay, q, "q"), _as_state(lay, qd, "qd"))
    return fd.copy(), Dt.copy()


def accelerations(case, elements_per_link, q, qd, t=0.0, strain="linear") -> np.ndarray:
    """Forward dynamics q̈ = M⁻¹(Q − h − f_int(q) − Dq̇) (f_int = Kq for the linear element).

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
    q, qd : (N,) array_like
        Coordinates and rates (order of :func:`coordinate_names`). The entries of
        motion-driven joints are used as given.
    t : float
        Time for the drive values (right limits at a breakpoint).
    strain : {"linear", "second-order"}
        Element strain measure (see :func:`elastic_forces`).

    Returns
    -------
    (N,) ndarray
        q̈; motion-driven joints take α̈ from their law.
    """
    lay = _layout(case, elements_per_link, strain)
    q = _as_state(lay, q, "q")
    qd = _as_state(lay, qd, "qd")
    gc.require_stepped(case, "accelerations()")
    return _forward(case, lay, q, qd, float(t), False)[0]


def kinematics(case, elements_per_link, q) -> dict:
    """Link frames by forward kinematics.

    Parameters
    ----------
    case : dttmm.Case
    elements_per_link : int
    q : (N,) array_like

    Returns
    -------
    dict
        ``root`` (n, 2) and ``tip`` (n, 2) positions (m), ``root_angle`` (n,) and
        ``tip_angle`` (n,) absolute cross-section angles (rad).
    """
    lay = _layout(case, elements_per_link)
    return _link_frames(lay, _as_state(lay, q, "q"))


def _tip_deflections(lay: _Layout, q: np.ndarray) -> np.ndarray:
    """(n,) transverse tip deflection of every link in its clamped-root frame (m)."""
    fr = _link_frames(lay, q)
    return tip_deflection(fr["root"], fr["root_angle"], fr["tip"])


def _link_frames(lay: _Layout, q: np.ndarray) -> dict:
    fr = _frames(lay, q)
    last = lay.last_el
    return {
        "root": fr.rI[lay.first_el],
        "root_angle": fr.theta[lay.first_el],
        "tip": fr.rO[last],
        "tip_angle": fr.theta[last] + fr.e[last, 2],
    }


def energy(case, elements_per_link, q, qd, strain="linear") -> dict:
    """Mechanical energy at a state (the arguments as in :func:`damping_forces`).

    Returns
    -------
    dict
        ``kinetic`` ½q̇ᵀM(q)q̇, ``elastic`` the strain energy Σ U (½qᵀKq for the linear
        element) and ``gravity`` −Σ m g·r (J).
    """
    lay = _layout(case, elements_per_link, strain)
    q = _as_state(lay, q, "q")
    qd = _as_state(lay, qd, "qd")
    return _energy(lay, q, qd)


def _energy(lay: _Layout, q: np.ndarray, qd: np.ndarray, kinetic=None) -> dict:
    fr = _frames(lay, q)
    sigma = lay.sigma0 + _matvec(lay.Sbar, fr.e)
    first = (lay.mass + lay.hub_m)[:, None] * fr.rI + _matvec(fr.A, sigma)
    moment = first.sum(axis=0)
    for p, (i, mp, _) in enumerate(lay.payloads):
        moment = moment + mp * fr.rO[lay.last_el[i]]
        if lay.pay_offset[p] != (0.0, 0.0):  # its centre of mass off the tip
            el = lay.last_el[i]
            th = fr.theta[el] + fr.e[el, 2]
            moment = moment + mp * _matvec(_rot(np.array([th]))[0], np.array(lay.pay_offset[p], float))
    T = _kinetic(lay, q, qd) if kinetic is None else kinetic(q, qd)
    return {"kinetic": T, "elastic": _strain_energy(lay, q), "gravity": -float(lay.gravity @ moment)}


def element_mass(rhoA, length, theta=0.0, e=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Mass matrix of one element in its own coordinates, as used by the solver.

    Parameters
    ----------
    rhoA : float
        Mass per unit length (kg/m).
    length : float
        Element length l (m).
    theta : float
        Frame angle θ (rad).
    e : sequence of 3 floats
        Elastic coordinates (u, v, φ).

    Returns
    -------
    (6, 6) ndarray
        ∫ρA J_pᵀJ_p dx on p = (x_I, y_I, θ, u, v, φ).
    """
    beam = Section(length, 1.0, rhoA, 1.0)
    case = Case(Manipulator((Link(beam),)), Scenario(1.0, 1.0, (Drive("torque", Constant(0.0)),)))
    lay = _layout(case, 1)
    q = np.array([theta, *e], float)
    fr = _frames(lay, q)
    Mel, _, _ = _element_terms(lay, fr, np.zeros(1), np.zeros((1, 3)))
    return Mel[0]


# ----------------------------------------------------------------------------------------------
# Outputs (used by the driver's recorder)
# ----------------------------------------------------------------------------------------------


def _link_shapes(lay: _Layout, q: np.ndarray, p: int) -> np.ndarray:
    """Deflected centre lines (nt, n_links, p, 2) m at the states q (nt, N): p material points
    per link at the reference arc lengths x = L·m/(p − 1), m = 0..p − 1, each placed in its
    element by r = r_I + A(θ) s(ξ), s(ξ) = (ξ(l + u), N3 v + N4 φ)."""
    k = lay.k
    el, l, xi = [], [], []
    for i in range(lay.n_links):
        li = lay.length[lay.first_el[i]]
        xs = np.linspace(0.0, k * li, p) / li  # in element lengths
        jj = np.minimum(np.floor(xs).astype(int), k - 1)
        el.append(lay.first_el[i] + jj)
        l.append(np.full(p, li))
        xi.append(xs - jj)
    el, l, xi = np.concatenate(el), np.concatenate(l), np.concatenate(xi)
    n3 = 3 * xi**2 - 2 * xi**3
    n4 = l * (xi**3 - xi**2)
    out = np.empty((q.shape[0], lay.n_links * p, 2))
    for r in range(q.shape[0]):
        fr = _frames(lay, q[r])
        e = fr.e[el]
        loc = np.stack([xi * (l + e[:, 0]), n3 * e[:, 1] + n4 * e[:, 2]], -1)
        out[r] = fr.rI[el] + _matvec(fr.A[el], loc)
    return out.reshape(q.shape[0], lay.n_links, p, 2)


def _joint_torques(case, lay, t, left, tau_p) -> np.ndarray:
    """Joint torques (n,): the drive value of open-loop torque joints and the computed one
    ``tau_p`` of motion joints (0 for closed-loop joints: the driver sets them)."""
    tau = np.zeros(lay.n_links)
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and not d.closed_loop:
            tau[i] = d.torque(t, left)
    tau[lay.motion] = tau_p
    return tau
