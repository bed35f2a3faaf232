"""The readable mechanics of the spatial global-equation solver (:mod:`reference_models.spatial_global`):
layout, frames and their Jacobians, bodies, M = Σ m J_vᵀJ_v + Σ J_ωᵀ I J_ω from dense
Jacobians, velocity terms by the complex step, elastic and damping forces, drives and the
forward dynamics, closures (g, J, loads), cut loads and the public functions of a state.
Engine "numpy" of the solver and the check of the compiled mechanics
(:mod:`reference_models._spatial_numba`, engine "numba"), which a layout carries in
``compiled``: :func:`_assemble`, :func:`_tip_frames`, the second-order strain, the energy and
the cut loads dispatch to it. No time loop: that is :mod:`reference_models._spatial_driver`."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dttmm import plumbing
from dttmm.case import Case
from dttmm.drives import require_open_loop
from dttmm.errors import InputError
from dttmm.shapes import frame_shapes
from dttmm.shapes import shape_points as check_shape_points
from dttmm.spatial import SpatialCase

from . import _checks
from . import _spatial_numba as _sn
from ._spatial_mechanics import (
    GAUSS_WEIGHTS,
    element_stiffness,
    exp_so3,
    left_jacobian,
    log_so3,
    rot_axis,
    rpy_matrix,
    shape_matrices,
    skew,
    strain_terms,
)

STRAINS = _checks.STRAINS
_EPS = 1e-30  # complex step
_SLOTS = ("u", "v", "w", "phix", "phiy", "phiz")


# ----------------------------------------------------------------------------------------------
# Layout
# ----------------------------------------------------------------------------------------------


@dataclass
class _Layout:
    """Coordinates and constant data of one (case, k) discretisation."""

    n_links: int
    k: int
    n_dof: int
    names: list
    alpha_idx: np.ndarray  # (n,) q index of α_i, −1 for a locked joint
    joints: np.ndarray  # (nj,) links with an unlocked joint, base first
    e_idx: np.ndarray  # (Nel, 6) q index of e's slots, −1 where absent
    sel: np.ndarray  # (Nel, 6, N) q → e
    link_of: np.ndarray  # (Nel,)
    length: np.ndarray  # (Nel,)
    # per link
    axis: np.ndarray  # (n, 3)
    origin_R: np.ndarray  # (n, 3, 3)
    origin_p: np.ndarray  # (n, 3)
    roll_R: np.ndarray  # (n, 3, 3) Rx(roll)
    hub_m: np.ndarray  # (n,)
    hub_J: np.ndarray  # (n, 3, 3)
    pay_m: np.ndarray  # (n,)
    pay_c: np.ndarray  # (n, 3)
    pay_J: np.ndarray  # (n, 3, 3)
    rb_m: np.ndarray  # (n,) rigid links' bodies: mass,
    rb_c: np.ndarray  # (n, 3) centre of mass (link frame),
    rb_J: np.ndarray  # (n, 3, 3) inertia about it (link frame)
    base_R: np.ndarray
    base_p: np.ndarray
    gravity: np.ndarray  # (3,)
    # Gauss points, per element
    s0: np.ndarray  # (Nel, ng, 3)
    S: np.ndarray  # (Nel, ng, 3, 6)
    P: np.ndarray  # (Nel, ng, 3, 6)
    m_g: np.ndarray  # (Nel, ng) point masses ρA l w_g
    I_g: np.ndarray  # (Nel, ng, 3) rotary inertia diagonals l w_g (ρJ, ρIy, ρIz)
    # elastic data, per element
    EA: list  # (Nel,) float or None
    K_el: np.ndarray  # (Nel, 6, 6) linear-strain stiffness
    mu: np.ndarray  # (Nel,)
    second: np.ndarray  # (Nel,) bool: second-order axial strain
    K: np.ndarray  # (N, N) linear stiffness
    D: np.ndarray  # (N, N) μK
    strain: str
    # drives
    motion: np.ndarray  # (nj,) bool
    presc: np.ndarray  # q indices of motion-driven α
    free: np.ndarray
    # topology
    parent: np.ndarray  # (n,) the parent link of each link, −1 for the base
    outboard: np.ndarray  # (n, n) bool: link j lies in the subtree of link i (j ≠ i)
    end_effector: int = -1  # the link whose tip is the end effector
    closures: tuple = ()  # (_Closure, …)
    compiled: tuple | None = None  # the compiled mechanics' arrays (engine "numba"), or None


def _check_case(case) -> SpatialCase:
    """The spatial case; a planar :class:`dttmm.Case` as the spatial case it is
    (:meth:`dttmm.spatial.SpatialCase.from_planar`, its plane the world's x–y plane)."""
    if isinstance(case, Case):
        return SpatialCase.from_planar(case)
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase or a dttmm.Case")
    return case


def _layout(case, k, strain="linear") -> _Layout:
    case = _check_case(case)
    k = plumbing.elements_per_link(k)
    strain = _checks.strain(strain)
    model = case.model
    links = model.links
    n = len(links)
    names, alpha_idx, e_idx = [], [], []
    for i, link in enumerate(links, start=1):
        if link.joint.locked:
            alpha_idx.append(-1)
        else:
            alpha_idx.append(len(names))
            names.append(f"alpha_{i}")
        if link.rigid:
            slots = range(0)  # a rigid link: no elastic coordinates
        else:
            slots = range(6) if link.beam.EA is not None else range(1, 6)
        for j in range(1, k + 1):
            row = [-1] * 6
            for s in slots:
                row[s] = len(names)
                names.append(f"{_SLOTS[s]}_{i}_{j}")
            e_idx.append(row)
    N = len(names)
    e_idx = np.array(e_idx, int)
    nel = n * k
    sel = np.zeros((nel, 6, N))
    el, slot = np.nonzero(e_idx >= 0)
    sel[el, slot, e_idx[el, slot]] = 1.0
    length = np.repeat([lk.beam.length / k for lk in links], k).astype(float)
    s0, S, P, m_g, I_g, K_el, EA, mu, second = [], [], [], [], [], [], [], [], []
    for link in links:
        b = link.beam
        l = b.length / k
        if link.rigid:  # k massless rigid segments of length l (e ≡ 0); the body is apart
            a, B, C = shape_matrices(l if l > 0 else 1.0)
            a = a * (l if l > 0 else 0.0)
            for _ in range(k):
                s0.append(a)
                S.append(B)
                P.append(C)
                m_g.append(np.zeros(GAUSS_WEIGHTS.size))
                I_g.append(np.zeros((GAUSS_WEIGHTS.size, 3)))
                K_el.append(np.zeros((6, 6)))
                EA.append(None)
                mu.append(0.0)
                second.append(False)
            continue
        a, B, C = shape_matrices(l)
        Ke = element_stiffness(l, b.EA, b.GJ, b.EIy, b.EIz)
        for _ in range(k):
            s0.append(a)
            S.append(B)
            P.append(C)
            m_g.append(b.rhoA * l * GAUSS_WEIGHTS)
            I_g.append(l * GAUSS_WEIGHTS[:, None] * np.array([b.rhoJ, b.rhoIy, b.rhoIz]))
            K_el.append(Ke)
            EA.append(b.EA)
            mu.append(b.damping)
            second.append(strain == "second-order" and b.EA is not None)
    K_el = np.array(K_el)
    mu = np.array(mu, float)
    K = np.zeros((N, N))
    for e in range(nel):
        K += sel[e].T @ K_el[e] @ sel[e]
    joints = np.array([i for i, lk in enumerate(links) if not lk.joint.locked], int)
    alpha_idx = np.array(alpha_idx, int)
    motion = np.array([d.kind == "motion" for d in case.scenario.drives], bool)
    presc = alpha_idx[joints[motion]]
    D = np.zeros((N, N))
    for e in range(nel):
        D += mu[e] * (sel[e].T @ K_el[e] @ sel[e])
    parent = np.array(getattr(model, "parents", range(-1, n - 1)), int)
    outboard = np.zeros((n, n), bool)
    for j in range(n):  # parents come first: a link's ancestors are marked before it
        i = parent[j]
        while i >= 0:
            outboard[i, j] = True
            i = parent[i]
    ee = getattr(model, "end_effector_index", n - 1)
    lay = _Layout(
        n_links=n,
        k=k,
        n_dof=N,
        names=names,
        alpha_idx=alpha_idx,
        joints=joints,
        e_idx=e_idx,
        sel=sel,
        link_of=np.repeat(np.arange(n), k),
        length=length,
        axis=np.array([lk.joint.axis for lk in links], float),
        origin_R=np.array([rpy_matrix(lk.joint.origin_rpy) for lk in links]),
        origin_p=np.array([lk.joint.origin_xyz for lk in links], float),
        roll_R=np.array([rot_axis((1, 0, 0), lk.roll) for lk in links]),
        hub_m=np.array([lk.hub_mass for lk in links], float),
        hub_J=np.array([lk.hub_inertia for lk in links], float),
        pay_m=np.array([lk.payload_mass for lk in links], float),
        pay_c=np.array([lk.payload_offset for lk in links], float),
        pay_J=np.array([lk.payload_inertia for lk in links], float),
        rb_m=np.array([lk.beam.mass if lk.rigid else 0.0 for lk in links], float),
        rb_c=np.array([lk.beam.com if lk.rigid else (0.0, 0.0, 0.0) for lk in links], float),
        rb_J=np.array([lk.beam.inertia_matrix if lk.rigid else np.zeros((3, 3)) for lk in links]),
        base_R=rpy_matrix(model.base_rpy),
        base_p=np.array(model.base_xyz, float),
        gravity=np.array(model.gravity, float),
        s0=np.array(s0),
        S=np.array(S),
        P=np.array(P),
        m_g=np.array(m_g),
        I_g=np.array(I_g),
        EA=EA,
        K_el=K_el,
        mu=mu,
        second=np.array(second, bool),
        K=K,
        D=D,
        strain=strain,
        motion=motion,
        presc=presc,
        free=np.setdiff1d(np.arange(N), presc),
        parent=parent,
        outboard=outboard,
        end_effector=int(ee),
    )
    if getattr(model, "closures", ()):
        lay.closures = _closure_data(case, lay)
    return lay


# ----------------------------------------------------------------------------------------------
# Kinematics: frames and their velocity Jacobians (any dtype: complex for the complex step)
# ----------------------------------------------------------------------------------------------


@dataclass
class _Frames:
    e: np.ndarray  # (Nel, 6)
    RI: np.ndarray  # (Nel, 3, 3) element frames
    rI: np.ndarray  # (Nel, 3)
    JrI: np.ndarray  # (Nel, 3, N)
    JwI: np.ndarray  # (Nel, 3, N)
    R_link: np.ndarray  # (n, 3, 3)
    p_link: np.ndarray  # (n, 3)
    Jr_link: np.ndarray  # (n, 3, N)
    Jw_link: np.ndarray
    R_tip: np.ndarray  # (n, 3, 3)
    p_tip: np.ndarray  # (n, 3)
    Jr_tip: np.ndarray
    Jw_tip: np.ndarray
    nodes: np.ndarray  # (Nel, 3) outboard node positions


def _frames(lay: _Layout, q: np.ndarray) -> _Frames:
    dt = q.dtype
    N, n, k = lay.n_dof, lay.n_links, lay.k
    nel = n * k
    e = np.einsum("esn,n->es", lay.sel, q)
    out = {
        "RI": np.empty((nel, 3, 3), dt),
        "rI": np.empty((nel, 3), dt),
        "JrI": np.empty((nel, 3, N), dt),
        "JwI": np.empty((nel, 3, N), dt),
        "R_link": np.empty((n, 3, 3), dt),
        "p_link": np.empty((n, 3), dt),
        "Jr_link": np.empty((n, 3, N), dt),
        "Jw_link": np.empty((n, 3, N), dt),
        "R_tip": np.empty((n, 3, 3), dt),
        "p_tip": np.empty((n, 3), dt),
        "Jr_tip": np.empty((n, 3, N), dt),
        "Jw_tip": np.empty((n, 3, N), dt),
        "nodes": np.empty((nel, 3), dt),
    }
    base = (lay.base_R.astype(dt), lay.base_p.astype(dt), np.zeros((3, N), dt), np.zeros((3, N), dt))
    R, p, Jr, Jw = base
    for i in range(n):
        par = lay.parent[i]
        if par != i - 1:  # a branch: start from the parent's tip frame (the base for −1)
            R, p, Jr, Jw = (
                base
                if par < 0
                else (out["R_tip"][par], out["p_tip"][par], out["Jr_tip"][par], out["Jw_tip"][par])
            )
        # joint frame: R_J = R_par R_rpy, p_J = p_par + R_par o
        off = R @ lay.origin_p[i]
        p = p + off
        Jr = Jr - skew(off) @ Jw
        R = R @ lay.origin_R[i]
        a = lay.alpha_idx[i]
        if a >= 0:
            Jw = Jw.copy()
            Jw[:, a] += R @ lay.axis[i]
            R = R @ rot_axis(lay.axis[i], q[a])
        out["R_link"][i], out["p_link"][i], out["Jr_link"][i], out["Jw_link"][i] = R, p, Jr, Jw
        R = R @ lay.roll_R[i]
        for j in range(k):
            el = i * k + j
            out["RI"][el], out["rI"][el], out["JrI"][el], out["JwI"][el] = R, p, Jr, Jw
            ee = e[el]
            d = R @ np.array([lay.length[el] + ee[0], ee[1], ee[2]])
            Jr = Jr - skew(d) @ Jw + R @ lay.sel[el, 0:3]
            Jw = Jw + R @ left_jacobian(ee[3:]) @ lay.sel[el, 3:6]
            p = p + d
            R = R @ exp_so3(ee[3:])
            out["nodes"][el] = p
        R = R @ lay.roll_R[i].T
        out["R_tip"][i], out["p_tip"][i], out["Jr_tip"][i], out["Jw_tip"][i] = R, p, Jr, Jw
    return _Frames(e=e, **out)


def _tip_frames(lay: _Layout, q: np.ndarray, qd=None):
    """The link and tip frames with their Jacobians at q (q + iε q̇ with ``qd``): the numpy
    :func:`_frames`, or the compiled engine's :class:`reference_models._spatial_numba.Frames`."""
    if lay.compiled is not None:
        return _sn.Frames(lay.compiled, q if qd is None else q + 1j * _EPS * qd, qd)
    return _frames(lay, q if qd is None else q + 1j * _EPS * qd)


@dataclass
class _Bodies:
    """Point masses (m, r, J_v) and rotary inertias (I, R, J_ω) of the discretised arm."""

    m: np.ndarray  # (Pm,)
    r: np.ndarray  # (Pm, 3)
    Jv: np.ndarray  # (Pm, 3, N)
    I: np.ndarray  # (Pr, 3, 3) in W
    Jw: np.ndarray  # (Pr, 3, N)


def _bodies(lay: _Layout, q: np.ndarray) -> _Bodies:
    fr = _frames(lay, q)
    nel, ng = lay.m_g.shape
    N = lay.n_dof
    RI = fr.RI[:, None]  # (Nel, 1, 3, 3)
    s = lay.s0 + np.einsum("egij,ej->egi", lay.S, fr.e)  # (Nel, ng, 3)
    psi = np.einsum("egij,ej->egi", lay.P, fr.e)
    x = np.einsum("eij,egj->egi", fr.RI, s)  # R_I s
    r = fr.rI[:, None] + x
    sel = lay.sel[:, None]  # (Nel, 1, 6, N)
    Jv = fr.JrI[:, None] - skew(x) @ fr.JwI[:, None] + RI @ lay.S @ sel
    Jw = fr.JwI[:, None] + RI @ left_jacobian(psi) @ lay.P @ sel
    Rs = RI @ exp_so3(psi)
    Ig = (Rs * lay.I_g[:, :, None, :]) @ np.swapaxes(Rs, -1, -2)
    # hubs (at the root point, rigid with R_link) and payloads (centre p_tip + R_tip c)
    hub_I = fr.R_link @ lay.hub_J @ np.swapaxes(fr.R_link, -1, -2)
    c = np.einsum("nij,nj->ni", fr.R_tip, lay.pay_c)
    pay_r = fr.p_tip + c
    pay_Jv = fr.Jr_tip - skew(c) @ fr.Jw_tip
    pay_I = fr.R_tip @ lay.pay_J @ np.swapaxes(fr.R_tip, -1, -2)
    # rigid links' bodies: centre p_link + R_link c, rigid with R_link
    cb = np.einsum("nij,nj->ni", fr.R_link, lay.rb_c)
    rb_r = fr.p_link + cb
    rb_Jv = fr.Jr_link - skew(cb) @ fr.Jw_link
    rb_I = fr.R_link @ lay.rb_J @ np.swapaxes(fr.R_link, -1, -2)
    return _Bodies(
        m=np.concatenate([lay.m_g.ravel(), lay.hub_m, lay.pay_m, lay.rb_m]),
        r=np.concatenate([r.reshape(-1, 3), fr.p_link, pay_r, rb_r]),
        Jv=np.concatenate([Jv.reshape(-1, 3, N), fr.Jr_link, pay_Jv, rb_Jv]),
        I=np.concatenate([Ig.reshape(-1, 3, 3), hub_I, pay_I, rb_I]),
        Jw=np.concatenate([Jw.reshape(-1, 3, N), fr.Jw_link, fr.Jw_tip, fr.Jw_link]),
    )


# ----------------------------------------------------------------------------------------------
# Inertia, velocity terms, gravity
# ----------------------------------------------------------------------------------------------


def _mass(b: _Bodies) -> np.ndarray:
    N = b.Jv.shape[-1]
    Jv = (b.Jv.real * np.sqrt(b.m)[:, None, None]).reshape(-1, N)
    Jw = b.Jw.real
    IJ = (b.I.real @ Jw).reshape(-1, N)
    M = Jv.T @ Jv + Jw.reshape(-1, N).T @ IJ
    return 0.5 * (M + M.T)


def _assemble(lay: _Layout, q: np.ndarray, qd: np.ndarray):
    """M(q) and f = Q_g − h(q, q̇): one complex evaluation of the bodies at q + iε q̇ gives the
    Jacobians (real part) and J̇q̇ (imaginary part of J q̇, divided by ε). With the compiled
    engine, the same quantities by composite inertias (:mod:`reference_models._spatial_numba`)."""
    if lay.compiled is not None:
        M, f = np.empty((lay.n_dof, lay.n_dof)), np.empty(lay.n_dof)
        _sn.assemble(lay.compiled[0], q, qd, lay.compiled[1], M, f)
        return M, f
    b = _bodies(lay, q + 1j * _EPS * qd)
    M = _mass(b)
    vel = b.Jv @ qd
    om = b.Jw @ qd
    av = vel.imag / _EPS  # J̇_v q̇
    aw = om.imag / _EPS  # J̇_ω q̇
    w = om.real
    I = b.I.real
    Iw = np.einsum("pij,pj->pi", I, w)
    N = lay.n_dof
    force = b.m[:, None] * (lay.gravity - av)  # gravity minus the velocity-term inertia forces
    moment = np.einsum("pij,pj->pi", I, aw) + np.cross(w, Iw)
    f = b.Jv.real.transpose(2, 0, 1).reshape(N, -1) @ force.ravel()
    f -= b.Jw.real.transpose(2, 0, 1).reshape(N, -1) @ moment.ravel()
    return M, f


def _cut_table(lay: _Layout):
    """Cuts (link i: the roots of its k elements, then its tip; (n(k + 1),)) and the bodies of
    :func:`_bodies` (then one more column per link: a load at its tip frame) outboard of each:
    a bool table (n(k + 1), bodies + n). On its own link a body is outboard of the local cuts
    below its local reach: Gauss points of element e beyond the roots of elements ≤ e; a hub
    beyond none (it is on the inboard side of its link's root cut); a payload (and a load at
    the tip frame) beyond every cut of its link up to and including the link's tip; a rigid
    link's body beyond its link's root cut only. Every body of a link in the subtree of link i
    is outboard of every cut of link i."""
    n, k = lay.n_links, lay.k
    nel, ng = lay.m_g.shape
    per = k + 1
    el = np.arange(nel)
    link = np.concatenate([np.repeat(el // k, ng), np.arange(n), np.arange(n), np.arange(n), np.arange(n)])
    reach = np.concatenate(
        [np.repeat(el % k + 1, ng), np.zeros(n, int), np.full(n, per), np.ones(n, int), np.full(n, per)]
    )
    cut_link = np.repeat(np.arange(n), per)
    cut_slot = np.tile(np.arange(per), n)
    own = (link[None, :] == cut_link[:, None]) & (cut_slot[:, None] < reach[None, :])
    return own | lay.outboard[cut_link][:, link]


def _cut_loads(lay: _Layout, q, qd, qdd, tip_loads=None, point_loads=()) -> np.ndarray:
    """Loads (n(k + 1), 6) at the cuts: force and moment about the cut point (W components) that
    the inboard part exerts on the outboard part, by Newton–Euler of the outboard bodies:
    F = Σ m (a − g), M = Σ (r − r_c) × m (a − g) + Σ (I ω̇ + ω × I ω), less the external loads
    ``tip_loads`` (n, 6) (world force and moment at each link's tip point, outboard of every cut
    of its link up to and including the tip, like a payload) and ``point_loads`` ((link, point,
    force, moment), …: world components, the moment about the point, at a point fixed in the
    link's tip frame, with a tip load's reach: the closure loads)."""
    if lay.compiled is not None:
        m, r, I, om, acc, dom, rI, p_tip = _sn.body_motion(lay.compiled, q, qd, qdd)
    else:
        b = _bodies(lay, q + 1j * _EPS * qd)
        fr = _frames(lay, q)
        Jv, Jw = b.Jv.real, b.Jw.real
        acc = Jv @ qdd + (b.Jv @ qd).imag / _EPS
        om = Jw @ qd
        dom = Jw @ qdd + (b.Jw @ qd).imag / _EPS
        I = b.I.real
        r = b.r.real
        m, rI, p_tip = b.m, fr.rI, fr.p_tip
    force = m[:, None] * (acc - lay.gravity)
    spin = np.einsum("pij,pj->pi", I, dom) + np.cross(om, np.einsum("pij,pj->pi", I, om))
    n, k = lay.n_links, lay.k
    points = np.concatenate([np.concatenate([rI[i * k : (i + 1) * k], p_tip[i : i + 1]]) for i in range(n)])
    table = _cut_table(lay)
    nb = m.size
    out = np.zeros((points.shape[0], 6))
    outboard = table[:, :nb].astype(float)
    out[:, :3] = outboard @ force
    arms = np.cross(r[None] - points[:, None], force[None])  # (cuts, bodies, 3)
    out[:, 3:] = np.einsum("cb,cbi->ci", outboard, arms) + outboard @ spin
    loads = [] if tip_loads is None else [(i, p_tip[i], tip_loads[i, :3], tip_loads[i, 3:]) for i in range(n)]
    loads += list(point_loads)
    for i, at, F, M in loads:
        on = table[:, nb + i]
        out[on, :3] -= F
        out[on, 3:] -= np.cross(at - points[on], F) + M
    return out


def cut_loads(case, elements_per_link, q, qd, t=0.0, strain="linear") -> np.ndarray:
    """Cut loads (n(k + 1), 6) at the state (q, q̇) and time t (right limits of the drives), per
    link the roots of its k elements and its tip, base link first: force (N) and moment about
    the cut point (N·m), W components, that the inboard part exerts on the outboard part; from
    the forward dynamics' q̈ by Newton–Euler of the outboard bodies. The hub of a link is on
    the inboard side of its root cut, its payload on the outboard side of its tip cut."""
    lay = _layout(case, elements_per_link, strain)
    require_open_loop(case, "the spatial global solver")
    q, qd = _as_state(lay, q, "q"), _as_state(lay, qd, "qd")
    if lay.closures:  # the closures held at acceleration level; their loads act as tip loads
        qdd, _, lam = _forward_constrained(case, lay, q, qd, float(t), False)
        points = _closure_loads(lay, q, lam)[1]
        return _cut_loads(lay, q, qd, qdd, _tip_loads(case, lay, _frames(lay, q), float(t), False), points)
    qdd = _forward(case, lay, q, qd, float(t), False)[0]
    return _cut_loads(lay, q, qd, qdd, _tip_loads(case, lay, _frames(lay, q), float(t), False))


def _kinetic(lay: _Layout, q, qd) -> float:
    b = _bodies(lay, q)
    v = b.Jv @ qd
    w = b.Jw @ qd
    return float(0.5 * np.sum(b.m * np.sum(v * v, -1)) + 0.5 * np.einsum("pi,pij,pj->", w, b.I, w))


def _potential(lay: _Layout, q) -> float:
    b = _bodies(lay, q)
    return -float(np.sum(b.m * (b.r @ lay.gravity)))


# ----------------------------------------------------------------------------------------------
# Elastic and damping forces
# ----------------------------------------------------------------------------------------------


def _element_e(lay, x):
    return np.einsum("esn,n->es", lay.sel, x)


def _scatter(lay: _Layout, el: int, fe, Ke, f, K) -> None:
    """f += Sᵀ fe and K += Sᵀ Ke S for element el's selection S (its coordinates' slots)."""
    idx = lay.e_idx[el]
    have = idx >= 0
    at = idx[have]
    f[at] += fe[have]
    K[np.ix_(at, at)] += Ke[np.ix_(have, have)]


def _strain_compiled(lay: _Layout, q, qd, damping: bool):
    """The second-order strain by the compiled engine: (U, f_int, K_T), or (f_d, D_t) with
    ``damping``."""
    N = lay.n_dof
    f, K = np.empty(N), np.empty((N, N))
    U = _sn.strain_forces(lay.compiled[0], q, qd, f, K, damping)
    return (f, K) if damping else (float(U), f, K)


def _elastic(lay: _Layout, q):
    """Strain energy U, internal force f_int (N,) and tangent K_T (N, N)."""
    if not lay.second.any():
        f = lay.K @ q
        return 0.5 * float(q @ f), f, lay.K
    if lay.compiled is not None:
        return _strain_compiled(lay, q, np.zeros(lay.n_dof), False)
    e = _element_e(lay, q)
    U, f, KT = 0.0, np.zeros(lay.n_dof), np.zeros((lay.n_dof, lay.n_dof))
    for el in range(e.shape[0]):
        Kb = lay.K_el[el].copy()
        Kb[0, 0] = 0.0  # the axial part comes from ε below
        fe = Kb @ e[el]
        Ue = 0.5 * e[el] @ fe
        Ke = Kb
        if lay.EA[el] is not None:
            eps, g, H = strain_terms(lay.length[el], lay.EA[el], e[el], lay.second[el])
            c = lay.EA[el] * lay.length[el]
            Ue += 0.5 * c * eps * eps
            fe = fe + c * eps * g
            Ke = Ke + c * (np.outer(g, g) + eps * H)
        U += Ue
        _scatter(lay, el, fe, Ke, f, KT)
    return float(U), f, KT


def _damping(lay: _Layout, q, qd):
    """Damping force f_d (N,) and its rate tangent D_t (N, N): R = ½μ[EA l ε̇² + ėᵀK_b ė]."""
    if not lay.second.any():
        return lay.D @ qd, lay.D
    if lay.compiled is not None:
        return _strain_compiled(lay, q, qd, True)
    e, ed = _element_e(lay, q), _element_e(lay, qd)
    f, Dt = np.zeros(lay.n_dof), np.zeros((lay.n_dof, lay.n_dof))
    for el in range(e.shape[0]):
        Kb = lay.K_el[el].copy()
        Kb[0, 0] = 0.0
        fe = Kb @ ed[el]
        De = Kb
        if lay.EA[el] is not None:
            _, g, _ = strain_terms(lay.length[el], lay.EA[el], e[el], lay.second[el])
            c = lay.EA[el] * lay.length[el]
            fe = fe + c * (g @ ed[el]) * g
            De = De + c * np.outer(g, g)
        _scatter(lay, el, lay.mu[el] * fe, lay.mu[el] * De, f, Dt)
    return f, Dt


# ----------------------------------------------------------------------------------------------
# Drives and forward dynamics
# ----------------------------------------------------------------------------------------------


def _torques(case, lay: _Layout, t, left) -> np.ndarray:
    Q = np.zeros(lay.n_dof)
    for j, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and not d.closed_loop:
            Q[lay.alpha_idx[lay.joints[j]]] = d.torque(t, left)
    return Q


def _tip_loads(case, lay: _Layout, fr: _Frames, t, left) -> np.ndarray:
    """The external loads of the case's scenario at t, per link tip (n, 6): force and moment
    (about the tip point), world components; a follower load's tip-frame components turned by
    the deformed tip frame R_tip."""
    out = np.zeros((lay.n_links, 6))
    for ld in getattr(case.scenario, "loads", ()):
        i = ld.link_index(lay.n_links)
        F, M = ld.value(t, left)
        if ld.follower:
            F, M = fr.R_tip[i] @ F, fr.R_tip[i] @ M
        out[i, :3] += F
        out[i, 3:] += M
    return out


def _load_forces(case, lay: _Layout, q, t, left) -> np.ndarray:
    """Generalized forces (N,) of the external loads from their virtual work
    δW = Σ (Fᵀ δr_tip + Mᵀ δθ_tip): Q = Σ J_r,tipᵀ F + J_ω,tipᵀ M (the tip point's and tip
    frame's velocity Jacobians of :func:`_frames`), at the configuration q."""
    if not getattr(case.scenario, "loads", ()):
        return np.zeros(lay.n_dof)
    fr = _tip_frames(lay, q)
    L = _tip_loads(case, lay, fr, t, left)
    return np.einsum("nim,ni->m", fr.Jr_tip, L[:, :3]) + np.einsum("nim,ni->m", fr.Jw_tip, L[:, 3:])


def _prescribed(case, t, left) -> np.ndarray:
    rows = [d.motion(t, left) for d in case.scenario.drives if d.kind == "motion"]
    return np.array(rows, float).reshape(-1, 3)


def _initial_state(case, lay: _Layout):
    q, qd = np.zeros(lay.n_dof), np.zeros(lay.n_dof)
    for j, d in enumerate(case.scenario.drives):
        a = lay.alpha_idx[lay.joints[j]]
        q[a], qd[a] = d.initial_angle, d.initial_rate
    return q, qd


def _forward(case, lay, q, qd, t, left, tau_closed=None, lam=None):
    """q̈ of M q̈ = Q − h − f_int − f_d with the motion joints prescribed; their torques.
    ``tau_closed`` (n_joints,): the torques of the closed-loop joints (as recorded). With
    closures, ``lam`` (m,) the multipliers as recorded (their force Jᵀλ is added), or None:
    the closures held at acceleration level, J q̈ + J̇q̇ = 0 (see :func:`_forward_constrained`)."""
    if lay.closures and lam is None:
        return _forward_constrained(case, lay, q, qd, t, left)[:2]
    P, F = lay.presc, lay.free
    pres = _prescribed(case, t, left)
    M, f = _assemble(lay, q, qd)
    rhs = f + _torques(case, lay, t, left) - _elastic(lay, q)[1] - _damping(lay, q, qd)[0]
    rhs += _load_forces(case, lay, q, t, left)
    if tau_closed is not None:
        for j, d in enumerate(case.scenario.drives):
            if d.closed_loop:
                rhs[lay.alpha_idx[lay.joints[j]]] += tau_closed[j]
    if lay.closures:
        rhs += _constraints(lay, q)[1].T @ lam
    qdd = np.zeros(lay.n_dof)
    qdd[P] = pres[:, 2]
    qdd[F] = np.linalg.solve(M[np.ix_(F, F)], rhs[F] - M[np.ix_(F, P)] @ qdd[P])
    return qdd, M[P] @ qdd - rhs[P]


def _forward_constrained(case, lay, q, qd, t, left):
    """The forward dynamics of a closed mechanism: M q̈ − Jᵀλ = Q − h − f_int − f_d with the
    closures at acceleration level, J q̈ = −J̇q̇, the motion joints prescribed. Returns (q̈, the
    motion joints' torques, λ)."""
    P, F = lay.presc, lay.free
    pres = _prescribed(case, t, left)
    M, f = _assemble(lay, q, qd)
    rhs = f + _torques(case, lay, t, left) - _elastic(lay, q)[1] - _damping(lay, q, qd)[0]
    rhs += _load_forces(case, lay, q, t, left)
    _, J, Jdqd = _constraints(lay, q, qd)
    x = np.zeros(lay.n_dof)
    x[P] = pres[:, 2]
    qdd, lam = _solve(M, rhs, x, P, F, (J, -Jdqd - J[:, P] @ x[P]))
    return qdd, M[P] @ qdd - rhs[P] - (J.T @ lam)[P], lam


def _joint_torques(case, lay, t, left, tau_p, tau_c=None) -> np.ndarray:
    """Per unlocked joint: open-loop torques, the motion joints' ``tau_p``, the closed-loop
    joints' ``tau_c`` (the laws' torques)."""
    tau = np.zeros(lay.joints.size)
    for j, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and not d.closed_loop:
            tau[j] = d.torque(t, left)
    tau[lay.motion] = tau_p
    if tau_c is not None:
        for j, d in enumerate(case.scenario.drives):
            if d.closed_loop:
                tau[j] = tau_c[j]
    return tau


# ----------------------------------------------------------------------------------------------
# Closed loops: constraint equations g(q) = 0, their Jacobian, the closure loads
# ----------------------------------------------------------------------------------------------

_CLOSURE_EQUATIONS = {"spherical": 3, "revolute": 5, "weld": 6}


@dataclass
class _Closure:
    """One closure, its constants fixed at the initial state: the attachment points in the tip
    frames of ``a`` (``link``) and ``b`` (``to``, −1: ground, its point in world components);
    revolute: the axis in a's tip frame and two unit vectors fixed in b's frame perpendicular
    to it at the initial state (and the axis's image there, for the angle gap); weld: the
    initial relative rotation C0 = R_aᵀ R_b."""

    name: str
    kind: str
    a: int
    b: int
    pa: np.ndarray
    pb: np.ndarray
    axis: np.ndarray
    axis_b: np.ndarray
    u: np.ndarray  # (2, 3)
    C0: np.ndarray
    n_eq: int


def _closure_data(case, lay: _Layout) -> tuple:
    """The closures of the case's model with their constants at the initial state (the drives'
    initial angles, motion drives at t = 0, elastic coordinates zero)."""
    model = case.model
    names = list(model.link_names)
    q0, _ = _initial_state(case, lay)
    q0[lay.presc] = _prescribed(case, 0.0, False)[:, 0]
    fr = _frames(lay, q0)
    size = model.size  # the unit of the closures' position tolerance
    out = []
    for c, cl in enumerate(model.closures):
        a = names.index(cl.link)
        b = -1 if cl.to == "ground" else names.index(cl.to)
        Ra, Rb = fr.R_tip[a], (fr.R_tip[b] if b >= 0 else np.eye(3))
        ob = fr.p_tip[b] if b >= 0 else np.zeros(3)
        pa = np.array(cl.point, float)
        xa = fr.p_tip[a] + Ra @ pa
        if cl.to_point is None:
            pb = Rb.T @ (xa - ob)
        else:
            pb = np.array(cl.to_point, float)
            gap = float(np.linalg.norm(ob + Rb @ pb - xa))
            if gap > 1e-9 * size:
                raise InputError(
                    f"model.closures[{c}].to_point",
                    tuple(cl.to_point),
                    f"closure {model.closure_names[c]!r} is open at the initial state by {gap:.3g} m "
                    f"(more than 1e-9 of the mechanism's size {size:.3g} m)",
                )
        axis = np.array(getattr(cl, "axis", (0.0, 0.0, 1.0)), float)
        axis = axis / np.linalg.norm(axis)
        na = Ra @ axis
        # two unit vectors perpendicular to the axis at the initial state, fixed in b's frame
        trial = np.eye(3)[int(np.argmin(np.abs(na)))]
        u1 = np.cross(na, trial)
        u1 /= np.linalg.norm(u1)
        u2 = np.cross(na, u1)
        out.append(
            _Closure(
                name=model.closure_names[c],
                kind=cl.kind,
                a=a,
                b=b,
                pa=pa,
                pb=pb,
                axis=axis,
                axis_b=Rb.T @ na,
                u=np.array([Rb.T @ u1, Rb.T @ u2]),
                C0=Ra.T @ Rb,
                n_eq=_CLOSURE_EQUATIONS[cl.kind],
            )
        )
    return tuple(out)


def _closure_terms(lay: _Layout, fr):
    """Per closure at the frames ``fr`` (any dtype): g (n_eq,) and the maps G_a, G_b (n_eq, 6)
    of the twists (v, ω) of the two attachment points onto ġ, with the points' Jacobians
    (3, N) (v = J_r q̇, ω = J_ω q̇; zero for ground) and the points (world):
    position  g = x_a − x_b                        (ġ = v_a − v_b);
    revolute  g_j = n_a · u_j,b, j = 1, 2          (ġ_j = (n_a × u_j)·(ω_a − ω_b));
    weld      g = ½ Σ_i A_i × B_i, A = R_a C0, B = R_b (ġ = C_a ω_a + C_b ω_b,
              C_a = ½ Σ [B_i]×[A_i]×, C_b = −½ Σ [A_i]×[B_i]×).
    The generalized force of the multipliers λ is Jᵀλ, J = G_a [J_ra; J_ωa] + G_b [J_rb; J_ωb];
    G_aᵀλ is the load (force, moment about x_a) that b exerts on a."""
    out = []
    N = lay.n_dof
    for cl in lay.closures:
        Ra = fr.R_tip[cl.a]
        ca = Ra @ cl.pa
        xa = fr.p_tip[cl.a] + ca
        Jra = fr.Jr_tip[cl.a] - skew(ca) @ fr.Jw_tip[cl.a]
        Jwa = fr.Jw_tip[cl.a]
        if cl.b >= 0:
            Rb = fr.R_tip[cl.b]
            cb = Rb @ cl.pb
            xb = fr.p_tip[cl.b] + cb
            Jrb = fr.Jr_tip[cl.b] - skew(cb) @ fr.Jw_tip[cl.b]
            Jwb = fr.Jw_tip[cl.b]
        else:
            Rb = np.eye(3)
            xb = cl.pb.astype(xa.dtype)
            Jrb = Jwb = np.zeros((3, N), xa.dtype)
        g = [xa - xb]
        Ga = [np.hstack([np.eye(3), np.zeros((3, 3))])]
        Gb = [np.hstack([-np.eye(3), np.zeros((3, 3))])]
        if cl.kind == "revolute":
            na = Ra @ cl.axis
            ub = cl.u @ Rb.T  # (2, 3) world
            g.append(ub @ na)
            m = np.cross(na, ub)
            Ga.append(np.hstack([np.zeros((2, 3)), m]))
            Gb.append(np.hstack([np.zeros((2, 3)), -m]))
        elif cl.kind == "weld":
            A, B = Ra @ cl.C0, Rb
            g.append(0.5 * sum(np.cross(A[:, i], B[:, i]) for i in range(3)))
            Ca = 0.5 * sum(skew(B[:, i]) @ skew(A[:, i]) for i in range(3))
            Cb = -0.5 * sum(skew(A[:, i]) @ skew(B[:, i]) for i in range(3))
            Ga.append(np.hstack([np.zeros((3, 3)), Ca]))
            Gb.append(np.hstack([np.zeros((3, 3)), Cb]))
        g, Ga, Gb = np.concatenate(g), np.vstack(Ga), np.vstack(Gb)
        J = Ga[:, :3] @ Jra + Ga[:, 3:] @ Jwa + Gb[:, :3] @ Jrb + Gb[:, 3:] @ Jwb
        out.append((g, J, Ga, Gb, xa, xb))
    return out


def _constraints(lay: _Layout, q, qd=None):
    """g(q) (m,), J = ∂g/∂q (m, N) and, with q̇, J̇q̇ (m,) (complex step along q̇)."""
    if qd is None:
        terms = _closure_terms(lay, _tip_frames(lay, q))
        return np.concatenate([t[0] for t in terms]), np.vstack([t[1] for t in terms]), None
    terms = _closure_terms(lay, _tip_frames(lay, q, qd))
    J = np.vstack([t[1] for t in terms])
    return np.concatenate([t[0].real for t in terms]), J.real, (J @ qd).imag / _EPS


def _closure_loads(lay: _Layout, q, lam):
    """(n_closures, 6): force and moment (about the closure point) that ``to`` exerts on
    ``link``, world components; and the point loads of :func:`_cut_loads` (both sides)."""
    out = np.zeros((len(lay.closures), 6))
    points = []
    i0 = 0
    for c, (cl, (_, _, Ga, Gb, xa, xb)) in enumerate(zip(lay.closures, _closure_terms(lay, _frames(lay, q)))):
        lc = lam[i0 : i0 + cl.n_eq]
        i0 += cl.n_eq
        la, lb = Ga.T @ lc, Gb.T @ lc
        out[c] = la
        points.append((cl.a, xa, la[:3], la[3:]))
        if cl.b >= 0:
            points.append((cl.b, xb, lb[:3], lb[3:]))
    return out, points


def _closure_gaps(lay: _Layout, q):
    """(position gap |x_a − x_b| (m), angle gap (rad)) per closure: revolute the angle between
    the axis in ``link`` and its initial image in ``to``, weld the relative rotation's angle
    from its initial value, spherical 0."""
    fr = _frames(lay, q)
    pos, ang = np.zeros(len(lay.closures)), np.zeros(len(lay.closures))
    for c, (cl, (_, _, _, _, xa, xb)) in enumerate(zip(lay.closures, _closure_terms(lay, fr))):
        pos[c] = np.linalg.norm(xa - xb)
        Ra = fr.R_tip[cl.a]
        Rb = fr.R_tip[cl.b] if cl.b >= 0 else np.eye(3)
        if cl.kind == "revolute":
            na, nb = Ra @ cl.axis, Rb @ cl.axis_b
            ang[c] = math.atan2(float(np.linalg.norm(np.cross(na, nb))), float(na @ nb))
        elif cl.kind == "weld":
            ang[c] = float(np.linalg.norm(log_so3((Ra @ cl.C0).T @ Rb)))
    return pos, ang


def _solve(A, rhs, x, P, F, con=None):
    """x with its free part from A x = rhs (the prescribed part x[P] given); with the closures
    ``con`` = (J, b): A x − Jᵀλ = rhs and J_F x_F = b together (LU). Returns (x, λ)."""
    new = x.copy()
    r = rhs[F] - A[np.ix_(F, P)] @ x[P]
    if con is None:
        new[F] = np.linalg.solve(A[np.ix_(F, F)], r)
        return new, np.zeros(0)
    J, b = con
    JF = J[:, F]
    m, nf = JF.shape[0], F.size
    K = np.zeros((nf + m, nf + m))
    K[:nf, :nf] = A[np.ix_(F, F)]
    K[:nf, nf:] = -JF.T
    K[nf:, :nf] = JF
    sol = np.linalg.solve(K, np.concatenate([r, b]))
    new[F] = sol[:nf]
    return new, sol[nf:]


# ----------------------------------------------------------------------------------------------
# Public functions of a state
# ----------------------------------------------------------------------------------------------


def _as_state(lay: _Layout, x, field: str) -> np.ndarray:
    arr = np.asarray(x, float)
    if arr.shape != (lay.n_dof,):
        raise InputError(field, f"shape {arr.shape}", f"must have shape ({lay.n_dof},)")
    if not np.all(np.isfinite(arr)):
        raise InputError(field, "non-finite entries", "must be finite")
    return arr


def coordinate_names(case, elements_per_link) -> list[str]:
    """Names of the minimal coordinates in the order of q: per link i ``alpha_i`` (unlocked
    joints), then per element j ``u_i_j`` (extensible links), ``v_i_j``, ``w_i_j``,
    ``phix_i_j``, ``phiy_i_j``, ``phiz_i_j`` (1-based)."""
    return list(_layout(case, elements_per_link).names)


def mass_matrix(case, elements_per_link, q) -> np.ndarray:
    """M(q) (N, N) = Σ m J_vᵀJ_v + Σ J_ωᵀ I J_ω over the Gauss points, hubs and payloads."""
    lay = _layout(case, elements_per_link)
    return _mass(_bodies(lay, _as_state(lay, q, "q")))


def generalized_forces(case, elements_per_link, q, qd) -> np.ndarray:
    """Q_g − h(q, q̇) (N,): gravity minus the velocity terms (no joint torques, no elastic or
    damping forces)."""
    lay = _layout(case, elements_per_link)
    return _assemble(lay, _as_state(lay, q, "q"), _as_state(lay, qd, "qd"))[1]


def load_forces(case, elements_per_link, q, t=0.0, left=False) -> np.ndarray:
    """Generalized forces (N,) of the scenario's external loads (``SpatialScenario.loads``) at
    the configuration q and time t (``left``: left limits of their laws): Σ J_r,tipᵀ F +
    J_ω,tipᵀ M from their virtual work."""
    lay = _layout(case, elements_per_link)
    return _load_forces(case, lay, _as_state(lay, q, "q"), float(t), bool(left))


def elastic_forces(case, elements_per_link, q, strain="linear"):
    """(U, f_int, K_T): strain energy (J), its gradient (N,) and Hessian (N, N)."""
    lay = _layout(case, elements_per_link, strain)
    U, f, KT = _elastic(lay, _as_state(lay, q, "q"))
    return U, f.copy(), KT.copy()


def damping_forces(case, elements_per_link, q, qd, strain="linear"):
    """(f_d, D_t): the Kelvin–Voigt force (N,) and its rate tangent (N, N)."""
    lay = _layout(case, elements_per_link, strain)
    f, Dt = _damping(lay, _as_state(lay, q, "q"), _as_state(lay, qd, "qd"))
    return f.copy(), Dt.copy()


def accelerations(case, elements_per_link, q, qd, t=0.0, strain="linear") -> np.ndarray:
    """Forward dynamics q̈ (N,) at the state (q, q̇) and time t (right limits of the drives);
    motion-driven joints take α̈ from their law (their entries of q, q̇ are used as given)."""
    lay = _layout(case, elements_per_link, strain)
    require_open_loop(case, "the spatial global solver")
    q, qd = _as_state(lay, q, "q"), _as_state(lay, qd, "qd")
    return _forward(case, lay, q, qd, float(t), False)[0]


def energy(case, elements_per_link, q, qd, strain="linear") -> dict:
    """``kinetic`` ½q̇ᵀMq̇, ``elastic`` Σ U and ``gravity`` −Σ m gᵀr (J)."""
    lay = _layout(case, elements_per_link, strain)
    q, qd = _as_state(lay, q, "q"), _as_state(lay, qd, "qd")
    return _energy(lay, q, qd)


def _energy(lay, q, qd) -> dict:
    if lay.compiled is not None:
        kinetic, gravity = _sn.kinetic_potential(lay.compiled, q, qd)
        return {"kinetic": kinetic, "elastic": _elastic(lay, q)[0], "gravity": gravity}
    return {"kinetic": _kinetic(lay, q, qd), "elastic": _elastic(lay, q)[0], "gravity": _potential(lay, q)}


def kinematics(case, elements_per_link, q) -> dict:
    """Frames at q: ``root`` (n, 3) and ``tip`` (n, 3) positions, ``root_rotation`` R_link and
    ``tip_rotation`` R_tip (n, 3, 3), ``nodes`` (n, k, 3) the outboard element nodes,
    ``tip_deflection`` (n, 2) and ``twist`` (n,)."""
    lay = _layout(case, elements_per_link)
    return _link_frames(lay, _as_state(lay, q, "q"))


def link_shapes(case, elements_per_link, q, p: int) -> np.ndarray:
    """Link shapes (nt, n, p, 3) m at the coordinates q (nt, n_dof): p points per link from root
    to tip at equal reference arc lengths, r(x) = r_I + R_I (s0(ξ) + S(ξ) e) in the element
    holding x (this module's frames and shape matrices; :func:`dttmm.shapes.frame_shapes`)."""
    lay = _layout(case, elements_per_link)
    return _link_shapes(case, lay, np.atleast_2d(np.asarray(q, float)), check_shape_points(p))


def _link_shapes(case, lay, q, p: int) -> np.ndarray:
    nt, nel = q.shape[0], lay.n_links * lay.k
    RI, rI, e = np.zeros((nt, nel, 3, 3)), np.zeros((nt, nel, 3)), np.zeros((nt, nel, 6))
    for j in range(nt):
        fr = _tip_frames(lay, q[j])
        RI[j], rI[j], e[j] = fr.RI, fr.rI, fr.e
    lengths = [lk.beam.length for lk in case.model.links]
    tables = lambda i, xi: shape_matrices(lay.length[i * lay.k], xi)[:2]
    return frame_shapes(RI, rI, e, lengths, lay.k, p, tables)


def _link_frames(lay, q) -> dict:
    fr = _tip_frames(lay, q)
    d = fr.p_tip - fr.p_link
    defl = np.einsum("nij,ni->nj", fr.R_link, d)[:, 1:]
    rel = np.swapaxes(fr.R_link, -1, -2) @ fr.R_tip
    return {
        "root": fr.p_link,
        "tip": fr.p_tip,
        "root_rotation": fr.R_link,
        "tip_rotation": fr.R_tip,
        "nodes": fr.nodes.reshape(lay.n_links, lay.k, 3),
        "tip_deflection": defl,
        "twist": log_so3(rel)[:, 0],
    }
