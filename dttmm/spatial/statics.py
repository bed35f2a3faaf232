"""Static equilibrium of a spatial arm with its joints held fixed (docs/spatial.md, "Spatial
benchmark problems").

The unknowns are the elastic coordinates e of every element (the joint angles stay at the given
values, 0 by default: a clamped base and rigidly held joints). The residual is

    r(e) = f_el(e) − Q(e),

f_el the elastic force of the discretisation (the kernel's ``elastic_into``, linear or
second-order strain) and Q the generalized force of gravity (the Gauss bodies of every element,
hubs and payloads) and of the external loads: the case's ``scenario.loads``
(:class:`dttmm.spatial.SpatialLoad`, at the tip point of their link, world components or
follower loads in the deformed tip frame, their factor laws taken at the time ``t``) and the
``loads`` argument (a force F with a fixed direction in the world frame at the tip point of the
last link and a moment M, world components). Q follows from
virtual work, with the kinematics of the kernel (``kinematics``): perturbing the coordinates e of
one element moves its Gauss bodies by R_I Σ_g δe and everything outboard of it rigidly with its
outboard node, δr_O = R_I Σ_O δe, δθ_O = R_I J_L(φ) δφ. So, with (F_O, M_O) the resultant of
the loads outboard of the node (the moment about r_O, follower loads turned by the current tip
frame),

    Q_e = Σ_g Σ_gᵀ R_Iᵀ m_g g + Σ_Oᵀ R_Iᵀ F_O + (J_L(φ) Ψ_O)ᵀ R_Iᵀ M_O,

accumulated tip to root in one pass. Newton's method solves r = 0 with the tangent
K_T(e) − ∂Q/∂e (the elastic tangent exact, the load stiffness by forward differences of Q),
the loads applied in ``steps`` equal increments (each increment starts from the previous
equilibrium). The section loads at the root of the first link are minus the resultant of the
external loads (the load the base exerts on the beam, docs/spatial.md §4; the first link's hub
is on the inboard side of that cut).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import plumbing
from ..errors import InputError, SimulationError
from .build import STRAINS, build_model, make_work
from .model import require_open_chain
from .rotation import left_jacobian
from .scenario import load_inputs
from .solver import _kernel, as_spatial_case

__all__ = ["StaticResult", "elastic_forces", "generalized_loads", "statics"]

LOAD_KEYS = ("force", "moment")


@dataclass(frozen=True)
class StaticResult:
    """The equilibrium of :func:`statics` at the full load, and the path of the increments.

    ``q`` (n_dof,) the coordinates; ``tip_position`` (3,) the tip point of the end-effector (the
    last link of a chain) and ``tip_rotation`` (3, 3) its tip frame (world); ``shape``
    (n_links·k + 1, 3) the first link's root, then the element nodes of every link in order (a
    chain: the nodes from the first link's root to the last tip, link tips included once; joint
    origins between links are rigid offsets not listed); ``root_loads`` (6,) force and moment
    (about the root point, world) that the base exerts on the first link; ``load_factors``
    (steps,) and ``tip_path`` (steps, 3) the end-effector's tip position at each converged
    increment; ``iterations`` (steps,) Newton iterations per increment; ``link_tips`` (n_links, 3)
    the tip point of every link (a tree: every branch)."""

    q: np.ndarray
    tip_position: np.ndarray
    tip_rotation: np.ndarray
    shape: np.ndarray
    root_loads: np.ndarray
    load_factors: np.ndarray
    tip_path: np.ndarray
    iterations: np.ndarray
    link_tips: np.ndarray


def _vector3(field: str, value) -> np.ndarray:
    if isinstance(value, (str, bool)):
        raise InputError(field, value, "must be 3 finite numbers")
    try:
        v = np.array(value, float)
    except (TypeError, ValueError):
        raise InputError(field, value, "must be 3 finite numbers") from None
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(field, value, "must be 3 finite numbers")
    return v


def _loads(loads) -> tuple[np.ndarray, np.ndarray]:
    if loads is None:
        return np.zeros(3), np.zeros(3)
    if not isinstance(loads, dict):
        raise InputError("loads", loads, "must be a dict with keys 'force' and/or 'moment'")
    for key in loads:
        if key not in LOAD_KEYS:
            raise InputError(f"loads[{key!r}]", loads[key], "unknown key (one of: force, moment)")
    return (
        _vector3("loads['force']", loads.get("force", (0.0, 0.0, 0.0))),
        _vector3("loads['moment']", loads.get("moment", (0.0, 0.0, 0.0))),
    )


class _Problem:
    """The discretised arm with its joints fixed: kinematics, elastic and external forces."""

    def __init__(self, case, k, strain, engine, angles):
        self.case = case
        _, self.core, _ = _kernel(engine)
        require_open_chain(case.model, "the spatial statics")
        self.md = md = build_model(case.model, k, strain)
        self.ws = make_work(md)
        self.q = np.zeros(md.ndof)
        unlocked = [i for i in range(md.n) if md.locked[i] == 0]
        if angles is not None:
            a = np.array(angles, float) if not isinstance(angles, (str, bool)) else None
            if a is None or a.shape != (len(unlocked),) or not np.all(np.isfinite(a)):
                raise InputError(
                    "angles", angles, f"must be {len(unlocked)} finite numbers (one per unlocked joint)"
                )
            self.q[md.ia[unlocked]] = a
        free = np.ones(md.ndof, bool)
        free[md.ia[unlocked]] = False
        self.free = np.flatnonzero(free)
        # padded element coordinate c of element el sits at q[ie[el] + c - (1 - ext)]
        self.cols = []
        for i in range(md.n):
            off = 0 if md.ext[i] else 1
            for j in range(md.k[i]):
                el = md.el0[i] + j
                pad = np.arange(off, 6) if md.rigid[i] == 0 else np.arange(0)  # rigid: no e
                self.cols.append((i, el, pad, md.ie[el] + pad - off))
        self.grav = np.array(case.model.gravity, float)
        self.ee = case.model.end_effector_index
        self.cs0 = np.einsum("ig,igj->ij", md.mg, md.s0[:, :4])  # Σ_g m_g s0_g per link

    def set(self, e_free):
        q = self.q.copy()
        q[self.free] = e_free
        self.core.kinematics(self.md, self.ws, q, np.zeros_like(q))
        return q

    def elastic(self, q):
        """f_el (n_dof,) and K_T (n_dof, n_dof) at q."""
        md = self.md
        f = np.zeros(md.ndof)
        KT = np.zeros((md.ndof, md.ndof))
        f6, K6, D6 = np.zeros(6), np.zeros((6, 6)), np.zeros((6, 6))
        for i, el, pad, idx in self.cols:
            self.core.elastic_into(md, i, self.ws.e[el].copy(), f6, K6, D6)
            f[idx] = f6[pad]
            KT[np.ix_(idx, idx)] = K6[np.ix_(pad, pad)]
        return f, KT

    def external(self, F, M, tips=None):
        """(Q (n_dof,), root loads (6,)) of gravity, the force F and moment M (world) at the
        end-effector's tip and the per-link tip loads ``tips`` ((n, 12) rows of
        :func:`dttmm.spatial.scenario.load_inputs`: world force and moment, tip-frame force and
        moment) at the current kinematics. The loads gather from the leaves to the base: at a
        link's tip, those its children's roots carry (a tree: each link's parent comes first)."""
        md, ws, g = self.md, self.ws, self.grav
        Q = np.zeros(md.ndof)
        zero = np.zeros(3)
        # per link: the load (force, moment about the tip) its children pass to its tip
        carried = [None] * md.n

        def move(p):
            nonlocal Mo, po
            Mo = Mo + np.cross(po - p, Fo)
            po = p

        def add(m, p):
            nonlocal Fo, Mo
            if m:
                Fo = Fo + m * g
                Mo = Mo + np.cross(p - po, m * g)

        root = np.zeros(6)
        for i in range(md.n - 1, -1, -1):
            tip = ws.pT[i + 1]
            po = tip.copy()
            if i == self.ee:
                Fo, Mo = F.copy(), M.copy()
                if carried[i] is not None:
                    Fo, Mo = Fo + carried[i][0], Mo + carried[i][1]
            else:
                Fo, Mo = (zero, zero) if carried[i] is None else carried[i]
            move(tip.copy())
            if tips is not None:
                RT = ws.RT[i + 1]
                Fo = Fo + tips[i, 0:3] + RT @ tips[i, 6:9]
                Mo = Mo + tips[i, 3:6] + RT @ tips[i, 9:12]
            add(md.pay_m[i], tip + ws.RT[i + 1] @ (md.Q[i] @ md.pay_d[i]))
            for j in range(md.k[i] - 1, -1, -1):
                el = md.el0[i] + j
                R, p, e = ws.Rw[el], ws.pw[el], ws.e[el]
                rO = p + R @ (md.s0[i, 4] + md.Sig[i, 4] @ e)
                move(rO)
                if md.rigid[i]:  # a rigid slot: no coordinates; the body at the root slot
                    if j == 0:
                        add(md.rb_m[i], p + R @ md.rb_c[i])
                    move(p.copy())
                    continue
                qe = md.Sig[i, 4].T @ (R.T @ Fo) + (left_jacobian(e[3:]) @ md.Psi[i, 4]).T @ (R.T @ Mo)
                # the Gauss bodies: Σ_g m_g Σ_gᵀ = CSᵀ, their weight at the mass centre
                qe += md.CS[i].T @ (R.T @ g)
                add(md.mel[i], p + R @ (self.cs0[i] + md.CS[i] @ e) / md.mel[i])
                Q[self.cols[el][3]] = qe[self.cols[el][2]]
                move(p.copy())
            if i == 0:
                root = -np.concatenate([Fo, Mo])
            add(md.hub_m[i], po)
            parent = md.par[i]
            if parent >= 0:
                move(ws.pT[parent + 1].copy())
                if carried[parent] is None:
                    carried[parent] = (Fo, Mo)
                else:
                    carried[parent] = (carried[parent][0] + Fo, carried[parent][1] + Mo)
        return Q, root

    def shape(self):
        md, ws = self.md, self.ws
        pts = [ws.pw[0].copy()]
        for i in range(md.n):
            for j in range(md.k[i]):
                el = md.el0[i] + j
                R, p, e = ws.Rw[el], ws.pw[el], ws.e[el]
                pts.append(p + R @ (md.s0[i, 4] + md.Sig[i, 4] @ e))
        return np.array(pts)


def _at(case, elements_per_link, q, strain, engine):
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    pb = _Problem(case, k, strain, engine, None)
    q = np.array(q, float)
    if q.shape != (pb.md.ndof,):
        raise InputError("q", q.shape, f"must have shape ({pb.md.ndof},)")
    pb.q = q.copy()
    pb.set(q[pb.free])
    return pb, q


def elastic_forces(case, elements_per_link, q, *, strain="linear", engine=None):
    """(f_el (n_dof,), K_T (n_dof, n_dof)): the elastic force ∂U/∂q of every element and its
    tangent at q (zero in the rows and columns of the joint angles)."""
    pb, q = _at(case, elements_per_link, q, strain, engine)
    return pb.elastic(q)


def _load_time(case, t) -> float:
    if t is None:
        return float(case.scenario.duration)
    if isinstance(t, bool) or not isinstance(t, (int, float, np.floating, np.integer)) or not np.isfinite(t):
        raise InputError("t", t, "must be a finite number (s)")
    return float(t)


def generalized_loads(case, elements_per_link, q, *, loads=None, t=None, engine=None):
    """Generalized force Q (n_dof,) of gravity, the case's ``scenario.loads`` at time ``t``
    (default: the scenario's duration) and the tip loads ``loads`` (``force`` and/or
    ``moment``, world components, at the end-effector's tip) at the coordinates q (the joint angles
    taken as given; the entries of the unlocked joints are 0: the joints are held), and the root
    section loads (6,) that balance them."""
    F, M = _loads(loads)
    pb, _ = _at(case, elements_per_link, q, "linear", engine)
    tl = _load_time(pb.case, t)
    return pb.external(F, M, load_inputs(pb.case, tl, tl > 0.0))


def statics(
    case,
    *,
    elements_per_link: int,
    loads=None,
    t: float | None = None,
    strain: str = "linear",
    tol: float = 1e-10,
    max_iterations: int = 30,
    steps: int = 1,
    angles=None,
    engine: str | None = None,
) -> StaticResult:
    """Static equilibrium of ``case`` (a :class:`SpatialCase`, a (SpatialManipulator,
    Scenario) pair or a planar :class:`dttmm.Case`, embedded; its drives are not used) under its gravity, the external loads of its
    scenario (``SpatialScenario.loads``, their factor laws at time ``t``, default the scenario's
    duration) and the extra tip ``loads`` (``{"force": (3,), "moment": (3,)}``, world
    components, fixed in direction, at the end-effector's tip), by Newton's method on the elastic
    coordinates with the joints held at ``angles`` (one per unlocked joint, default 0). The
    loads and gravity are applied in ``steps`` equal increments; each
    increment iterates until ‖r‖ ≤ tol·‖Q‖ (Q the generalized load of that increment) or
    ``max_iterations`` (then SimulationError). Returns a :class:`StaticResult`."""
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    F, M = _loads(loads)
    tol = plumbing.positive_number("tol", tol)
    max_iterations = plumbing.positive_integer("max_iterations", max_iterations)
    steps = plumbing.positive_integer("steps", steps)
    tl = _load_time(case, t)
    pb = _Problem(case, k, strain, engine, angles)
    tips = load_inputs(case, tl, tl > 0.0)
    g_full = pb.grav.copy()
    x = np.zeros(pb.free.size)
    fr = pb.free
    factors, path, its = [], [], []
    root = np.zeros(6)
    for s in range(1, steps + 1):
        lam = s / steps
        pb.grav = lam * g_full
        Fs, Ms = lam * F, lam * M
        rn_prev = np.inf
        for it in range(max_iterations + 1):
            q = pb.set(x)
            f, KT = pb.elastic(q)
            Q, root = pb.external(Fs, Ms, lam * tips)
            r = (f - Q)[fr]
            scale = max(np.linalg.norm(Q[fr]), np.linalg.norm(f[fr]), 1e-300)
            if not np.all(np.isfinite(r)):
                raise SimulationError(
                    "statics: non-finite residual", t=lam, step=s - 1, component="elastic coordinates"
                )
            rn = np.linalg.norm(r)
            if rn <= tol * scale:
                break
            if it == max_iterations:
                raise SimulationError(
                    f"statics: no convergence in {max_iterations} Newton iterations "
                    f"(residual {np.linalg.norm(r) / scale:.3g} relative; use more steps)",
                    t=lam,
                    step=s - 1,
                    component="elastic coordinates",
                )
            if it == 0 or rn > 0.05 * rn_prev:
                # a fresh tangent (else the last one is kept while the residual falls fast):
                # the load stiffness −∂Q/∂e by forward differences
                A = KT[np.ix_(fr, fr)].copy()
                for c in range(fr.size):
                    h = 1e-7 * max(1.0, abs(x[c]))
                    xc = x.copy()
                    xc[c] += h
                    pb.set(xc)
                    A[:, c] -= (pb.external(Fs, Ms, lam * tips)[0][fr] - Q[fr]) / h
                lu = np.linalg.inv(A)
            rn_prev = rn
            x = x - lu @ r
        factors.append(lam)
        path.append(pb.ws.pT[pb.ee + 1].copy())
        its.append(it)
    q = pb.set(x)
    return StaticResult(
        q=q,
        tip_position=pb.ws.pT[pb.ee + 1].copy(),
        tip_rotation=pb.ws.RT[pb.ee + 1].copy(),
        shape=pb.shape(),
        root_loads=root,
        load_factors=np.array(factors),
        tip_path=np.array(path),
        iterations=np.array(its),
        link_tips=pb.ws.pT[1:].copy(),
    )
