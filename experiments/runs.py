"""One run of a method, and the on-disk store that makes sweeps resumable.

A :class:`Task` names a run: (case, duration, method, k, h, options). :func:`execute` runs it
(on any worker) and returns an :class:`Outcome`; :class:`RunStore` writes each finished run
at once as a parquet time history and a JSON row (the row last, so a run counts as done only
when both are on disk), keyed by the case's content and the method's code, verified on read.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import re
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import cachefiles, console, fingerprint, methods, metrics

__all__ = [
    "INFRASTRUCTURE",
    "WITH_HISTORY",
    "Outcome",
    "RunStore",
    "Task",
    "execute",
    "infrastructure",
    "options_text",
    "row_status",
    "task_from_row",
]


def options_text(options) -> str:
    """Canonical text of a run's options, e.g. ``iterations=0,sweep=plain`` ('' for none)."""
    return ",".join(f"{k}={v}" for k, v in sorted(dict(options).items()))


@dataclass(frozen=True)
class Task:
    """One run: ``method`` on case ``case`` (shortened to ``duration`` s) at k elements per link
    and step h (s), with extra method ``options`` as sorted (name, value) pairs."""

    case: str
    method: str
    k: int
    h: float
    duration: float
    options: tuple = ()

    def __post_init__(self):
        object.__setattr__(self, "options", tuple(sorted(dict(self.options).items())))
        # the rigid baseline has no elements: one k (0) so its runs are shared between studies
        object.__setattr__(self, "k", int(self.k) if methods.uses_k(self.method) else 0)
        object.__setattr__(self, "h", float(self.h))
        object.__setattr__(self, "duration", float(self.duration))

    @property
    def key(self) -> str:
        """File-safe name, unique per task."""
        opts = options_text(self.options)
        raw = f"{self.method}_k{self.k}_h{self.h:.6g}_T{self.duration:g}" + (f"_{opts}" if opts else "")
        return re.sub(r"[^A-Za-z0-9_.=+-]", "-", raw.replace(",", "_"))


@dataclass
class Outcome:
    """What a worker sends back: status ``ok`` | ``failed`` | ``unavailable``, the Result and,
    for a run that finished, its timing (``timing_*`` columns, see :mod:`experiments.timing`).

    ``infrastructure``: the run did not get to give its own verdict (its worker died, the method
    could not be loaded there, the future was cancelled, the report was interrupted). Such an
    outcome is shown as an omission but never stored, so the next report runs it again.
    ``console``: what the method's engine printed to the terminal during the run (fd level).
    ``runaway``: a call past its time limit still runs in the worker (the sweep restarts it).
    """

    status: str
    reason: str = ""
    result: object = None
    run_time: float = math.nan  # s, least wall time of the calls (build + solve), in the worker
    worker: str = field(default_factory=lambda: f"{os.uname().nodename}:{os.getpid()}")
    timing: dict = field(default_factory=dict)
    infrastructure: bool = False
    console: str = ""
    runaway: bool = False


#: Prefix of the reason of every infrastructure failure (never stored, see Outcome).
INFRASTRUCTURE = "infrastructure failure (not stored; the next report runs it again)"

#: Reason prefix of the rows an earlier sweep stored for infrastructure failures (it turned any
#: exception out of a Dask future into a stored "failed" row). A method's own exception is
#: stored as "<ExceptionType>: message", which never contains a space before the colon, so
#: the two cannot be confused; such entries are dropped on read and computed again.
LEGACY_INFRASTRUCTURE = "worker error:"


def infrastructure(why: str, **kw) -> Outcome:
    """The outcome of a run that did not get to give its own verdict."""
    return Outcome("failed", f"{INFRASTRUCTURE}: {why}", infrastructure=True, **kw)


_SHAPES = {  # Result field -> its shape, from (nt, n joints), planar cases
    "joint_angle": lambda nt, n: (nt, n),
    "joint_rate": lambda nt, n: (nt, n),
    "joint_torque": lambda nt, n: (nt, n),
    "link_root": lambda nt, n: (nt, n, 2),
    "link_tip": lambda nt, n: (nt, n, 2),
    "tip_deflection": lambda nt, n: (nt, n),
    "end_effector": lambda nt, n: (nt, 2),
}


def malformed(result, case) -> str:
    """Why a method's return value is not a Result of ``case`` ('' when it is): not a
    ``dttmm.Result``, a field of the wrong shape, or a time grid other than the case's output
    grid (times in other units than seconds show up here)."""
    from dttmm.result import Result

    if not isinstance(result, Result):
        return f"returned a {type(result).__name__}, not a dttmm.Result"
    t = np.asarray(result.t, float)
    grid = np.asarray(case.scenario.output_times, float)
    if t.shape != grid.shape or not np.allclose(t, grid, rtol=1e-9, atol=1e-9 * case.scenario.duration):
        span = f"{t[0]:g}…{t[-1]:g} s, {t.size} samples" if t.size else "empty"
        return (
            f"time grid {span} is not the case's output grid "
            f"(0…{grid[-1]:g} s every {case.scenario.output_step:g} s, {grid.size} samples)"
        )
    if methods.is_spatial(case):
        nt, m, n = t.size, case.n_joints, case.model.n_links
        want = {"joint_angle": (nt, m), "joint_rate": (nt, m), "joint_torque": (nt, m)}
        want.update(
            link_root=(nt, n, 3), link_tip=(nt, n, 3), tip_deflection=(nt, n, 2), end_effector=(nt, 3)
        )
    else:
        want = {name: shape(t.size, case.n_joints) for name, shape in _SHAPES.items()}
    for name, shape in want.items():
        got = np.shape(getattr(result, name))
        if got != shape:
            return f"{name} has shape {got}, expected {shape}"
    return ""


def _is_spatial_result(result) -> bool:
    from dttmm.spatial.result import SpatialResult

    return isinstance(result, SpatialResult)


def _check(result, case=None) -> str:
    """Why a returned Result is not usable ('' when it is).

    A value that is not a Result of the case (:func:`malformed`), a Result with status "failed"
    or with non-finite output is not; "unconverged" and "ill-conditioned" ones are kept (their
    errors are measured) and marked by their status.
    """
    if case is not None and getattr(result, "status", "ok") != "failed" and (why := malformed(result, case)):
        return f"malformed result: {why}"
    if getattr(result, "status", "ok") == "failed":
        meta = result.meta or {}
        why = "; ".join(result.warnings) or meta.get("reason") or meta.get("message") or "no reason given"
        return f"method reported failure: {why}"
    arrays = (result.joint_angle, result.tip_deflection, result.end_effector)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return "non-finite output (diverged)"
    return ""


_WARM: set = set()  # (method, options, case) already run in this process
_RUNAWAY: list = []  # calls that ran past their time limit and still run in this process


class RunTimeout(RuntimeError):
    """A call ran past its method's time limit."""


def _call(simulate, limit: float, *args, **kwargs):
    """``simulate(*args, **kwargs)``, or RunTimeout once it has run ``limit`` s (wall).

    A call with a limit runs in a daemon thread; one that does not return in time is left
    running (Python cannot stop a thread) and the process's later timings are marked noisy.
    """
    if not math.isfinite(limit):
        return simulate(*args, **kwargs)
    import threading

    box: dict = {}

    def target():
        try:
            box["value"] = simulate(*args, **kwargs)
        except BaseException as exc:  # noqa: BLE001 - handed to the caller's thread
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True, name="dttmm-run")
    th.start()
    th.join(limit)
    if th.is_alive():
        _RUNAWAY.append(th)
        raise RunTimeout(f"ran past its time limit of {limit:g} s")
    if "error" in box:
        raise box["error"]
    return box["value"]


def _warm_up(simulate, case, task: Task) -> None:
    """Run the task's method once, untimed, on the first few steps of its case, the first time
    this process times it: JIT compilation (or loading cached machine code) and first-call
    imports stay out of a long run that is timed once. Failures are left to the timed call."""
    key = (task.method, task.options, task.case)
    if key in _WARM:
        return
    _WARM.add(key)
    from dataclasses import replace

    sc = case.scenario
    T = min(sc.duration, max(20 * task.h, 2 * sc.output_step))
    short = replace(case, scenario=replace(sc, duration=T))
    with contextlib.suppress(Exception):
        simulate(short, task.k, task.h, **dict(task.options))


def execute(simulate, case, task: Task, repeats: int = 1) -> Outcome:
    """Run one task with a resolved method; never raises for a failing run.

    ``repeats`` ≥ 1 calls (one BLAS thread, CPU and wall time each, see
    :func:`experiments.timing.measure`); the first call's Result is kept. Studies that report
    cost ask for ≥ 3, accuracy-only studies for 1; with more than one, a short run is called
    again until calls × least CPU time reach ``timing.MIN_CPU`` (and its spread is small), and a
    run of ≥ ``timing.LONG_CPU`` is timed once, after an untimed warm-up (:func:`_warm_up`). ``KeyboardInterrupt`` and
    ``SystemExit`` still propagate (they stop the sweep).
    """
    with console.captured() as printed:
        out = _execute(simulate, case, task, repeats)
    out.console = printed.text()
    if out.console and out.status != "ok":
        out.reason = f"{out.reason}; it printed: {printed.last_line()}"
    return out


def _execute(simulate, case, task: Task, repeats: int) -> Outcome:
    from . import timing as tm

    t0 = time.perf_counter()
    min_cpu = tm.MIN_CPU if repeats > 1 else 0.0
    limit = float(getattr(simulate, "timeout", math.inf))
    if repeats > 1:
        _warm_up(simulate, case, task)
    try:
        res, timing = tm.measure(
            lambda: _call(simulate, limit, case, task.k, task.h, **dict(task.options)),
            repeats,
            min_cpu=min_cpu,
        )
    except methods.MethodShippingError as exc:  # not the method's verdict: never stored
        return infrastructure(str(exc), run_time=time.perf_counter() - t0)
    except methods.MethodUnavailable as exc:
        return Outcome("unavailable", str(exc), run_time=time.perf_counter() - t0)
    except RunTimeout as exc:  # the method's own verdict; its thread still runs here
        return Outcome("failed", f"RunTimeout: {exc}", run_time=time.perf_counter() - t0, runaway=True)
    except Exception as exc:  # recorded with its reason, never dropped
        msg = str(exc).splitlines()[0][:300] if str(exc) else ""
        return Outcome("failed", f"{type(exc).__name__}: {msg}", run_time=time.perf_counter() - t0)
    if _RUNAWAY and any(th.is_alive() for th in _RUNAWAY):
        from dataclasses import replace

        noise = "; ".join(filter(None, [timing.noise, "a timed-out run still runs in this worker"]))
        timing = replace(timing, noisy=True, noise=noise)
    why = _check(res, case)
    if why.startswith("malformed"):
        res = None  # nothing of it can be stored or scored
    return Outcome("failed" if why else "ok", why, res, timing.wall_min, timing=timing.columns())


def _plain(v):
    """JSON-able copy of a metadata value (nested dicts kept, others as text)."""
    if isinstance(v, (str, bool, type(None))):
        return v
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v) if math.isfinite(v) else None
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    return str(v)


# Layout of a stored row; part of every entry key, so raise it when the row's columns change.
STORE_FORMAT = 2

# Row statuses whose run left a time history (errors are computed; only "ok" counts as ok).
WITH_HISTORY = ("ok", "unconverged", "ill-conditioned")


class RunStore:
    """Folder of finished runs: one verified JSON row and parquet history per run.

    Entries are named ``<case>/<task.key>@<entry key>`` where the entry key hashes the task,
    the case's content and the method's code version (see ``experiments.fingerprint``), so a
    changed case or changed code never finds an old entry. Every read is verified (see
    ``experiments.cachefiles``); a damaged entry is reported with a ``CacheWarning`` and run
    again.

    Parameters
    ----------
    root : folder of the store
    cases : dict case name -> dttmm.Case (more can be added with :meth:`bind`)
    recompute : ignore every entry not written by this store object (rewrite them all)
    """

    def __init__(self, root, cases=None, *, recompute: bool = False):
        self.root = Path(root)
        self.recompute = recompute
        self._case_digest: dict[str, str] = {}
        self._code: dict[str, dict] = {}
        self._fresh: set[str] = set()
        self._warned: set[str] = set()
        self.repaired = 0  # stored infrastructure failures dropped on read (see _infrastructure_row)
        self.bind(cases or {})

    def bind(self, cases: dict) -> None:
        """Make the cases (name -> dttmm.Case) known; runs are keyed by their content."""
        for name, case in cases.items():
            self._case_digest[name] = fingerprint.case_digest(case)

    def entry_key(self, task: Task) -> str:
        """sha256 of the task, its case's content and its method's code version."""
        if task.case not in self._case_digest:
            raise KeyError(f"RunStore: case {task.case!r} is unknown; pass it in cases= or bind()")
        if task.method not in self._code:
            self._code[task.method] = fingerprint.code_version(task.method)
        return fingerprint.digest(
            {
                "task": [task.case, task.method, task.k, task.h, task.duration, options_text(task.options)],
                "case": self._case_digest[task.case],
                "code": self._code[task.method],
                "format": STORE_FORMAT,
            }
        )

    def _paths(self, task: Task) -> tuple[Path, Path, str]:
        key = self.entry_key(task)
        folder, stem = self.root / task.case, f"{task.key}@{key[:16]}"
        return folder / f"{stem}.json", folder / f"{stem}.parquet", key

    def _load(self, task: Task):
        """(row, history bytes or None) of a usable entry, else None (warned when damaged)."""
        jpath, ppath, key = self._paths(task)
        if self.recompute and key not in self._fresh:
            return None
        try:
            got = cachefiles.read_entry(jpath, ppath, key)
        except cachefiles.BadEntry as exc:
            if key not in self._warned:
                self._warned.add(key)
                cachefiles.warn(jpath, str(exc))
            return None
        if got is not None and _infrastructure_row(got[0]):
            # an earlier sweep stored an infrastructure failure as if it were the method's
            # verdict: not trusted, removed, and the run is computed again
            for p in (jpath, ppath):
                with contextlib.suppress(OSError):
                    p.unlink()
            self.repaired += 1
            return None
        if got is not None:
            _touch(jpath, ppath)
        return got

    def prune(self, before: float) -> tuple[int, int]:
        """Delete the entries not read or written since ``before`` (a ``time.time()``): every
        read marks its files as used (their modification time), every write is new. Returns
        (files deleted, bytes freed); empty case folders are removed too."""
        files = n_bytes = 0
        if not self.root.is_dir():
            return 0, 0
        for path in sorted(self.root.rglob("*")):
            if path.is_file() and path.suffix in (".json", ".parquet") and path.stat().st_mtime < before:
                n_bytes += path.stat().st_size
                path.unlink()
                files += 1
        for folder in sorted((p for p in self.root.rglob("*") if p.is_dir()), reverse=True):
            left = list(folder.iterdir())
            if all(p.is_file() and p.suffix not in (".json", ".parquet") for p in left):
                for p in left:  # the folder's lock file
                    p.unlink()
                folder.rmdir()
        return files, n_bytes

    def has(self, task: Task) -> bool:
        """Whether a verified entry of the run exists (damaged ones are warned about)."""
        return self._load(task) is not None

    def write(self, task: Task, outcome: Outcome, n_joints: int, reference=None, reference_id="") -> dict:
        """Store one finished run and return its row (errors against ``reference`` included).
        An infrastructure failure is never stored (ValueError): use :meth:`unstored_row`."""
        if outcome.infrastructure:
            raise ValueError(f"{task.case}/{task.key}: an infrastructure failure is not a verdict to store")
        jpath, ppath, key = self._paths(task)
        jpath.parent.mkdir(parents=True, exist_ok=True)
        row = self.unstored_row(task, outcome, n_joints, reference, reference_id)
        row["key"] = key
        history = cachefiles.result_bytes(outcome.result) if outcome.result is not None else None
        row = cachefiles.write_entry(jpath, ppath, row, history)
        self._fresh.add(key)
        self._warned.discard(key)
        return row

    def unstored_row(
        self, task: Task, outcome: Outcome, n_joints: int, reference=None, reference_id=""
    ) -> dict:
        """The row of a run as :meth:`write` would store it, without storing it (the rows of
        infrastructure failures, which the report shows but the store never keeps)."""
        row = self._row(task, outcome, n_joints)
        has_history = row["status"] in WITH_HISTORY and outcome.result is not None
        row.update(score(outcome.result if has_history else None, reference, n_joints, row))
        row["reference_id"] = reference_id
        row["scored_with"] = _metrics_version()
        return row

    @staticmethod
    def _row(task: Task, outcome: Outcome, n_joints: int) -> dict:
        res = outcome.result
        meta = dict(res.meta) if res is not None else {}
        status, reason = row_status(outcome)
        return {
            "case": task.case,
            "method": task.method,
            "k": task.k,
            "h": task.h,
            "duration": task.duration,
            "options": options_text(task.options),
            **{f"opt_{k}": str(v) for k, v in task.options},
            "status": status,
            "reason": reason,
            "warnings": "; ".join(getattr(res, "warnings", ())),
            "n_joints": n_joints,
            "space": "spatial" if _is_spatial_result(res) else "planar",
            "wall_time": float(res.wall_time) if res is not None else math.nan,
            "run_time": outcome.run_time,
            "n_steps": int(res.n_steps) if res is not None else -1,
            "n_dof": _plain(meta.get("n_dof", meta.get("ndof"))),
            "worker": outcome.worker,
            "console": outcome.console[-2000:],
            "iterations_mean": _plain(meta.get("iterations_mean")),
            "meta": _plain({k: v for k, v in meta.items() if k not in ("versions",)}),
            "versions": _plain(meta.get("versions", {})),
            "task": task.key,
            **outcome.timing,
        }

    def row(self, task: Task) -> dict:
        """The stored row of a finished run (KeyError when there is no usable entry)."""
        got = self._load(task)
        if got is None:
            raise KeyError(f"no usable stored run for {task.case}/{task.key}")
        return got[0]

    def history(self, task: Task):
        """The stored Result of a finished run, or None when the run left none."""
        got = self._load(task)
        return cachefiles.result_from_bytes(got[1]) if got is not None and got[1] is not None else None

    def table(self, tasks, references=None, unstored=None):
        """Rows of the given (finished) tasks as a DataFrame, errors rescored where the stored
        reference id differs from the current one. ``references``: case -> (Result, id).
        ``unstored``: Task -> row of runs not in the store (infrastructure failures), in place."""
        import pandas as pd

        rows = []
        for task in dict.fromkeys(tasks):
            got = self._load(task)
            if got is None:
                if unstored and task in unstored:
                    rows.append(dict(unstored[task]))
                continue
            row, data = got
            ref, ref_id = (references or {}).get(task.case, (None, ""))
            stale = row.get("reference_id") != ref_id or row.get("scored_with") != _metrics_version()
            if references is not None and stale:
                usable = row["status"] in WITH_HISTORY and data is not None
                res = cachefiles.result_from_bytes(data) if usable else None
                row.update(score(res, ref, row["n_joints"], row))
                row["reference_id"] = ref_id
                row["scored_with"] = _metrics_version()
            drop = ("meta", "versions", "history_sha256", cachefiles.SEAL, "scored_with")
            rows.append({k: v for k, v in row.items() if k not in drop})
        return pd.DataFrame(rows)


def _infrastructure_row(row: dict) -> bool:
    """Whether a stored row records an infrastructure failure instead of a method's verdict."""
    reason = str(row.get("reason") or "")
    return row.get("status") == "failed" and (
        reason.startswith(LEGACY_INFRASTRUCTURE) or reason.startswith(INFRASTRUCTURE)
    )


def _touch(*paths) -> None:
    """Mark entry files as used now (see :meth:`RunStore.prune`); a read-only store is left as it is."""
    for p in paths:
        with contextlib.suppress(OSError):
            os.utime(p)


@functools.cache
def _metrics_version() -> str:
    """Hash of the code that computes the error columns: a stored row scored by other code is
    scored again when it is read."""
    return fingerprint.tree_hash(Path(metrics.__file__))[:16]


def row_status(outcome: Outcome) -> tuple[str, str]:
    """(status, reason) of a run's row: the outcome's, refined by the Result's own status
    ("unconverged", "ill-conditioned") when the run returned one; the reason then lists the
    Result's warnings."""
    res = outcome.result
    status = getattr(res, "status", "ok") if outcome.status == "ok" and res is not None else outcome.status
    reason = outcome.reason
    if status != outcome.status and not reason:
        reason = "; ".join(getattr(res, "warnings", ())) or f"method reported {status}"
    return status, reason


def score(result, reference, n_joints: int, row: dict) -> dict:
    """Error columns (and ``error_note``) of one run against the reference; NaN with a note
    when there is no result or no reference."""
    if result is None:
        return {**metrics.nan_errors(n_joints), "error_note": row.get("reason", "") or "no result"}
    if reference is None:
        return {**metrics.nan_errors(n_joints), "error_note": "no reference solution for this case"}
    try:
        return {**metrics.errors(result, reference), "error_note": ""}
    except ValueError as exc:
        return {**metrics.nan_errors(n_joints), "error_note": f"cannot compare: {exc}"}


def task_from_row(row) -> Task:
    """The task of a stored row (option values come back as text; the key is the same)."""
    opts = dict(x.split("=", 1) for x in row["options"].split(",")) if row["options"] else {}
    return Task(row["case"], row["method"], row["k"], row["h"], row["duration"], tuple(opts.items()))
