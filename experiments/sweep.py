"""Sweep runner: many (case, method, k, h) runs on Dask distributed, resumable.

By default a LocalCluster on this machine's cores (one process per core, one thread each, so
each timing is one run alone in its worker process); ``scheduler="tcp://HOST:PORT"`` uses a
running cluster; ``scheduler="serial"`` runs in this process (debugging, tests). Each finished
run is written at once by the :class:`~experiments.runs.RunStore`, so a killed sweep resumes
where it stopped and recomputes only the missing runs (and any stored run whose files fail
verification, with a warning).

Isolation: a worker holds one run at a time, so a run that kills its process takes no other
run with it; Dask's nanny starts a new worker and the run is tried again
(:data:`ATTEMPTS` in all), then it is an omission. A run past its method's time limit is the
method's verdict (stored); its worker, where the call still runs, is restarted. Anything that
keeps a run from giving its own verdict (a lost worker, a method that cannot be loaded on the
worker, a cancelled future, an interrupted sweep) is an *infrastructure failure*: shown in the
table with its reason, never stored, so the next sweep runs it again.
"""

from __future__ import annotations

import contextlib
import logging
import os
from collections.abc import Iterable
from contextlib import contextmanager

from . import estimate, methods
from .runs import Outcome, RunStore, Task, execute, infrastructure

#: Tries of a run whose worker process dies under it (the Dask scheduler's allowed failures + 1)
#: on a cluster this sweep starts; an outside scheduler keeps its own setting.
ATTEMPTS = 2

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
    import dask

    with (
        dask.config.set(
            {
                # one run per worker at a time: a process that dies takes no queued run with it
                "distributed.scheduler.worker-saturation": 1.0,
                "distributed.scheduler.allowed-failures": ATTEMPTS - 1,
            }
        ),
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
    costs = estimate.load_costs()
    est = {t: estimate.estimate(t, cases[t.case], costs, repeats.get(t, 1)) for t in todo}
    n_workers = 1 if scheduler == "serial" else (workers or os.cpu_count() or 1)
    by_method: dict = {}
    for t, s in est.items():
        by_method[t.method] = by_method.get(t.method, 0.0) + s
    if progress:
        print(estimate.plan_text(len(tasks), len(todo), sum(est.values()), n_workers, by_method), flush=True)
    bar = _bar(sum(est.values()), desc, progress)
    done, spent = [0], [0.0]
    unstored: dict = {}

    def finish(task, outcome):
        ref, ref_id = references.get(task.case, (None, ""))
        if outcome.infrastructure:
            unstored[task] = store.unstored_row(task, outcome, cases[task.case].n_joints, ref, ref_id)
        else:
            store.write(task, outcome, cases[task.case].n_joints, ref, ref_id)
        done[0] += 1
        spent[0] += est.get(task, 0.0)
        _advance(bar, spent[0], done[0] == len(todo))
        bar.set_postfix_str(
            f"{done[0]}/{len(todo)} runs; {task.case} {task.method} k={task.k} h={task.h:g}: {outcome.status}"
        )

    runnable = []
    for t in todo:
        f = resolved[t.method]
        if isinstance(f, Exception):
            finish(t, Outcome("unavailable", str(f)))
        else:
            runnable.append(t)
    runnable.sort(key=lambda t: -est[t])  # longest first: no worker is left with one long run at the end
    try:
        if scheduler == "serial":
            for t in runnable:
                finish(t, execute(resolved[t.method], cases[t.case], t, repeats.get(t, 1)))
        elif runnable:
            _distributed(runnable, resolved, cases, finish, scheduler, workers, store, repeats, est)
    finally:  # an interrupted sweep stores nothing more: its runs in flight are run next time
        bar.close()
    if store.repaired and progress:
        print(
            f"run store: {store.repaired} stored infrastructure failure(s) of an earlier sweep dropped and run again",
            flush=True,
        )
    return store.table(tasks, references if references else None, unstored)


def _advance(bar, spent: float, last: bool) -> None:
    """Move the bar to ``spent`` estimated seconds; it reaches its end only with the last run
    (an estimate that runs ahead of the runs still in flight stops just short of it)."""
    total = float(bar.total)
    # short of the end as the bar prints it too: its count ({n:.0f}) and its percentage
    cap = min(total - 1.0, 0.99 * total, round(total) - 0.51)
    target = total if last else max(0.0, min(spent, cap))
    if target > bar.n:
        bar.update(target - bar.n)


def _distributed(runnable, resolved, cases, finish, scheduler, workers, store, repeats, est):
    from dask.distributed import as_completed

    with _client(scheduler, workers) as client:
        # Every task carries its case (small): data scattered to a worker that dies would take
        # every run depending on it down ("lost dependencies").
        def submit(t, attempt=0):
            return client.submit(
                execute,
                resolved[t.method],
                cases[t.case],
                t,
                repeats.get(t, 1),
                pure=False,
                # the entry key: a shared scheduler never confuses two versions of a run
                key=f"run-{t.case}-{t.key}-{store.entry_key(t)[:16]}" + (f"-try{attempt}" if attempt else ""),
                # longest runs first (the estimated CPU time in ms), so no worker is left with
                # one long run at the end
                priority=int(1e3 * est[t]),
            )

        fut = {submit(t): (t, 0) for t in runnable}
        queue = as_completed(list(fut))
        for f in queue:
            task, attempt = fut.pop(f)
            try:
                outcome = f.result()
            except Exception as exc:  # noqa: BLE001 - the run gave no verdict of its own
                why = _infrastructure_reason(exc)
                if attempt + 1 < ATTEMPTS and not _killed_worker(exc):
                    g = submit(task, attempt + 1)  # a lost future, not a crash: try it again
                    fut[g] = (task, attempt + 1)
                    queue.add(g)
                    continue
                outcome = infrastructure(why)
            finish(task, outcome)
            if outcome.runaway:
                _restart(client, outcome.worker)


def _killed_worker(exc) -> bool:
    return type(exc).__name__ == "KilledWorker"


def _infrastructure_reason(exc) -> str:
    """What kept a run from giving its verdict, in words."""
    name = type(exc).__name__
    if name == "KilledWorker":
        return (
            f"its worker process died during the run, {ATTEMPTS} times (the method may end or crash "
            "its process: os._exit, a segmentation fault, out of memory)"
        )
    if "Cancelled" in name:
        return f"the run was cancelled before it finished ({name}: {exc})"
    text = str(exc).splitlines()[0][:300] if str(exc) else ""
    return f"the run could not be carried out on the cluster ({name}: {text})"


def _restart(client, worker: str) -> None:
    """Restart the worker process where a call past its time limit still runs (a thread
    cannot be stopped), so the runs after it are timed alone. ``worker`` is the outcome's
    ``host:pid``; a worker that cannot be found or restarted is left (its timings are marked
    noisy)."""
    with contextlib.suppress(Exception):
        pid = int(worker.rsplit(":", 1)[1])
        info = client.scheduler_info()["workers"]
        pids = client.run(os.getpid)
        for addr in info:
            if pids.get(addr) == pid:
                client.restart_workers([addr], raise_for_error=False)


class _NoBar:
    total = n = 0.0

    def update(self, n):
        pass

    def set_postfix_str(self, s):
        pass

    def close(self):
        pass


def _bar(seconds, desc, progress):
    """A bar over the estimated CPU seconds of the runs to compute (its rate and time to go are
    in estimated work, not in run counts, so longest-first ordering does not fool it)."""
    if not progress:
        return _NoBar()
    from tqdm import tqdm

    return tqdm(
        total=float(seconds),
        desc=desc,
        unit="s",
        unit_scale=False,
        dynamic_ncols=True,
        bar_format="{l_bar}{bar}| {n:.0f}/{total:.0f} s of est. CPU [{elapsed}<{remaining}{postfix}]",
    )
