"""One run of a method, and the on-disk store that makes sweeps resumable.

A :class:`Task` names a run: (case, duration, method, k, h, options). :func:`execute` runs it
(on any worker) and returns an :class:`Outcome`; :class:`RunStore` writes each finished run
at once as ``<case>/<key>.parquet`` (its time history) and ``<case>/<key>.json`` (its row),
the JSON last, so a run counts as done only when both are on disk.
"""

from __future__ import annotations

import json
import math
import os
import re
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from . import methods, metrics

__all__ = ["Task", "Outcome", "execute", "RunStore", "options_text", "task_from_row"]


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
    for a run that finished, its timing (``timing_*`` columns, see :mod:`experiments.timing`)."""

    status: str
    reason: str = ""
    result: object = None
    run_time: float = math.nan  # s, least wall time of the calls (build + solve), in the worker
    worker: str = field(default_factory=lambda: f"{os.uname().nodename}:{os.getpid()}")
    timing: dict = field(default_factory=dict)


def _check(result) -> str:
    """Why a returned Result is not usable ('' when it is)."""
    meta = result.meta or {}
    if meta.get("success", True) is False:
        return f"method reported failure: {meta.get('reason') or meta.get('message') or 'no reason given'}"
    arrays = (result.joint_angle, result.tip_deflection, result.end_effector)
    if not all(np.all(np.isfinite(a)) for a in arrays):
        return "non-finite output (diverged)"
    return ""


def execute(simulate, case, task: Task, repeats: int = 1) -> Outcome:
    """Run one task with a resolved method; never raises for a failing run.

    ``repeats`` ≥ 1 calls (one BLAS thread, CPU and wall time each, see
    :func:`experiments.timing.measure`); the first call's Result is kept. Studies that report
    cost ask for ≥ 3, accuracy-only studies for 1. ``KeyboardInterrupt`` and ``SystemExit``
    still propagate (they stop the sweep).
    """
    from .timing import measure

    t0 = time.perf_counter()
    try:
        res, timing = measure(lambda: simulate(case, task.k, task.h, **dict(task.options)), repeats)
    except methods.MethodUnavailable as exc:
        return Outcome("unavailable", str(exc), run_time=time.perf_counter() - t0)
    except Exception as exc:  # recorded with its reason, never dropped
        msg = str(exc).splitlines()[0][:300] if str(exc) else ""
        return Outcome("failed", f"{type(exc).__name__}: {msg}", run_time=time.perf_counter() - t0)
    why = _check(res)
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


class RunStore:
    """Folder of finished runs: one JSON row and one parquet history per task."""

    def __init__(self, root):
        self.root = Path(root)

    def _paths(self, task: Task) -> tuple[Path, Path]:
        d = self.root / task.case
        return d / f"{task.key}.json", d / f"{task.key}.parquet"

    def has(self, task: Task) -> bool:
        return self._paths(task)[0].exists()

    def write(self, task: Task, outcome: Outcome, n_joints: int, reference=None, reference_id="") -> dict:
        """Store one finished run and return its row (errors against ``reference`` included)."""
        jpath, ppath = self._paths(task)
        jpath.parent.mkdir(parents=True, exist_ok=True)
        row = self._row(task, outcome, n_joints)
        if outcome.result is not None:
            tmp = ppath.with_suffix(".tmp.parquet")
            outcome.result.to_frame().to_parquet(tmp)
            os.replace(tmp, ppath)
        row.update(score(outcome.result if outcome.status == "ok" else None, reference, n_joints, row))
        row["reference_id"] = reference_id
        tmp = jpath.with_suffix(".tmp")
        tmp.write_text(json.dumps(row, indent=1))
        os.replace(tmp, jpath)
        return row

    @staticmethod
    def _row(task: Task, outcome: Outcome, n_joints: int) -> dict:
        res = outcome.result
        meta = dict(res.meta) if res is not None else {}
        row = {
            "case": task.case,
            "method": task.method,
            "k": task.k,
            "h": task.h,
            "duration": task.duration,
            "options": options_text(task.options),
            **{f"opt_{k}": str(v) for k, v in task.options},
            "status": outcome.status,
            "reason": outcome.reason,
            "n_joints": n_joints,
            "wall_time": float(res.wall_time) if res is not None else math.nan,
            "run_time": outcome.run_time,
            "n_steps": int(res.n_steps) if res is not None else -1,
            "n_dof": _plain(meta.get("n_dof", meta.get("ndof"))),
            "worker": outcome.worker,
            "iterations_mean": _plain(meta.get("iterations_mean")),
            "meta": _plain({k: v for k, v in meta.items() if k not in ("versions",)}),
            "versions": _plain(meta.get("versions", {})),
            "key": task.key,
            **outcome.timing,
        }
        return row

    def row(self, task: Task) -> dict:
        return json.loads(self._paths(task)[0].read_text())

    def history(self, task: Task):
        """The stored Result of a finished run, or None when the run left none."""
        from dttmm import Result
        import pandas as pd

        p = self._paths(task)[1]
        return Result.from_frame(pd.read_parquet(p)) if p.exists() else None

    def table(self, tasks, references=None):
        """Rows of the given (finished) tasks as a DataFrame, errors rescored where the stored
        reference id differs from the current one. ``references``: case -> (Result, id)."""
        import pandas as pd

        rows = []
        for task in dict.fromkeys(tasks):
            if not self.has(task):
                continue
            row = self.row(task)
            ref, ref_id = (references or {}).get(task.case, (None, ""))
            if references is not None and row.get("reference_id") != ref_id:
                res = self.history(task) if row["status"] == "ok" else None
                row.update(score(res, ref, row["n_joints"], row))
                row["reference_id"] = ref_id
            rows.append({k: v for k, v in row.items() if k not in ("meta", "versions")})
        return pd.DataFrame(rows)


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


def task_dict(task: Task) -> dict:
    """Plain-data form of a task (for provenance files)."""
    return asdict(task)
