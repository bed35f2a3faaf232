"""``dttmm report [--quick|--full] [--case PATH ...] [--method SPEC ...] [--out DIR] [--scheduler ADDR] [--from-data] [--recompute]``.

Runs every study (one resumable sweep on Dask), stores the tables under ``<out>/data/`` and
writes ``<out>/index.html`` and ``<out>/REPORT.md``. ``--case`` (repeatable) runs the studies on
the given case files instead of the shipped ones; their references are computed and cached
like those of the shipped cases. ``--method`` (repeatable) adds a method of one's own to every
study: ``my_pkg.my_solver:simulate``, ``path/to/solver.py:simulate`` or the name of an entry
point of the group ``dttmm.methods`` (docs/methods.md). ``--from-data`` only rebuilds the figures and pages from the
stored tables.
"""

from __future__ import annotations

import json
import shlex
import sys
import time
from pathlib import Path

__all__ = ["main", "run_report"]


def _methods_in(plan) -> list:
    """Every method the plan's studies run: those a study names, else every registered method
    that takes part in it (experiments/methods.py)."""
    from experiments import methods
    from experiments.params import study_params

    names = []
    for study, p in plan.studies.items():
        p = study_params(study, p)
        names += list(p.methods) if p.methods is not None else methods.takes_part(study, size=plan.name)
    return list(dict.fromkeys(names))


def run_report(
    plan,
    out,
    *,
    data="data",
    scheduler=None,
    workers=None,
    progress=True,
    command="",
    bench_dir="data/bench",
    log=print,
    recompute=False,
    prune_cache=False,
):
    """Run the plan's studies and write the report into ``out``; returns (html, md) paths.
    ``recompute``: ignore every cached run and reference and write them again. ``prune_cache``:
    afterwards delete the cached runs of this plan's store that the report did not use."""
    from dttmm import case_to_dict
    from experiments import methods
    from experiments.context import prepare
    from experiments.params import as_dicts
    from experiments.study import run_studies, save_tables, sitting_out

    from . import provenance
    from .build import build

    t0 = time.perf_counter()
    mark = time.time()
    out = Path(out)
    t_probe = time.perf_counter()
    log("checking which methods run here (a fresh checkout compiles the numba engines first: about 2 min)")
    avail = methods.available(_methods_in(plan), workers=1 if scheduler == "serial" else workers)
    log(f"methods checked ({time.perf_counter() - t_probe:.0f} s)")
    for m, why in avail.items():
        if why:
            log(f"unavailable: {m}: {why}")
    ctx = prepare(plan, data, log=log, recompute=recompute)
    tables = run_studies(ctx, scheduler=scheduler, workers=workers, progress=progress)
    from .animations import motion_table, report_cases

    tables.update(motion_table(report_cases(ctx), log=log))
    save_tables(tables, out / "data")
    meta = {
        **provenance.collect(command),
        "plan": plan.name,
        "note": plan.note,
        "availability": avail,
        "references": ctx.provenance,
        "elapsed": time.perf_counter() - t0,
        "studies": as_dicts(plan.studies),
        "cases": {n: case_to_dict(c) for n, c in ctx.cases.items()},
        # spatial arms: which methods sit them out, and why (the studies run the rest)
        "sitting_out": {
            n: {m: why for m in methods.names() if (why := methods.get(m).why_not_case(c))}
            for n, c in ctx.cases.items()
            if methods.is_spatial(c)
        },
        # runs a study plans but sits out before they start, and why (study -> case -> method)
        "sitting_out_runs": sitting_out(ctx),
        "case_files": dict(plan.case_files),
    }
    (out / "data" / "report_meta.json").write_text(json.dumps(meta, indent=1, default=str))
    paths = build(tables, meta, out, bench_dir=bench_dir)
    log(f"report: {paths[0]} and {paths[1]} ({time.perf_counter() - t0:.0f} s)")
    if prune_cache:
        n_files, n_bytes = ctx.store.prune(mark)
        log(
            f"pruned {n_files} cached-run files ({n_bytes / 1e6:.1f} MB) this report did not use from {ctx.store.root}"
        )
    return paths


def _from_data(out, command, bench_dir, log=print):
    from experiments.study import load_tables

    from . import provenance
    from .build import build

    out = Path(out)
    mpath = out / "data" / "report_meta.json"
    if not mpath.exists():
        raise SystemExit(
            f"dttmm report --from-data: no stored study data in {out / 'data'} "
            "(run `dttmm report` without --from-data first)"
        )
    meta = json.loads(mpath.read_text())
    tables = {
        k: v for k, v in load_tables(out / "data").items() if not (k == "bench" or k.startswith("bench_"))
    }
    now = provenance.collect(command)
    paths = build(
        tables,
        meta,
        out,
        bench_dir=bench_dir,
        footer_extra={"figures rebuilt": f"{now['date']} from stored data by `{command}`"},
    )
    log(f"report rebuilt from stored data: {paths[0]} and {paths[1]}")
    return paths


def add_methods(specs, timeout=None) -> list[str]:
    """Register the outside methods named by ``specs`` (``experiments.methods.load_spec``), with
    a time limit per call of ``timeout`` s when given; returns their names. InputError (one
    line) for a bad spec or timeout."""
    from dataclasses import replace

    from dttmm.errors import InputError
    from experiments import methods

    if timeout is not None and not timeout > 0:
        raise InputError("--method-timeout", timeout, "must be a positive number of seconds")
    out = []
    for spec in specs:
        rec = methods.load_spec(spec)
        if timeout is not None and rec.name not in methods.METHODS:
            rec = methods.register(replace(rec, timeout=float(timeout)))
        out.append(rec.name)
    return out


def main(argv=None) -> int:
    """Entry point of ``dttmm report``."""
    from dttmm.cliparse import OneLineParser
    from experiments.plan import plan_for

    argv = list(sys.argv[1:] if argv is None else argv)
    ap = OneLineParser(prog="dttmm report", description=__doc__.splitlines()[0])
    g = ap.add_mutually_exclusive_group()
    g.add_argument(
        "--quick", dest="size", action="store_const", const="quick", help="the < 10 min size (default)"
    )
    g.add_argument("--full", dest="size", action="store_const", const="full", help="the paper-size studies")
    ap.add_argument("--out", default="out/report", help="report folder (default out/report)")
    ap.add_argument("--data", default="data", help="folder of references and cached runs (default data)")
    ap.add_argument(
        "--scheduler",
        default=None,
        help="dask scheduler address (default: a LocalCluster on this machine; 'serial': no dask)",
    )
    ap.add_argument("--workers", type=int, default=None, help="LocalCluster workers (default: cores)")
    ap.add_argument(
        "--from-data", action="store_true", help="only rebuild figures and pages from stored tables"
    )
    ap.add_argument("--bench", default="data/bench", help="pytest-benchmark JSON folder")
    ap.add_argument("--no-progress", action="store_true")
    ap.add_argument(
        "--recompute",
        action="store_true",
        help="ignore every cached run and reference solution and compute (and store) them again",
    )
    ap.add_argument(
        "--prune-cache",
        action="store_true",
        help="afterwards delete this plan's cached runs that the report did not use (older code, edited cases)",
    )
    ap.add_argument(
        "--case",
        action="append",
        default=[],
        metavar="PATH",
        help="case TOML file to report on instead of the shipped cases (repeat for several)",
    )
    ap.add_argument(
        "--method",
        action="append",
        default=[],
        metavar="SPEC",
        help="a method of one's own in every study: module:function, file.py:function or an entry-point name",
    )
    ap.add_argument(
        "--method-timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds one call of an outside method may take (default 600); a run past it is an omission",
    )
    a = ap.parse_args(argv)
    command = "dttmm report " + shlex.join(argv)
    if a.from_data and a.recompute:
        ap.error("--recompute computes the runs again; --from-data only redraws stored tables")
    if a.from_data and a.prune_cache:
        ap.error("--prune-cache needs a report that reads its runs; --from-data reads none")
    if a.from_data:
        _from_data(a.out, command, a.bench)
        return 0
    from dttmm.errors import InputError

    try:
        plan = plan_for(a.size or "quick", a.case)
        add_methods(a.method, a.method_timeout)
    except InputError as exc:
        ap.error(str(exc))
    run_report(
        plan,
        a.out,
        data=a.data,
        scheduler=a.scheduler,
        workers=a.workers,
        progress=not a.no_progress,
        command=command,
        bench_dir=a.bench,
        recompute=a.recompute,
        prune_cache=a.prune_cache,
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
