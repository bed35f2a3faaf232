"""``dttmm validate``: every check of a method against a published, closed-form or independent value.

For each method (built-in or outside, see :mod:`experiments.methods`) the suite runs

* every benchmark problem of ``experiments/cases/benchmarks/`` whose target is fixed in its
  ``[provenance]`` table (published, closed form or a recorded converged value) and whose case
  the method can model; pass/fail is decided by the benchmark-problems study's own rule
  (:func:`experiments.studies.problems._row`: the provenance tolerance, relative or absolute)
  at the largest k of a three-point ladder, and the observed order in k is fitted over the ladder;
  problems compared against a *reference run* are listed as not run (the report runs them);
* the independent checks: the rigid limit against Pinocchio (:func:`rigid_limit`), the static
  deflection of a cantilever against the Euler-Bernoulli closed form (:func:`static_deflection`),
  the clamped-beam natural frequencies against the β_nL closed form (:func:`clamped_frequencies`),
  the energy balance of an undamped free swing (:func:`energy_balance`), and the observed order in
  k and in h against finer runs of the same method (:func:`order_k`, :func:`order_h`);
* for methods with a spatial entry (``spatial`` in the record, docs/methods.md) the spatial
  benchmark problems (``experiments/cases/spatial/``: the Princeton beam, the 45° bend, the
  right-angle cantilever, :data:`experiments.studies.problems.SPATIAL_PROBLEMS`) at their own k
  ladders (:attr:`Size.spatial_ks`), and two spatial independent checks: the spatial rigid limit
  against Pinocchio's rigid spatial arm (:func:`spatial_rigid_limit`) and the spatial cantilever
  statics in both bending planes and twist against the closed forms
  (:func:`spatial_static_deflection`); on the shipped robots (``experiments/cases/spatial/
  robots/``) the rigid limit against Pinocchio's own reading of the URDF (:func:`robot_rigid_limit`),
  the tool sag against the cantilever worked by hand (:func:`robot_statics`) and the energy of a
  free swing (:func:`robot_energy`); on the shipped trees and loops (``experiments/cases/spatial/
  topology/``) the link tips against the spatial global solver (:func:`topology_global`), the
  closure gap (:func:`topology_closure`) and the stiff five-bar against its closed-form loop
  geometry (:func:`five_bar_rigid`); the independent values in :mod:`experiments.handchecks`.
  A method without a spatial entry gets these rows as not run, with the reason.

Each check returns rows (plain dicts, :data:`ROW_KEYS`); a check a method cannot run is a row
with ``passed = None`` and the reason. Every simulation runs in a forked child process with a
per-run timeout (:data:`SIZES`), so a method that raises, returns a malformed Result or hangs
becomes a failed row with a one-line reason; validate itself never crashes on a bad method.

Command line: ``python -m experiments.validate`` or ``dttmm validate`` (:func:`main`); the
terminal table, ``DIR/scorecard.json`` and the HTML pages ``DIR/index.html`` and
``DIR/<method>.html`` (:mod:`reports.validate_page`). See docs/validate.md.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import math
import multiprocessing.connection
import os
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from . import methods
from .studies import problems as problems_study

__all__ = [
    "CHECKS",
    "ROW_KEYS",
    "SIZES",
    "Worker",
    "clamped_frequencies",
    "energy_balance",
    "five_bar_rigid",
    "main",
    "malformed",
    "order_h",
    "order_k",
    "rigid_limit",
    "robot_energy",
    "robot_rigid_limit",
    "robot_statics",
    "scorecard_links",
    "spatial_rigid_limit",
    "spatial_static_deflection",
    "static_deflection",
    "topology_closure",
    "topology_global",
    "validate_method",
]

EXIT_OK, EXIT_FAILED, EXIT_INPUT = 0, 1, 2
ROOT = Path(__file__).resolve().parents[1]  # the source tree holding experiments/ and dttmm/

#: The keys of every scorecard row.
ROW_KEYS = (
    "method",
    "check",
    "problem",
    "quantity",
    "value",
    "reference",
    "source",
    "tolerance",
    "tolerance_kind",
    "passed",
    "reason",
    "order",
    "k",
    "h",
    "cpu_time",
)


@dataclass(frozen=True)
class Size:
    """What one size of the suite runs.

    ks : k ladder of the benchmark problems, the static and the frequency checks (pass/fail at
        the largest, observed order over all three)
    spin_up : the spin-up problems run, and their duration (s; None = the file's)
    rigid_duration, energy_duration, order_duration : durations (s) of those checks' runs
    order_ks, order_k_fine : k ladder of the order-in-k check and the finer run it is measured against
    order_hs, order_h_fine, order_h_k : h ladder of the order-in-h check, its finer step, its k
    timeout : s per simulation (a run past it is a failed row)
    spatial_ks : problem -> k ladder of the spatial benchmark problems (their cost: the
        Princeton sweep is 14 equilibria per k, the 45° bend has 8 links)
    spatial_rigid_duration : duration (s) of the spatial rigid-limit run
    robot_duration, robot_energy_duration : durations (s) of the robots' rigid-limit and
        energy runs
    topology_duration : duration (s) of the trees' and loops' runs against the global solver
    """

    ks: tuple = (8, 16, 32)
    spin_up: tuple = ("spin_up_w4", "spin_up_w6", "spin_up_w10")
    spin_duration: float | None = None
    rigid_duration: float = 2.0
    energy_duration: float = 1.0
    order_duration: float = 1.0
    order_ks: tuple = (2, 4, 8)
    order_k_fine: int = 32
    order_hs: tuple = (4e-3, 2e-3, 1e-3)
    order_h_fine: float = 1.25e-4
    order_h_k: int = 4
    timeout: float = 600.0
    durations: tuple = ()
    explicit_ks: tuple = (8, 16, 32)
    spatial_ks: tuple = (
        ("princeton_beam", (8, 16, 32)),
        ("bend_45deg", (1, 2, 4)),
        ("right_angle_cantilever", (8, 16, 32)),
    )
    spatial_rigid_duration: float = 1.0
    robot_duration: float = 0.5
    robot_energy_duration: float = 0.5
    topology_duration: float = 0.1


#: The quick size drops the spin-up problems at ω_s = 6 and 10 rad/s and shortens the one at
#: 4 rad/s to 8 s (its peak comes before 7 s), runs the self-weight cantilever 10 s (its quick
#: size, see its provenance), halves the rigid-limit, energy and order runs, refines h only to
#: 2.5e-4 s, gives explicit methods with a ``max_step`` the k ladder 4, 8, 16 instead of 8, 16,
#: 32, and the spatial problems shorter ladders; the per-run timeout is 60 s.
SIZES = {
    "full": Size(),
    "quick": Size(
        spin_up=("spin_up_w4",),
        spin_duration=8.0,
        rigid_duration=1.0,
        energy_duration=0.5,
        order_duration=0.5,
        order_h_fine=2.5e-4,
        timeout=60.0,
        durations=(("cantilever_self_weight", 10.0),),
        explicit_ks=(4, 8, 16),
        spatial_ks=(
            ("princeton_beam", (2, 4, 8)),
            ("bend_45deg", (1, 2)),
            ("right_angle_cantilever", (4, 8, 16)),
        ),
        spatial_rigid_duration=0.5,
        robot_duration=0.2,
        robot_energy_duration=0.2,
        topology_duration=0.05,
    ),
}


# ----------------------------------------------------------------------------- running one method
def _serve(conn, spec):
    """The worker: load the method by its spec, then answer (fn, args) requests until told to stop."""
    try:
        methods.load_spec(spec)
        conn.send(("ready", None, 0.0))
    except BaseException as exc:  # noqa: BLE001 - reported to the parent
        conn.send(("error", _one_line(exc), math.nan))
        return
    while True:
        try:
            msg = conn.recv()
        except (EOFError, OSError):
            return
        if msg is None:
            return
        fn, args = msg
        try:
            t0 = time.process_time()
            out = fn(*args)
            reply = ("ok", out, time.process_time() - t0)
        except BaseException as exc:  # noqa: BLE001 - every failure goes back as one line
            reply = ("error", _one_line(exc), math.nan)
        try:
            conn.send(reply)
        except Exception as exc:  # noqa: BLE001 - e.g. a value that does not pickle
            conn.send(("error", f"its output cannot be sent back: {_one_line(exc)}", math.nan))


def _worker_main(fd: int, spec: str) -> None:
    """Entry of the worker process (``python -m experiments.validate --worker FD SPEC``)."""
    sock = socket.socket(fileno=fd)
    conn = multiprocessing.connection.Connection(sock.detach())
    _serve(conn, spec)


def _one_line(exc) -> str:
    msg = " ".join(str(exc).split())[:300]
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


class Worker:
    """A child process that runs one method's calls, each within ``timeout`` s; a call past it
    kills the child (the next call starts a fresh one). The method is loaded in the child from
    its spec (a registered name, module:function, file.py:function or entry point)."""

    START_TIMEOUT = 120.0  # s to import the suite and load the method

    def __init__(self, spec: str, timeout: float):
        self.spec, self.timeout = spec, timeout
        self._proc = self._conn = None

    def _start(self) -> str:
        mine, theirs = socket.socketpair()
        env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
        env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *filter(None, [env.get("PYTHONPATH")])])
        fd = theirs.fileno()
        self._proc = subprocess.Popen(
            [sys.executable, "-m", "experiments.validate", "--worker", str(fd), self.spec],
            pass_fds=(fd,),
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        theirs.close()
        self._conn = parent = multiprocessing.connection.Connection(mine.detach())
        if not parent.poll(self.START_TIMEOUT):
            self.stop()
            return f"the worker did not start within {self.START_TIMEOUT:g} s"
        try:
            status, out, _ = parent.recv()
        except EOFError:
            self.stop()
            return "the worker died while loading the method"
        if status != "ready":
            self.stop()
            return f"cannot load the method in the worker: {out}"
        return ""

    def call(self, fn, *args):
        """(value or None, CPU time of the call in the worker (s), reason '' or one line)."""
        if self._proc is None or self._proc.poll() is not None:
            why = self._start()
            if why:
                return None, math.nan, why
        try:
            self._conn.send((fn, args))
        except Exception as exc:  # noqa: BLE001
            self.stop()
            return None, math.nan, f"cannot send the run to the worker: {_one_line(exc)}"
        if not self._conn.poll(self.timeout):
            self.stop()
            return None, math.nan, f"no answer within the per-run timeout of {self.timeout:g} s (killed)"
        try:
            status, out, cpu = self._conn.recv()
        except EOFError:
            code = self._proc.wait(5)
            self.stop()
            return None, math.nan, f"the run's process died (exit code {code})"
        return (out, cpu, "") if status == "ok" else (None, math.nan, out)

    def stop(self):
        if self._conn is not None:
            try:
                self._conn.send(None)
            except Exception:  # noqa: BLE001, S110 - already gone
                pass
            self._conn.close()
        if self._proc is not None:
            try:
                self._proc.wait(1)
            except subprocess.TimeoutExpired:
                self._proc.kill()
                self._proc.wait(5)
        self._proc = self._conn = None


def _simulate(name, case, k, h):
    """One run of a registered method, in the worker: the Result (or the exception)."""
    return methods.run(name, case, k, h)


def expected_grid(case) -> np.ndarray:
    """The output times every method returns: 0, output_step, ..., duration (s)."""
    sc = case.scenario
    n = int(round(sc.duration / sc.output_step))
    return np.arange(n + 1) * sc.output_step


def malformed(res, case) -> str:
    """Why ``res`` is not a usable Result of ``case`` ('' when it is): not a Result, status
    "failed", wrong shapes, a time grid other than the case's output grid (e.g. in ms), NaN."""
    need = ("t", "joint_angle", "tip_deflection", "end_effector")
    if not all(hasattr(res, a) for a in need):
        return f"returned a {type(res).__name__}, not a dttmm.Result"
    if getattr(res, "status", "ok") == "failed":
        return "the method reported failure: " + ("; ".join(getattr(res, "warnings", ())) or "no reason")
    if methods.is_spatial(case):
        from .runs import malformed as spatial_malformed

        why = spatial_malformed(res, case)
        if why:
            return f"malformed Result: {why}"
        for a in ("end_effector", "link_tip", "joint_angle"):
            if not np.all(np.isfinite(np.asarray(getattr(res, a), float))):
                return f"non-finite output ({a} has NaN or inf)"
        return ""
    n = case.model.n_links
    t = np.asarray(res.t, float)
    grid = expected_grid(case)
    shapes = {
        "t": (len(grid),),
        "joint_angle": (len(grid), n),
        "tip_deflection": (len(grid), n),
        "end_effector": (len(grid), 2),
    }
    for a, shape in shapes.items():
        got = np.shape(getattr(res, a))
        if got != shape:
            return f"malformed Result: {a} has shape {got}, expected {shape}"
    if not np.allclose(t, grid, rtol=0, atol=1e-9 * max(1.0, grid[-1])):
        return (
            f"malformed Result: time grid {t[0]:g} … {t[-1]:g} s is not the case's output grid "
            f"0 … {grid[-1]:g} s (wrong units of time?)"
        )
    for a in need[1:]:
        if not np.all(np.isfinite(np.asarray(getattr(res, a), float))):
            return f"non-finite output ({a} has NaN or inf)"
    return ""


class Runner:
    """Runs one method: every simulation in its :class:`Worker` with the size's timeout, results
    cached per (case, k, h) within this validation."""

    def __init__(self, name: str, size: Size, spec: str | None = None):
        self.name, self.size = name, size
        self.rec = methods.get(name)
        self.worker = Worker(spec or name, size.timeout)
        self._memo: dict = {}

    @property
    def step_unknown(self) -> str:
        """Why the method cannot be given a fixed step ('' when it can): explicit with no
        ``max_step`` in its record, so no step is known to be stable for it."""
        if self.rec.explicit and self.rec.max_step is None:
            return (
                "explicit in time with no max_step in its record: no step is known to be stable for it "
                "(this check runs at a fixed h)"
            )
        return ""

    @property
    def ks(self) -> tuple:
        """The k ladder of the benchmark, static and frequency checks for this method."""
        return self.size.explicit_ks if self.rec.explicit and self.rec.max_step else self.size.ks

    def step(self, k, h, case=None):
        """h, lowered to the record's ``max_step(k)`` for an explicit method (its
        ``spatial_max_step(k)`` on a spatial ``case``, where it has one)."""
        rule = methods.step_rule(self.rec, case)
        if self.rec.explicit and rule is not None:
            return min(h, float(rule(k)))
        return h

    def run(self, case, k, h):
        """(Result or None, CPU time (s), reason '')."""
        key = (repr(case), k, h)
        if key not in self._memo:
            res, cpu, why = self.worker.call(_simulate, self.name, case, k, h)
            if not why:
                why = malformed(res, case)
            self._memo[key] = (None if why else res, cpu, why)
        return self._memo[key]

    def run_at_step(self, case, k, h):
        """:meth:`run` at :meth:`step`'s h: (that h, Result or None, CPU time (s), reason '')."""
        h = self.step(k, h, case)
        return (h, *self.run(case, k, h))

    def call(self, fn, *args):
        return self.worker.call(fn, *args)


# ----------------------------------------------------------------------------- rows
def _row(method, check, problem, quantity, **kw) -> dict:
    row = dict.fromkeys(ROW_KEYS)
    row.update(method=method, check=check, problem=problem, quantity=quantity, reason="")
    row.update(kw)
    for key in ("value", "reference", "tolerance", "order", "cpu_time", "h"):
        v = row[key]
        if isinstance(v, (float, np.floating)) and not math.isfinite(v):
            row[key] = None
        elif isinstance(v, (np.floating, np.integer)):
            row[key] = v.item()
    return row


def _not_run(method, check, problem, quantity, reason, **kw) -> list:
    return [_row(method, check, problem, quantity, passed=None, reason=reason, **kw)]


@dataclass(frozen=True)
class _Quantity:
    """One compared quantity of a check: the fields each of its rows carries (``fields``: source,
    tolerance, tolerance_kind and reference)."""

    method: str
    check: str
    problem: str
    quantity: str
    fields: dict

    def not_run(self, reason) -> list:
        return _not_run(self.method, self.check, self.problem, self.quantity, reason, **self.fields)

    def measured(self, value, reason, relative=False, **kw) -> dict:
        """The row of a measured ``value`` (None: no value, ``reason`` says why), passed when its
        deviation is within the tolerance: with ``relative`` |value − reference| / |reference|,
        else the value itself (a deviation from the reference 0)."""
        f, err = self.fields, value
        if value is not None and relative:
            err = abs(value - f["reference"]) / abs(f["reference"])
        passed = err is not None and err <= f["tolerance"]
        return _row(
            self.method,
            self.check,
            self.problem,
            self.quantity,
            value=value,
            passed=passed,
            reason=reason,
            **f,
            **kw,
        )


def _needs(case) -> list:
    """The capabilities a case asks of a method."""
    need = {d.kind if d.kind in ("torque", "motion") else "closed_loop" for d in case.scenario.drives}
    if any(case.model.gravity):
        need.add("gravity")
    if any(link.beam.damping for link in case.model.links):
        need.add("damping")
    if any(
        (link.hub and (link.hub.mass or link.hub.inertia))
        or (link.payload and (link.payload.mass or link.payload.inertia))
        for link in case.model.links
    ):
        need.add("payload")
    return sorted(need)


def _missing(rec, needs) -> str:
    """'' when ``rec`` has every capability in ``needs``, else the reason."""
    lack = [c for c in needs if not rec.has(c)]
    return (
        f"{rec.label or rec.name} has no {', '.join(methods.CAPABILITIES[c] for c in lack)}" if lack else ""
    )


def _fit(xs, errs) -> float:
    """Slope of log err against log x (least squares) over the points with a positive finite
    error; NaN with fewer than two."""
    pts = [(x, e) for x, e in zip(xs, errs) if e is not None and np.isfinite(e) and e > 0]
    if len(pts) < 2:
        return math.nan
    lx, le = np.log([p[0] for p in pts]), np.log([p[1] for p in pts])
    return float(np.polyfit(lx, le, 1)[0])


def order_in_k(ks, errs) -> float:
    """Observed order p of err ∝ k^-p."""
    return -_fit(ks, errs)


def _error_order(ks, values, target):
    """The observed order in k of |value − target| over the ladder ``ks`` (None: not found)."""
    return _nan_none(order_in_k(ks, [abs(v - target) if v is not None else None for v in values]))


# ----------------------------------------------------------------------------- benchmark problems
def _bench_value(prov, case, res) -> tuple:
    """(value, note) of a benchmark run, from the benchmark-problems study's extractors."""
    kind = prov["quantity"]
    if kind == "peak_tip_deflection":
        return problems_study.peak_tip_deflection(res), ""
    if kind == "static_tip_displacement":
        v, moved = problems_study.tip_displacement(res, case, prov["component"])
        note = (
            ""
            if moved < problems_study.SETTLE_TOL
            else f"not at rest: the tip moved {moved:.2g} m over the last second"
        )
        return v, note
    raise ValueError(f"no extractor for {kind!r}")


def _frequencies(name, case, k, n):
    """The method's lowest n natural frequencies (Hz), in the child (see :func:`linearisation`)."""
    fn = linearisation(name)
    return np.asarray(fn(case, k, n), float)


def linearisation(name: str):
    """``f(case, k, n) -> Hz`` of a method with the "modes" capability, or None when none is
    reachable: DT-TMM methods use :func:`dttmm.modes` with their strain option; the benchmark-problems
    study's linearisations (:func:`experiments.studies.problems.frequencies`) by name; an
    outside function may carry one as its ``frequencies`` attribute."""
    rec = methods.get(name)
    if rec.module == "dttmm":
        strain = dict(rec.options).get("strain", "linear")

        def f(case, k, n):
            import dttmm

            return dttmm.modes(case, k, n=n, strain=strain).frequencies

        return f
    if rec.simulate is not None:
        return getattr(rec.simulate, "frequencies", None)
    if rec.module is None:
        return None
    # the benchmark-problems study's dispatch knows a few built-in linearisations by name; one it does
    # not know raises ValueError("frequencies: no linearisation ...") in the worker (see _NO_LIN)
    return lambda case, k, n: problems_study.frequencies(case, k, name, n=n)


def _no_lin(got) -> bool:
    """Whether every answer of a frequency check says the study has no linearisation for it."""
    return all("no linearisation for method" in why for _, _, why in got)


def _published(prov) -> bool:
    return prov.get("value_kind") != "reference run"


def benchmark_problem(run: Runner, problem: str, case, prov) -> list:
    """Rows of one benchmark problem: each compared quantity at the largest k of the ladder,
    pass/fail by the benchmark-problems study's rule, observed order in k over the ladder."""
    rec, ks = run.rec, run.ks
    src = prov.get("source", "")
    check = "benchmark"
    quantities = targets = problems_study.targets(prov)
    tol = float(prov["tolerance"])
    kw = dict(source=src, tolerance=tol, tolerance_kind=prov["tolerance_kind"])
    if not _published(prov):
        r = prov["reference"]
        return _not_run(
            rec.name,
            check,
            problem,
            prov["quantity"],
            f"its target is a reference run ({r['method']}, k = {r['k']}, h = {r['h']} s), not a published "
            "or closed-form value: the report's benchmark-problems study runs it",
            **kw,
        )
    kind = prov["quantity"]
    if methods.is_spatial(case):
        return _spatial_problem(run, problem, case, prov)

    def not_run(why):
        return [_not_run(rec.name, check, problem, q, why, reference=v, **kw)[0] for q, v in quantities]

    if rec.physics.strain == "rigid":
        return not_run(_RIGID)
    if kind == "frequencies":
        if not rec.has("modes"):
            return not_run(_missing(rec, ["modes"]))
        if linearisation(rec.name) is None:
            return not_run(_NO_LIN.format(rec.name))
        got = [run.call(_frequencies, rec.name, case, k, len(targets)) for k in ks]
        if _no_lin(got):
            return not_run(_NO_LIN.format(rec.name))
        rows = []
        for i, (q, target) in enumerate(targets):
            vals = [None if why else float(f[i]) for f, _, why in got]
            cpu = sum(c for _, c, _ in got if np.isfinite(c))
            # order: differences to the finest k (the published values are rounded to 0.01 Hz)
            diffs = [abs(v - vals[-1]) if v is not None and vals[-1] is not None else None for v in vals[:-1]]
            rows.append(
                _judge(rec.name, check, problem, q, target, vals[-1], prov, got[-1][2], ks, cpu, **kw)
            )
            rows[-1]["order"] = _nan_none(order_in_k(ks[:-1], diffs))
        return rows
    why = _missing(rec, _needs(case)) or run.step_unknown
    if why:
        return _not_run(rec.name, check, problem, kind, why, reference=targets[0][1], **kw)
    h = problems_study.step_of(prov)

    def value(res):
        try:
            return _bench_value(prov, case, res)
        except Exception as exc:  # noqa: BLE001 - an extractor failing on odd output is a failed row
            return None, f"{type(exc).__name__}: {exc}"

    vals, cpu, reason = _ladder(run, case, ks, h, value)
    target = targets[0][1]
    row = _judge(rec.name, check, problem, kind, target, vals[-1], prov, reason, ks, cpu, **kw)
    row["h"] = run.step(ks[-1], h)
    row["order"] = _error_order(ks, vals, target)
    return [row]  # the study's rule decides: a run not quite at rest is noted in the reason only


def _ladder(run, case, ks, h, value) -> tuple:
    """Runs of ``case`` at every k of ``ks`` (step h, lowered for an explicit method) and the
    (value, note) ``value(res)`` of each: (values, None where a run failed; CPU time (s); the
    reason: the last failed run's, else the largest k's note)."""
    vals, cpu, reason = [], 0.0, ""
    for k in ks:
        res, c, why = run.run(case, k, run.step(k, h))
        cpu += c if np.isfinite(c) else 0.0
        if why:
            vals.append(None)
            reason = f"k = {k}: {why}"
            continue
        v, note = value(res)
        vals.append(v)
        if k == ks[-1] and note:
            reason = note
    return vals, cpu, reason


_RIGID = "rigid links: the problem's quantity is a deformation, which a rigid model does not have"
_NO_LIN = (
    "{0} claims natural modes, but no linearisation of it is reachable here (a DT-TMM method, one the "
    "benchmark-problems study knows, or an outside function's 'frequencies' attribute)"
)


def _nan_none(v):
    return None if v is None or not np.isfinite(v) else float(v)


def _judge(method, check, problem, quantity, target, value, prov, reason, ks, cpu, scale=None, **kw) -> dict:
    """A row judged by the benchmark-problems study's rule (provenance tolerance, relative or
    absolute; a relative error to ``scale`` where given)."""
    r = {"method": method, "k": ks[-1], "h": math.nan, "status": "ok" if value is not None else "failed"}
    judged = problems_study._row(
        problem, prov, quantity, target, r, math.nan if value is None else value, scale
    )
    kw = {**kw, "tolerance": judged["tolerance"]}
    passed = judged["passed"] if value is not None else False
    if value is None and not reason:
        reason = "no value"
    return _row(
        method,
        check,
        problem,
        quantity,
        value=value,
        reference=target,
        passed=bool(passed),
        reason=reason,
        k=ks[-1],
        cpu_time=cpu,
        **{**kw, "tolerance_kind": judged["tolerance_kind"]},
    )


# ----------------------------------------------------------------------------- spatial problems
def _spatial_statics(name, case, k, steps):
    """The method's own statics (:func:`experiments.studies.problems.statics_of`), in the worker:
    (tip position (3,), twist (rad, NaN when not given))."""
    fn = problems_study.statics_of(name)
    if fn is None:
        raise ValueError(f"{name}: no spatial statics")
    return problems_study.tip_and_twist(fn(case, int(k), int(steps)))


def _no_spatial(rec, case) -> str:
    """Why the method does not run this spatial case ('' when it does)."""
    why = rec.why_not_case(case)
    if why:
        return f"{rec.label or rec.name}: {why}"
    return ""


def _statics_unknown(rec, case) -> str:
    """Why a check of the method's own spatial statics on ``case`` does not run ('' when it does):
    rigid links, the case refused, no spatial statics."""
    why = (_RIGID if rec.physics.strain == "rigid" else "") or _no_spatial(rec, case)
    if not why and problems_study.statics_of(rec.name) is None:
        why = _NO_STATICS.format(rec.label or rec.name).replace("this problem", "this check")
    return why


_NO_STATICS = (
    "{0} has no spatial statics (DT-TMM's dttmm.spatial.statics, Exudyn's SolveStatic, or an outside "
    "spatial function's 'statics' attribute): this problem is an equilibrium"
)


def _spatial_problem(run: Runner, problem: str, case, prov) -> list:
    """Rows of a spatial benchmark problem at the problem's k ladder (:attr:`Size.spatial_ks`):
    the static ones by the method's own statics, the right-angle cantilever by a run at the
    study's step; each compared quantity judged at the largest k by the study's rule, the
    observed order in k over the ladder."""
    rec = run.rec
    ks = tuple(dict(run.size.spatial_ks).get(problem, run.size.ks))
    trows = problems_study.target_rows(prov)
    check, kind = "benchmark", prov["quantity"]

    def kw_of(t):
        tol, tkind = problems_study.tolerance_of(prov, t["quantity"])
        return dict(source=prov.get("source", ""), tolerance=tol, tolerance_kind=tkind, reference=t["target"])

    def not_run(why):
        return [_not_run(rec.name, check, problem, t["quantity"], why, **kw_of(t))[0] for t in trows]

    # a rigid model's first reason is physics: the quantity is a deformation
    why = (_RIGID if rec.physics.strain == "rigid" else "") or _no_spatial(rec, case)
    if why:
        return not_run(why)
    vals = {t["quantity"]: [] for t in trows}
    cpu, reason = 0.0, ""
    if kind in problems_study.STATIC_KINDS:
        if problems_study.statics_of(rec.name) is None:
            return not_run(_NO_STATICS.format(rec.label or rec.name))
        points = problems_study.static_points(case, prov)
        for k in ks:
            for c, steps, quantities in points:
                got, cc, w = run.call(_spatial_statics, rec.name, c, k, steps)
                cpu += cc if np.isfinite(cc) else 0.0
                if w:
                    reason = f"k = {k}: {w}"
                for t, f in quantities:
                    vals[t["quantity"]].append(None if w else f(got[0]))
        h = math.nan
    else:
        why = run.step_unknown
        if why:
            return not_run(why)
        h = problems_study.step_of(prov)
        for k in ks:
            res, c, w = run.run(case, k, run.step(k, h))
            cpu += c if np.isfinite(c) else 0.0
            got = {}
            if w:
                reason = f"k = {k}: {w}"
            else:
                try:
                    got = {q: v for q, v, _ in problems_study._values(problem, case, prov, res, None)}
                except Exception as exc:  # noqa: BLE001 - an extractor failing on odd output is a failed row
                    reason = f"k = {k}: {type(exc).__name__}: {exc}"
            for t in trows:
                vals[t["quantity"]].append(got.get(t["quantity"]))
        h = run.step(ks[-1], h)
    rows = []
    for t in trows:
        v = vals[t["quantity"]]
        kw = kw_of(t)
        kw.pop("reference")
        row = _judge(
            rec.name,
            check,
            problem,
            t["quantity"],
            t["target"],
            v[-1],
            prov,
            reason,
            ks,
            cpu,
            t["scale"],
            **kw,
        )
        row["h"] = _nan_none(h)
        row["order"] = _error_order(ks, v, t["target"])
        rows.append(row)
    return rows


# ----------------------------------------------------------------------------- independent checks
SHIPPED = Path(__file__).resolve().parent / "cases"
RIGID_STIFFEN = 1e6  # EI factor of the rigid-limit arm
RIGID_STIFFEN_EA = 1e3  # its EA factor (see rigid_case)
RIGID_TOL = 1e-5  # rad, max |joint angle − Pinocchio| over the run
RIGID_H = 1e-4  # s
RIGID_K = 2


def _case(d: dict):
    import dttmm

    return dttmm.case_from_dict(d)


def _restiffened(case, links, duration: float, name: str):
    """``case`` with ``links`` (its stiffened links), run for ``duration`` s, named ``name``."""
    return replace(
        case,
        model=replace(case.model, links=links),
        scenario=replace(case.scenario, duration=float(duration)),
        name=name,
    )


def rigid_case(duration: float):
    """The shipped three-link arm (gravity, hubs, payload, torques) with EI × 1e6 and EA × 1e3.

    The flexible-minus-rigid joint angles scale as 1/EI (0.12 rad on the shipped arm, so ~1e-7
    rad here) and 1/EA (7e-6 rad at the shipped EA, 7e-9 rad here). EA is raised by 1e3 only:
    at 1e6 the axial stiffness (7e12 N) is ill-conditioned for the Newton solves of the Exudyn
    elements (measured: 1.4 rad off), a conditioning limit the check is not about."""
    import dttmm

    case = dttmm.load_case(SHIPPED / "three_link.toml")
    links = tuple(
        replace(ln, beam=replace(ln.beam, EI=ln.beam.EI * RIGID_STIFFEN, EA=ln.beam.EA * RIGID_STIFFEN_EA))
        for ln in case.model.links
    )
    return _restiffened(case, links, duration, "three_link_stiff")


def _pinocchio(case):
    """The rigid arm by Pinocchio, adaptive DOP853 at rtol = atol = 1e-12."""
    from reference_models import pinocchio_rigid

    return pinocchio_rigid.simulate(case, elements_per_link=None, h=1e-3, integrator="dop853")


def rigid_limit(run: Runner) -> list:
    """Joint angles of the three-link arm with EI × 1e6 and EA × 1e3 (:func:`rigid_case`) against
    the rigid arm by Pinocchio (DOP853, tolerance 1e-12): max |Δα| ≤ 1e-5 rad at k = 2,
    h = 1e-4 s. Explicit methods sit it out (their stable step falls as 1/√EI)."""
    rec = run.rec
    case = rigid_case(run.size.rigid_duration)
    src = (
        "rigid-body dynamics of the same arm by Pinocchio (RNEA/ABA), DOP853 at rtol = atol = 1e-12; "
        f"links {RIGID_STIFFEN:g}× stiffer than experiments/cases/three_link.toml"
    )
    why = (_STIFF_EXPLICIT if rec.explicit else "") or _missing(rec, _needs(case))
    return _rigid_angles(run, "rigid limit", case, _pinocchio, src, RIGID_TOL, RIGID_K, RIGID_H, why)


_STIFF_EXPLICIT = (
    "explicit in time: its stable step falls as 1/√EI, so the stiff-link limit is out of its reach"
)


def _rigid_angles(run, check, case, rigid, src, tol, k, h, why) -> list:
    """The row of a stiffened arm's joint angles at k, h against the rigid arm's (``rigid(case)``,
    run in the worker): max |joint angle − rigid| ≤ ``tol`` rad; not run with ``why``."""
    kw = dict(source=src, tolerance=tol, tolerance_kind="absolute", reference=0.0)
    row = _Quantity(run.rec.name, check, case.name, "max |joint angle − rigid| (rad)", kw)
    if why:
        return row.not_run(why)
    ref, _, rwhy = run.call(rigid, case)
    if rwhy:
        return row.not_run(f"the Pinocchio reference: {rwhy}")
    res, cpu, why = run.run(case, k, h)
    value = None if why else float(np.max(np.abs(res.joint_angle - ref.joint_angle)))
    return [row.measured(value, why, k=k if run.rec.uses_k else None, h=h, cpu_time=cpu)]


STATIC_G = 0.1  # m/s², small: deflection/L ≈ 2e-3, geometric nonlinearity ≈ 4e-6 relative
STATIC_TOL = 1e-4  # relative
STATIC_H = 1e-2


def static_case():
    """A clamped strip (L = 1 m, EI = 2.333 N m², ρA = 0.27 kg/m) with a 0.05 kg tip mass under
    0.1 m/s² gravity, Kelvin-Voigt damping 0.2 s, 4 s to rest."""
    return _case(
        {
            "name": "cantilever_small",
            "model": {
                "gravity": [0.0, -STATIC_G],
                "links": [
                    {
                        "length": 1.0,
                        "EI": 7e10 * 0.05 * 0.002**3 / 12,
                        "rhoA": 0.27,
                        "EA": 7e6,
                        "damping": 0.2,
                        "payload": {"mass": 0.05, "inertia": 0.0},
                    }
                ],
            },
            "scenario": {
                "duration": 4.0,
                "output_step": 5e-2,
                "drives": [{"kind": "motion", "law": "constant", "value": 0.0}],
            },
        }
    )


def static_closed_form(case) -> float:
    """Tip deflection (m, negative: down) of a cantilever under its weight and a tip mass:
    −g (ρA L⁴ / (8 EI) + m L³ / (3 EI))."""
    link = case.model.links[0]
    b, g = link.beam, -case.model.gravity[1]
    m = link.payload.mass if link.payload else 0.0
    return -g * (b.rhoA * b.length**4 / (8 * b.EI) + m * b.length**3 / (3 * b.EI))


def static_deflection(run: Runner) -> list:
    """Settled tip deflection of :func:`static_case` against the closed form, relative 1e-4 at the
    largest k of the ladder; not at rest (tip moved ≥ 1e-6 m in the last second) fails."""
    case = static_case()
    prov = {
        "quantity": "static_tip_displacement",
        "component": "y",
        "tolerance": STATIC_TOL,
        "tolerance_kind": "relative",
        "source": "Euler-Bernoulli cantilever, q L⁴/(8EI) + P L³/(3EI) (e.g. Gere & Timoshenko, "
        "Mechanics of Materials, Appendix G)",
        "value": static_closed_form(case),
        "value_kind": "closed form",
    }
    rows = _static_like(run, "static deflection", case, prov)
    return rows


def _static_like(run, check, case, prov):
    rec, ks = run.rec, run.ks
    target = float(prov["value"])
    kw = dict(source=prov["source"], tolerance=prov["tolerance"], tolerance_kind=prov["tolerance_kind"])
    why = (_RIGID if rec.physics.strain == "rigid" else "") or _missing(rec, _needs(case)) or run.step_unknown
    if why:
        return _not_run(rec.name, check, case.name, "tip deflection at rest (m)", why, reference=target, **kw)
    vals, cpu, reason = _ladder(run, case, ks, STATIC_H, lambda res: _bench_value(prov, case, res))
    row = _judge(
        rec.name,
        check,
        case.name,
        "tip deflection at rest (m)",
        target,
        vals[-1],
        prov,
        reason,
        ks,
        cpu,
        **kw,
    )
    row["h"] = run.step(ks[-1], STATIC_H)
    row["order"] = _error_order(ks, vals, target)
    if "not at rest" in reason:
        row["passed"] = False
    if not rec.uses_k:
        row["k"] = None
    return [row]


# ----------------------------------------------------------------------------- spatial checks
SPATIAL_RIGID_TOL = 1e-5  # rad, max |joint angle − Pinocchio| over the run
SPATIAL_RIGID_K = 2
SPATIAL_RIGID_H = 1e-4  # s


def spatial_rigid_case(duration: float):
    """The shipped spatial three-joint arm (``experiments/cases/spatial/three_joint_arm.toml``:
    gravity, hubs, an offset payload, torque pulses) with EIy, EIz and GJ × 1e6 and EA × 1e3
    (as :func:`rigid_case`), run for ``duration`` s."""
    from dttmm.spatial import load_case

    case = load_case(SHIPPED / "spatial" / "three_joint_arm.toml")
    f, fa = RIGID_STIFFEN, RIGID_STIFFEN_EA
    links = tuple(
        replace(
            ln,
            beam=replace(
                ln.beam, EIy=ln.beam.EIy * f, EIz=ln.beam.EIz * f, GJ=ln.beam.GJ * f, EA=ln.beam.EA * fa
            ),
        )
        for ln in case.model.links
    )
    return _restiffened(case, links, duration, "three_joint_arm_stiff")


def _pinocchio_spatial(case):
    """The rigid spatial arm by Pinocchio, RK4 at h = 1e-5 s."""
    from reference_models import pinocchio_spatial

    return pinocchio_spatial.simulate(case, h=1e-5, integrator="rk4")


def spatial_rigid_limit(run: Runner) -> list:
    """Joint angles of the spatial three-joint arm with EIy, EIz, GJ × 1e6 and EA × 1e3
    (:func:`spatial_rigid_case`) against the rigid arm by Pinocchio (RK4, h = 1e-5 s): max |Δα|
    ≤ 1e-5 rad at k = 2, h = 1e-4 s. Methods without a spatial entry and explicit ones sit it out."""
    rec = run.rec
    case = spatial_rigid_case(run.size.spatial_rigid_duration)
    src = (
        "rigid-body dynamics of the same spatial arm by Pinocchio (reference_models.pinocchio_spatial), "
        f"RK4 at h = 1e-5 s; links {RIGID_STIFFEN:g}× stiffer in bending and torsion than "
        "experiments/cases/spatial/three_joint_arm.toml"
    )
    why = _no_spatial(rec, case) or (_STIFF_EXPLICIT if rec.explicit else "")
    return _rigid_angles(
        run,
        "spatial rigid limit",
        case,
        _pinocchio_spatial,
        src,
        SPATIAL_RIGID_TOL,
        SPATIAL_RIGID_K,
        SPATIAL_RIGID_H,
        why,
    )


SPATIAL_STATIC_SCALE = 1e-3  # gravity factor: deflection/L ≤ 3.3e-4; the offset payload's lever arm turns with the tip (~3e-5 relative)
SPATIAL_STATIC_TOL = 1e-4  # relative


def spatial_static_cases() -> dict:
    """``experiments/cases/spatial/cantilever_3d.toml`` (a clamped beam, EIy ≠ EIz, a payload
    offset along y) under 1e-3 of its gravity, split in its two components: ``"y"`` (gravity
    along −y: bending about z) and ``"z"`` (gravity along −z: bending about y and, through the
    payload's offset, a twist). Split so that each equilibrium bends in one plane: the twist is
    then the rotation's x component to second order in the small bending slope."""
    from dttmm.spatial import load_case

    case = load_case(SHIPPED / "spatial" / "cantilever_3d.toml")
    g = np.asarray(case.model.gravity, float) * SPATIAL_STATIC_SCALE
    out = {}
    for axis, i in (("y", 1), ("z", 2)):
        gi = [0.0, 0.0, 0.0]
        gi[i] = float(g[i])
        out[axis] = replace(case, model=replace(case.model, gravity=tuple(gi)), name=f"cantilever_3d_g{axis}")
    return out


def spatial_static_closed_forms(cases: dict) -> dict:
    """Closed forms of the split cantilever (Euler-Bernoulli and Saint-Venant torsion, small
    deflections): u_y = g_y (ρA L⁴/(8 EIz) + m L³/(3 EIz)), u_z the same with g_z and EIy, twist
    φ = T L / GJ with T = r_y m g_z, the moment of the payload's weight about the axis (r_y its
    offset)."""
    out = {}
    for axis, c in cases.items():
        link = c.model.links[0]
        b, m, g = link.beam, link.payload.mass, c.model.gravity
        EI = b.EIz if axis == "y" else b.EIy
        gi = g[1] if axis == "y" else g[2]
        out[f"u_{axis}"] = gi * (b.rhoA * b.length**4 / (8 * EI) + m * b.length**3 / (3 * EI))
        if axis == "z":
            out["twist"] = link.payload.offset[1] * m * gi * b.length / b.GJ
    return out


def spatial_static_deflection(run: Runner) -> list:
    """Tip displacements u_y, u_z and the tip twist of the split cantilever_3d
    (:func:`spatial_static_cases`) by the method's own statics against the closed forms
    (:func:`spatial_static_closed_forms`), relative 1e-4 at the largest k of the ladder (that of
    the planar static check: 8, 16, 32)."""
    rec = run.rec
    cases = spatial_static_cases()
    ref = spatial_static_closed_forms(cases)
    src = (
        "Euler-Bernoulli cantilever q L⁴/(8EI) + P L³/(3EI) in each bending plane and Saint-Venant "
        "torsion φ = T L/GJ (e.g. Gere & Timoshenko, Mechanics of Materials, Appendix G)"
    )
    qs = {"u_y": "tip u_y at rest (m)", "u_z": "tip u_z at rest (m)", "twist": "tip twist at rest (rad)"}
    rows = {
        key: _Quantity(
            rec.name,
            "spatial static deflection",
            "cantilever_3d",
            qs[key],
            dict(source=src, tolerance=SPATIAL_STATIC_TOL, tolerance_kind="relative", reference=r),
        )
        for key, r in ref.items()
    }
    why = _statics_unknown(rec, cases["y"])
    if why:
        return [row.not_run(why)[0] for row in rows.values()]
    ks, cpu, reason = run.ks, 0.0, ""
    vals = {key: [] for key in ref}
    L = cases["y"].model.links[0].beam.length
    for k in ks:
        for axis, c in cases.items():
            got, cc, w = run.call(_spatial_statics, rec.name, c, k, 1)
            cpu += cc if np.isfinite(cc) else 0.0
            if w:
                reason = f"k = {k}: {w}"
            tip, twist = (None, None) if w else got
            vals[f"u_{axis}"].append(None if w else float(tip[1 if axis == "y" else 2]))
            if axis == "z":
                vals["twist"].append(None if w or not np.isfinite(twist) else twist)
                if not w and not np.isfinite(twist):
                    reason = "its statics gives no twist"
            if not w and abs(tip[0] - L) > 1e-3 * L:
                reason = f"k = {k}: the tip moved {tip[0] - L:.3g} m along the axis (not the clamped beam's length)"
    return [
        row.measured(
            vals[key][-1], reason, True, order=_error_order(ks, vals[key], ref[key]), k=ks[-1], cpu_time=cpu
        )
        for key, row in rows.items()
    ]


# ----------------------------------------------------------------------------- robots
ROBOTS = ("ur5", "panda")
ROBOT_K = 1  # the rigid robot has no elements: k does not matter
ROBOT_H = 1e-3  # s, the robots' output step: the values are compared at step ends
ROBOT_TORQUE_TOL = 1e-6  # relative to the largest torque
ROBOT_TOOL_TOL = 1e-9  # m
ROBOT_SAG_TOL = 1e-4  # relative
ROBOT_ENERGY_TOL = 1e-3  # of M g R
ROBOT_ENERGY_K = 2
_ROBOT_SRC = (
    "Pinocchio's own reading of the unmodified URDF (pin.buildModelFromUrdf): RNEA along the "
    "prescribed motion, forward kinematics of the tool frame"
)


def _robot_reference(name, duration):
    """Pinocchio's torques and tool point along the rigid robot's motion, in the worker."""
    from . import handchecks

    return handchecks.robot_inverse_dynamics(name, handchecks.rigid_robot_case(name, duration))


def _sag_reference(name):
    """The hand-worked tool displacement of the robot's sag case (no method runs in it)."""
    from . import handchecks

    return handchecks.tool_displacement(name)


def robot_rigid_limit(run: Runner) -> list:
    """The shipped robots (``experiments/cases/spatial/robots/``) with every link rigid (the
    unmodified URDF, the case's pick-and-place motion prescribed at every joint): the joint
    torques the motion needs and the tool point against Pinocchio's RNEA and forward kinematics
    on its own reading of the URDF, at h = 1 ms (the output step)."""
    from . import handchecks

    rec, rows = run.rec, []
    for name in ROBOTS:
        T = run.size.robot_duration
        case = handchecks.rigid_robot_case(name, T)
        kw_t = dict(source=_ROBOT_SRC, tolerance=ROBOT_TORQUE_TOL, tolerance_kind="relative", reference=0.0)
        kw_p = dict(source=_ROBOT_SRC, tolerance=ROBOT_TOOL_TOL, tolerance_kind="absolute", reference=0.0)
        pair = (
            _Quantity(
                rec.name, "robot rigid limit", case.name, "max |joint torque − RNEA| / max |RNEA|", kw_t
            ),
            _Quantity(rec.name, "robot rigid limit", case.name, "max |tool point − rigid| (m)", kw_p),
        )
        why = _no_spatial(rec, case) or run.step_unknown
        if not why:
            ref, _, rwhy = run.call(_robot_reference, name, T)
            why = rwhy and f"the Pinocchio reference: {rwhy}"
        if why:
            rows += [row for q in pair for row in q.not_run(why)]
            continue
        h, res, cpu, why = run.run_at_step(case, ROBOT_K, ROBOT_H)
        vt = vp = None
        wt = wp = why
        if not why:
            dt = np.abs(np.asarray(res.joint_torque, float) - ref["torque"])
            vt = float(np.max(dt) / np.max(np.abs(ref["torque"])))
            i, j = np.unravel_index(np.argmax(dt), dt.shape)
            wt = (
                f"largest at t = {ref['t'][i]:.4g} s, joint {j + 1}: {res.joint_torque[i][j]:.6g} N m "
                f"against {ref['torque'][i, j]:.6g} N m"
            )
            dp = np.linalg.norm(np.asarray(res.end_effector) - ref["tool"], axis=1)
            vp, i = float(np.max(dp)), int(np.argmax(dp))
            wp = f"largest at t = {ref['t'][i]:.4g} s"
        k = ROBOT_K if rec.uses_k else None
        for q, v, w in zip(pair, (vt, vp), (wt, wp)):
            row = q.measured(v, w, k=k, h=h, cpu_time=cpu)
            rows.append({**row, "reason": "" if row["passed"] else w})
    return rows


def robot_statics(run: Runner) -> list:
    """The tool point's sag under gravity of each robot with one tube flexible (the case file's
    upper-arm tube, the rest rigid, joints held at zero, the tube horizontal:
    :func:`experiments.handchecks.sag_case`) by the method's own statics at the k ladder of the
    static checks, against the cantilever worked by hand (:func:`experiments.handchecks.
    tool_displacement`), relative 1e-4 at the largest k."""
    from . import handchecks

    rec, rows = run.rec, []
    src = (
        "cantilever formulas worked by hand (Gere & Timoshenko, Appendix G): the tube clamped at its "
        "joint under its weight and the outboard bodies' weight and moment (masses, centres and the "
        "tool point from Pinocchio's model of the URDF), the tube's section by hand"
    )
    for name in ROBOTS:
        case = handchecks.sag_case(name)
        why = _statics_unknown(rec, case)
        try:  # the hand check runs no method: here, not in the method's worker
            ref, rwhy = _sag_reference(name), ""
        except Exception as exc:  # noqa: BLE001 - e.g. Pinocchio or the URDFs missing: the rows say so
            ref, rwhy = None, _one_line(exc)
        target = None if rwhy else ref["sag"]
        kw = dict(source=src, tolerance=ROBOT_SAG_TOL, tolerance_kind="relative", reference=target)
        row = _Quantity(rec.name, "robot statics", case.name, "tool sag at rest (m)", kw)
        if why or rwhy:
            rows += row.not_run(why or f"the hand check: {rwhy}")
            continue
        vals, cpu, reason = [], 0.0, ""
        for k in run.ks:
            got, c, w = run.call(_spatial_statics, rec.name, case, k, 1)
            cpu += c if np.isfinite(c) else 0.0
            if w:
                reason = f"k = {k}: {w}"
            vals.append(None if w else float(ref["rigid"][2] - got[0][2]))
        order = _error_order(run.ks, vals, target)
        rows.append(row.measured(vals[-1], reason, True, order=order, k=run.ks[-1], cpu_time=cpu))
    return rows


def robot_energy_case(name: str, duration: float):
    """The shipped robot case ``name`` (its flexible tubes) released from its initial pose at
    rest under gravity with every joint free (zero torque), for ``duration`` s."""
    import dttmm
    from dttmm import Constant, Drive

    from . import handchecks

    case = dttmm.load_case(SHIPPED / "spatial" / "robots" / f"{name}.toml")
    drives = tuple(
        Drive("torque", Constant(0.0), initial_angle=float(d.motion(0.0)[0]), initial_rate=0.0)
        for d in case.scenario.drives
    )
    case = replace(case, scenario=replace(case.scenario, drives=drives), name=f"{name}_free")
    return handchecks.shortened(case, duration)


def energy_scale(case) -> float:
    """M g R of a spatial arm: its whole mass (beams, rigid bodies, hubs, payloads) times |g|
    times its size (the sum of its link lengths and joint-origin distances)."""
    mass = sum(lk.beam.mass + lk.hub_mass + lk.payload_mass for lk in case.model.links)
    return float(mass * np.linalg.norm(case.model.gravity) * case.model.size)


def robot_energy(run: Runner) -> list:
    """Energy balance of each robot's free swing (:func:`robot_energy_case`: undamped, torque-
    free joints, gravity; the tubes released undeformed ring): max |E(t) − E(0)| / (M g R)
    (:func:`energy_scale`) ≤ 1e-3, at k = 2, h = 1 ms."""
    rec, rows = run.rec, []
    for name in ROBOTS:
        case = robot_energy_case(name, run.size.robot_energy_duration)
        kw = dict(
            source="conservation of energy: no damping, zero-torque joints do no work (M the arm's mass, "
            "R its size)",
            tolerance=ROBOT_ENERGY_TOL,
            tolerance_kind="absolute",
            reference=0.0,
        )
        row = _Quantity(rec.name, "robot energy balance", case.name, "max |E(t) − E(0)| / (M g R)", kw)
        # the cheap reasons first: a spatial check may linearise the arm (the explicit DT-TMM's)
        why = _missing(rec, ["energy"]) or run.step_unknown or _no_spatial(rec, case)
        if why:
            rows += row.not_run(why)
            continue
        h, res, cpu, why = run.run_at_step(case, ROBOT_ENERGY_K, ENERGY_H)
        value = None
        if not why:
            e = None if res.energy is None else np.asarray(res.energy, float)
            if e is None or not np.all(np.isfinite(e)):
                why = "no finite energy in its Result (energy is None or NaN)"
            else:
                value = float(np.max(np.abs(e - e[0])) / energy_scale(case))
        rows.append(row.measured(value, why, k=ROBOT_ENERGY_K if rec.uses_k else None, h=h, cpu_time=cpu))
    return rows


# ----------------------------------------------------------------------------- trees and loops
TOPOLOGY = ("four_bar", "five_bar", "branched_arm")
TOPOLOGY_K = 2
TOPOLOGY_H = 1e-3  # s, the cases' output step: the values are compared at step ends
TOPOLOGY_TOL = 1e-9  # m
CLOSURE_TOL = 1e-10  # × the mechanism's size
FIVE_BAR_STIFFEN = 1e3
FIVE_BAR_H = 5e-4
FIVE_BAR_DURATION = 0.1
FIVE_BAR_TOL = 1e-6  # m
_GLOBAL = "reference_models.spatial_global:simulate"
_GLOBAL_OPTIONS = ("integrator", "strain", "rho_inf")


def topology_case(name: str, duration: float):
    """``experiments/cases/spatial/topology/<name>.toml`` run for ``duration`` s."""
    from dttmm.spatial import load_case

    from . import handchecks

    return handchecks.shortened(load_case(SHIPPED / "spatial" / "topology" / f"{name}.toml"), duration)


def _global_run(case, k, h, options):
    """The spatial global solver's run (its own equations: tree recursion, Lagrange multipliers)."""
    from reference_models import spatial_global

    return spatial_global.simulate(case, elements_per_link=k, h=h, **dict(options))


def _global_options(rec) -> tuple:
    opts = dict(rec.options if rec.spatial_options is None else rec.spatial_options)
    return tuple((k, v) for k, v in sorted(opts.items()) if k in _GLOBAL_OPTIONS)


def topology_global(run: Runner) -> list:
    """The shipped trees and loops (four-bar, five-bar, branched arm) at k = 2, h = 1 ms: every
    link tip against the spatial global solver's (:mod:`reference_models.spatial_global`, the
    same discretisation assembled as one system with Lagrange multipliers for the closures, run
    with the method's integrator and strain), ≤ 1e-9 m. A method of another discretisation
    solves other discrete equations: not run, with that reason."""
    rec, rows = run.rec, []
    src = (
        "the spatial global solver (reference_models.spatial_global: the tree's frame recursion, "
        "Lagrange multipliers for the closures) at the same k, h, integrator and strain"
    )
    kw = dict(source=src, tolerance=TOPOLOGY_TOL, tolerance_kind="absolute", reference=0.0)
    for name in TOPOLOGY:
        case = topology_case(name, run.size.topology_duration)
        row = _Quantity(rec.name, "topology vs global solver", name, "max |link tip − global solver| (m)", kw)
        why = _no_spatial(rec, case)
        if not why and rec.spatial == _GLOBAL:
            why = "it is the global solver, this check's reference"
        elif not why and rec.physics.strain == "rigid":
            why = "rigid links: the global solver's links bend"
        elif not why and rec.physics.element not in ("hermite-fe", "unknown"):
            why = (
                f"another discretisation ({rec.physics.element}): only the suite's Hermite elements solve "
                "the global solver's discrete equations (its peers converge to them in k, the report's studies)"
            )
        why = why or run.step_unknown
        if not why:
            ref, _, rwhy = run.call(_global_run, case, TOPOLOGY_K, TOPOLOGY_H, _global_options(rec))
            why = rwhy and f"the global solver: {rwhy}"
        if why:
            rows += row.not_run(why)
            continue
        h, res, cpu, why = run.run_at_step(case, TOPOLOGY_K, TOPOLOGY_H)
        v = None if why else float(np.max(np.abs(np.asarray(res.link_tip) - np.asarray(ref.link_tip))))
        rows.append(row.measured(v, why, k=TOPOLOGY_K, h=h, cpu_time=cpu))
    return rows


def closure_gap(res, case) -> tuple:
    """(max over the output times and closures of the cut joint's position gap (m), how): from
    the Result's link tips where every closure joins two tips (points at the tip frames'
    origins, the shipped loops), else the Result's own ``closure_residual``."""
    model = case.model
    tips = all(
        not any(cl.point) and cl.to != "ground" and (cl.to_point is None or not any(cl.to_point))
        for cl in model.closures
    )
    if tips:
        tip = np.asarray(res.link_tip, float)
        gaps = [
            np.linalg.norm(tip[:, model.link_index(cl.link)] - tip[:, model.link_index(cl.to)], axis=-1)
            for cl in model.closures
        ]
        return float(np.max(gaps)), "link tips"
    own = getattr(res, "closure_residual", None)
    if own is None:
        return math.nan, "no link-tip closure and no closure_residual in its Result"
    return float(np.max(own)), "its closure_residual"


def topology_closure(run: Runner) -> list:
    """The loops (four-bar, five-bar) at k = 2, h = 1 ms: the cut joint's position gap at every
    output time (step ends), from the Result's link tips, ≤ 1e-10 × the mechanism's size."""
    rec, rows = run.rec, []
    kw = dict(
        source="the closure: the cut joint holds its two points together (docs/spatial.md §11)",
        tolerance=CLOSURE_TOL,
        tolerance_kind="absolute",
        reference=0.0,
    )
    for name in TOPOLOGY:
        case = topology_case(name, run.size.topology_duration)
        if not case.model.closures:
            continue
        row = _Quantity(rec.name, "topology closure", name, "max closure gap / mechanism size", kw)
        why = _no_spatial(rec, case) or run.step_unknown
        if why:
            rows += row.not_run(why)
            continue
        h, res, cpu, why = run.run_at_step(case, TOPOLOGY_K, TOPOLOGY_H)
        v = None
        if not why:
            gap, how = closure_gap(res, case)
            v = gap / case.model.size if np.isfinite(gap) else None
            why = "" if v is not None else how
        rows.append(row.measured(v, why, k=TOPOLOGY_K, h=h, cpu_time=cpu))
    return rows


def five_bar_case():
    """The shipped five-bar with every stiffness × 1e3, run for 0.1 s."""
    from . import handchecks

    case = topology_case("five_bar", FIVE_BAR_DURATION)
    return replace(handchecks.stiffened(case, FIVE_BAR_STIFFEN), name="five_bar_stiff")


def five_bar_rigid(run: Runner) -> list:
    """The five-bar with every stiffness × 1e3 (:func:`five_bar_case`), k = 2, h = 5e-4 s: its
    end-effector (the distal tip) against the rigid five-bar's closed-form loop geometry
    (:func:`experiments.handchecks.five_bar_tip`), ≤ 1e-6 m."""
    from . import handchecks

    rec = run.rec
    case = five_bar_case()
    kw = dict(
        source="the rigid five-bar's loop-closure geometry: the distal tip where the circles about the "
        "driven proximal tips meet",
        tolerance=FIVE_BAR_TOL,
        tolerance_kind="absolute",
        reference=0.0,
    )
    row = _Quantity(
        rec.name, "five-bar rigid limit", case.name, "max |distal tip − rigid loop geometry| (m)", kw
    )
    why = _no_spatial(rec, case) or (_STIFF_EXPLICIT if rec.explicit else "")
    if why:
        return row.not_run(why)
    res, cpu, why = run.run(case, TOPOLOGY_K, FIVE_BAR_H)
    v = None
    if not why:
        ref = handchecks.five_bar_tip(case, np.asarray(res.t))
        v = float(np.max(np.linalg.norm(np.asarray(res.end_effector) - ref, axis=1)))
    return [row.measured(v, why, k=TOPOLOGY_K if rec.uses_k else None, h=FIVE_BAR_H, cpu_time=cpu)]


#: β_n L of the clamped-free Euler-Bernoulli beam (roots of cos βL cosh βL = −1).
BETA_L = (1.8751040687119611, 4.6940911329741745, 7.8547574382376126)
FREQ_TOL = 1e-4  # relative


def clamped_case():
    """The single-link strip (L = 1 m, EI = 2.333 N m², ρA = 0.27 kg/m, inextensible) clamped."""
    return _case(
        {
            "name": "clamped_strip",
            "model": {"links": [{"length": 1.0, "EI": 7e10 * 0.05 * 0.002**3 / 12, "rhoA": 0.27}]},
            "scenario": {
                "duration": 1.0,
                "output_step": 1e-2,
                "drives": [{"kind": "motion", "law": "constant", "value": 0.0}],
            },
        }
    )


def clamped_closed_form(case) -> list:
    """f_n = (β_n L)² / (2π L²) √(EI/ρA) (Hz) of a uniform clamped-free beam."""
    b = case.model.links[0].beam
    return [bl**2 / (2 * math.pi * b.length**2) * math.sqrt(b.EI / b.rhoA) for bl in BETA_L]


def clamped_frequencies(run: Runner) -> list:
    """Lowest three frequencies of :func:`clamped_case` from the method's own linearisation
    against the β_nL closed form, relative 1e-4 at the largest k; order in k over the ladder."""
    rec, ks = run.rec, run.ks
    case = clamped_case()
    ref = clamped_closed_form(case)
    src = (
        "clamped-free Euler-Bernoulli beam, f_n = (β_n L)²/(2π L²) √(EI/ρA), cos βL cosh βL = −1 "
        "(Blevins, Formulas for Natural Frequency and Mode Shape, 1979, Table 8-1)"
    )
    kw = dict(source=src, tolerance=FREQ_TOL, tolerance_kind="relative")
    qs = [
        _Quantity(rec.name, "frequencies", case.name, f"f{i + 1} (Hz)", {**kw, "reference": r})
        for i, r in enumerate(ref)
    ]
    why = _missing(rec, ["modes"]) or ("" if linearisation(rec.name) else _NO_LIN.format(rec.name))
    got = [] if why else [run.call(_frequencies, rec.name, case, k, len(ref)) for k in ks]
    if why or _no_lin(got):
        return [q.not_run(why or _NO_LIN.format(rec.name))[0] for q in qs]
    cpu = sum(c for _, c, _ in got if np.isfinite(c))
    rows = []
    for i, (q, r) in enumerate(zip(qs, ref)):
        vals = [None if why else float(f[i]) for f, _, why in got]
        order = _error_order(ks, vals, r)
        rows.append(q.measured(vals[-1], got[-1][2], True, order=order, k=ks[-1], cpu_time=cpu))
    return rows


ENERGY_PROBLEM = "pendulum_stiff"
ENERGY_K = 8
ENERGY_H = 1e-3


def energy_balance(run: Runner) -> list:
    """Energy drift max |E(t) − E(0)| / (m g L/2) of the undamped free swing ``pendulum_stiff``
    (:func:`experiments.studies.problems.energy_drift`) within the problem's energy tolerance."""
    rec = run.rec
    case, prov = problems_study.problems([ENERGY_PROBLEM])[ENERGY_PROBLEM]
    case = problems_study._shortened(case, run.size.energy_duration)
    tol = float(prov["energy_tolerance"])
    kw = dict(
        source="conservation of energy: no damping, a zero-torque joint does no work (case "
        f"{ENERGY_PROBLEM}, its energy_tolerance)",
        tolerance=tol,
        tolerance_kind="absolute",
        reference=0.0,
    )
    row = _Quantity(rec.name, "energy balance", ENERGY_PROBLEM, "max |E(t) − E(0)| / (m g L/2)", kw)
    why = _missing(rec, ["energy", *_needs(case)]) or run.step_unknown
    if why:
        return row.not_run(why)
    h, res, cpu, why = run.run_at_step(case, ENERGY_K, ENERGY_H)
    value = None
    if not why:
        value = problems_study.energy_drift(res, case)
        if not np.isfinite(value):
            value, why = None, "no finite energy in its Result (energy is None or NaN)"
    return [row.measured(value, why, k=ENERGY_K if rec.uses_k else None, h=h, cpu_time=cpu)]


#: Minimum observed orders: every built-in discretisation converges at least at order 2 in k
#: (hinge chain, GE beam; the cubic elements more), every built-in integrator at order ≥ 1
#: (MuJoCo's semi-implicit Euler 1; Newmark, generalised-α 2; RK4 4). Pass: observed ≥ the
#: expected order − 0.5 where the record's integrator option names a known order, else ≥ the minimum.
MIN_ORDER_K = 1.5
MIN_ORDER_H = 0.8
INTEGRATOR_ORDER = {"newmark": 2, "generalized-alpha": 2, "rk4": 4, "implicitfast": 1, "euler": 1}
ORDER_FLOOR = 1e-12  # relative: errors below it are round-off, not discretisation


def order_case(duration: float):
    """A single-link strip on a hub (inextensible), smooth torque 1 N m · sin 2πt, no gravity."""
    return _case(
        {
            "name": "order_strip",
            "model": {
                "links": [
                    {
                        "length": 1.0,
                        "EI": 7e10 * 0.05 * 0.002**3 / 12,
                        "rhoA": 0.27,
                        "hub": {"mass": 0.0, "inertia": 0.01},
                    }
                ]
            },
            "scenario": {
                "duration": float(duration),
                "output_step": 2e-2,
                "drives": [{"kind": "torque", "law": "sine", "amplitude": 1.0, "frequency": 1.0}],
            },
        }
    )


def _history_error(res, ref) -> float:
    """max over time of |tip deflection − finer run's| / max |finer run's| (last link); the joint
    angles instead (same form, all joints) when the finer run has no tip deflection (rigid links)."""
    a, b = res.tip_deflection[:, -1], ref.tip_deflection[:, -1]
    if not np.any(b):
        a, b = np.asarray(res.joint_angle), np.asarray(ref.joint_angle)
    return float(np.max(np.abs(a - b)) / np.max(np.abs(b)))


def _order_rows(run, check, xs, runs, fine, rule_min, expected, label, cpu):
    rec = run.rec
    case_name = "order_strip"
    q = f"observed order in {label}"
    src = f"the method's own run at {label} = {fine[0]:g} (finer), error = max |tip deflection difference| / max |tip deflection|"
    kw = dict(source=src, tolerance=rule_min, tolerance_kind="minimum order")
    ref, _, rwhy = fine[1]
    if rwhy:
        return [
            _row(
                rec.name,
                check,
                case_name,
                q,
                passed=False,
                reason=f"the finer run: {rwhy}",
                cpu_time=cpu,
                **kw,
            )
        ]
    errs, why = [], ""
    for x, (res, _, w) in zip(xs, runs):
        if w:
            why = f"{label} = {x:g}: {w}"
            errs.append(None)
        else:
            errs.append(_history_error(res, ref))
    if why:
        return [_row(rec.name, check, case_name, q, passed=False, reason=why, cpu_time=cpu, **kw)]
    if max(errs) <= ORDER_FLOOR:
        return [
            _row(
                rec.name,
                check,
                case_name,
                q,
                value=None,
                passed=False,
                reason=f"the result does not change with {label} (differences ≤ {ORDER_FLOOR:g}): {label} is ignored",
                cpu_time=cpu,
                **kw,
            )
        ]
    # err ∝ k^-p: fit against 1/k; err ∝ h^p: fit against h
    p = order_in_k(xs, errs) if label == "k" else _fit(xs, errs)
    need = rule_min if expected is None else max(rule_min, expected - 0.5)
    reason = f"errors {', '.join(f'{e:.2g}' for e in errs)} at {label} = {', '.join(f'{x:g}' for x in xs)}"
    reason += f"; expected order {expected}" if expected is not None else "; no expected order known"
    return [
        _row(
            rec.name,
            check,
            case_name,
            q,
            value=_nan_none(p),
            reference=expected,
            passed=bool(np.isfinite(p) and p >= need),
            reason=reason,
            order=_nan_none(p),
            tolerance=need,
            cpu_time=cpu,
            **{k: v for k, v in kw.items() if k != "tolerance"},
        )
    ]


def order_k(run: Runner) -> list:
    """Observed order in k: the order case at k = 2, 4, 8 against k = 32 at one common h (1e-3 s,
    the record's ``max_step`` at k = 32 for an explicit method)."""
    rec, s = run.rec, run.size
    case = order_case(s.order_duration)
    q = "observed order in k"
    kw = dict(source="the method's own finer run", tolerance=MIN_ORDER_K, tolerance_kind="minimum order")
    if not rec.uses_k:
        return _not_run(
            rec.name, "order in k", "order_strip", q, "no discretisation parameter (rigid links)", **kw
        )
    why = _missing(rec, _needs(case))
    if why:
        return _not_run(rec.name, "order in k", "order_strip", q, why, **kw)
    if rec.explicit and rec.max_step is None:
        return _not_run(
            rec.name,
            "order in k",
            "order_strip",
            q,
            "explicit in time with no max_step in its record: no common stable step for the k ladder",
            **kw,
        )
    h = run.step(s.order_k_fine, 1e-3)
    runs = [run.run(case, k, h) for k in s.order_ks]
    fine = (s.order_k_fine, run.run(case, s.order_k_fine, h))
    cpu = sum(c for _, c, _ in [*runs, fine[1]] if np.isfinite(c))
    rows = _order_rows(run, "order in k", s.order_ks, runs, fine, MIN_ORDER_K, None, "k", cpu)
    rows[0]["h"] = h
    return rows


def order_h(run: Runner) -> list:
    """Observed order in h: the order case at k = 4 and h = 4, 2, 1 ms (explicit methods: from
    their ``max_step(k)``, or 1/4 of those without one) against h/8 of the smallest (quick: h/4)."""
    rec, s = run.rec, run.size
    case = order_case(s.order_duration)
    k = s.order_h_k
    why = _missing(rec, _needs(case))
    integrator = str(dict(rec.options).get("integrator", "")) or None
    expected = INTEGRATOR_ORDER.get(integrator)
    if why:
        return _not_run(
            rec.name, "order in h", "order_strip", "observed order in h", why, tolerance=MIN_ORDER_H
        )
    hs = list(s.order_hs)
    fine_h = s.order_h_fine
    if rec.explicit:
        top = float(rec.max_step(k)) if rec.max_step is not None else hs[0] / 4
        scale = top / hs[0]
        hs, fine_h = [x * scale for x in hs], fine_h * scale
    # every step must divide the output step
    runs = [run.run(case, k, x) for x in hs]
    fine = (fine_h, run.run(case, k, fine_h))
    cpu = sum(c for _, c, _ in [*runs, fine[1]] if np.isfinite(c))
    rows = _order_rows(run, "order in h", hs, runs, fine, MIN_ORDER_H, expected, "h", cpu)
    rows[0]["k"] = k if rec.uses_k else None
    return rows


# ----------------------------------------------------------------------------- the suite
def _bench(run, *, problem, case, prov):
    return benchmark_problem(run, problem, case, prov)


def _bench_checks(size: Size) -> dict:
    out = {}
    for name, (case, prov) in problems_study.problems().items():
        if name.startswith("spin_up"):
            if name not in size.spin_up:
                continue
            case = problems_study._shortened(case, size.spin_duration)
        case = problems_study._shortened(case, dict(size.durations).get(name))
        out[name] = functools.partial(_bench, problem=name, case=case, prov=prov)
    return out


#: The independent checks, by name (``--only`` selects among these and the problem names).
CHECKS = {
    "rigid_limit": rigid_limit,
    "static_deflection": static_deflection,
    "frequencies": clamped_frequencies,
    "energy_balance": energy_balance,
    "order_k": order_k,
    "order_h": order_h,
    "spatial_rigid_limit": spatial_rigid_limit,
    "spatial_static_deflection": spatial_static_deflection,
    "robot_rigid_limit": robot_rigid_limit,
    "robot_statics": robot_statics,
    "robot_energy": robot_energy,
    "topology_global": topology_global,
    "topology_closure": topology_closure,
    "five_bar_rigid": five_bar_rigid,
}


def check_names(size: Size | None = None) -> list:
    """Every check name of a size: the benchmark problems, then :data:`CHECKS`."""
    return [*_bench_checks(size or SIZES["full"]), *CHECKS]


def validate_method(name: str, size: Size, only=None, progress=None, spec: str | None = None) -> list:
    """Every check of one method: a list of rows (:data:`ROW_KEYS`).

    ``only``: check names to run (default all); ``progress``: a tqdm bar to advance; ``spec``:
    how the worker process loads the method (default its name: a built-in method, or one
    registered from an entry point).
    """
    rec = methods.get(name)
    table = {**_bench_checks(size), **CHECKS}
    rows = []
    run = Runner(name, size, spec)
    # a method that cannot run here at all is one row per check, not a crash
    try:
        methods.resolve(name)
        why = ""
    except methods.MethodUnavailable as exc:
        why = f"unavailable: {exc}"
    for check, fn in table.items():
        if only and check not in only:
            continue
        if progress is not None:
            progress.set_postfix_str(f"{name}: {check}")
        if why:
            rows += _not_run(name, check, check, "", why)
        else:
            try:
                rows += fn(run)
            except Exception as exc:  # noqa: BLE001 - a bug in one check must not lose the others
                msg = " ".join(str(exc).split())[:300]
                rows.append(
                    _row(
                        name,
                        check,
                        check,
                        "",
                        passed=False,
                        reason=f"check failed: {type(exc).__name__}: {msg}",
                    )
                )
        if progress is not None:
            progress.update(1)
    run.worker.stop()
    for r in rows:
        r["label"] = rec.label or name
    return rows


def warm_kernel() -> None:
    """Compile (or load from numba's disk cache) DT-TMM's kernel in this process before any worker
    starts: a first compile takes minutes and would otherwise run into every worker's timeout."""
    import dttmm
    from dttmm import spatial

    case = methods._probe_case()
    for opts in ({}, {"strain": "second-order", "integrator": "generalized-alpha"}, {"integrator": "rk4"}):
        try:
            dttmm.simulate(case, elements_per_link=1, h=0.002, progress=False, **opts)
        except Exception:  # noqa: BLE001, S112 - a warm-up only; the checks report failures
            continue
    # the spatial kernel too (the spatial checks, and outside methods built on it)
    with contextlib.suppress(Exception):
        spatial.simulate(methods._spatial_probe_case(), elements_per_link=1, h=0.002)


def default_methods() -> list:
    """Every built-in method that runs here (a two-step probe, :func:`experiments.methods.available`)."""
    builtin = list(methods.METHODS)
    return [n for n, why in methods.available(builtin).items() if why is None]


def verdict(rows) -> int:
    """0 when every row that ran passed, else 1."""
    return EXIT_FAILED if any(r["passed"] is False for r in rows) else EXIT_OK


def summary(rows) -> dict:
    """method -> (passed, failed, not run)."""
    out = {}
    for r in rows:
        p, f, n = out.get(r["method"], (0, 0, 0))
        out[r["method"]] = (p + (r["passed"] is True), f + (r["passed"] is False), n + (r["passed"] is None))
    return out


def _cell(v) -> str:
    if v is None:
        return "—"
    if isinstance(v, float):
        return f"{v:.4g}"
    return str(v)


def terminal_table(rows, width: int = 60) -> str:
    """The scorecard as fixed-width text, one block per method."""
    cols = ("problem", "quantity", "value", "reference", "tolerance", "passed", "order", "cpu_time", "reason")
    out = []
    for method in dict.fromkeys(r["method"] for r in rows):
        mine = [r for r in rows if r["method"] == method]
        p, f, n = summary(mine)[method]
        out.append(f"\n{method}: {p} passed, {f} failed, {n} not run")
        cells = [[_verdict(r) if c == "passed" else _cell(r[c]) for c in cols] for r in mine]
        cells = [[c if len(c) <= width else c[: width - 1] + "…" for c in row] for row in cells]
        w = [max(len(c), *(len(row[i]) for row in cells)) for i, c in enumerate(cols)]
        out.append("  ".join(c.ljust(w[i]) for i, c in enumerate(cols)).rstrip())
        for row in cells:
            out.append("  ".join(c.ljust(w[i]) for i, c in enumerate(row)).rstrip())
    return "\n".join(out)


def _verdict(r) -> str:
    return {True: "pass", False: "FAIL", None: "not run"}[r["passed"]]


def write(rows, out_dir) -> Path:
    """``out_dir/scorecard.json`` and the HTML pages; returns the JSON path."""
    from reports import validate_page

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "scorecard.json"
    path.write_text(json.dumps(rows, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
    validate_page.write(rows, out)
    return path


def scorecard_links(out_dir) -> list:
    """[(method, label, page path relative to ``out_dir``, passed, failed, not run)] of the
    scorecards written in ``out_dir`` by ``dttmm validate`` ([] when there are none); see
    :func:`reports.validate_page.scorecard_links`."""
    from reports.validate_page import scorecard_links as links

    return links(out_dir)


# ----------------------------------------------------------------------------- command line
def _seconds(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise argparse.ArgumentTypeError(f"--timeout = {text!r}: must be a positive number of seconds")
    return v


def parser() -> argparse.ArgumentParser:
    from dttmm.cli import OneLineParser

    p = OneLineParser(
        prog="dttmm validate",
        description="Check methods against the suite's published, closed-form and independent values.",
        epilog="Exit codes: 0 every check that ran passed; 1 a check failed; 2 bad input. See docs/validate.md.",
    )
    p.add_argument(
        "--method",
        action="append",
        default=None,
        metavar="NAME|SPEC",
        help="a registered method, module:function, path/to/file.py:function or an entry point of "
        "dttmm.methods (repeatable; default: every built-in method that runs here)",
    )
    p.add_argument("--quick", action="store_true", help="the quick size (about two minutes per method)")
    p.add_argument("--out", default="out/validate", help="output folder (default out/validate)")
    p.add_argument(
        "--timeout",
        type=_seconds,
        default=None,
        metavar="S",
        help="per-run timeout in s (default 60 with --quick, 600 without)",
    )
    p.add_argument(
        "--only", action="append", default=None, metavar="CHECK", help="run only these checks (repeatable)"
    )
    return p


def main(argv=None) -> int:
    """``dttmm validate``: returns the exit code (0 all passed, 1 something failed, 2 bad input)."""
    from tqdm import tqdm

    from dttmm.errors import InputError

    args = parser().parse_args(argv)
    size = SIZES["quick" if args.quick else "full"]
    if args.timeout is not None:
        size = replace(size, timeout=args.timeout)
    try:
        specs = {methods.load_spec(s).name: s for s in args.method} if args.method else {}
    except InputError as exc:
        print(f"dttmm validate: bad input: {exc}", file=sys.stderr)
        return EXIT_INPUT
    warm_kernel()
    names = list(specs) or default_methods()
    known = check_names(size)
    only = None
    if args.only:
        only = [c for o in args.only for c in o.split(",") if c]
        bad = [c for c in only if c not in known]
        if bad:
            print(
                f"dttmm validate: bad input: --only = {bad[0]!r}: known checks: {', '.join(known)}",
                file=sys.stderr,
            )
            return EXIT_INPUT
    n = len(only or known)
    rows, t0 = [], time.perf_counter()
    walls = {}
    with tqdm(total=n * len(names), desc="validate", unit="check", file=sys.stderr) as bar:
        for name in names:
            t1 = time.perf_counter()
            rows += validate_method(name, size, only, bar, spec=specs.get(name))
            walls[name] = time.perf_counter() - t1
    path = write(rows, args.out)
    print(terminal_table(rows))
    print()
    for m, (p, f, nr) in summary(rows).items():
        print(f"{m}: {p} passed, {f} failed, {nr} not run ({walls.get(m, math.nan):.0f} s)")
    print(f"scorecard: {path} (pages: {Path(args.out) / 'index.html'}); {time.perf_counter() - t0:.0f} s")
    return verdict(rows)


if __name__ == "__main__":
    if sys.argv[1:2] == ["--worker"]:
        _worker_main(int(sys.argv[2]), sys.argv[3])
    else:
        raise SystemExit(main())
