"""Linearisation and natural modes of a spatial arm (docs/modes.md, "Spatial arms").

The same construction as the planar :mod:`dttmm.linear`, on the spatial kernel's forward
dynamics (``kernel.core.accelerations``, the sweep that :func:`dttmm.spatial.simulate`
integrates):

* M: q̈ is affine in applied generalized forces Q, so unit forces on the free coordinates,
  differenced against Q = 0, give M⁻¹ column by column, exactly (to round-off);
* K = −M ∂q̈/∂q and D = −M ∂q̈/∂q̇ by the planar 8th-order central stencil, step 2·10⁻⁴ times
  the coordinate's scale (1 for the angles α, φx, φy, φz; the element length for u, v, w);
* B = M ∂q̈/∂τ, a unit torque on each torque-driven joint.

Free coordinates: the kernel's q (docs/spatial.md §3: α of every unlocked joint, then per
element (u, v, w, φx, φy, φz), without u for an inextensible link) without the angles of
motion-driven joints, which stay on their law (held); locked joints have no coordinate.

``state="equilibrium"`` linearises about the static equilibrium of the arm under its gravity
and external loads (:func:`dttmm.spatial.statics`) with every unlocked joint at its initial
angle (a motion-driven joint at its law's angle at t), and the torque-driven joints loaded
with the torques that hold it there (the torques of the same arm with every joint held, so
q̈ = 0 at the point).
"""

from __future__ import annotations

import numpy as np

from .. import plumbing
from ..errors import InputError
from ..modal import (
    MAX_FREE,
    STEP,
    Linearization,
    Modes,
    check_n,
    derivative,
    modes_of,
    state_pair,
)
from .build import STRAINS, build_model, make_work
from .model import require_open_chain
from .rotation import log_so3
from .solver import _drive_values, _kernel, _motion_flags, as_spatial_case, initial_state

__all__ = ["coordinate_names", "equilibrium", "frequencies", "linearize", "modes"]

_COMPS = ("u", "v", "w", "phix", "phiy", "phiz")


def coordinate_names(case, md) -> list[str]:
    """Names of the kernel's coordinates, in the order of q."""
    names = [""] * md.ndof
    joint = {int(i): j for j, i in enumerate(case.model.unlocked)}
    for i in range(md.n):
        if md.ia[i] >= 0:
            names[md.ia[i]] = f"joint {joint[i] + 1} angle"
        comps = () if md.rigid[i] else _COMPS if md.ext[i] else _COMPS[1:]  # rigid: no coordinates
        for j in range(md.k[i]):
            r = md.ie[md.el0[i] + j]
            for c, name in enumerate(comps):
                names[r + c] = f"link {i + 1}, element {j + 1}, {name}"
    return names


def _scales(md) -> np.ndarray:
    """Difference-step scale of each coordinate: 1 for angles, the element length for u, v, w."""
    s = np.ones(md.ndof)
    for i in range(md.n):
        nd = 0 if md.rigid[i] else 3 if md.ext[i] else 2  # a rigid link has no coordinates
        for j in range(md.k[i]):
            r = md.ie[md.el0[i] + j]
            s[r : r + nd] = md.l[i]
    return s


class _Arm:
    """The discretised spatial arm and its forward dynamics at fixed drive inputs."""

    def __init__(self, case, k, strain, engine, motion=None):
        _, self.core, _ = _kernel(engine)
        require_open_chain(case.model, "the spatial linearisation")
        flags = _motion_flags(case) if motion is None else motion
        self.md = build_model(case.model, k, strain, flags)
        self.ws = make_work(self.md)
        self.cut = np.zeros((self.md.nel + self.md.n, 6))

    def qdd(self, q, qd, tau, mot, forces=None) -> np.ndarray:
        md = self.md
        out = np.zeros(md.ndof)
        f = np.zeros(md.ndof) if forces is None else forces
        ok = self.core.accelerations(md, self.ws, q, qd, tau, mot, f, out, False, self.cut)
        if not ok:
            raise np.linalg.LinAlgError("the spatial sweep is singular at this state")
        return out


def _angles(case, t) -> np.ndarray:
    """Per unlocked joint: a motion law's angle at t, else the drive's initial angle."""
    a = []
    for d in case.scenario.drives:
        a.append(d.motion(t, False)[0] if d.kind == "motion" else d.initial_angle)
    return np.array(a, float)


def equilibrium(case, elements_per_link: int, t: float = 0.0, *, strain="linear", engine=None):
    """The static equilibrium about which ``state="equilibrium"`` linearises.

    Returns (q (n_dof,), torques (n_joints,)): the coordinates from :func:`dttmm.spatial.statics`
    (joints held at their initial angles, motion joints at their law's angle at t; gravity and
    the scenario's loads at t) and the torque each unlocked joint needs to hold the arm there.
    """
    from .statics import statics

    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    st = statics(case, elements_per_link=k, t=t, strain=strain, angles=_angles(case, t), engine=engine)
    held = np.array([0 if lk.joint.locked else 1 for lk in case.model.links], np.int64)
    arm = _Arm(case, k, strain, engine, motion=held)
    tau, mot = _drive_values(case, arm.md.n, t, False)
    mot[:, :3] = 0.0
    unl = np.asarray(case.model.unlocked, int)
    mot[unl, 0] = st.q[arm.md.ia[unl]]
    arm.qdd(st.q, np.zeros_like(st.q), np.zeros_like(tau), mot)
    return st.q, arm.ws.acc[unl, 1].copy()


def _point(case, md, t, state, mot, k, strain, engine):
    """(q, q̇, torques of the unlocked joints or None) of the linearisation point."""
    unl = np.asarray(case.model.unlocked, int)
    hold = None
    if state is None:
        q, qd = initial_state(case, md)
        qd[:] = 0.0
    elif isinstance(state, str):
        if state != "equilibrium":
            raise InputError("state", state, "must be None, 'equilibrium' or a pair (q, qd)")
        q, hold = equilibrium(case, k, t, strain=strain, engine=engine)
        qd = np.zeros(md.ndof)
    else:
        q, qd = state_pair(state, md.ndof)
    im = unl[md.motion[unl] == 1]
    q[md.ia[im]], qd[md.ia[im]] = mot[im, 0], mot[im, 1]
    return q, qd, hold


def linearize(
    case,
    elements_per_link: int,
    t: float = 0.0,
    state=None,
    *,
    strain: str = "linear",
    torque=None,
    step: float = STEP,
    engine: str | None = None,
) -> Linearization:
    """Linearise the spatial DT-TMM forward dynamics of ``case`` about a state.

    Parameters
    ----------
    case : dttmm.spatial.SpatialCase or (SpatialManipulator, Scenario)
    elements_per_link : int
    t : float
        Time (s) of the drives' and loads' laws.
    state : None, "equilibrium" or (q, qd)
        None: rest (joints at their initial angles, undeformed links, zero rates);
        "equilibrium": the static equilibrium (:func:`equilibrium`), the torque-driven joints
        holding it; else full (n_dof,) vectors in the kernel's order.
    strain : "linear" or "second-order"
    torque : None or (n_joints,) array
        Nominal torques (N·m) of the torque-driven joints (one per unlocked joint, drive
        order); default: the open-loop laws' values at t (closed-loop joints 0), or the holding
        torques at "equilibrium".
    step : float
        Relative difference step of K and D.
    engine : None, "numba" or "python"

    Returns
    -------
    dttmm.Linearization
        Over the free coordinates; ``torque_joints`` are drive indices (0-based, unlocked
        joints in order).
    """
    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    try:
        t = float(t)
    except (TypeError, ValueError):
        raise InputError("t", t, "must be a time in s") from None
    if not np.isfinite(t):
        raise InputError("t", t, "must be finite")
    if not (isinstance(step, (int, float)) and 0.0 < step < 0.1):
        raise InputError("step", step, "must be a relative difference step in (0, 0.1)")
    arm = _Arm(case, k, strain, engine)
    md = arm.md
    tau, mot = _drive_values(case, md.n, t, False)
    q0, qd0, hold = _point(case, md, t, state, mot, k, strain, engine)
    unl = np.asarray(case.model.unlocked, int)
    tq_links = unl[md.motion[unl] == 0]
    if hold is not None:
        tau[unl] = np.where(md.motion[unl] == 1, 0.0, hold)
    if torque is not None:
        given = np.asarray(torque, float)
        if given.shape != (unl.size,) or not np.all(np.isfinite(given)):
            raise InputError("torque", torque, f"must be {unl.size} finite joint torques (N·m)")
        tau[unl] = np.where(md.motion[unl] == 1, 0.0, given)
    held = md.ia[unl[md.motion[unl] == 1]]
    free = np.flatnonzero(~np.isin(np.arange(md.ndof), held))
    if free.size > MAX_FREE:
        raise InputError(
            "elements_per_link",
            elements_per_link,
            f"gives {free.size} free coordinates (dense limit {MAX_FREE})",
        )

    def acc(q, qd, Q=None, tq=tau):
        return arm.qdd(q, qd, tq, mot, Q)[free]

    a0 = acc(q0, qd0)
    Minv = np.empty((free.size, free.size))
    for c, j in enumerate(free):
        Q = np.zeros(md.ndof)
        Q[j] = 1.0
        Minv[:, c] = acc(q0, qd0, Q) - a0
    M = np.linalg.inv(Minv)
    M = 0.5 * (M + M.T)
    scale = _scales(md)
    Jq = derivative(lambda q: acc(q, qd0), q0, free, scale, step)
    Jv = derivative(lambda qd: acc(q0, qd), qd0, free, scale, step)
    Jt = np.zeros((free.size, tq_links.size))
    for c, i in enumerate(tq_links):
        dt = tau.copy()
        dt[i] += 1.0
        Jt[:, c] = acc(q0, qd0, tq=dt) - a0
    K, D, B = (np.linalg.solve(Minv, J) for J in (-Jq, -Jv, Jt))
    Z = np.zeros((free.size, free.size))
    names = coordinate_names(case, md)
    drive_of = {int(i): j for j, i in enumerate(unl)}
    return Linearization(
        M=M,
        D=D,
        K=K,
        B=B,
        A=np.block([[Z, np.eye(free.size)], [Jq, Jv]]),
        B_ss=np.vstack([np.zeros_like(Jt), Jt]),
        coordinates=tuple(names[j] for j in free),
        free=free,
        torque_joints=tuple(drive_of[int(i)] for i in tq_links),
        q=q0,
        qd=qd0,
        qdd=arm.qdd(q0, qd0, tau, mot),
        t=t,
        elements_per_link=k,
        strain=strain,
    )


def _nodes(arm, case, q) -> list[np.ndarray]:
    """Per link (k + 1, 3): the element nodes' (y, z) offsets from the root in the link frame
    R_link and their sections' twist about the link's x axis (rad)."""
    md, ws = arm.md, arm.ws
    arm.core.kinematics(md, ws, q, np.zeros(md.ndof))
    out = []
    for i in range(md.n):
        el0, k = md.el0[i], md.k[i]
        Rl = ws.Rw[el0] @ md.Q[i].T
        pts = np.vstack([ws.pw[el0 : el0 + k], ws.pT[i + 1]])
        frames = [ws.Rw[el0 + j] @ md.Q[i].T for j in range(k)] + [ws.RT[i + 1]]
        d = (pts - pts[0]) @ Rl[:, 1:]
        tw = [log_so3(Rl.T @ R)[0] for R in frames]
        out.append(np.column_stack([d, tw]))
    return out


def _deflections(arm, case, lin, shapes):
    """Per link (n_modes, k + 1, 2) node deflections (along the link frame's y and z) and
    (n_modes, k + 1) twists per unit modal amplitude (central difference, linear in it)."""
    md = arm.md
    nm = shapes.shape[1]
    defl = [np.empty((nm, md.k[i] + 1, 2)) for i in range(md.n)]
    twist = [np.empty((nm, md.k[i] + 1)) for i in range(md.n)]
    for m in range(nm):
        dq = np.zeros(md.ndof)
        dq[lin.free] = shapes[:, m]
        eps = 1e-7 / max(np.abs(dq).max(), 1e-300)
        plus, minus = _nodes(arm, case, lin.q + eps * dq), _nodes(arm, case, lin.q - eps * dq)
        for i in range(md.n):
            d = (plus[i] - minus[i]) / (2 * eps)
            defl[i][m], twist[i][m] = d[:, :2], d[:, 2]
    return tuple(defl), tuple(twist)


def modes(
    case,
    elements_per_link: int,
    t: float = 0.0,
    state=None,
    n: int | None = None,
    *,
    strain: str = "linear",
    torque=None,
    zero_tol: float = 1e-13,
    engine: str | None = None,
) -> Modes:
    """Natural modes of a spatial arm about a state (motion-driven joints held, torque-driven
    free), as :func:`dttmm.modes`. ``deflections[i]`` is (n_modes, k + 1, 2): the nodes' offsets
    along the link frame's y and z axes; ``twists[i]`` (n_modes, k + 1) their sections' twist."""
    case = as_spatial_case(case)
    check_n(n)
    lin = linearize(case, elements_per_link, t, state, strain=strain, torque=torque, engine=engine)
    s_nodes = tuple(np.linspace(0.0, lk.beam.length, lin.elements_per_link + 1) for lk in case.model.links)
    k = lin.elements_per_link
    return modes_of(
        lin, n, zero_tol, s_nodes, lambda V: _deflections(_Arm(case, k, strain, engine), case, lin, V)
    )


def frequencies(case, elements_per_link: int, n: int | None = None) -> np.ndarray:
    """Lowest ``n`` natural frequencies (Hz) of a spatial arm at rest."""
    return np.asarray(modes(case, elements_per_link, n=n).frequencies, float)
