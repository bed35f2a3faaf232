"""The MuJoCo model of a flexible arm, planar or spatial: every link a chain of rigid pieces
joined by elastic hinges. What both chains share lives here once: the pieces' mass properties
(:func:`piece_properties`; a planar link's pieces, :func:`link_pieces`, are that rule applied to
the link's spatial embedding), the number format of the MJCF (:func:`_f`), the exact inertias
written into a compiled model (:func:`set_inertias`), and the linearised chain's eigenvalues
(:func:`stability_limit`, :func:`frequencies`).

Lumping rule ("modified rigid finite elements") of a planar link, length L, k segments, l = L/k:

* k elastic hinges (axis z) at x_j = (j − ½) l, j = 1..k, each a rotational spring of stiffness
  EI/l and a damper of coefficient μ·EI/l (Kelvin–Voigt damping D = μK of the beam);
* k + 1 rigid pieces between them: [0, l/2] (welded to the hub, behind the arm joint), the full
  pieces [(j − ½) l, (j + ½) l] and the half piece [L − l/2, L] at the tip (carrying the payload);
* every piece carries its own share of the beam: mass ρA·len at its centre and the inertia
  ρA·len³/12 of a thin rod about it, so the rigid-body inertia of the whole link is exact.

Each spring then stands for the bending compliance of the segment of length l centred on it
(the midpoint rule for ∫ M/EI ds). The static tip deflection under a tip force is
F L³/(3EI)·(1 − 1/(4k²)): second order in 1/k, as are the natural frequencies (measured).

The arm joint i is a hinge at the root of link i whose body (the hub body) is the first half
piece plus the hub; its parent is the tip piece of link i − 1 (the world for i = 1). Motors with
gear 1 on every arm joint apply the drive torques.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

__all__ = [
    "INTEGRATORS",
    "ChainLayout",
    "chain_xml",
    "eig_mk",
    "frequencies",
    "layout",
    "link_pieces",
    "piece_properties",
    "set_inertias",
    "stability_limit",
]

#: integrators offered (MuJoCo's names) and their explicit stability factor c in h < c/ω_max
INTEGRATORS = {"implicitfast": 2.0, "euler": 2.0, "implicit": 2.0, "rk4": 2.0 * np.sqrt(2.0)}
_MJCF_NAME = {"implicitfast": "implicitfast", "euler": "Euler", "implicit": "implicit", "rk4": "RK4"}


@dataclass(frozen=True)
class ChainLayout:
    """Where things are in the compiled model.

    arm_qpos : (n,) qpos index of each arm joint
    flex_qpos : (n, k) qpos indices of the elastic hinges of each link
    hub_body, tip_body : (n,) body id of each link's root (hub) piece and tip piece
    tip_site : (n,) site id of each link tip
    """

    arm_qpos: np.ndarray
    flex_qpos: np.ndarray
    hub_body: np.ndarray
    tip_body: np.ndarray
    tip_site: np.ndarray


def _rx(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _combine(parts):
    """(mass, centre (3,), inertia (3, 3) about the centre) of parts (mass, centre, own inertia)."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * np.asarray(p[1], float) for p in parts) / m
    J = np.zeros((3, 3))
    for mp, cp, Jp in parts:
        d = np.asarray(cp, float) - c
        J += np.asarray(Jp, float) + mp * (d @ d * np.eye(3) - np.outer(d, d))
    return m, c, 0.5 * (J + J.T)


def piece_properties(link, k: int):
    """The rigid pieces of one spatial link (``dttmm.spatial.SpatialLink``): list of (body offset
    (3,), mass, centre (3,), inertia (3, 3)).

    Each piece carries its share of the beam: mass ρA·len at its centre, the rod inertia
    ρA·len³/12 about the two transverse axes and the section inertia len·Rx(roll) diag(ρJ, ρIy,
    ρIz) Rx(roll)ᵀ. Offsets and centres (m) are in the piece's own frame, whose origin is the
    station in front of it (the joint for piece 0) and whose axes are the link frame's when
    undeformed; the inertia (kg·m²) is about the centre. Piece 0 includes the hub (full inertia
    about the root point), piece k the payload (at its offset in the tip frame, full inertia
    about its centre).
    """
    b = link.beam
    l = b.length / k
    Rr = _rx(b.roll)
    section = Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
    out = []
    for j in range(k + 1):
        ln = l / 2 if j in (0, k) else l
        rod = b.rhoA * ln**3 / 12
        parts = [(b.rhoA * ln, (ln / 2, 0.0, 0.0), np.diag([0.0, rod, rod]) + ln * section)]
        if j == 0 and link.hub is not None and link.hub.mass > 0:
            parts.append((link.hub.mass, (0.0, 0.0, 0.0), link.hub_inertia))
        elif j == 0 and link.hub is not None:  # inertia without mass: a pure rotor at the root
            parts[0] = (parts[0][0], parts[0][1], parts[0][2] + link.hub_inertia)
        if j == k and link.payload is not None:
            c = np.array([ln, 0.0, 0.0]) + link.payload_offset
            if link.payload.mass > 0:
                parts.append((link.payload.mass, c, link.payload_inertia))
            else:
                parts[0] = (parts[0][0], parts[0][1], parts[0][2] + link.payload_inertia)
        offset = 0.0 if j == 0 else (l / 2 if j == 1 else l)
        out.append((np.array([offset, 0.0, 0.0]), *_combine(parts)))
    return out


def link_pieces(link, k: int) -> list[tuple[float, float, float, float]]:
    """The rigid pieces of one planar link: (body offset from its parent frame, mass, centre, Izz).

    The spatial rule (:func:`piece_properties`) on the link's embedding
    (:func:`dttmm.spatial.embed_planar`), read in the plane: offsets and centres (m) along the
    link axis in the piece's own frame, whose origin is the hinge in front of it (the arm joint
    for piece 0); Izz (kg·m²) about the centre. Piece 0 includes the hub, piece k the payload.
    """
    from dttmm.model import Manipulator
    from dttmm.spatial import embed_planar

    spatial = embed_planar(Manipulator((link,))).links[0]
    return [
        (float(o[0]), float(m), float(c[0]), float(J[2, 2])) for o, m, c, J in piece_properties(spatial, k)
    ]


def _f(x) -> str:
    """MJCF text of a number or a vector (round-trip exact)."""
    return " ".join(repr(float(v)) for v in np.atleast_1d(x))


def _quat(R) -> np.ndarray:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(R, float).ravel())
    return q


def inertial(pad: str, mass: float, centre, diag) -> str:
    """The ``<inertial>`` line of a body: mass at ``centre`` (3,), principal inertia ``diag`` (3,)."""
    return f'{pad}  <inertial pos="{_f(centre)}" mass="{_f(mass)}" diaginertia="{_f(diag)}"/>'


def set_inertias(m, links, k: int) -> None:
    """Write the exact mass properties of every piece (:func:`piece_properties` of the spatial
    ``links``; bodies ``link{i}_{j}``) into the compiled model ``m``: mass, centre, principal
    axes (``body_iquat``) and inertia. ``mj_setConst`` must follow."""
    for i, link in enumerate(links):
        for j, (_, mass, c, J) in enumerate(piece_properties(link, k)):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"link{i}_{j}")
            w, V = np.linalg.eigh(J)
            if np.linalg.det(V) < 0:
                V[:, 0] = -V[:, 0]
            m.body_mass[bid] = mass
            m.body_ipos[bid] = c
            m.body_iquat[bid] = _quat(V)
            m.body_inertia[bid] = np.maximum(w, 0.0)


def chain_xml(manipulator, k: int, h: float, integrator: str, *, clamp_first: bool = False) -> str:
    """MJCF of the whole arm (a ``dttmm.Manipulator``) (initial configuration: qpos = 0, every link along +x).

    ``clamp_first`` welds link 1 to the ground (no arm joint 1): the clamped-free beam used for
    the natural frequencies.
    """
    gx, gy = manipulator.gravity
    lines = [
        '<mujoco model="dttmm-chain">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_f(h)}" integrator="{_MJCF_NAME[integrator]}" gravity="{_f(gx)} {_f(gy)} 0">',
        '    <flag contact="disable" energy="enable"/>',
        "  </option>",
        "  <worldbody>",
    ]
    closers = []
    depth = 2
    for i, link in enumerate(manipulator.links):
        beam = link.beam
        l = beam.length / k
        stiff = beam.EI / l
        damp = beam.damping * stiff
        pieces = link_pieces(link, k)
        for j, (offset, m, c, izz) in enumerate(pieces):
            # the hub body of link i sits at the tip of link i − 1 (half a segment beyond its hinge)
            pos = offset if j > 0 else (0.0 if i == 0 else manipulator.links[i - 1].beam.length / k / 2)
            pad = " " * depth
            lines.append(f'{pad}<body name="link{i}_{j}" pos="{_f(pos)} 0 0">')
            if j == 0:
                if not (clamp_first and i == 0):
                    lines.append(f'{pad}  <joint name="arm{i}" type="hinge" axis="0 0 1"/>')
            else:
                lines.append(
                    f'{pad}  <joint name="flex{i}_{j}" type="hinge" axis="0 0 1" '
                    f'stiffness="{_f(stiff)}" damping="{_f(damp)}" springref="0"/>'
                )
            # planar motion: only Izz enters; Ixx = Iyy = Izz keeps the triangle inequality
            lines.append(inertial(pad, m, (c, 0.0, 0.0), (izz, izz, izz)))
            if j == k:
                lines.append(f'{pad}  <site name="tip{i}" pos="{_f(l / 2)} 0 0"/>')
            closers.append(f"{pad}</body>")
            depth += 2
    lines += closers[::-1]
    lines.append("  </worldbody>")
    lines.append("  <actuator>")
    for i in range(manipulator.n_links):
        if not (clamp_first and i == 0):
            lines.append(f'    <motor name="drive{i}" joint="arm{i}" gear="1"/>')
    lines += ["  </actuator>", "</mujoco>"]
    return "\n".join(lines)


def layout(model, n_links: int, k: int, *, clamp_first: bool = False) -> ChainLayout:
    """Index maps of a compiled :func:`chain_xml` model."""
    import mujoco

    def jq(name):
        return int(model.jnt_qposadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)])

    def bid(name):
        return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)

    arm = [(-1 if clamp_first and i == 0 else jq(f"arm{i}")) for i in range(n_links)]
    flex = [[jq(f"flex{i}_{j}") for j in range(1, k + 1)] for i in range(n_links)]
    return ChainLayout(
        arm_qpos=np.array(arm, int),
        flex_qpos=np.array(flex, int).reshape(n_links, k),
        hub_body=np.array([bid(f"link{i}_0") for i in range(n_links)], int),
        tip_body=np.array([bid(f"link{i}_{k}") for i in range(n_links)], int),
        tip_site=np.array(
            [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"tip{i}") for i in range(n_links)], int
        ),
    )


def eig_mk(m, d, vectors: bool = True):
    """Generalised eigenvalues ω² (ascending; zeros for free joints) of (K, M) at the state in d,
    K the joint stiffnesses and M MuJoCo's mass matrix; with ``vectors`` the pair (ω², modes)."""
    import scipy.linalg

    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    K = np.diag(m.jnt_stiffness[m.dof_jntid])
    return scipy.linalg.eigh(K, M, eigvals_only=not vectors)


def stability_limit(m, d, integrator: str = "implicitfast") -> tuple[float, float]:
    """(ω_max rad/s, the largest stable step c/ω_max s) of the undamped linearised chain at d."""
    w2 = eig_mk(m, d)[0]
    wmax = math.sqrt(max(float(w2[-1]), 0.0))
    return wmax, (INTEGRATORS[integrator] / wmax if wmax > 0 else math.inf)


def frequencies(w2) -> np.ndarray:
    """Natural frequencies (rad/s) of the eigenvalues ω² (round-off negatives as 0)."""
    return np.sqrt(np.clip(w2, 0.0, None))
