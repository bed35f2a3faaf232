"""Running studies: one sweep for all their runs, then each study's analysis; tables saved
as parquet and CSV. ``study_main`` is the command line of each single study."""

from __future__ import annotations

import argparse
from pathlib import Path

import pandas as pd

from . import methods
from .context import prepare
from .plan import PLANS
from .studies import STUDIES
from .sweep import run_sweep

__all__ = [
    "add_cases",
    "load_tables",
    "run_studies",
    "save_tables",
    "sitting_out",
    "study_main",
    "study_tasks",
]


def add_cases(ctx, names=None) -> None:
    """Put the studies' own cases (a study module's ``cases(ctx)``: benchmark problems, the
    closed-loop arm and its variants) into ``ctx.cases``; a different case of the same name is an
    error. Listing a study's tasks afterwards changes nothing."""
    for n in names or STUDIES:
        fn = getattr(STUDIES[n], "cases", None) if n in ctx.plan.studies else None
        for name, case in (fn(ctx) if fn else {}).items():
            if ctx.cases.get(name, case) != case:
                raise ValueError(f"{n} study: case {name!r} clashes with a different case of that name")
            ctx.cases[name] = case


def study_tasks(ctx, name: str) -> list:
    """The runs of study ``name``: its module's tasks, each kept where its method runs the case
    at that k. One rule for every study: a spatial arm needs a method with a spatial entry, up to
    its ``spatial_max_k`` (``Method.runs_on``, experiments/methods.py). The studies' own cases
    must be in ``ctx.cases`` (:func:`add_cases`). A run whose study options the method refuses
    on that case (:func:`experiments.methods.why_not_options`) is sat out before it starts, with
    the reason (:func:`sitting_out`)."""
    return [
        t
        for t in STUDIES[name].tasks(ctx)
        if methods.runs_on(t.method, ctx.cases[t.case], t.k)
        and not methods.why_not_options(t.method, ctx.cases[t.case], t.options)
    ]


def sitting_out(ctx, names=None) -> dict:
    """study -> case -> method -> why: the runs a study plans that are sat out before they start
    (a study option the method refuses on the case, :func:`experiments.methods.why_not_options`;
    the cases a study does not take, its module's ``sitting_out(ctx)``). The studies' own cases
    must be in ``ctx.cases``."""
    out: dict = {}
    for n in (n for n in (names or STUDIES) if n in ctx.plan.studies):
        mine = out.setdefault(n, {})
        for t in STUDIES[n].tasks(ctx):
            case = ctx.cases[t.case]
            if methods.runs_on(t.method, case, t.k):
                why = methods.why_not_options(t.method, case, t.options)
                if why:
                    mine.setdefault(t.case, {})[t.method] = why
        fn = getattr(STUDIES[n], "sitting_out", None)
        for case, whys in (fn(ctx) if fn else {}).items():
            mine.setdefault(case, {}).update(whys)
        if not mine:
            del out[n]
    return out


def run_studies(ctx, names=None, *, scheduler=None, workers=None, progress=True) -> dict:
    """Run the studies ``names`` (default: every study of the plan) and return their tables."""
    names = [n for n in (names or STUDIES) if n in ctx.plan.studies]
    add_cases(ctx, names)
    per_study = {n: study_tasks(ctx, n) for n in names}
    every = [t for ts in per_study.values() for t in ts]
    repeats = {}  # timed calls per run: the most any study that reports cost asks for
    for n, ts in per_study.items():
        for t in ts:
            repeats[t] = max(repeats.get(t, 1), getattr(STUDIES[n], "REPEATS", 1))
    run_sweep(
        every,
        ctx.cases,
        ctx.store,
        references=ctx.references,
        scheduler=scheduler,
        workers=workers,
        progress=progress,
        desc=f"{ctx.plan.name} runs",
        repeats=repeats,
    )
    tables = {}
    for n in names:
        tables.update(STUDIES[n].analyse(ctx, ctx.store.table(per_study[n], ctx.references)))
    return tables


def _clean(df: pd.DataFrame) -> pd.DataFrame:
    """Columns parquet can store (mixed object columns become text)."""
    df = df.copy()
    for c in df.columns:
        if df[c].dtype == object:
            kinds = {type(v) for v in df[c] if v is not None and v == v}
            if len(kinds) > 1 or (kinds and not kinds <= {str}):
                df[c] = df[c].map(lambda v: "" if v is None else str(v))
    return df


def save_tables(tables: dict, folder) -> Path:
    """Write each table as ``<name>.parquet`` and ``<name>.csv`` in ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for name, df in tables.items():
        df = _clean(df)
        df.to_parquet(folder / f"{name}.parquet", index=False)
        df.to_csv(folder / f"{name}.csv", index=False)
    return folder


def load_tables(folder) -> dict:
    """Every ``<name>.parquet`` table in ``folder``."""
    return {p.stem: pd.read_parquet(p) for p in sorted(Path(folder).glob("*.parquet"))}


def study_main(name: str, argv=None) -> int:
    """``python -m experiments.studies.<name> [--quick|--full] [--out DIR] [--scheduler ADDR]
    [--recompute]``."""
    ap = argparse.ArgumentParser(prog=f"python -m experiments.studies.{name}")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--quick", dest="size", action="store_const", const="quick")
    g.add_argument("--full", dest="size", action="store_const", const="full")
    ap.add_argument("--out", default=f"out/{name}", help="folder for the study's tables")
    ap.add_argument("--data", default="data", help="folder of references and cached runs")
    ap.add_argument("--scheduler", default=None, help="dask scheduler address, or 'serial'")
    ap.add_argument("--workers", type=int, default=None)
    ap.add_argument("--recompute", action="store_true", help="ignore cached runs and references")
    a = ap.parse_args(argv)
    ctx = prepare(PLANS[a.size or "quick"], a.data, recompute=a.recompute)
    tables = run_studies(ctx, [name], scheduler=a.scheduler, workers=a.workers)
    out = save_tables(tables, a.out)
    print(f"{name}: tables in {out}")
    return 0
