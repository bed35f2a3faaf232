"""The skeleton of the Exudyn peers, written once for the planar and the spatial ones.

The family: the planar chain :mod:`reference_models._exudyn2d` with its elements
:mod:`exudyn_ancf` (ObjectANCFCable2D) and :mod:`exudyn_beam` (ObjectBeamGeometricallyExact2D),
the spatial arm :mod:`reference_models._exudyn3d` with :mod:`exudyn_ancf3d` (ObjectANCFCable)
and :mod:`exudyn_beam3d` (ObjectBeamGeometricallyExact), and the natural modes
(:mod:`exudyn_modes`, :mod:`exudyn_modes3d`, :func:`exudyn_ancf3d.frequencies`). What they
share lives here: the import, the output grid (h divides the output step: sensors sample on the
step grid, no interpolation), the solver settings (generalized-α with a fixed step, modified
Newton, EigenSparse, one thread, no files), the integration segments (a drive breakpoint on the
step grid restarts the integrator), the segmented ``SolveDynamic`` run, the sensors (node
frames, beam nodes, bodies) and their stored rows on the output grid, gravity loads, the
pre-step function that sets the drive inputs, the link shapes from the beam nodes and the
eigenvalues of an assembled system. Each element adapter supplies only its bodies and nodes
and how its sensors become the Result's fields.
"""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np

from dttmm.errors import InputError
from dttmm.shapes import hermite_shapes, stations

__all__ = [
    "beam_elements",
    "beam_nodes",
    "body_sensor",
    "cable_properties",
    "dynamic_settings",
    "eigen_frequencies",
    "gravity_loads",
    "import_exudyn",
    "link_shapes",
    "node_sensors",
    "output_grid",
    "run_segments",
    "segments",
    "set_pre_step",
    "shape_sensors",
    "solve",
    "stored_rows",
]


def import_exudyn(who: str):
    """(exudyn, exudyn.itemInterface); ``who`` ("exudyn-ancf needs") opens the ImportError."""
    try:
        import exudyn as exu
        import exudyn.itemInterface as ii
    except ImportError as exc:
        raise ImportError(f"{who} the exudyn package (pip install 'dttmm[exudyn]'): {exc}") from exc
    return exu, ii


def output_grid(sc, h: float, why: str = "") -> tuple[int, int]:
    """(steps per output step, steps in the run): h must divide the output step (``why`` ends
    the InputError's message); the run ends at the last output time."""
    ratio = sc.output_step / h
    per_out = int(round(ratio))
    if per_out < 1 or abs(ratio - per_out) > 1e-9 * ratio:
        raise InputError("h", h, f"must divide the output step {sc.output_step}{why}")
    return per_out, (len(sc.output_times) - 1) * per_out


def segments(sc, h: float, n_steps: int, per_out: int):
    """Integration segments: a drive breakpoint on the step grid ends a segment and the next one
    restarts the integrator there (initial accelerations recomputed with the right limit).
    Returns (breakpoints on the grid, breakpoints off it, the step ranges, whether every range
    starts on the output grid)."""
    grid, off = [], []
    for b in sc.breakpoints:
        if b < n_steps * h:
            (grid if abs(b / h - round(b / h)) <= 1e-9 * max(1.0, b / h) else off).append(b)
    idx = [0] + [int(round(b / h)) for b in grid] + [n_steps]
    segs = [(a, b) for a, b in zip(idx, idx[1:]) if b > a]
    return grid, off, segs, all(a % per_out == 0 for a, _ in segs)


def dynamic_settings(
    exu, rho_inf, rel_tol, abs_tol, max_iterations, modified_newton, write_period, jacobian_per_step=True
):
    """Exudyn's generalized-α with a fixed step h (adaptive step off: a Newton failure is an
    error, not a silent step halving), modified Newton with a fresh Jacobian at every step by
    default (the reuse across steps thrashes at h >= 2e-3 on the suite's arms), EigenSparse, one
    thread, nothing written to files; sensors stored every ``write_period``. Returns (settings,
    its timeIntegration)."""
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
    ti.newton.modifiedNewtonJacUpdatePerStep = bool(jacobian_per_step)
    s.linearSolver.solverType = exu.LinearSolverType.EigenSparse
    s.parallel.numberOfThreads = 1
    s.solution.file.write = False
    s.solution.sensors.writePeriod = write_period
    s.show.computationTime = False
    s.show.statistics = False
    return s, ti


def set_pre_step(mbs, set_inputs, seg_start: list) -> None:
    """The PreStepUserFunction that sets the drive inputs once per step: at the end time t of the
    step about to be solved, the left limit of the laws there (the right limit at a segment
    start, where ``seg_start[0]`` is)."""

    def pre_step(mbs_, t):
        set_inputs(t, t > seg_start[0])
        return True

    mbs.SetPreStepUserFunction(pre_step)


def run_segments(mbs, exu, s, ti, segs, h, seg_start, set_inputs, rows, closed=None, quiet=False):
    """``SolveDynamic`` over the segments, restarting at each with the state carried over; the
    rows every sensor of ``rows`` stored go there (a segment's first row repeats the last one).
    ``closed``: the planar closed-loop joints (:class:`reference_models._exudyn_control.
    ClosedLoop`) or None; ``quiet``: Exudyn's allocation warning off (user functions that return
    new arrays). Returns a record: wall, cpu (s), steps, newton, jacobians, t_reached, it,
    start_solves, and where it stopped: ok (False: SolveDynamic failed), error (what it raised),
    short (a segment that ended early), None for all three after a complete run."""
    import exudyn.solver as exu_solver

    run = SimpleNamespace(wall=0.0, cpu=0.0, steps=0, newton=0, jacobians=0, t_reached=0.0, it=None)
    run.start_solves, run.ok, run.error, run.short = 0, True, None, None
    check = exu_solver.solverCheckMemoryAllocations
    if quiet:
        exu_solver.solverCheckMemoryAllocations = False
    try:
        for a, b in segs:
            ta, tb = a * h, b * h
            seg_start[0] = ta
            set_inputs(ta, False)  # right limit: the initial accelerations of the segment use it
            ti.startTime, ti.endTime, ti.numberOfSteps = ta, tb, b - a
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                if closed is not None:
                    closed.start_segment(mbs, ta)
                    if closed.needs_consistent_start:
                        run.start_solves += closed.consistent_start(mbs, exu, s)
                run.ok = bool(mbs.SolveDynamic(s, solverType=exu.DynamicSolverType.GeneralizedAlpha))
            except InputError:
                raise
            except Exception as exc:  # Exudyn raises on some failures (e.g. singular Jacobian)
                run.ok, run.error = False, exc
            run.wall += time.perf_counter() - t0
            run.cpu += time.process_time() - c0
            if closed is not None and closed.error is not None:
                raise closed.error  # a user law failed (InputError naming the time and the joint)
            it = run.it = mbs.sys["dynamicSolver"].it
            done = int(it.currentStepIndex) - 1  # 1-based: N + 1 after a complete run of N steps
            run.steps += max(done, 0)
            run.newton += int(it.newtonStepsCount)
            run.jacobians += int(it.newtonJacobiCount)
            run.t_reached = float(it.currentTime)
            for sn, r in rows.items():
                d = np.atleast_2d(np.asarray(mbs.GetSensorStoredData(sn), float))
                r.append(d if not r else d[1:])
            if not run.ok:
                break
            if done != b - a or not abs(run.t_reached - tb) <= 1e-9 * max(1.0, tb):
                run.short = (
                    f"segment [{ta}, {tb}] stopped after {done} of {b - a} steps at t = {run.t_reached}"
                )
                break
            sd = mbs.systemData
            sd.SetSystemState(sd.GetSystemState(exu.ConfigurationType.Current), exu.ConfigurationType.Initial)
            if closed is not None:  # the start guess of the next segment's ω̇ loop (not in the state)
                sd.SetODE2Coordinates_tt(sd.GetODE2Coordinates_tt(), exu.ConfigurationType.Initial)
    finally:
        exu_solver.solverCheckMemoryAllocations = check
    return run


def stored_rows(rows, output_step: float, per_out: int):
    """A function of a sensor giving its stored rows on the output grid (time column first)."""

    def stored(sn):
        d = np.concatenate(rows[sn], axis=0)
        x = d[:, 0] / output_step
        return d[np.abs(x - np.round(x)) <= 1e-6 * per_out]

    return stored


def solve(
    mbs, exu, sc, h, sensors, set_inputs, seg_start, newton, jacobian_per_step=True, closed=None, quiet=False
):
    """The assembled system over the scenario's output grid: :func:`segments`, the settings of
    :func:`dynamic_settings` (``newton``: rho_inf, relative and absolute tolerance, maximum
    iterations, modified Newton), :func:`run_segments` with ``sensors`` stored. Returns (the run
    with its ``restarts``, ``off_grid`` breakpoints and ``n_steps``, :func:`stored_rows`)."""
    per_out, n_steps = output_grid(sc, h)
    grid, off, segs, on_grid = segments(sc, h, n_steps, per_out)
    # sensors are written from each segment start every writePeriod: the output step when all
    # segments start on the output grid, else every step (rows off the grid are dropped)
    s, ti = dynamic_settings(exu, *newton, sc.output_step if on_grid else h, jacobian_per_step)
    rows = {sn: [] for sn in sensors}
    run = run_segments(mbs, exu, s, ti, segs, h, seg_start, set_inputs, rows, closed, quiet)
    run.restarts, run.off_grid, run.n_steps = grid, off, n_steps
    return run, stored_rows(rows, sc.output_step, per_out)


def node_sensors(mbs, ii, nodes, variables) -> list:
    """Per node, a tuple of sensors (one per output variable), stored internally."""
    return [
        tuple(
            mbs.AddSensor(
                ii.SensorNode(nodeNumber=nd, outputVariableType=v, storeInternal=True, writeToFile=False)
            )
            for v in variables
        )
        for nd in nodes
    ]


def body_sensor(mbs, ii, body, variable, local=None):
    """A sensor of a body (at its local point ``local`` where given), stored internally."""
    at = {} if local is None else {"localPosition": list(local)}
    return mbs.AddSensor(
        ii.SensorBody(
            bodyNumber=body, outputVariableType=variable, storeInternal=True, writeToFile=False, **at
        )
    )


def beam_nodes(mbs, elements) -> list:
    """The nodes of a link's beam elements in order, base to tip."""
    nodes = [int(mbs.GetObject(e)["nodeNumbers"][0]) for e in elements]
    return nodes + [int(mbs.GetObject(elements[-1])["nodeNumbers"][1])]


def shape_sensors(mbs, ii, link_elements, variables) -> list:
    """Per link and beam node (base to tip), its sensors: total coordinates of an ANCF node
    ((x, y, ∂r/∂s) in 2-D and 3-D) or a beam's rigid-body node ((x, y, θ) in 2-D; position and
    rotation matrix in 3-D)."""
    return [node_sensors(mbs, ii, beam_nodes(mbs, elements), variables) for elements in link_elements]


def link_shapes(links, nodes, p: int) -> np.ndarray:
    """Link shapes (nt, n, p, d) m from the beam nodes of the links (d = 2 or 3).

    ``nodes[i][j]`` (nt, w): node j of link i (at the reference arc length j·L/k): an ANCF node's
    position and slope ∂r/∂s (w = 4 or 6; the element's own interpolation), a 2-D beam node's
    (x, y, θ) (w = 3) or a 3-D beam node's position and row-major rotation matrix (w = 12). The
    centre line between nodes is the cubic Hermite curve of the node positions and slopes; a
    beam node's slope is taken as its cross-section direction ((cos θ, sin θ), the matrix's first
    column: shear and axial strain neglected in the slope, both O(1e-6) on the suite's arms).
    """
    out = []
    for link, nd in zip(links, nodes):
        c = np.stack(nd, axis=1)  # (nt, k + 1, w)
        w = c.shape[-1]
        if w == 3:
            pos, slope = c[..., :2], np.stack([np.cos(c[..., 2]), np.sin(c[..., 2])], axis=-1)
        elif w == 12:
            pos, slope = c[..., :3], c[..., [3, 6, 9]]
        else:
            pos, slope = c[..., : w // 2], c[..., w // 2 :]
        L = link.beam.length
        out.append(hermite_shapes(np.linspace(0.0, L, c.shape[1]), pos, slope, stations(L, p)))
    return np.stack(out, axis=1)


def beam_elements(mbs, item, nodes, **properties) -> list:
    """A beam element ``item`` (an itemInterface class) with ``properties`` between every two
    consecutive nodes, base to tip."""
    return [mbs.AddObject(item(nodeNumbers=[a, b], **properties)) for a, b in zip(nodes, nodes[1:])]


def cable_properties(beam, l, EI, EA) -> dict:
    """The element properties a cable and a 2-D beam share: length l, ρA, EI, EA and their
    Kelvin–Voigt damping μ·EI, μ·EA."""
    return dict(
        length=l,
        massPerLength=beam.rhoA,
        bendingStiffness=EI,
        axialStiffness=EA,
        bendingDamping=beam.damping * EI,
        axialDamping=beam.damping * EA,
    )


def gravity_loads(mbs, ii, bodies, g) -> None:
    """A mass-proportional load ``g`` on every body (or element) of ``bodies``."""
    for e in bodies:
        mbs.AddLoad(
            ii.LoadMassProportional(markerNumber=mbs.AddMarker(ii.MarkerBodyMass(bodyNumber=e)), loadVector=g)
        )


def modes_check(case, kind, name: str, elements_per_link, n) -> int:
    """What the eigenvalues at rest need: a case of ``kind`` (``name`` in the message), k, n None
    or ≥ 1, no gravity. Returns k."""
    from dttmm import plumbing

    if not isinstance(case, kind):
        raise InputError("case", case, f"must be a {name}")
    k = plumbing.elements_per_link(elements_per_link)
    if n is not None and (isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1):
        raise InputError("n", n, "must be an integer >= 1 (number of modes)")
    if any(case.model.gravity):
        raise InputError(
            "model.gravity",
            list(case.model.gravity),
            "the Exudyn eigenvalues are taken at rest, which is an equilibrium only without gravity",
        )
    return k


def modes_rest(case) -> None:
    """Torque-driven joints start at rest (modes at rest)."""
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "torque" and d.initial_rate != 0.0:
            raise InputError(
                f"scenario.drives[{i}].initial_rate", d.initial_rate, "must be 0 (modes at rest)"
            )


def eigen_frequencies(mbs, case, n, method: str) -> np.ndarray:
    """Natural frequencies (Hz) of an assembled Exudyn system: one rigid-body mode (ω² = 0 up to
    Exudyn's round-off) per torque-driven joint, then the elastic ones; ArithmeticError when the
    two are not separated. ``method`` names the peer in that message."""
    from exudyn.solver import ComputeODE2Eigenvalues

    lam, _ = ComputeODE2Eigenvalues(mbs, useAbsoluteValues=False, computeComplexEigenvalues=False)
    lam = np.sort(np.asarray(lam, float).real)
    n_rigid = sum(d.kind == "torque" for d in case.scenario.drives)
    rigid, rest = lam[:n_rigid], lam[n_rigid:]
    if rest.size and (np.any(np.abs(rigid) > 1e-3 * rest[0]) or rest[0] <= 0):
        raise ArithmeticError(
            f"{method} modes: rigid-body ω² {rigid} not separated from the elastic {rest[:1]}"
        )
    lam = np.concatenate([np.zeros(n_rigid), rest])
    lam = lam if n is None else lam[:n]
    return np.sqrt(lam) / (2 * np.pi)
