"""Trees and closed loops of a spatial arm (docs/spatial.md "Trees and closed loops"): the
undeformed kinematics of a tree at given joint angles, the closures' attachment data resolved at
the initial state, and the closures' position and angle gaps."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import InputError
from .model import SpatialManipulator
from .rotation import axis_angle_matrix, log_so3, rpy_matrix

__all__ = [
    "ResolvedClosures",
    "check_initial_closures",
    "closure_gaps",
    "initial_angles",
    "resolve_closures",
    "rigid_tip_frames",
]

#: an explicit `to_point` may leave this gap (× the mechanism's size) at the initial state
INITIAL_GAP = 1e-9


class ResolvedClosures(NamedTuple):
    """The closures' data in the frames the constraint uses, fixed at the initial state."""

    a: np.ndarray  # (nc,) index of `link`
    b: np.ndarray  # (nc,) index of `to` (−1: the ground)
    kind: np.ndarray  # (nc,) 0 spherical, 1 revolute, 2 weld
    pa: np.ndarray  # (nc, 3) point in a's tip frame
    pb: np.ndarray  # (nc, 3) point in b's tip frame (world for the ground)
    ua: np.ndarray  # (nc, 3) revolute axis in a's tip frame
    ub: np.ndarray  # (nc, 3) its image in b's tip frame (world for the ground)
    R0: np.ndarray  # (nc, 3, 3) weld: R_aᵀ R_b at the initial state


KIND_CODE = {"spherical": 0, "revolute": 1, "weld": 2}


def rigid_tip_frames(model: SpatialManipulator, angles) -> tuple[np.ndarray, np.ndarray]:
    """(R (n, 3, 3), p (n, 3)): every link's tip frame with the links undeformed, at the joint
    angles ``angles`` (one per unlocked joint, base first)."""
    n = model.n_links
    angles = np.asarray(angles, float)
    R, p = np.zeros((n, 3, 3)), np.zeros((n, 3))
    Rb, pb = model.base_rotation, np.array(model.base_xyz, float)
    r = 0
    for i, link in enumerate(model.links):
        par = model.parents[i]
        Rp, pp = (Rb, pb) if par < 0 else (R[par], p[par])
        jn = link.joint
        Rj = Rp @ rpy_matrix(jn.origin_rpy)
        pj = pp + Rp @ np.array(jn.origin_xyz, float)
        alpha = 0.0
        if not jn.locked:
            alpha = float(angles[r])
            r += 1
        Rl = Rj @ axis_angle_matrix(jn.axis, alpha)
        R[i] = Rl
        p[i] = pj + Rl[:, 0] * link.beam.length
    return R, p


def initial_angles(case) -> np.ndarray:
    """The joint angles of the case's initial state (a motion law's value at t = 0)."""
    out = []
    for d in case.scenario.drives:
        out.append(d.motion(0.0, False)[0] if d.kind == "motion" else d.initial_angle)
    return np.array(out, float)


def _frame(R, p, i):
    if i < 0:
        return np.eye(3), np.zeros(3)
    return R[i], p[i]


def resolve_closures(model: SpatialManipulator, R, p) -> ResolvedClosures:
    """The closures' attachment data, with the initial tip frames (R, p) fixing what the case
    leaves to the initial state (`to_point` None, the revolute axis's image, the weld's
    relative rotation)."""
    nc = len(model.closures)
    out = ResolvedClosures(
        a=np.zeros(nc, np.int64),
        b=np.zeros(nc, np.int64),
        kind=np.zeros(nc, np.int64),
        pa=np.zeros((nc, 3)),
        pb=np.zeros((nc, 3)),
        ua=np.zeros((nc, 3)),
        ub=np.zeros((nc, 3)),
        R0=np.zeros((nc, 3, 3)),
    )
    for j, cl in enumerate(model.closures):
        a = model.link_index(cl.link)
        b = -1 if cl.to == "ground" else model.link_index(cl.to)
        Ra, xa = _frame(R, p, a)
        Rb, xb = _frame(R, p, b)
        out.a[j], out.b[j], out.kind[j] = a, b, KIND_CODE[cl.kind]
        out.pa[j] = cl.point
        world_a = xa + Ra @ out.pa[j]
        out.pb[j] = Rb.T @ (world_a - xb) if cl.to_point is None else cl.to_point
        out.ua[j] = cl.axis
        out.ub[j] = Rb.T @ (Ra @ out.ua[j])
        out.R0[j] = Ra.T @ Rb
    return out


def closure_gaps(rc: ResolvedClosures, R, p) -> tuple[np.ndarray, np.ndarray]:
    """(position gaps |p_a − p_b| (nc,) in m, angle gaps (nc,) in rad: revolute the angle between
    the two images of the axis, weld the angle of R_aᵀR_b R0ᵀ, spherical 0) at tip frames (R, p)."""
    nc = rc.a.size
    dp, da = np.zeros(nc), np.zeros(nc)
    for j in range(nc):
        Ra, xa = _frame(R, p, rc.a[j])
        Rb, xb = _frame(R, p, rc.b[j])
        dp[j] = np.linalg.norm(xa + Ra @ rc.pa[j] - xb - Rb @ rc.pb[j])
        if rc.kind[j] == 1:
            s = np.linalg.norm(np.cross(Ra @ rc.ua[j], Rb @ rc.ub[j]))
            c = float(np.dot(Ra @ rc.ua[j], Rb @ rc.ub[j]))
            da[j] = np.arctan2(s, c)
        elif rc.kind[j] == 2:
            da[j] = np.linalg.norm(log_so3(Ra.T @ Rb @ rc.R0[j].T))
    return dp, da


def check_initial_closures(case) -> None:
    """Refuse a closure whose explicit `to_point` leaves a gap above INITIAL_GAP × the
    mechanism's size at the initial state (the loop must be assembled there)."""
    model = case.model
    R, p = rigid_tip_frames(model, initial_angles(case))
    rc = resolve_closures(model, R, p)
    gaps, _ = closure_gaps(rc, R, p)
    tol = INITIAL_GAP * model.size
    for j, cl in enumerate(model.closures):
        if cl.to_point is not None and not gaps[j] <= tol:
            raise InputError(
                f"model.closures[{j}].to_point",
                list(cl.to_point),
                f"leaves closure {model.closure_names[j]!r} open by {gaps[j]:.3g} m at the initial state "
                f"(at most {tol:.3g} m; omit to_point to close it where the initial state places it)",
            )
