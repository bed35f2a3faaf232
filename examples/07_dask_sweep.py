"""A sweep on a Dask cluster: every (method, k) of a small grid run on a LocalCluster of worker
processes, each finished run stored at once (a second call only reads the store)."""

import tempfile
from dataclasses import replace

from _gallery import CASES, QUICK

import dttmm
from experiments.runs import RunStore, Task
from experiments.sweep import run_sweep

if __name__ == "__main__":  # the workers are processes: they import this file
    from dask.distributed import LocalCluster

    case = dttmm.load_case(CASES / "single_link.toml")
    T = 0.1 if QUICK else 1.0
    cases = {"single_link": replace(case, scenario=replace(case.scenario, duration=T))}
    tasks = [
        Task("single_link", m, k, 1e-3, T)
        for m in ("dttmm", "global")
        for k in ((1, 2) if QUICK else (2, 4, 8, 16))
    ]
    with (
        tempfile.TemporaryDirectory() as store_dir,
        LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=":0") as cluster,
    ):
        store = RunStore(store_dir, cases)
        table = run_sweep(tasks, cases, store, scheduler=cluster.scheduler_address, progress=not QUICK)
        print(table[["method", "k", "h", "status", "wall_time"]].to_string(index=False))
