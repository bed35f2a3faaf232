"""Reference solutions: computed once per case at high accuracy, cached on disk, reused.

Each reference is stored as ``<folder>/<case>_T<duration>_dt<output step>.parquet``
(``Result.to_frame``) with a
JSON provenance beside it: method, k, h, options, versions, date, wall time, the size it was
made for, and a cross-check — the errors of a second, independent method against it.
A cached reference is reused only when its provenance matches the requested spec.
"""

from __future__ import annotations

import datetime
import json
import math
import platform
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from . import methods, metrics

__all__ = ["RefSpec", "reference", "load_reference"]


@dataclass(frozen=True)
class RefSpec:
    """How to compute a reference: a method at k elements per link and step h (s)."""

    method: str
    k: int
    h: float
    options: tuple = ()

    def describe(self) -> str:
        return f"{self.method} k={self.k} h={self.h:g}"


def _paths(folder, case) -> tuple[Path, Path]:
    stem = f"{case.name}_T{case.scenario.duration:g}_dt{case.scenario.output_step:g}"
    return Path(folder) / f"{stem}.parquet", Path(folder) / f"{stem}.json"


def load_reference(folder, case):
    """(Result, provenance) from the cache, or (None, None) when absent."""
    import pandas as pd
    from dttmm import Result

    ppath, jpath = _paths(folder, case)
    if not (ppath.exists() and jpath.exists()):
        return None, None
    prov = json.loads(jpath.read_text())
    if prov.get("status") != "ok":
        return None, prov
    return Result.from_frame(pd.read_parquet(ppath)), prov


def _versions(res) -> dict:
    from dttmm.timegrid import versions

    v = versions()
    v.update({k: str(x) for k, x in (res.meta.get("versions") or {}).items()})
    return v


def _try(spec: RefSpec, case):
    t0 = time.perf_counter()
    try:
        res = methods.run(spec.method, case, spec.k, spec.h, **dict(spec.options))
    except Exception as exc:  # a failing candidate is recorded and the next one tried
        return None, f"{spec.describe()}: {type(exc).__name__}: {str(exc)[:200]}", time.perf_counter() - t0
    from .runs import _check

    why = _check(res)
    return (None if why else res), (f"{spec.describe()}: {why}" if why else ""), time.perf_counter() - t0


def reference(case, candidates, folder, *, check=(), size="", recompute=False):
    """The reference Result of ``case`` and its provenance dict (cached in ``folder``).

    Parameters
    ----------
    case : dttmm.Case, already shortened to the study duration
    candidates : sequence of RefSpec, tried in order until one succeeds
    folder : cache folder
    check : sequence of RefSpec for the cross-check (the first that runs is used)
    size : name of the study size (recorded; e.g. ``quick`` references are cheaper)

    Returns
    -------
    (Result or None, dict). With no candidate working the Result is None and the provenance
    lists every failure; studies then report NaN errors with that reason.
    """
    candidates = list(candidates)
    ppath, jpath = _paths(folder, case)
    want = [asdict(c) for c in candidates]
    if not recompute:
        res, prov = load_reference(folder, case)
        if prov is not None and prov.get("candidates") == json.loads(json.dumps(want)):
            return res, prov
    jpath.parent.mkdir(parents=True, exist_ok=True)
    failures, res, used, wall = [], None, None, math.nan
    for spec in candidates:
        res, why, wall = _try(spec, case)
        if res is not None:
            used = spec
            break
        failures.append(why)
    prov = {
        "case": case.name,
        "duration": case.scenario.duration,
        "size": size,
        "candidates": want,
        "failures": failures,
        "date": datetime.datetime.now().isoformat(timespec="seconds"),
        "machine": f"{platform.node()} ({platform.machine()}, {platform.processor() or '?'})",
    }
    if res is None:
        prov.update(status="failed", id=f"none-{prov['date']}")
        jpath.write_text(json.dumps(prov, indent=1))
        return None, prov
    prov.update(
        status="ok",
        method=used.method,
        k=used.k,
        h=used.h,
        options=dict(used.options),
        wall_time=res.wall_time,
        run_time=wall,
        n_steps=res.n_steps,
        versions=_versions(res),
        id=f"{used.describe()} @ {prov['date']}",
        cross_check=_cross_check(case, res, check),
    )
    res.to_frame().to_parquet(ppath)
    jpath.write_text(json.dumps(prov, indent=1))
    return res, prov


def _cross_check(case, ref, check) -> dict:
    """Errors of the first working check method against the reference."""
    tried = []
    for spec in check:
        res, why, wall = _try(spec, case)
        if res is None:
            tried.append(why)
            continue
        err = metrics.errors(res, ref)
        keep = {k: v for k, v in err.items() if k.endswith("_l2") or k.endswith("_linf")}
        return {
            "method": spec.method,
            "k": spec.k,
            "h": spec.h,
            "wall_time": res.wall_time,
            "errors": keep,
            "failures": tried,
        }
    return {"method": None, "failures": tried}
