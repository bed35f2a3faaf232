"""The MuJoCo model of a planar flexible arm: every link a chain of rigid pieces and hinge springs.

Lumping rule ("modified rigid finite elements"), link of length L, k segments, l = L/k:

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

from dataclasses import dataclass

import numpy as np

__all__ = ["INTEGRATORS", "ChainLayout", "chain_xml", "layout", "link_pieces"]

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


def _combine(parts):
    """Total mass, centre x and Izz about the centre of point/rod parts (mass, x, Izz_own)."""
    m = sum(p[0] for p in parts)
    c = sum(p[0] * p[1] for p in parts) / m
    izz = sum(p[2] + p[0] * (p[1] - c) ** 2 for p in parts)
    return m, c, izz


def link_pieces(link, k: int) -> list[tuple[float, float, float, float]]:
    """The rigid pieces of one link: (body offset from its parent frame, mass, centre, Izz).

    Offsets and centres (m) are along the link axis in the piece's own frame, whose origin is
    the hinge in front of it (the arm joint for piece 0). Izz (kg·m²) is about the centre.
    Piece 0 includes the hub, piece k the payload.
    """
    beam = link.beam
    L, rhoA = beam.length, beam.rhoA
    l = L / k
    out = []
    for j in range(k + 1):
        ln = l / 2 if j in (0, k) else l
        parts = [(rhoA * ln, ln / 2, rhoA * ln**3 / 12)]
        if j == 0 and link.hub_mass + link.hub_inertia > 0:
            parts.append((link.hub_mass, 0.0, link.hub_inertia))
        if j == k and link.payload_mass + link.payload_inertia > 0:
            parts.append((link.payload_mass, ln, link.payload_inertia))
        offset = 0.0 if j == 0 else (l / 2 if j == 1 else l)
        out.append((offset, *_combine(parts)))
    return out


def _f(x: float) -> str:
    return repr(float(x))


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
            lines.append(
                f'{pad}  <inertial pos="{_f(c)} 0 0" mass="{_f(m)}" '
                f'diaginertia="{_f(izz)} {_f(izz)} {_f(izz)}"/>'
            )
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
