"""Rigid inverse dynamics of a spatial arm: the recursive Newton–Euler algorithm over the
rigid chain of docs/spatial.md §1 (the limit of infinitely stiff links).

Each link is one rigid body in its link frame (R_link, p_link): the beam as a uniform rod (mass
ρA L at (L/2, 0, 0), inertia m L²/12 about the centre across the rod) with the sections' rotary
inertia L · Rx(roll) diag(ρJ, ρIy, ρIz) Rx(roll)ᵀ (a rigid link: its own body, mass at its
centre of mass, inertia about it), the hub (mass at the root, inertia J_h about
it) and the payload (mass at (L, 0, 0) + c, inertia J_p about its centre; the rigid tip frame
has the link frame's axes): the rigid body of :mod:`reference_models.pinocchio_spatial` and of
the kernel at e = 0. Joints as in the model: R_J = R_par R_rpy, p_J = p_par + R_par o,
R_link = R_J Rot(a, α); a locked joint has α ≡ 0; the parent frame of link i is the rigid tip
frame of link i − 1 (the link frame moved by L along x), or the base frame.

Forward pass (world components), per link with ω, ω̇ of the parent and a_par the classical
acceleration of the parent's origin p_par (gravity as a base acceleration −g):

    z = R_J a,  ω = ω_par + z α̇,  ω̇ = ω̇_par + z α̈ + ω_par × z α̇,
    a_J = a_par + ω̇_par × d + ω_par × (ω_par × d),   d = p_J − p_par.

Each body's load about its link origin with mass m, first moment h = m c and inertia I_o about
the origin (world components): f = m a_J + ω̇ × h + ω × (ω × h), n = I_o ω̇ + ω × I_o ω + h × a_J.
Backward pass: f_i += f_{i+1}, n_i += n_{i+1} + d_{i+1} × f_{i+1}; τ_i = z_i · n_i (n_i about
the link origin, which lies on the joint axis).
Everything broadcasts over leading axes (e.g. time).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from .model import require_serial
from .rotation import rpy_matrix

__all__ = ["link_body", "rigid_inverse_dynamics"]


def _rx(t: float) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _skew_sq(c: np.ndarray) -> np.ndarray:
    """(|c|² I − c cᵀ): the inertia of a unit point mass at c about the origin."""
    return np.dot(c, c) * np.eye(3) - np.outer(c, c)


def link_body(link) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass m, first moment h = m c (3,), inertia I_o about the link origin (3, 3)) of a rigid
    link in its link frame (kg, kg·m, kg·m²)."""
    b = link.beam
    L = b.length
    if link.rigid:  # a rigid link's own body: mass at its centre c, inertia about c
        m_rod, c_rod, I_rod = b.mass, b.com_vector, b.inertia_matrix
    else:
        m_rod = b.rhoA * b.length
        Rr = _rx(b.roll)
        c_rod = np.array([L / 2.0, 0.0, 0.0])
        I_rod = (
            np.diag([0.0, m_rod * L * L / 12, m_rod * L * L / 12])
            + L * Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
        )
    m = m_rod
    h = m_rod * c_rod
    I_o = I_rod + m_rod * _skew_sq(c_rod)
    if link.hub is not None:
        m += link.hub_mass
        I_o = I_o + link.hub_inertia
    if link.payload is not None:
        c = np.array([L, 0.0, 0.0]) + np.asarray(link.payload_offset, float)
        mp = link.payload_mass
        m += mp
        h = h + mp * c
        I_o = I_o + link.payload_inertia + mp * _skew_sq(c)
    return float(m), h, np.asarray(I_o, float)


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues rotations (..., 3, 3) about the unit ``axis`` by ``angle`` (...)."""
    k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    s, c = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + s * k + (1.0 - c) * (k @ k)


def rigid_inverse_dynamics(manipulator, q, qd, qdd) -> np.ndarray:
    """Joint torques (..., m) of the rigid spatial arm at the angles, rates and accelerations
    (..., m) of its m unlocked joints (drive order), under the arm's gravity (N·m)."""
    require_serial(manipulator, "the rigid inverse dynamics (computed_torque)")
    q, qd, qdd = (np.asarray(x, float) for x in (q, qd, qdd))
    unl = manipulator.unlocked
    m = len(unl)
    shape = np.broadcast_shapes(q.shape, qd.shape, qdd.shape)
    if shape[-1:] != (m,):
        raise InputError("q", q.shape, f"must end with the number of unlocked joints, {m}")
    q, qd, qdd = (np.broadcast_to(x, shape) for x in (q, qd, qdd))
    lead = shape[:-1]
    col = {int(i): j for j, i in enumerate(unl)}
    vec = lambda v: np.broadcast_to(np.asarray(v, float), (*lead, 3))
    R = np.broadcast_to(rpy_matrix(manipulator.base_rpy), (*lead, 3, 3))
    p = vec(manipulator.base_xyz)  # origin of the parent frame
    o = p  # the point of the parent body whose acceleration is a (the base: any)
    w, wd = vec(np.zeros(3)), vec(np.zeros(3))
    a = vec(-np.asarray(manipulator.gravity, float))
    mv = lambda A, x: np.einsum("...ij,...j->...i", A, x)
    bodies = []
    for i, link in enumerate(manipulator.links):
        jn = link.joint
        RJ = R @ rpy_matrix(jn.origin_rpy)
        pJ = p + mv(R, np.asarray(jn.origin_xyz, float))
        d = pJ - o
        a = a + np.cross(wd, d) + np.cross(w, np.cross(w, d))
        z = vec(np.zeros(3))
        if i in col:
            axis = np.asarray(jn.axis, float)
            j = col[i]
            z = mv(RJ, axis)
            zd = z * qd[..., j, None]
            wd = wd + z * qdd[..., j, None] + np.cross(w, zd)
            w = w + zd
            R = RJ @ _rot(axis, q[..., j])
        else:
            R = RJ
        mass, h, I_o = link_body(link)
        hw = mv(R, h)
        Iw = R @ I_o @ np.swapaxes(R, -1, -2)
        f = mass * a + np.cross(wd, hw) + np.cross(w, np.cross(w, hw))
        n = mv(Iw, wd) + np.cross(w, mv(Iw, w)) + np.cross(hw, a)
        bodies.append((d, z, f, n))
        o, p = pJ, pJ + R[..., :, 0] * link.beam.length  # the link origin, its rigid tip frame
    tau = np.zeros(shape)
    f_out, n_out, d_out = vec(np.zeros(3)), vec(np.zeros(3)), vec(np.zeros(3))
    for i in range(len(manipulator.links) - 1, -1, -1):
        d, z, f, n = bodies[i]
        n = n + n_out + np.cross(d_out, f_out)
        f = f + f_out
        if i in col:
            tau[..., col[i]] = np.einsum("...i,...i->...", z, n)
        f_out, n_out, d_out = f, n, d
    return tau
