"""The parts both Exudyn 3-D peers share (:mod:`exudyn_beam3d`, :mod:`exudyn_ancf3d`): the
undeformed frames at t = 0, the solver settings, the segmented ``SolveDynamic`` run, the sensors
of the link frames and motion joints, and the conversion of what they stored into the
:class:`dttmm.spatial.SpatialResult` fields (link frames, tip deflections, twist, joint angles,
rates and torques) and into the static solution's fields.

An adapter builds its own model (elements, nodes, joints, bodies) and hands over the nodes
whose frame is the link's root and tip frame (``rolls``: the section roll Rx(roll) of the node
frames, None where the node frame is the link frame itself).
"""

from __future__ import annotations

import time

import numpy as np

from dttmm.errors import InputError, SimulationError
from dttmm.spatial import SpatialCase, load_case
from dttmm.spatial.rotation import log_so3

from ._spatial_mechanics import rot_axis, rpy_matrix

__all__ = [
    "as_case",
    "axis_frame",
    "dynamic_settings",
    "frame_outputs",
    "frame_sensors",
    "initial_joint_states",
    "joint_outputs",
    "motion_sensors",
    "reference_frames",
    "run_segments",
    "segments",
    "solve_static",
    "static_frames",
    "stored_reader",
]


def as_case(case) -> SpatialCase:
    """The case itself, or the spatial case read from a path; anything else is refused."""
    if isinstance(case, str) or hasattr(case, "__fspath__"):
        case = load_case(case)
    if not isinstance(case, SpatialCase):
        raise InputError("case", type(case).__name__, "must be a dttmm.spatial.SpatialCase or a path to one")
    return case


def axis_frame(a) -> np.ndarray:
    """A rotation A with A·e_z = a (columns: two unit vectors normal to a, then a)."""
    a = np.asarray(a, float)
    t = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(t, a)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(a, x), a])


def initial_joint_states(case: SpatialCase):
    """The joint angles and rates at t = 0, one per link (0 for a locked joint)."""
    alpha, rate = [], []
    drives = iter(case.scenario.drives)
    for link in case.model.links:
        if link.joint.locked:
            alpha.append(0.0)
            rate.append(0.0)
            continue
        d = next(drives)
        if d.kind == "motion":
            a = d.motion(0.0, False)
            alpha.append(float(a[0]))
            rate.append(float(a[1]))
        else:
            alpha.append(float(d.initial_angle))
            rate.append(float(d.initial_rate))
    return alpha, rate


def reference_frames(case: SpatialCase):
    """Undeformed frames at t = 0: per link (R_J, p_J, R_link, p_link, R_tip, p_tip, ω, a_W)
    with ω the rigid angular velocity of the link (world) from the initial joint rates and a_W
    the joint axis in the world; a link's joint hangs on its parent's tip frame (the base for a
    root link)."""
    m = case.model
    alpha, rate = initial_joint_states(case)
    out = []
    for i, link in enumerate(m.links):
        par = m.parents[i]
        if par < 0:
            R_par, p_par, om = rpy_matrix(m.base_rpy), np.array(m.base_xyz, float), np.zeros(3)
        else:
            R_par, p_par, om = out[par]["R_tip"], out[par]["p_tip"], out[par]["omega"]
        j = link.joint
        R_J = R_par @ rpy_matrix(j.origin_rpy)
        p_J = p_par + R_par @ np.array(j.origin_xyz, float)
        a = np.array(j.axis, float)
        aw = R_J @ a
        R_l = R_J @ rot_axis(a, alpha[i])
        om = om + aw * rate[i]
        L = link.beam.length
        p_t = p_J + R_l @ np.array([L, 0.0, 0.0])
        out.append(
            dict(R_J=R_J, p_J=p_J, R_link=R_l, p_link=p_J, R_tip=R_l, p_tip=p_t, omega=om.copy(), a_w=aw)
        )
    return out


def frame_sensors(mbs, ii, OV, nodes) -> list:
    """(position, rotation matrix, angular velocity) sensors of every node, stored internally."""

    def sens(nd, var):
        return mbs.AddSensor(
            ii.SensorNode(nodeNumber=nd, outputVariableType=var, storeInternal=True, writeToFile=False)
        )

    return [
        (sens(nd, OV.Position), sens(nd, OV.RotationMatrix), sens(nd, OV.AngularVelocity)) for nd in nodes
    ]


def motion_sensors(mbs, ii, OV, motion_joints: dict) -> dict:
    """The reaction-torque sensor (``TorqueLocal``) of every motion joint, by link."""
    return {
        i: mbs.AddSensor(
            ii.SensorObject(
                objectNumber=c, outputVariableType=OV.TorqueLocal, storeInternal=True, writeToFile=False
            )
        )
        for i, c in motion_joints.items()
    }


def dynamic_settings(exu, rho_inf, rel_tol, abs_tol, max_iterations, modified_newton):
    """Exudyn's generalized-α with a fixed step, modified Newton with a Jacobian per step,
    EigenSparse, one thread, no files: returns (settings, its timeIntegration)."""
    s = exu.SimulationSettings()
    ti = s.timeIntegration
    ti.adaptiveStep = False
    ti.verboseMode = 0
    ti.generalizedAlpha.spectralRadius = float(rho_inf)
    ti.generalizedAlpha.computeInitialAccelerations = True
    ti.newton.relativeTolerance = rel_tol
    ti.newton.absoluteTolerance = abs_tol
    ti.newton.maxIterations = max_iterations
    ti.newton.useModifiedNewton = bool(modified_newton)
    ti.newton.modifiedNewtonJacUpdatePerStep = True
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    s.parallel.numberOfThreads = 1
    s.solution.file.write = False
    s.show.computationTime = False
    s.show.statistics = False
    return s, ti


def segments(sc, h: float, n_steps: int, per_out: int):
    """The drive breakpoints on the step grid (where the integrator restarts), the step ranges
    between them, and whether every range starts on the output grid."""
    t_end = n_steps * h
    bps = [b for b in sc.breakpoints if 0 < b < t_end and abs(b / h - round(b / h)) <= 1e-9 * max(1.0, b / h)]
    idx = sorted({0, n_steps, *[int(round(b / h)) for b in bps]})
    segs = [(a, b) for a, b in zip(idx, idx[1:]) if b > a]
    return bps, segs, all(a % per_out == 0 for a, _ in segs)


def run_segments(mbs, exu, s, ti, segments, h, seg_start, set_inputs, sensors, rows):
    """SolveDynamic over the segments (restarting at each); the sensor rows go to ``rows``.
    Returns (wall, cpu, Newton iterations, steps, Jacobians, failure message or None, it)."""
    wall = cpu = 0.0
    newton = steps = jacobians = 0
    failure = it = None
    for a, b in segments:
        seg_start[0] = a * h
        set_inputs(a * h, False)
        ti.startTime, ti.endTime, ti.numberOfSteps = a * h, b * h, b - a
        t0, c0 = time.perf_counter(), time.process_time()
        try:
            ok = mbs.SolveDynamic(s, solverType=exu.DynamicSolverType.GeneralizedAlpha)
            err = None
        except Exception as exc:  # Exudyn raises on singular Jacobians
            ok, err = False, exc
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        it = mbs.sys["dynamicSolver"].it
        steps += max(int(it.currentStepIndex) - 1, 0)
        newton += int(it.newtonStepsCount)
        jacobians += int(it.newtonJacobiCount)
        for sn in sensors:
            d = np.atleast_2d(np.asarray(mbs.GetSensorStoredData(sn), float))
            rows[sn].append(d if not rows[sn] else d[1:])
        if not ok:
            failure = f"SolveDynamic failed at t = {float(it.currentTime)}" + (f": {err}" if err else "")
            break
        mbs.systemData.SetSystemState(
            mbs.systemData.GetSystemState(exu.ConfigurationType.Current), exu.ConfigurationType.Initial
        )
    return wall, cpu, newton, steps, jacobians, failure, it


def stored_reader(rows, sc, t_out, per_out: int, t_end: float, steps: int, method: str):
    """A function of a sensor giving its stored values on the output grid (nt, width); a count
    that misses the grid is a SimulationError."""

    def stored(sn):
        d = np.concatenate(rows[sn], axis=0)
        x = d[:, 0] / sc.output_step
        d = d[np.abs(x - np.round(x)) <= 1e-6 * per_out]
        if len(d) != len(t_out):
            raise SimulationError(
                f"Exudyn {method}: {len(d)} sensor rows for {len(t_out)} outputs",
                t=t_end,
                step=steps,
                component="sensors",
            )
        return d[:, 1:]

    return stored


def frame_outputs(stored, s_root, s_tip, nt: int, rolls=None, reach=None):
    """Link roots and tips (nt, n, 3), link and tip frames (nt, n, 3, 3) (the node frames with
    their section roll taken off), the root and tip angular velocities (nt, n, 3), the tip
    deflections (nt, n, 2) and the twist (nt, n). ``reach``: per link the tip's offset from its
    tip node in the tip frame (a rigid link's L·x), None where the tip node is the tip."""
    root = np.stack([stored(x[0]) for x in s_root], axis=1)
    if rolls is None:
        Rl = np.stack([stored(x[1]).reshape(nt, 3, 3) for x in s_root], axis=1)
        Rt = np.stack([stored(x[1]).reshape(nt, 3, 3) for x in s_tip], axis=1)
    else:
        Rl = np.stack([stored(x[1]).reshape(nt, 3, 3) @ rolls[i].T for i, x in enumerate(s_root)], axis=1)
        Rt = np.stack([stored(x[1]).reshape(nt, 3, 3) @ rolls[i].T for i, x in enumerate(s_tip)], axis=1)
    if reach is None:
        tip = np.stack([stored(x[0]) for x in s_tip], axis=1)
    else:
        tip = np.stack([stored(x[0]) + Rt[:, i] @ reach[i] for i, x in enumerate(s_tip)], axis=1)
    w_root = np.stack([stored(x[2]) for x in s_root], axis=1)
    w_tip = np.stack([stored(x[2]) for x in s_tip], axis=1)
    d = tip - root
    defl = np.stack(
        [np.einsum("tni,tni->tn", d, Rl[..., 1]), np.einsum("tni,tni->tn", d, Rl[..., 2])], axis=-1
    )
    n = root.shape[1]
    twist = np.array([[log_so3(Rl[t_, i].T @ Rt[t_, i])[0] for i in range(n)] for t_ in range(nt)])
    return root, tip, Rl, Rt, w_root, w_tip, defl, twist


def joint_outputs(case, Rl, Rt, w_root, w_tip, stored, s_mot, t_out):
    """Angles (unwrapped, continuing the initial angle), rates and torques (nt, m) of the
    unlocked joints: the angle from the relative rotation of the joint frame and the link frame
    about the axis; a motion drive's torque is its joint's reaction moment about the axis (0 at
    t = 0: no multiplier before the first step), a torque drive's its law."""
    model, sc = case.model, case.scenario
    nt = len(t_out)
    unl = list(model.unlocked)
    ja, jr, jt = np.zeros((nt, len(unl))), np.zeros((nt, len(unl))), np.zeros((nt, len(unl)))
    alpha0, _ = initial_joint_states(case)
    for c_, (i, dr) in enumerate(zip(unl, sc.drives)):
        j = model.links[i].joint
        a = np.array(j.axis, float)
        par = model.parents[i]
        if par < 0:
            R_par = np.broadcast_to(rpy_matrix(model.base_rpy), (nt, 3, 3))
            w_par = np.zeros((nt, 3))
        else:
            R_par, w_par = Rt[:, par], w_tip[:, par]
        R_J = R_par @ rpy_matrix(j.origin_rpy)
        rel = np.einsum("tji,tjk->tik", R_J, Rl[:, i])
        vee = 0.5 * np.stack(
            [rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0], rel[:, 1, 0] - rel[:, 0, 1]], -1
        )
        ang = np.unwrap(np.arctan2(vee @ a, 0.5 * (np.trace(rel, axis1=1, axis2=2) - 1.0)))
        ang += 2 * np.pi * round((alpha0[i] - ang[0]) / (2 * np.pi))
        ja[:, c_] = ang
        jr[:, c_] = np.einsum("ti,ti->t", w_root[:, i] - w_par, R_J @ a)
        if dr.kind == "motion":
            jt[:, c_] = stored(s_mot[i])[:, 2]
            jt[0, c_] = 0.0  # no multiplier before the first step (as the planar peers)
        else:
            jt[:, c_] = [dr.torque(float(t_), t_ > 0) for t_ in t_out]
    return ja, jr, jt


def solve_static(mbs, exu, kmax: float, steps: int, method: str) -> None:
    """``SolveStatic`` in ``steps`` load steps, Newton to 1e-12 relative (1e-14·kmax absolute);
    a failure is a SimulationError."""
    s = exu.SimulationSettings()
    s.staticSolver.newton.relativeTolerance = 1e-12
    s.staticSolver.newton.absoluteTolerance = 1e-14 * kmax
    s.staticSolver.numberOfLoadSteps = steps
    s.staticSolver.verboseMode = 0
    s.solution.file.write = False
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    if not mbs.SolveStatic(s):
        raise SimulationError(f"Exudyn {method}: SolveStatic failed", t=0.0, step=0, component="newton")


def static_frames(mbs, OV, root_nodes, tip_nodes, rolls=None, reach=None) -> dict:
    """The static solution's ``link_root``, ``link_tip`` (n, 3), ``tip_deflection`` (n, 2) (tip
    − root along the root frame's y and z) and ``twist`` (n,) (``rolls``, ``reach``: as
    :func:`frame_outputs`)."""
    root = np.array([mbs.GetNodeOutput(nd, OV.Position) for nd in root_nodes])

    def frame(nd, i):
        R = np.reshape(mbs.GetNodeOutput(nd, OV.RotationMatrix), (3, 3))
        return R if rolls is None else R @ rolls[i].T

    Rl = [frame(nd, i) for i, nd in enumerate(root_nodes)]
    Rt = [frame(nd, i) for i, nd in enumerate(tip_nodes)]
    if reach is None:
        tip = np.array([mbs.GetNodeOutput(nd, OV.Position) for nd in tip_nodes])
    else:
        tip = np.array([mbs.GetNodeOutput(nd, OV.Position) + R @ c for nd, R, c in zip(tip_nodes, Rt, reach)])
    d = tip - root
    return dict(
        link_root=root,
        link_tip=tip,
        tip_deflection=np.array([[di @ R[:, 1], di @ R[:, 2]] for di, R in zip(d, Rl)]),
        twist=np.array([log_so3(a.T @ b)[0] for a, b in zip(Rl, Rt)]),
    )
