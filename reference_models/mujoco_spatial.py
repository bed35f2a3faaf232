"""MuJoCo peer for spatial arms: every flexible link a chain of k rigid pieces joined by
three-hinge elastic stations (docs/mujoco.md, "Spatial chain"). The model is built by
``_mujoco_model`` (:func:`build`, :func:`xml`, :func:`layout`, re-exported here), the builder of
the planar chain too; this module is the spatial adapter: input checks, the stepper, the outputs,
the closures' loads and statics.

Lumping rule, link of length L, k segments of length l = L/k (the planar chain's rule in 3-D):

* k elastic stations at x_j = (j − ½) l, j = 1 … k. Each is three hinges through one point:
  bending about the section's z axis (stiffness EIz/l: deflection along y), bending about its y
  axis (EIy/l: deflection along z) and twist about x (GJ/l), in this order at odd stations and
  in the reverse order at even ones; each with a damper of μ times its stiffness (the beam's
  Kelvin–Voigt D = μK). The section axes are the link frame's turned by ``roll`` about x.
  Axial stiffness: rigid (EA is not used; the pieces keep their lengths).
* k + 1 rigid pieces between the stations: [0, l/2] behind the arm joint (the hub body), k − 1
  full pieces [(j − ½) l, (j + ½) l] and the half piece [L − l/2, L] at the tip. Each piece
  carries its share of the beam: mass ρA·len at its centre, the rod inertia ρA·len³/12 about
  the two transverse axes and the section inertia len·Rx(roll) diag(ρJ, ρIy, ρIz) Rx(roll)ᵀ.
  The rigid-body inertia of every link is therefore exact at any k. The hub (mass at the root
  point, full inertia about it, link frame) joins piece 0; the payload (mass at its offset in
  the tip frame, full inertia about its centre) joins piece k.

Each spring stands for the compliance of the segment of length l centred on it (the midpoint
rule for ∫ M/EI ds and ∫ T/GJ ds): a tip force deflects the chain by F L³/(3EI)·(1 − 1/(4k²)),
a tip torque twists it by exactly T L/GJ; the natural frequencies and the dynamics converge at
O(1/k²) (measured, docs/mujoco.md).

Why three hinges, and why the alternating order: a hinge triple is a Cardan chart of the
station's relative rotation; its twist angle differs from the rotation vector's by ½ θz θy
(second order per station, so first order in 1/k summed over a link bent in both planes): with
one order at every station the twist converged at first order (measured); reversing it at every
other station flips the sign of that term and restores second order. A ball joint (the exact
rotation vector) needs three affine-bias actuators for EIy ≠ EIz ≠ GJ, since MuJoCo's ball
stiffness is one scalar; it was measured as accurate as the alternating hinges, and no cheaper
(docs/mujoco.md). The chart is singular only at a 90° bend of one station.

MuJoCo's compiler requires every body inertia to satisfy the triangle inequality; a short piece
of a beam with ρJ > ρIy + ρIz (e.g. the bending rotary inertia neglected) violates it. The
model is therefore compiled with placeholder inertias and the exact mass, centre and principal
inertia (its eigen-decomposition) of every body are written into the compiled model
(``body_mass``, ``body_ipos``, ``body_iquat``, ``body_inertia``; ``mj_setConst`` after). The
dynamics do not need the inequality: the mass matrix stays positive definite.

Joints as in URDF (docs/spatial.md §1): the hub body of link i sits at the parent frame (the
base frame, a fixed body at ``base_xyz``/``base_rpy``, for link 1; else the tip frame of link
i − 1, a point l/2 beyond its last station) moved by ``origin_xyz`` and turned by
``origin_rpy``; an unlocked joint is a hinge about ``axis`` (joint frame) at the body origin, a
locked one welds the body (no joint). Gravity is MuJoCo's ``gravity`` option (the case's
vector).

Trees and closed loops (docs/spatial.md §11 "Peers on trees and loops"): a link's root piece is a
child of its parent link's tip piece (the base body for a link on the base); closures are
equality constraints between sites on the tip pieces (:func:`closure_equalities`: spherical a
``connect``, revolute two ``connect``s on its axis, weld a ``weld``), solref 2 steps and solimp
0.9999; their loads come from ``efc_force`` (:func:`closure_loads`). A chain's MJCF is the text
it was before trees.

Time integration, drives and the fast loop are the planar chain's (:mod:`mujoco_chain`):
``implicitfast`` with a fixed step h (the springs explicit: h < 2/ω_max, ``meta["h_stable"]``),
torque drives as motors with the control τ(t_k + Δt/2) stepped by ``mujoco.rollout``, motion
drives by Newton on the motor torque of each step so that the joint angle at the step end is the
law's. Closed-loop drives are refused (the spatial suite has no closed-loop state yet).

Outputs as :func:`dttmm.spatial.simulate`: joint angles, rates and torques of the unlocked
joints; link roots (the hub bodies' origins) and link frames (their orientation), tips (a site at
the end of the last piece) and tip frames (the last piece's orientation); tip deflections
(components of tip − root along the link frame's y and z axes), twist (x component of
log(R_rootᵀ R_tip)), end effector, energy (MuJoCo's kinetic + gravity + spring energy; gravity
zero at the world origin); with closures ``closure_loads``, ``closure_residual`` and
``closure_angle_residual`` as the DT-TMM's. Cut loads: not computed (None).

MuJoCo is imported by the MuJoCo modules only (this one, mujoco_chain, _mujoco_model).
"""

from __future__ import annotations

import mujoco
import numpy as np

from dttmm import plumbing
from dttmm.drives import require_open_loop
from dttmm.errors import InputError, SimulationError
from dttmm.shapes import shape_points as check_shape_points
from dttmm.spatial import SpatialCase, SpatialManipulator, SpatialResult
from dttmm.spatial.model import require_flexible, require_serial
from dttmm.spatial.rotation import log_so3
from dttmm.spatial.scenario import require_no_loads
from dttmm.spatial.topology import closure_gaps, initial_angles, resolve_closures, rigid_tip_frames

from . import _checks
from ._mujoco_model import (
    INTEGRATORS,
    STATION,
    STATIONS,
    SpatialLayout,
    build,
    closure_equalities,
    eig_mk,
    frequencies,
    layout,
    piece_properties,
    stability_limit,
    xml,
)
from .mujoco_chain import (
    _drive_outputs,
    _kinematics_and_energy,
    _raise_failure,
    _run,
    piece_shapes,
    step_nodes,
)
from .mujoco_chain import _Stepper as _PlanarStepper

__all__ = [
    "INTEGRATORS",
    "STATIONS",
    "SpatialLayout",
    "build",
    "check_case",
    "closure_equalities",
    "closure_loads",
    "layout",
    "natural_frequencies",
    "piece_properties",
    "simulate",
    "stability_limit",
    "statics",
    "xml",
]

METHOD = "mujoco-spatial"
_OPTIONS = {"motion_tol": 1e-12, "motion_max_iter": 10, "station": "hinges"}


def natural_frequencies(link, k: int, n_modes: int = 3) -> dict:
    """The lowest ``n_modes`` natural frequencies (rad/s) of one link clamped at its root (joint
    locked, no gravity, hub and payload included), per family: ``"EIz"`` (bending along the
    section's y axis), ``"EIy"`` (along z) and ``"GJ"`` (torsion). A mode belongs to the family
    whose hinges carry most of its (mass-normalised) shape; at rest the families decouple for a
    straight link whose payload sits on its axis."""
    import dataclasses

    from dttmm.spatial import SpatialJoint

    link = dataclasses.replace(link, joint=SpatialJoint(locked=True))
    manip = SpatialManipulator((link,))
    m, d, lay = build(manip, k)
    w2, V = eig_mk(m, d)
    fam = np.argmax([np.sum(V[lay.flex_qpos[0, :, c]] ** 2, axis=0) for c in range(3)], axis=0)
    out = {}
    for c, (_, _, key) in enumerate(STATION):
        out[key] = frequencies(w2[fam == c])[:n_modes]
    return out


def _vector3(field, value):
    try:
        v = np.array(value, float)
    except (TypeError, ValueError):
        raise InputError(field, value, "must be 3 finite numbers") from None
    if isinstance(value, (str, bool)) or v.shape != (3,) or not np.all(np.isfinite(v)):
        raise InputError(field, value, "must be 3 finite numbers")
    return v


def _frames(m, d, lay):
    """(root (n, 3), R_link (n, 3, 3), tip (n, 3), R_tip (n, 3, 3)) at the kinematics in d."""
    root = d.xpos[lay.hub_body].copy()
    Rl = d.xmat[lay.hub_body].reshape(-1, 3, 3).copy()
    tip = d.site_xpos[lay.tip_site].copy()
    Rt = d.xmat[lay.tip_body].reshape(-1, 3, 3).copy()
    return root, Rl, tip, Rt


def _deflection_twist(root, Rl, tip, Rt):
    dv = tip - root
    defl = np.stack(
        [np.einsum("...i,...i->...", dv, Rl[..., 1]), np.einsum("...i,...i->...", dv, Rl[..., 2])], -1
    )
    twist = np.array([log_so3(a.T @ b)[0] for a, b in zip(Rl.reshape(-1, 3, 3), Rt.reshape(-1, 3, 3))])
    return defl, twist.reshape(defl.shape[:-1])


def statics(case, elements_per_link: int, *, loads=None, angles=None, tol: float = 1e-12, max_iter: int = 30):
    """Static equilibrium of the chain with the joints held at ``angles`` (the unlocked joints,
    default 0): Newton's method on the elastic hinges, residual MuJoCo's spring forces
    (``qfrc_passive``) minus its gravity forces (``qfrc_bias`` at rest) plus the tip loads, the
    Jacobian by central differences. ``loads``: {"force": F, "moment": M} (world components), a
    dead force at the tip point of the last link and a moment on its tip piece.

    Returns a dict: ``qpos``, ``tip_deflection`` (n, 2), ``twist`` (n,), ``link_tip`` (n, 3),
    ``tip_rotation`` (n, 3, 3), ``iterations``.
    """
    if not isinstance(case, SpatialCase):
        raise InputError("case", case, "must be a dttmm.spatial.SpatialCase")
    require_no_loads(case, f"{METHOD} statics (its ``loads`` argument takes a tip load)")
    require_serial(case.model, f"{METHOD} statics")
    loads = {} if loads is None else dict(loads)
    for key in loads:
        if key not in ("force", "moment"):
            raise InputError(f"loads.{key}", loads[key], "unknown load (one of: force, moment)")
    F = _vector3("loads.force", loads.get("force", (0.0, 0.0, 0.0)))
    Mo = _vector3("loads.moment", loads.get("moment", (0.0, 0.0, 0.0)))
    m, d, lay = build(case.model, elements_per_link)
    q0 = np.zeros(m.nq)
    if angles is not None:
        a = np.array(angles, float)
        if a.shape != lay.arm_qpos.shape or not np.all(np.isfinite(a)):
            raise InputError("angles", angles, f"must be {lay.arm_qpos.size} finite joint angles")
        q0[lay.arm_qpos] = a
    free = lay.flex_qpos.ravel()
    tip_b, tip_s = int(lay.tip_body[-1]), int(lay.tip_site[-1])

    def residual(x):
        d.qpos[:] = q0
        d.qpos[free] = x
        d.qvel[:] = 0.0
        mujoco.mj_forward(m, d)
        r = d.qfrc_passive - d.qfrc_bias
        qf = np.zeros(m.nv)
        mujoco.mj_applyFT(m, d, F, Mo, d.site_xpos[tip_s].copy(), tip_b, qf)
        return (r + qf)[free]

    x = np.zeros(free.size)
    scale = np.abs(residual(x)).max() + 1e-300
    for it in range(1, max_iter + 1):  # noqa: B007 (the count is read after the loop)
        r = residual(x)
        eps = 1e-7
        J = np.empty((free.size, free.size))
        for c in range(free.size):
            e = np.zeros(free.size)
            e[c] = eps
            J[:, c] = (residual(x + e) - residual(x - e)) / (2 * eps)
        dx = np.linalg.solve(J, -r)
        x = x + dx
        if np.abs(dx).max() <= tol * max(1.0, np.abs(x).max()):
            break
    r = residual(x)
    if not np.abs(r).max() <= 1e-8 * scale:
        raise SimulationError(
            f"{METHOD} statics: Newton did not converge (residual {np.abs(r).max():.3g})",
            t=0.0,
            step=it,
            component="state",
        )
    root, Rl, tip, Rt = _frames(m, d, lay)
    defl, twist = _deflection_twist(root, Rl, tip, Rt)
    return {
        "qpos": d.qpos.copy(),
        "tip_deflection": defl,
        "twist": twist,
        "link_tip": tip,
        "tip_rotation": Rt,
        "iterations": it,
    }


class _Stepper(_PlanarStepper):
    """Model, data, drives and state handling of one run (the interface of the planar chain's
    stepping loops; its ``step`` is the planar chain's)."""

    def __init__(self, case, k, h, integrator, station):
        self.mj = mujoco
        self.case_model = case.model
        self.angles = initial_angles(case)
        if case.model.closures:
            self.rc = resolve_closures(case.model, *rigid_tip_frames(case.model, self.angles))
        self.m, self.d, self.lay = build(case.model, k, h, integrator, station, self.angles)
        self.h = h
        self.k = k
        self.drives = case.scenario.drives
        self.n = len(self.drives)
        self.free = np.array([i for i, dr in enumerate(self.drives) if dr.kind == "torque"], int)
        self.pres = np.array([i for i, dr in enumerate(self.drives) if dr.kind == "motion"], int)
        self.closed = np.zeros(0, int)
        self.spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
        self.nstate = mujoco.mj_stateSize(self.m, self.spec)
        self.messages = []

    def initial_state(self):
        """Straight links, joint angles and rates from the drives."""
        d, lay = self.d, self.lay
        d.qpos[:] = self.m.qpos0
        d.qvel[:] = 0.0
        d.time = 0.0
        for i, dr in enumerate(self.drives):
            d.qpos[lay.arm_qpos[i]] = dr.initial_angle
            d.qvel[lay.arm_dof[i]] = dr.initial_rate
        mujoco.mj_forward(self.m, d)
        x = np.empty(self.nstate)
        mujoco.mj_getState(self.m, d, x, self.spec)
        return x


def _outputs(st, X, t, ctrl, T):
    """Result fields at the output times t from the kept states X (rows)."""
    m, d, lay = st.m, st.d, st.lay
    nt, nj, nl = t.size, st.n, lay.hub_body.size
    q, v, tau = np.empty((nt, nj)), np.empty((nt, nj)), np.empty((nt, nj))
    root, tip = np.empty((nt, nl, 3)), np.empty((nt, nl, 3))
    Rl, Rt = np.empty((nt, nl, 3, 3)), np.empty((nt, nl, 3, 3))
    energy = np.empty(nt)
    node = np.clip(np.searchsorted(T, t - 1e-9 * st.h), 0, T.size - 1)
    for s in range(nt):
        mujoco.mj_setState(m, d, X[s], st.spec)
        _kinematics_and_energy(mujoco, m, d)
        q[s], v[s] = d.qpos[lay.arm_qpos], d.qvel[lay.arm_dof]
        root[s], Rl[s], tip[s], Rt[s] = _frames(m, d, lay)
        energy[s] = d.energy[0] + d.energy[1]
        _drive_outputs(st, float(t[s]), node[s], ctrl, q[s], v[s], tau[s])
    defl, twist = _deflection_twist(root, Rl, tip, Rt)
    closures = {}
    if st.case_model.closures:
        closures = _closure_outputs(st, X, tau, tip, Rt)
    return {
        **closures,
        "joint_angle": q,
        "joint_rate": v,
        "joint_torque": tau,
        "link_root": root,
        "link_tip": tip,
        "tip_deflection": defl,
        "end_effector": tip[:, st.case_model.end_effector_index].copy(),
        "twist": twist,
        "link_rotation": Rl,
        "tip_rotation": Rt,
        "energy": energy,
    }


def closure_loads(m, d, manipulator) -> np.ndarray:
    """(n_closures, 6): the closures' loads at the state in d after ``mj_forward`` — force (N) and
    moment (N·m, about the closure point), world components, that `to` exerts on `link` — from
    the equality constraints' forces ``efc_force``. A ``connect``'s three rows are the world force
    on its first body at its first site (its Jacobian is that site's Jacobian minus the second's);
    a revolute closure's two connects sum to the force, their moments about the closure point (the
    midpoint of the two sites) to the moment. A ``weld``'s first three rows are the same force;
    its three rotational rows are A (ω_a − ω_b) with A MuJoCo's quaternion-error map, so their
    generalised force is the moment Aᵀ f on the first body, A recovered from the rows and the two
    sites' angular Jacobians (A = J_rot · pinv(J_ωa − J_ωb))."""
    out = np.zeros((len(manipulator.closures), 6))
    J = np.zeros((d.nefc, m.nv))
    if d.nefc:
        if mujoco.mj_isSparse(m):
            mujoco.mju_sparse2dense(J, d.efc_J, d.efc_J_rownnz, d.efc_J_rowadr, d.efc_J_colind)
        else:
            J[:] = d.efc_J.reshape(d.nefc, m.nv)
    eq_of = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_EQUALITY, e): e for e in range(m.neq)}
    for j, cl in enumerate(manipulator.closures):
        parts = [eq_of[f"closure{j}_{c}"] for c in range(2 if cl.kind == "revolute" else 1)]
        sites = [int(m.eq_obj1id[e]) for e in parts]
        centre = np.mean([d.site_xpos[s] for s in sites], axis=0)
        for e, s in zip(parts, sites):
            rows = np.flatnonzero((d.efc_id == e) & (d.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY))
            f = d.efc_force[rows]
            out[j, :3] += f[:3]
            out[j, 3:] += np.cross(d.site_xpos[s] - centre, f[:3])
            if cl.kind == "weld":
                ra, rb = np.zeros((3, m.nv)), np.zeros((3, m.nv))
                mujoco.mj_jacSite(m, d, None, ra, s)
                mujoco.mj_jacSite(m, d, None, rb, int(m.eq_obj2id[e]))
                A = J[rows[3:]] @ np.linalg.pinv(ra - rb)
                out[j, 3:] += A.T @ f[3:]
    return out


def _closure_outputs(st, X, tau, tip, Rt):
    """closure_loads (nt, nc, 6) at the output states (``mj_forward`` with the reported joint
    torques as controls), closure_residual and closure_angle_residual (nt, nc) from the tip frames
    (:func:`dttmm.spatial.topology.closure_gaps`, the closures resolved as the DT-TMM resolves
    them)."""
    m, d, model = st.m, st.d, st.case_model
    nt, nc = X.shape[0], len(model.closures)
    loads, gap, angle = np.empty((nt, nc, 6)), np.empty((nt, nc)), np.empty((nt, nc))
    for s in range(nt):
        mujoco.mj_setState(m, d, X[s], st.spec)
        d.ctrl[:] = 0.0
        d.ctrl[: st.n] = tau[s]
        mujoco.mj_forward(m, d)
        loads[s] = closure_loads(m, d, model)
        gap[s], angle[s] = closure_gaps(st.rc, Rt[s], tip[s])
    return {"closure_loads": loads, "closure_residual": gap, "closure_angle_residual": angle}


def check_case(case):
    """Refuse (InputError) what this chain cannot model, on the case alone (what
    :func:`simulate` refuses whatever its k, h and options): not a spatial case, closed-loop
    drives, external loads, rigid links."""
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase")
    _check(case, 1, case.scenario.duration, "implicitfast", {})


def _check(case, k, h, integrator, options):
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase")
    k = plumbing.elements_per_link(k)
    h = plumbing.step_size(h, case.scenario.duration)
    _checks.integrator(integrator, INTEGRATORS)
    _checks.option_names(options, _OPTIONS, METHOD)
    opts = {**_OPTIONS, **options}
    opts["motion_tol"] = plumbing.positive_number("motion_tol", opts["motion_tol"])
    opts["motion_max_iter"] = plumbing.positive_integer("motion_max_iter", opts["motion_max_iter"])
    plumbing.choice("station", opts["station"], STATIONS)
    require_open_loop(case, METHOD)
    require_no_loads(case, METHOD)
    require_flexible(case.model, METHOD)
    return k, h, opts


def simulate(
    case, *, elements_per_link, h, integrator="implicitfast", shape_points=0, **options
) -> SpatialResult:
    """Simulate a spatial case with MuJoCo, every link a chain of ``elements_per_link`` elastic
    stations (three hinges each).

    Parameters
    ----------
    case : dttmm.spatial.SpatialCase
    elements_per_link : int
        k, the number of elastic stations (segments of length L/k) per link.
    h : float
        Step size (s); it must divide the case's output step (outputs are step nodes).
    integrator : ``"implicitfast"`` (default) | ``"euler"`` | ``"implicit"`` | ``"rk4"``
    **options
        motion_tol (1e-12, relative angle tolerance of a motion drive), motion_max_iter (10);
        station (``"hinges"``; ``"hinges-zyx"``, ``"ball"``: the alternatives of :func:`xml`, for
        comparison; with ``"ball"`` no stability bound is computed, ``meta["h_stable"]`` None).
    shape_points : p ≥ 2 records ``link_shapes`` (nt, n, p, 3): the polyline of every link's
        rigid pieces (:func:`piece_shapes`); 0 (default): none.

    Returns
    -------
    dttmm.spatial.SpatialResult on ``case.scenario.output_times`` (``cut_loads`` None);
    ``wall_time`` covers the time stepping only, ``meta["cpu_time_solve"]`` its CPU time,
    ``meta["omega_max"]``, ``meta["h_stable"]`` the explicit stability bound (a larger h adds
    a warning).

    Raises
    ------
    dttmm.InputError
        not a SpatialCase; bad k, h, integrator or option; h not dividing the output step; a
        closed-loop drive.
    dttmm.SimulationError
        non-finite state, MuJoCo's instability reset, or a motion drive not imposed; ``partial``
        holds the outputs up to the last good step.
    """
    k, h, opts = _check(case, elements_per_link, h, integrator, dict(options))
    shape_points = check_shape_points(shape_points)
    T, t_out, keep = step_nodes(case.scenario, h)
    st = _Stepper(case, k, h, integrator, opts["station"])
    X, n_steps, ctrl, wall, meta, stats, warnings = _run(st, T, keep, integrator, k, opts, METHOD)
    tg = t_out[: X.shape[0]]
    fields = _outputs(st, X, tg, ctrl[:n_steps], T)
    res = SpatialResult(
        t=tg,
        **fields,
        link_shapes=piece_shapes(st, case, X[: tg.size], shape_points, 3) if shape_points else None,
        wall_time=wall,
        n_steps=int(n_steps),
        meta=meta,
        status="ok" if "fail" not in stats else "failed",
        warnings=tuple(warnings),
    )
    _raise_failure(st, stats, METHOD, res)
    return res
