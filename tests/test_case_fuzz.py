"""Fuzzing the case reader: mutated case files either load and run, or raise InputError.

Hypothesis mutates the shipped cases (and a motion-table case): keys deleted, renamed or added,
values retyped (bool, string, list, table), set to extreme or non-finite numbers, wrapped in or
unwrapped from lists, and whole files truncated or made binary. Every file must either

* raise :class:`dttmm.InputError` (at load, or from the run-size guard), or
* load, pass the guard, and run (k = 1, at most 0.02 s, so bounded) to ``success = True``.

One exception to the last point, by design: a file whose numbers were set to an extreme
magnitude (1e±12, 1e±300) is physically absurd but valid; its run may end in a
:class:`dttmm.SimulationError` (divergence is then the honest outcome) or a non-"ok" status.
No other exception and no hang is accepted for any file.
"""

from __future__ import annotations

import copy
import dataclasses as dc
import json
import math
import tomllib

import pytest
from conftest import CASES
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import dttmm
from dttmm.resources import check_run_size

MOTION_TABLE = """
[model]
[[model.links]]
length = 1.0
EI = 1.0e4
rhoA = 0.27
hub = { mass = 0.0, inertia = 0.01 }
[scenario]
duration = 0.05
output_step = 1e-3
[[scenario.drives]]
kind = "motion"
law = "table"
times = [0.0, 0.01, 0.03]
values = [0.0, 0.002, 0.004]
"""
BASES = [tomllib.loads((CASES / f"{n}.toml").read_text()) for n in ("single_link", "three_link", "spin_up")]
BASES.append(tomllib.loads(MOTION_TABLE))

EXTREME = [1e300, -1e300, 1e-300, 1e12, 1e-12]
NONFINITE = [math.inf, -math.inf, math.nan]
MILD = [0, 1, -1, 0.0, 2.5, -0.5, 0.01]
KEYS = [
    "gravity",
    "gravty",
    "length",
    "EI",
    "rhoA",
    "EA",
    "E",
    "rho",
    "width",
    "thickness",
    "hub",
    "payload",
    "mass",
    "inertia",
    "damping",
    "inextensible",
    "kind",
    "law",
    "value",
    "levels",
    "switch_times",
    "amplitude",
    "frequency",
    "until",
    "rate",
    "ramp_time",
    "times",
    "values",
    "duration",
    "output_step",
    "drives",
    "links",
    "_spline",
    "_where",
    "name",
    "provenance",
]


def _paths(doc, prefix=()):
    """Every (path, value) in the document: table keys and list items."""
    out = []
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for k, v in items:
        out.append((prefix + (k,), v))
        out.extend(_paths(v, prefix + (k,)))
    return out


def _parent(doc, path):
    for k in path[:-1]:
        doc = doc[k]
    return doc


values = st.one_of(
    st.sampled_from(MILD + NONFINITE + [True, False, "1.0", "", "torque", "motion", "sine", [], {}]),
    st.sampled_from(EXTREME).map(lambda x: ("extreme", x)),
    st.lists(st.sampled_from(MILD + [math.nan, "x"]), max_size=4),
    st.dictionaries(st.sampled_from(KEYS), st.sampled_from(MILD), max_size=2),
    st.text(max_size=8),
)


@st.composite
def mutated(draw):
    """(TOML text, extreme) — a shipped case with 1–3 mutations, or a damaged file."""
    doc = copy.deepcopy(draw(st.sampled_from(BASES)))
    extreme = False
    for _ in range(draw(st.integers(1, 3))):
        paths = _paths(doc)
        if not paths:
            break
        path, old = draw(st.sampled_from(paths))
        parent, key = _parent(doc, path), path[-1]
        op = draw(st.sampled_from(["delete", "rename", "retype", "retype", "scale", "add", "wrap", "unwrap"]))
        if op == "delete":
            del parent[key]
        elif op == "rename" and isinstance(parent, dict):
            new = draw(
                st.one_of(
                    st.sampled_from(KEYS), st.text("abcdefghijklmnopqrstuvwxyz_", min_size=1, max_size=12)
                )
            )
            parent[new] = parent.pop(key)
        elif op == "retype":
            v = draw(values)
            if isinstance(v, tuple):
                extreme, v = True, v[1]
            parent[key] = v
        elif op == "scale" and isinstance(old, (int, float)) and not isinstance(old, bool):
            f = draw(st.sampled_from([0.0, -1.0, 0.5, 2.0, 10.0, 1e6, 1e-6]))
            extreme = extreme or f in (1e6, 1e-6)
            parent[key] = old * f
        elif op == "add" and isinstance(old, dict):
            old[draw(st.sampled_from(KEYS))] = draw(st.sampled_from(MILD))
        elif op == "wrap":
            parent[key] = [old]
        elif op == "unwrap" and isinstance(old, list) and old:
            parent[key] = old[0]
    text = _toml(doc)
    damage = draw(st.sampled_from([None] * 12 + ["truncate", "binary", "latin1"]))
    if damage == "truncate":
        text = text[: draw(st.integers(0, len(text)))]
    elif damage == "binary":
        return text.encode()[:40] + b"\x00\xff\xfe" + text.encode()[40:], extreme
    elif damage == "latin1":
        return ("# é\n" + text).encode("latin-1", errors="replace"), extreme
    return text.encode(), extreme


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a TOML basic string (bar rare escapes: then invalid TOML)
    if isinstance(v, list):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{json.dumps(str(k))} = {_value(x)}" for k, x in v.items()) + " }"
    raise TypeError(v)


def _toml(doc) -> str:
    """Any document as TOML: top-level keys, everything below as inline tables and arrays."""
    if not isinstance(doc, dict):
        return f"x = {_value(doc)}\n"
    return "".join(f"{json.dumps(str(k))} = {_value(v)}\n" for k, v in doc.items())


OUTCOMES: dict[str, int] = {}


def _count(what: str):
    OUTCOMES[what] = OUTCOMES.get(what, 0) + 1


@settings(
    max_examples=520,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(mutated())
def test_mutated_case_files_load_and_run_or_raise_input_error(tmp_path_factory, sample):
    data, extreme = sample
    path = tmp_path_factory.mktemp("fuzz") / "case.toml"
    path.write_bytes(data)
    try:
        case = dttmm.load_case(path)
        h = min(1e-3, case.scenario.duration)
        check_run_size(case, 1, h)
    except dttmm.InputError as exc:
        assert "\n" not in str(exc)
        _count("input error")
        return
    s = case.scenario
    dur = min(s.duration, 0.02)
    short = dc.replace(case, scenario=dc.replace(s, duration=dur, output_step=min(s.output_step, dur)))
    try:
        res = dttmm.simulate(short, elements_per_link=1, h=min(1e-3, dur), progress=False)
    except dttmm.SimulationError:
        assert extreme, "a simulation failed on a file with no extreme value"
        _count("simulation error (extreme)")
        return
    except dttmm.InputError:  # a setting the guard cannot see (none known); still a clear error
        _count("input error at run")
        return
    assert res.success or extreme, (res.status, res.warnings)
    _count("ran ok" if res.success else f"ran {res.status} (extreme)")


def test_fuzz_outcomes_were_varied():
    # run after the fuzz test (file order): both outcomes must have occurred, or the fuzzing is vacuous
    if not OUTCOMES:
        pytest.skip("the fuzz test did not run in this session")
    assert sum(OUTCOMES.values()) >= 500, OUTCOMES
    assert OUTCOMES.get("input error", 0) >= 100 and OUTCOMES.get("ran ok", 0) >= 50, OUTCOMES
