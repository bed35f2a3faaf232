"""The MuJoCo model of a flexible arm, planar or spatial: every link a chain of k rigid pieces
joined by elastic stations (docs/mujoco.md). One builder serves both chains: a spatial arm is
built by :func:`build` (:func:`xml`, :func:`set_inertias`, :func:`layout`), a planar arm by
:func:`build_planar` as its spatial embedding (:func:`dttmm.spatial.embed_planar`) with one hinge
about the plane's normal per station, so it keeps the planar degrees of freedom alone.

Lumping rule, link of length L, k segments, l = L/k ("modified rigid finite elements"):

* k elastic stations at x_j = (j − ½) l, j = 1..k: three hinges through one point (bending about
  the section's z axis with stiffness EIz/l, about its y axis with EIy/l, twist about x with
  GJ/l; the order z, y, x at odd stations and reversed at even ones, see mujoco_spatial) or, on
  a planar arm, the z hinge alone (EI/l); each with a damper of μ times its stiffness
  (Kelvin–Voigt damping D = μK of the beam). Axial stiffness: rigid.
* k + 1 rigid pieces between them: [0, l/2] behind the arm joint (the hub body), the full
  pieces [(j − ½) l, (j + ½) l] and the half piece [L − l/2, L] at the tip. Every piece carries
  its own share of the beam (:func:`piece_properties`): mass ρA·len at its centre, the rod
  inertia ρA·len³/12 about the transverse axes and the section inertia; the hub joins piece 0,
  the payload piece k. So the rigid-body inertia of every link is exact at any k.

Each spring stands for the compliance of the segment of length l centred on it (the midpoint
rule for ∫ M/EI ds): a tip force deflects the chain by F L³/(3EI)·(1 − 1/(4k²)), second order
in 1/k, as are the natural frequencies (measured).

The arm joint i is a hinge at the root of link i whose body (the hub body) is the first half
piece plus the hub; its parent is the tip piece of the parent link (the base body for a link on
the base). Motors with gear 1 on every unlocked arm joint apply the drive torques. MuJoCo's
compiler requires body inertias that satisfy the triangle inequality, which a short piece of a
beam with ρJ > ρIy + ρIz breaks; the MJCF therefore carries placeholders and :func:`set_inertias`
writes the exact mass, centre and principal inertia of every piece into the compiled model.

Shared by both chains beside the builder: the integrators (:data:`INTEGRATORS`), the number
format of the MJCF (:func:`_f`), the linearised chain's eigenvalues (:func:`eig_mk`,
:func:`stability_limit`, :func:`frequencies`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import mujoco
import numpy as np

from dttmm import plumbing
from dttmm.errors import InputError
from dttmm.spatial import SpatialJoint, SpatialManipulator, embed_planar
from dttmm.spatial.rotation import rpy_matrix
from dttmm.spatial.topology import resolve_closures, rigid_tip_frames

__all__ = [
    "INTEGRATORS",
    "PLANAR_STATION",
    "STATIONS",
    "ChainLayout",
    "SpatialLayout",
    "build",
    "build_planar",
    "closure_equalities",
    "eig_mk",
    "frequencies",
    "layout",
    "piece_properties",
    "set_inertias",
    "stability_limit",
    "xml",
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


def set_inertias(m, links, k: int, *, link_axes: bool = False) -> None:
    """Write the exact mass properties of every piece (:func:`piece_properties` of the spatial
    ``links``; bodies ``link{i}_{j}``) into the compiled model ``m``: mass, centre, principal
    axes (``body_iquat``) and inertia. ``mj_setConst`` must follow.

    ``link_axes``: a piece whose inertia is diagonal in the link frame keeps that frame (identity
    ``body_iquat``, the diagonal as it is) instead of its eigenvectors in ascending order. A
    planar arm's embedding uses it: its in-plane inertia Izz then enters exactly, where a
    rotated principal frame would mix the out-of-plane inertias into it at round-off."""
    for i, link in enumerate(links):
        for j, (_, mass, c, J) in enumerate(piece_properties(link, k)):
            bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"link{i}_{j}")
            if link_axes and not np.any(J - np.diag(np.diag(J))):
                w, q = np.diag(J).copy(), np.array([1.0, 0.0, 0.0, 0.0])
            else:
                w, V = np.linalg.eigh(J)
                if np.linalg.det(V) < 0:
                    V[:, 0] = -V[:, 0]
                q = _quat(V)
            m.body_mass[bid] = mass
            m.body_ipos[bid] = c
            m.body_iquat[bid] = q
            m.body_inertia[bid] = np.maximum(w, 0.0)


#: the elastic stations of a spatial arm (:func:`xml`)
STATIONS = ("hinges", "hinges-zyx", "ball")
#: the station of a planar arm's embedding: its in-plane bending hinge alone (:func:`build_planar`)
PLANAR_STATION = "hinge-z"
#: the three hinges of an elastic station: name suffix, axis in the section frame, stiffness key
STATION = (("bz", (0.0, 0.0, 1.0), "EIz"), ("by", (0.0, 1.0, 0.0), "EIy"), ("tx", (1.0, 0.0, 0.0), "GJ"))


@dataclass(frozen=True)
class SpatialLayout:
    """Where things are in the compiled model (m unlocked joints, n links, k stations).

    arm_qpos, arm_dof : (m,) qpos and dof index of each unlocked joint, in drive order
    flex_qpos : (n, k, 3) qpos indices of the hinges (bend z, bend y, twist) of every station
        (−1 where the station has no such hinge: ball stations, the planar station's y and x)
    hub_body, tip_body : (n,) body id of each link's root piece and tip piece
    tip_site : (n,) site id of each link tip
    """

    arm_qpos: np.ndarray
    arm_dof: np.ndarray
    flex_qpos: np.ndarray
    hub_body: np.ndarray
    tip_body: np.ndarray
    tip_site: np.ndarray


def xml(
    manipulator: SpatialManipulator,
    k: int,
    h: float,
    integrator: str = "implicitfast",
    station: str = "hinges",
    angles=None,
) -> str:
    """MJCF of the spatial arm (undeformed links, every joint angle 0); body inertias are
    placeholders (see the module notes: :func:`build` writes the exact ones). Links hang from
    their parents' tip pieces (a tree), closures are equality constraints
    (:func:`closure_equalities`) whose attachment data are resolved with the links undeformed at
    the joint angles ``angles`` (the unlocked joints; None: all 0), the case's initial state.

    ``station``: ``"hinges"`` (three hinges, the order bend z, bend y, twist at odd stations and
    reversed at even ones), ``"hinges-zyx"`` (the same order everywhere) or ``"ball"`` (a ball
    joint whose three stiffnesses and dampers are affine-bias actuators on the section axes, the
    torque −(K φ + μ K ω) with φ the ball's rotation vector). The last two exist for the
    comparison in docs/mujoco.md. ``"hinge-z"`` (:data:`PLANAR_STATION`): the bend-z hinge alone,
    the planar chain's station on a planar arm's embedding (:func:`build_planar`)."""
    g = manipulator.gravity
    lines = [
        '<mujoco model="dttmm-spatial-chain">',
        '  <compiler angle="radian" autolimits="true"/>',
        f'  <option timestep="{_f(h)}" integrator="{_MJCF_NAME[integrator]}" gravity="{_f(g)}"'
        + (f' tolerance="{_f(CLOSURE_SOLVER_TOL)}"' if manipulator.closures else "")
        + ">",
        '    <flag contact="disable" energy="enable"/>',
        "  </option>",
        "  <worldbody>",
        f'    <body name="base" pos="{_f(manipulator.base_xyz)}" quat="{_f(_quat(manipulator.base_rotation))}">',
    ]
    acts = []
    sites, equalities = closure_equalities(manipulator, k, h, angles) if manipulator.closures else ({}, [])

    def emit(i, depth, parent_tip):
        # link i's pieces nested in one another, its children inside its tip piece; the pieces'
        # closing tags after the children (a chain: the same text as one nested body list)
        link = manipulator.links[i]
        b, jn = link.beam, link.joint
        l = b.length / k
        Rr = _rx(b.roll)
        closers = []
        for j, (offset, m, c, J) in enumerate(piece_properties(link, k)):
            pad = " " * depth
            if j == 0:
                pos = np.array([parent_tip, 0.0, 0.0]) + np.array(jn.origin_xyz)
                quat = _quat(rpy_matrix(jn.origin_rpy))
                lines.append(f'{pad}<body name="link{i}_0" pos="{_f(pos)}" quat="{_f(quat)}">')
                if not jn.locked:
                    lines.append(f'{pad}  <joint name="arm{i}" type="hinge" axis="{_f(jn.axis)}"/>')
            else:
                lines.append(f'{pad}<body name="link{i}_{j}" pos="{_f(offset)}">')
                seq = STATION if (station == "hinges-zyx" or j % 2 == 1) else STATION[::-1]
                if station == PLANAR_STATION:
                    seq = STATION[:1]
                if station == "ball":
                    seq = ()
                    lines.append(f'{pad}  <joint name="ball{i}_{j}" type="ball"/>')
                    for _, axis, key in STATION:
                        stiff = getattr(b, key) / l
                        acts.append(
                            f'    <general joint="ball{i}_{j}" gear="{_f(Rr @ np.array(axis))} 0 0 0" gainprm="0" '
                            f'biastype="affine" biasprm="0 {_f(-stiff)} {_f(-b.damping * stiff)}"/>'
                        )
                for tag, axis, key in seq:
                    stiff = getattr(b, key) / l
                    lines.append(
                        f'{pad}  <joint name="{tag}{i}_{j}" type="hinge" axis="{_f(Rr @ np.array(axis))}" '
                        f'stiffness="{_f(stiff)}" damping="{_f(b.damping * stiff)}" springref="0"/>'
                    )
            ev = max(float(np.trace(J)) / 3.0, 1e-12)  # a placeholder (set_inertias)
            lines.append(inertial(pad, m, c, (ev, ev, ev)))
            if j == k:
                lines.append(f'{pad}  <site name="tip{i}" pos="{_f(l / 2 if k > 0 else 0.0)} 0 0"/>')
                lines.extend(f"{pad}  {x}" for x in sites.get(i, ()))
                for child in manipulator.children(i):
                    emit(child, depth + 2, l / 2)
            closers.append(f"{pad}</body>")
            depth += 2
        lines.extend(closers[::-1])

    for i in manipulator.children(-1):
        emit(i, 6, 0.0)
    lines.append("    </body>")
    lines.extend(f"    {x}" for x in sites.get(-1, ()))
    lines.append("  </worldbody>")
    if manipulator.closures:
        lines += ["  <equality>", *(f"    {x}" for x in equalities), "  </equality>"]
    lines.append("  <actuator>")
    for i in manipulator.unlocked:
        lines.append(f'    <motor name="drive{i}" joint="arm{i}" gear="1"/>')
    lines += acts
    lines += ["  </actuator>", "</mujoco>"]
    return "\n".join(lines)


#: the closures' equality constraints: solref (time constant in steps, damping ratio) and solimp
#: (impedance 0.9999 throughout: regularisation 1e-4 of the constraint's own inertia); the time
#: constant is the least MuJoCo's ``refsafe`` takes (2 steps): the stiffest stable constraint
CLOSURE_TIMECONST_STEPS, CLOSURE_DAMPRATIO = 2.0, 1.0
CLOSURE_SOLIMP = (0.9999, 0.9999, 0.001, 0.5, 2.0)
#: the constraint solver's tolerance with closures (MuJoCo's default 1e-8)
CLOSURE_SOLVER_TOL = 1e-12
#: a revolute closure: two ``connect`` constraints at the points ± d·axis about the joint, d this
#: fraction of the shorter of the two links (the ground: the link's length)
REVOLUTE_ARM = 0.5


def revolute_arm(manipulator, closure) -> float:
    """d (m): half the distance of a revolute closure's two connect points along its axis."""
    lengths = [manipulator.links[manipulator.link_index(closure.link)].beam.length]
    if closure.to != "ground":
        lengths.append(manipulator.links[manipulator.link_index(closure.to)].beam.length)
    return REVOLUTE_ARM * min(lengths)


def closure_equalities(manipulator, k: int, h: float, angles=None):
    """The closures as MJCF: ({link index (−1: the world): site lines on its tip piece}, equality
    lines). Spherical: one ``connect`` of a site at ``point`` (link's tip frame) to a site at
    ``to_point`` (to's). Revolute: two ``connect`` pairs at ``point`` ± d·axis and their images
    (:func:`revolute_arm`): the two points hold the axis, the rotation about it stays free (6
    equations of rank 5; MuJoCo's regularised constraint solver takes the redundant one). Weld:
    one ``weld`` of two sites whose frames coincide at the initial state. Attachment data from
    :func:`dttmm.spatial.topology.resolve_closures` at the links undeformed at ``angles``."""

    if angles is None:
        angles = np.zeros(manipulator.n_joints)
    R, p = rigid_tip_frames(manipulator, angles)
    rc = resolve_closures(manipulator, R, p)
    solref = (
        f'solref="{_f(CLOSURE_TIMECONST_STEPS * h)} {_f(CLOSURE_DAMPRATIO)}" solimp="{_f(CLOSURE_SOLIMP)}"'
    )
    sites, eqs = {}, []

    def site(i, name, pos, quat=None):
        # a site on link i's tip piece (origin l/2 behind the tip, the tip frame's axes) or the world
        off = np.array([manipulator.links[i].beam.length / k / 2, 0.0, 0.0]) if i >= 0 else np.zeros(3)
        q = f' quat="{_f(quat)}"' if quat is not None else ""
        sites.setdefault(i, []).append(f'<site name="{name}" pos="{_f(off + pos)}"{q}/>')

    for j, cl in enumerate(manipulator.closures):
        a, b = int(rc.a[j]), int(rc.b[j])
        if cl.kind == "revolute":
            d = revolute_arm(manipulator, cl)
            for c, sgn in enumerate((1.0, -1.0)):
                site(a, f"cl{j}_a{c}", rc.pa[j] + sgn * d * rc.ua[j])
                site(b, f"cl{j}_b{c}", rc.pb[j] + sgn * d * rc.ub[j])
                eqs.append(f'<connect name="closure{j}_{c}" site1="cl{j}_a{c}" site2="cl{j}_b{c}" {solref}/>')
        elif cl.kind == "spherical":
            site(a, f"cl{j}_a0", rc.pa[j])
            site(b, f"cl{j}_b0", rc.pb[j])
            eqs.append(f'<connect name="closure{j}_0" site1="cl{j}_a0" site2="cl{j}_b0" {solref}/>')
        else:
            site(a, f"cl{j}_a0", rc.pa[j], (1.0, 0.0, 0.0, 0.0))
            site(b, f"cl{j}_b0", rc.pb[j], _quat(rc.R0[j].T))
            eqs.append(f'<weld name="closure{j}_0" site1="cl{j}_a0" site2="cl{j}_b0" {solref}/>')
    return sites, eqs


def layout(m, manipulator, k: int) -> SpatialLayout:
    """Index maps of a compiled :func:`xml` model."""

    def jq(name):  # −1: no such joint
        j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, name)
        return int(m.jnt_qposadr[j]) if j >= 0 else -1

    def bid(name):
        return mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)

    n = manipulator.n_links
    flex = [[[jq(f"{tag}{i}_{j}") for tag, _, _ in STATION] for j in range(1, k + 1)] for i in range(n)]
    arm = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"arm{i}") for i in manipulator.unlocked]
    return SpatialLayout(
        arm_qpos=np.array([jq(f"arm{i}") for i in manipulator.unlocked], int),
        arm_dof=np.array([m.jnt_dofadr[j] for j in arm], int),
        flex_qpos=np.array(flex, int).reshape(n, k, 3),
        hub_body=np.array([bid(f"link{i}_0") for i in range(n)], int),
        tip_body=np.array([bid(f"link{i}_{k}") for i in range(n)], int),
        tip_site=np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"tip{i}") for i in range(n)], int),
    )


def build(
    manipulator: SpatialManipulator,
    k: int,
    h: float = 1e-3,
    integrator: str = "implicitfast",
    station="hinges",
    angles=None,
):
    """Compile the chain with the exact piece inertias: returns (MjModel, MjData, SpatialLayout).
    ``angles``: the joint angles at which the closures are assembled (:func:`xml`)."""
    plumbing.choice("station", station, (*STATIONS, PLANAR_STATION))
    if not isinstance(manipulator, SpatialManipulator):
        raise InputError("model", manipulator, "must be a dttmm.spatial.SpatialManipulator")
    k = plumbing.elements_per_link(k)
    m = mujoco.MjModel.from_xml_string(xml(manipulator, k, h, integrator, station, angles))
    set_inertias(m, manipulator.links, k, link_axes=station == PLANAR_STATION)
    d = mujoco.MjData(m)
    mujoco.mj_setConst(m, d)
    return m, d, layout(m, manipulator, k)


def build_planar(manipulator, k: int, h: float, integrator: str = "implicitfast", *, clamp_first=False):
    """Compile the chain of a planar arm (a ``dttmm.Manipulator``): its spatial embedding
    (:func:`dttmm.spatial.embed_planar`) built by :func:`build` with one hinge about the plane's
    normal z per station (:data:`PLANAR_STATION`), so the chain has the planar degrees of freedom
    alone. Returns (MjModel, MjData, ChainLayout).

    ``clamp_first`` locks arm joint 1 (link 1 welded to the ground): the clamped-free beam of
    the natural frequencies.
    """
    spatial = embed_planar(manipulator)
    if clamp_first:
        first = dataclasses.replace(spatial.links[0], joint=SpatialJoint(locked=True))
        spatial = dataclasses.replace(spatial, links=(first, *spatial.links[1:]))
    m, d, lay = build(spatial, k, h, integrator, PLANAR_STATION)
    arm = list(lay.arm_qpos)
    return (
        m,
        d,
        ChainLayout(
            arm_qpos=np.array([-1, *arm] if clamp_first else arm, int),
            flex_qpos=lay.flex_qpos[:, :, 0].copy(),
            hub_body=lay.hub_body,
            tip_body=lay.tip_body,
            tip_site=lay.tip_site,
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
