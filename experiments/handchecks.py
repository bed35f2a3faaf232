"""Independent values for the spatial arms' checks (``dttmm validate``, the tests): the shipped
robots' rigid limit by Pinocchio's own reading of the unmodified URDF, the tool point's sag of
a robot arm with one flexible tube worked by hand from the cantilever formulas, and the rigid
five-bar's closed-form loop geometry. Nothing here runs a method under test.

See docs/validate.md ("The checks") and docs/urdf.md.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from pathlib import Path

import numpy as np

CASES = Path(__file__).resolve().parent / "cases" / "spatial"
ROBOTS = CASES / "robots"
TOPOLOGY = CASES / "topology"
#: E, G, ρ of aluminium 6061-T6 (ASM Aerospace Specification Metals data sheet)
ALUMINIUM = (68.9e9, 26.0e9, 2700.0)

__all__ = [
    "ALUMINIUM",
    "five_bar_tip",
    "pin_urdf_model",
    "rigid_robot_case",
    "robot_document",
    "robot_inverse_dynamics",
    "sag_case",
    "stiffened",
    "tool_displacement",
    "tube",
]


# ----------------------------------------------------------------------------- common
def stiffened(case, factor: float, axial: float | None = None):
    """The spatial ``case`` with every flexible link's stiffnesses GJ, EIy, EIz × ``factor`` and
    EA × ``axial`` (default ``factor``); rigid links unchanged."""
    axial = factor if axial is None else axial
    links = []
    for lk in case.model.links:
        if lk.rigid:
            links.append(lk)
            continue
        b = lk.beam
        ea = None if b.EA is None else b.EA * axial
        beam = dataclasses.replace(b, EA=ea, GJ=b.GJ * factor, EIy=b.EIy * factor, EIz=b.EIz * factor)
        links.append(dataclasses.replace(lk, beam=beam))
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=tuple(links)))


def shortened(case, duration: float, output_step: float | None = None):
    """``case`` run for ``duration`` s (and its output step, when given)."""
    sc = dataclasses.replace(case.scenario, duration=float(duration))
    if output_step is not None:
        sc = dataclasses.replace(sc, output_step=float(output_step))
    return dataclasses.replace(case, scenario=sc)


# ----------------------------------------------------------------------------- robots
def robot_document(name: str) -> dict:
    """The parsed case file ``experiments/cases/spatial/robots/<name>.toml``."""
    return tomllib.loads((ROBOTS / f"{name}.toml").read_text(encoding="utf-8"))


def rigid_robot_case(name: str, duration: float | None = None):
    """The shipped robot case ``name`` with every link rigid: the unmodified URDF (the case
    file without its ``flexible`` table: same joints, lock, tool, gravity and drives)."""
    from dttmm.urdf_import import case_from_urdf_dict

    doc = robot_document(name)
    doc["model"].pop("flexible", None)
    doc["name"] = f"{name}_rigid"
    case = case_from_urdf_dict(doc, ROBOTS)
    return case if duration is None else shortened(case, duration)


def pin_urdf_model(name: str):
    """(Pinocchio model, tool frame id or None) of the shipped robot ``name``'s URDF as
    Pinocchio reads it (``pin.buildModelFromUrdf``), its locked joints removed at zero
    (``pin.buildReducedModel``), the case file's gravity set."""
    import pinocchio as pin

    from dttmm.urdf_import import resolve_urdf

    m = robot_document(name)["model"]
    model = pin.buildModelFromUrdf(str(resolve_urdf(m["urdf"], ROBOTS)))
    lock = m.get("lock", [])
    if lock:
        model = pin.buildReducedModel(model, [model.getJointId(j) for j in lock], pin.neutral(model))
    model.gravity.linear = np.array(m.get("gravity", [0.0, 0.0, -9.81]), float)
    tool = m.get("tool")
    return model, (model.getFrameId(tool) if tool else None)


def robot_inverse_dynamics(name: str, case) -> dict:
    """Along the motion-driven ``case`` (every joint prescribed: the robot's drives), at its
    output times: the joint torques by Pinocchio's RNEA and the tool point by its forward
    kinematics, on the unmodified URDF (:func:`pin_urdf_model`). {"t", "torque" (nt, n), "tool"
    (nt, 3)}."""
    import pinocchio as pin

    model, tool = pin_urdf_model(name)
    data = model.createData()
    t = case.scenario.output_times
    drives = case.scenario.drives
    tau, pos = np.zeros((t.size, model.nv)), np.zeros((t.size, 3))
    for i, tt in enumerate(t):
        q, v, a = (np.array(x) for x in zip(*(d.motion(float(tt)) for d in drives)))
        tau[i] = pin.rnea(model, data, q, v, a)
        pin.framesForwardKinematics(model, data, q)
        pos[i] = data.oMf[tool].translation if tool is not None else data.oMi[model.njoints - 1].translation
    return {"t": t, "torque": tau, "tool": pos}


def tube(outer_diameter: float, wall: float, material=ALUMINIUM) -> dict:
    """EA, GJ, EI (both planes), ρA of a round tube, by hand: A = π(r_o² − r_i²), I = π(r_o⁴ −
    r_i⁴)/4, J = 2I."""
    E, G, rho = material
    ro = outer_diameter / 2
    ri = ro - wall
    area, inertia = math.pi * (ro**2 - ri**2), math.pi / 4 * (ro**4 - ri**4)
    return {"EA": E * area, "GJ": G * 2 * inertia, "EI": E * inertia, "rhoA": rho * area}


#: the sag checks: per robot, the link made a tube (its overlay in the shipped case file, the
#: URDF body kept at the beam's root), the joint that carries it, the next joint (the beam's
#: tip), and the base's roll-pitch-yaw (rad) that lays the tube horizontal with every joint at
#: zero (the statics hold the joints at zero): the UR5 stands on its base, its arm stretched out;
#: the Panda, upright at zero, lies on its back
SAG = {
    "ur5": ("upper_arm_link", "shoulder_lift_joint", "elbow_joint", (0.0, 0.0, 0.0)),
    "panda": ("panda_link2", "panda_joint2", "panda_joint3", (0.0, math.pi / 2, 0.0)),
}


def sag_case(name: str):
    """The shipped robot ``name`` with only the tube of :data:`SAG` flexible (the case file's
    overlay for it), its base turned as :data:`SAG` says, the joints held at zero (constant
    motion drives)."""
    from dttmm.urdf_import import case_from_urdf_dict

    link, _, _, rpy = SAG[name]
    doc = robot_document(name)
    doc["model"]["flexible"] = {link: doc["model"]["flexible"][link]}
    doc["model"]["base"] = {"rpy": list(rpy)}
    doc["name"] = f"{name}_sag"
    n = len(doc["scenario"]["drives"])
    doc["scenario"] = {
        "duration": 1.0,
        "output_step": 0.5,
        "drives": [{"kind": "motion", "law": "constant", "value": 0.0}] * n,
    }
    return case_from_urdf_dict(doc, ROBOTS)


def tool_displacement(name: str) -> dict:
    """The tool point's displacement (m, world) at rest under gravity of :func:`sag_case`, by
    hand: the tube a cantilever of length L from its joint to the next joint (both from
    Pinocchio's model of the URDF at zero), clamped there (the joints held; the URDF body rides
    on the joint), under its own weight w = ρA g, and the weight W of everything outboard
    (masses and centres from the URDF) at its centre: a tip force W and a tip moment M = r × W.
    The loads' parts across the beam bend it (δ = w⊥L⁴/8EI + W⊥L³/3EI + (M⊥ × x̂)L²/2EI,
    θ = x̂ × w⊥L³/6EI + x̂ × W⊥L²/2EI + M⊥L/EI), the moment about its axis twists it (φ = T L/GJ),
    the axial parts stretch it ((w∥L²/2 + W∥L)/EA); the tool point t moves by δ + θ × (t − tip).
    Worked in the base frame (gravity turned into it), returned in the world. The tube's data by
    hand (:func:`tube`) from the case file's section (Gere & Timoshenko, Mechanics of Materials,
    Appendix G; small deflections). {"rigid": the tool point of the rigid arm, "displacement":
    (3,), "sag": −displacement_z}."""
    import pinocchio as pin

    from dttmm.spatial.rotation import rpy_matrix

    link, joint, nxt, rpy = SAG[name]
    sec = robot_document(name)["model"]["flexible"][link]["section"]["tube"]
    t = tube(sec["outer_diameter"], sec["wall"])
    model, tool = pin_urdf_model(name)
    R = rpy_matrix(rpy)
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.zeros(model.nq))
    root = data.oMi[model.getJointId(joint)].translation
    j_tip = model.getJointId(nxt)
    tip = data.oMi[j_tip].translation
    pt = data.oMf[tool].translation.copy()
    g = R.T @ np.array(model.gravity.linear, float)
    outboard = [(j, model.inertias[j]) for j in range(j_tip, model.njoints)]  # a chain: the joints beyond
    mass = sum(i.mass for _, i in outboard)
    com = sum(i.mass * data.oMi[j].act(i.lever) for j, i in outboard) / mass
    L = float(np.linalg.norm(tip - root))
    x = (tip - root) / L
    w, F = t["rhoA"] * g, mass * g
    M = np.cross(com - tip, F)
    EI, GJ, EA = t["EI"], t["GJ"], t["EA"]

    def across(v):
        return v - (v @ x) * x

    u = (
        across(w) * L**4 / (8 * EI)
        + across(F) * L**3 / (3 * EI)
        + np.cross(across(M), x) * L**2 / (2 * EI)
        + x * ((w @ x) * L**2 / 2 + (F @ x) * L) / EA
    )
    theta = (
        np.cross(x, across(w)) * L**3 / (6 * EI)
        + np.cross(x, across(F)) * L**2 / (2 * EI)
        + across(M) * L / EI
        + x * (M @ x) * L / GJ
    )
    d = R @ (u + np.cross(theta, pt - tip))
    return {"rigid": R @ pt, "displacement": d, "sag": float(-d[2])}


# ----------------------------------------------------------------------------- the five-bar
def five_bar_tip(case, t) -> np.ndarray:
    """The rigid five-bar's distal tip (m, (nt, 3)) at the times t: the base angles from the
    motion laws of drives 0 and 2, the tip where the two distal circles about the proximal tips
    meet on the initial (upper) side."""
    m = case.model
    pl, pr = m.links[0], m.links[2]
    out = []
    for tt in np.atleast_1d(t):
        B = []
        for lk, d in ((pl, case.scenario.drives[0]), (pr, case.scenario.drives[2])):
            th = lk.joint.origin_rpy[2] + d.motion(float(tt))[0]
            B.append(np.array(lk.joint.origin_xyz[:2]) + lk.beam.length * np.array([np.cos(th), np.sin(th)]))
        L = m.links[1].beam.length
        mid, dv = 0.5 * (B[0] + B[1]), B[1] - B[0]
        h = np.sqrt(L * L - 0.25 * dv @ dv)
        nrm = np.array([-dv[1], dv[0]]) / np.linalg.norm(dv)
        out.append([*(mid + h * nrm), 0.0])
    return np.array(out)
