"""Reference solutions: computed once per case at high accuracy, cached on disk, reused.

Each reference is stored as ``<folder>/<case>_T<duration>_dt<output step>.parquet``
(``Result.to_frame``) with a JSON provenance beside it: method, k, h, options, versions, date,
wall time, the size it was made for, and a cross-check — the errors of a second, independent
method against it. The provenance carries a key: the hash of the case's content, the candidate
and cross-check specs and the code version of every method among them (see
``experiments.fingerprint``). A cached reference is reused only when its key matches and its
files verify (see ``experiments.cachefiles``); otherwise it is computed again and overwritten.
"""

from __future__ import annotations

import datetime
import math
import platform
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from . import cachefiles, fingerprint, methods, metrics
from .runs import _check

__all__ = ["RefSpec", "load_reference", "reference", "reference_key"]


# Layout of the stored provenance; part of the key, so raise it when its fields change.
PROVENANCE_FORMAT = 1


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


def reference_key(case, candidates, check=()) -> str:
    """sha256 of what a reference depends on: the case's content, the candidate and
    cross-check specs, and the code version of each of their methods."""
    specs = list(candidates) + list(check)
    return fingerprint.digest(
        {
            "case": fingerprint.case_digest(case),
            "candidates": [asdict(c) for c in candidates],
            "check": [asdict(c) for c in check],
            "code": {m: fingerprint.code_version(m) for m in dict.fromkeys(s.method for s in specs)},
            "format": PROVENANCE_FORMAT,
        }
    )


def load_reference(folder, case, key: str):
    """(Result or None, provenance) of the stored reference made for ``key``, or (None, None)
    when there is none or it does not verify (a CacheWarning then says why)."""
    ppath, jpath = _paths(folder, case)
    try:
        got = cachefiles.read_entry(jpath, ppath, key)
    except cachefiles.BadEntry as exc:
        cachefiles.warn(jpath, str(exc))
        return None, None
    if got is None:
        return None, None
    prov, data = got
    if prov.get("status") != "ok":
        return None, prov
    if data is None:
        cachefiles.warn(jpath, "provenance says ok but there is no history")
        return None, None
    return cachefiles.result_from_bytes(data), prov


def _versions(res) -> dict:
    from dttmm.plumbing import versions

    v = versions()
    v.update({k: str(x) for k, x in (res.meta.get("versions") or {}).items()})
    return v


def _try(spec: RefSpec, case):
    from . import console

    t0 = time.perf_counter()
    try:
        with console.captured() as printed:  # an engine's messages go into the reason, not the terminal
            res = methods.run(spec.method, case, spec.k, spec.h, **dict(spec.options))
    except Exception as exc:  # noqa: BLE001 -- a failing candidate is recorded and the next one tried
        said = f"; it printed: {printed.last_line()}" if printed.last_line() else ""
        return (
            None,
            f"{spec.describe()}: {type(exc).__name__}: {str(exc)[:200]}{said}",
            time.perf_counter() - t0,
        )
    why = _check(res)
    if not why and res.status != "ok":  # a reference must be a fully trusted run
        why = f"status {res.status}: " + ("; ".join(res.warnings) or "no reason given")
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
    recompute : ignore the stored reference and compute (and store) it again

    Returns
    -------
    (Result or None, dict). With no candidate working the Result is None and the provenance
    lists every failure; studies then report NaN errors with that reason.
    """
    candidates, check = list(candidates), list(check)
    ppath, jpath = _paths(folder, case)
    want = [asdict(c) for c in candidates]
    key = reference_key(case, candidates, check)
    if not recompute:
        res, prov = load_reference(folder, case, key)
        if prov is not None:
            return res, prov
    jpath.parent.mkdir(parents=True, exist_ok=True)
    failures, res, used, wall = [], None, None, math.nan
    for spec in candidates:
        if not methods.runs_on(spec.method, case, spec.k):
            failures.append(f"{spec.describe()}: does not run this case (a spatial arm)")
            continue
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
    prov["key"] = key
    if res is None:
        prov.update(status="failed", id=f"none-{prov['date']}")
        return None, cachefiles.write_entry(jpath, ppath, prov, None)
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
        id=f"{used.describe()} @ {prov['date']} #{key[:12]}",
        cross_check=_cross_check(case, res, check, used.method),
    )
    return res, cachefiles.write_entry(jpath, ppath, prov, cachefiles.result_bytes(res))


def _cross_check(case, ref, check, ref_method="") -> dict:
    """Errors of the first working check method against the reference: the reference's own
    method, and methods that do not run the case, are passed over."""
    tried = []
    for spec in check:
        if spec.method == ref_method or not methods.runs_on(spec.method, case, spec.k):
            continue
        res, why, _ = _try(spec, case)
        if res is None:
            tried.append(why)
            continue
        err = metrics.errors(res, ref)
        keep = {k: v for k, v in err.items() if k.endswith(("_l2", "_linf"))}
        return {
            "method": spec.method,
            "k": spec.k,
            "h": spec.h,
            "wall_time": res.wall_time,
            "errors": keep,
            "failures": tried,
        }
    return {"method": None, "failures": tried}
