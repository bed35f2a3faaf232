"""Sweep runner: many (case, method, k, h) runs on Dask distributed, resumable.

By default a LocalCluster on this machine's cores (one process per core, one thread each, so
each timing is one run alone in its worker process); ``scheduler="tcp://HOST:PORT"`` uses a
running cluster; ``scheduler="serial"`` runs in this process (debugging, tests). Each finished
run is written at once by the :class:`~experiments.runs.RunStore`, so a killed sweep resumes
where it stopped and recomputes only the missing runs (and any stored run whose files fail
verification, with a warning).
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable
from contextlib import contextmanager

from . import methods
from .runs import Outcome, RunStore, Task, execute

__all__ = ["run_sweep", "pending"]


def pending(tasks: Iterable[Task], store: RunStore, repeats=None) -> list[Task]:
    """Tasks (deduplicated, in order) that have no finished run in the store, or whose stored
    successful run was timed with fewer repeats than ``repeats`` (Task -> int) asks for."""
    need = repeats or {}

    def done(t):
        if not store.has(t):
            return False
        if need.get(t, 1) <= 1:
            return True
        row = store.row(t)
        return row.get("status") != "ok" or int(row.get("timing_repeats") or 1) >= need[t]

    return [t for t in dict.fromkeys(tasks) if not done(t)]


@contextmanager
def _client(scheduler, workers):
    """A dask.distributed Client: to ``scheduler`` when given, else to a new LocalCluster."""
    from dask.distributed import Client, LocalCluster

    if scheduler:
        client = Client(scheduler)
        try:
            yield client
        finally:
            client.close()
        return
    # Workers inherit the environment: one BLAS thread each so runs do not compete for cores.
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    n = workers or os.cpu_count() or 1
    with (
        LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
            silence_logs=logging.ERROR,
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def _resolved(tasks):
    """Method name -> resolved callable, or the reason it is unavailable."""
    out = {}
    for name in dict.fromkeys(t.method for t in tasks):
        try:
            out[name] = methods.resolve(name)
        except methods.MethodUnavailable as exc:
            out[name] = exc
    return out


def run_sweep(
    tasks,
    cases: dict,
    store: RunStore,
    *,
    references=None,
    scheduler=None,
    workers=None,
    progress=True,
    desc="sweep",
    repeats=None,
):
    """Run every task not yet in ``store``, writing each as it finishes; return the table.

    Parameters
    ----------
    tasks : iterable of Task
    cases : dict case name -> dttmm.Case, already shortened to the tasks' durations
    store : RunStore
    references : dict case name -> (Result or None, reference id), for the error columns
    scheduler : None (LocalCluster), ``"serial"`` (this process) or a scheduler address
    workers : number of LocalCluster workers (default: this machine's cores)
    repeats : dict Task -> timed calls per run (default 1; cost studies ask for ≥ 3)

    Returns
    -------
    pandas.DataFrame, one row per task (see RunStore.table).
    """
    tasks = list(dict.fromkeys(tasks))
    store.bind(cases)  # runs are keyed by the content of these cases
    repeats = repeats or {}
    todo = pending(tasks, store, repeats)
    references = references or {}
    for t in todo:
        if abs(cases[t.case].scenario.duration - t.duration) > 1e-12:
            raise ValueError(
                f"task {t.key} wants duration {t.duration}, case {t.case!r} has "
                f"{cases[t.case].scenario.duration}"
            )
    resolved = _resolved(todo)
    bar = _bar(len(tasks), len(tasks) - len(todo), desc, progress)

    def finish(task, outcome):
        ref, ref_id = references.get(task.case, (None, ""))
        store.write(task, outcome, cases[task.case].n_joints, ref, ref_id)
        bar.update(1)
        bar.set_postfix_str(f"{task.case} {task.method} k={task.k} h={task.h:g}: {outcome.status}")

    runnable = []
    for t in todo:
        f = resolved[t.method]
        if isinstance(f, Exception):
            finish(t, Outcome("unavailable", str(f)))
        else:
            runnable.append(t)
    try:
        if scheduler == "serial":
            for t in runnable:
                finish(t, execute(resolved[t.method], cases[t.case], t, repeats.get(t, 1)))
        elif runnable:
            _distributed(runnable, resolved, cases, finish, scheduler, workers, store, repeats)
    finally:
        bar.close()
    return store.table(tasks, references if references else None)


def _distributed(runnable, resolved, cases, finish, scheduler, workers, store, repeats):
    from dask.distributed import as_completed

    with _client(scheduler, workers) as client:
        # Cases and methods go to the workers once; each task then ships only its key.
        case_f = {
            name: client.scatter(c, broadcast=True)
            for name, c in cases.items()
            if any(t.case == name for t in runnable)
        }
        # Longest runs first (higher priority), so no worker is left with one long run at the end.
        fut = {
            client.submit(
                execute,
                resolved[t.method],
                case_f[t.case],
                t,
                repeats.get(t, 1),
                pure=False,
                # the entry key: a shared scheduler never confuses two versions of a run
                key=f"run-{t.case}-{t.key}-{store.entry_key(t)[:16]}",
                priority=_cost(t, cases[t.case]),
            ): t
            for t in runnable
        }
        for f in as_completed(fut):
            task = fut[f]
            try:
                outcome = f.result()
            except Exception as exc:  # a worker died under the run
                outcome = Outcome("failed", f"worker error: {type(exc).__name__}: {exc}")
            finish(task, outcome)


def _cost(task: Task, case) -> int:
    """Rough relative cost of a run (steps × joints × elements), for scheduling order only."""
    return int(task.duration / task.h * case.n_joints * (max(task.k, 1) + 4))


class _NoBar:
    def update(self, n):
        pass

    def set_postfix_str(self, s):
        pass

    def close(self):
        pass


def _bar(total, done, desc, progress):
    if not progress:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(total=total, initial=done, desc=desc, unit="run", dynamic_ncols=True)
