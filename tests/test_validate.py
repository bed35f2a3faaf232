"""``dttmm validate``: outside methods in files written here, a planted error, broken methods, exit codes."""

from __future__ import annotations

import json
import textwrap

import pytest

from dttmm import cli
from experiments import validate as V

GOOD = '''
import dttmm


def simulate(case, *, elements_per_link, h, **options):
    """DT-TMM at the k and h it is given: an outside method with no traits declared."""
    return dttmm.simulate(case, elements_per_link=elements_per_link, h=h, progress=False)


simulate.frequencies = lambda case, k, n: dttmm.modes(case, k, n=n).frequencies
'''

# the same model with a planted error: the gravity it simulates is half the case's
HALF_GRAVITY = """
import dataclasses

import dttmm


def _half(case):
    g = tuple(0.5 * x for x in case.model.gravity)
    return dataclasses.replace(case, model=dataclasses.replace(case.model, gravity=g))


def simulate(case, *, elements_per_link, h, **options):
    return dttmm.simulate(_half(case), elements_per_link=elements_per_link, h=h, progress=False)


simulate.frequencies = lambda case, k, n: dttmm.modes(_half(case), k, n=n).frequencies
"""

BROKEN = """
import dataclasses
import time

import numpy as np

import dttmm


def _run(case, k, h):
    return dttmm.simulate(case, elements_per_link=k, h=h, progress=False)


def raises(case, *, elements_per_link, h, **options):
    raise RuntimeError("boom in the outside solver")


def nan(case, *, elements_per_link, h, **options):
    res = _run(case, elements_per_link, h)
    return dataclasses.replace(res, joint_angle=np.full_like(res.joint_angle, np.nan))


def shapes(case, *, elements_per_link, h, **options):
    res = _run(case, elements_per_link, h)
    return dataclasses.replace(res, tip_deflection=res.tip_deflection[::2])


def milliseconds(case, *, elements_per_link, h, **options):
    res = _run(case, elements_per_link, h)
    return dataclasses.replace(res, t=res.t * 1e3)


def not_a_result(case, *, elements_per_link, h, **options):
    return {"t": [0.0]}


def hangs(case, *, elements_per_link, h, **options):
    time.sleep(3600)
"""

# checks the planted error decides (gravity sets their value) and checks it cannot touch
GRAVITY_DECIDES = {"elastica_tip_load", "static_deflection", "rigid_limit"}
GRAVITY_FREE = {"energy_balance", "order_h"}  # energy: conserved at any gravity; order: no gravity
FAST = sorted(GRAVITY_DECIDES | GRAVITY_FREE)


def _file(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return str(path)


def _validate(tmp_path, *args):
    out = tmp_path / "out"
    code = V.main([*args, "--out", str(out)])
    rows = json.loads((out / "scorecard.json").read_text())
    return code, rows, out


def _by_check(rows, method):
    out = {}
    for r in rows:
        if r["method"] == method:
            out.setdefault(r["check"] if r["check"] != "benchmark" else r["problem"], []).append(r)
    return out


def _passed(rows):
    """check -> True when all its rows passed, False when one failed (rows not run left out)."""
    return {
        c: all(r["passed"] for r in rs) for c, rs in rows.items() if all(r["passed"] is not None for r in rs)
    }


def test_outside_method_passes_and_planted_error_fails_where_gravity_decides(tmp_path, cleanup):
    good = _file(tmp_path, "good_arm.py", GOOD)
    bad = _file(tmp_path, "half_gravity.py", HALF_GRAVITY)
    code, rows, out = _validate(
        tmp_path, "--quick", "--method", good, "--method", bad, "--only", ",".join(FAST)
    )
    assert code == V.EXIT_FAILED
    good_rows, bad_rows = _by_check(rows, "good-arm"), _by_check(rows, "half-gravity")
    assert set(good_rows) == set(bad_rows) == {V_name(c) for c in FAST}
    assert _passed(good_rows) == dict.fromkeys(good_rows, True)
    verdicts = _passed(bad_rows)
    assert {c for c, ok in verdicts.items() if not ok} == {V_name(c) for c in GRAVITY_DECIDES}
    assert {c for c, ok in verdicts.items() if ok} == {V_name(c) for c in GRAVITY_FREE}
    # half the gravity: half the static deflection, to within the closed form's tolerance
    static = bad_rows["static deflection"][0]
    assert static["value"] == pytest.approx(0.5 * static["reference"], rel=1e-3)
    # the pages and the links the report reads
    assert (out / "index.html").is_file() and (out / "good-arm.html").is_file()
    links = {m: rest for m, *rest in V.scorecard_links(out)}
    assert links["half-gravity"][1:] == ["half-gravity.html", 2, 3, 0]


def V_name(check):
    """The check column of a row for a check name (benchmark problems are their own name)."""
    return {
        "rigid_limit": "rigid limit",
        "static_deflection": "static deflection",
        "energy_balance": "energy balance",
        "order_h": "order in h",
        "order_k": "order in k",
        "frequencies": "frequencies",
    }.get(check, check)


def test_broken_methods_are_rows_with_their_reason(tmp_path, cleanup):
    path = _file(tmp_path, "broken.py", BROKEN)
    specs = ["raises", "nan", "shapes", "milliseconds", "not_a_result", "hangs"]
    args = [a for s in specs for a in ("--method", f"{path}:{s}")]
    code, rows, _ = _validate(tmp_path, "--quick", *args, "--only", "energy_balance", "--timeout", "10")
    assert code == V.EXIT_FAILED
    why = {r["method"]: r["reason"] for r in rows}
    assert all(r["passed"] is False for r in rows) and len(rows) == len(specs)
    assert "RuntimeError: boom in the outside solver" in why["raises"]
    assert "non-finite output (joint_angle" in why["nan"]
    assert "malformed Result: tip_deflection has shape" in why["shapes"]
    assert "wrong units of time" in why["milliseconds"]
    assert "not a dttmm.Result" in why["not-a-result"]
    assert "per-run timeout of 10 s" in why["hangs"]


def test_json_keys_exit_zero_and_not_run_rows(tmp_path, cleanup):
    good = _file(tmp_path, "good_arm.py", GOOD)
    code, rows, _ = _validate(
        tmp_path, "--quick", "--method", good, "--only", "order_h,energy_balance,pendulum_stiff"
    )
    assert code == V.EXIT_OK
    need = {"method", "problem", "quantity", "value", "reference", "source", "tolerance", "passed", "reason"}
    assert all(need | {"order", "cpu_time"} <= set(r) for r in rows)
    (ref_run,) = [r for r in rows if r["problem"] == "pendulum_stiff" and r["check"] == "benchmark"]
    assert ref_run["passed"] is None and "reference run" in ref_run["reason"]
    (order,) = [r for r in rows if r["check"] == "order in h"]
    assert order["order"] == pytest.approx(2.0, abs=0.3)  # Newmark


def test_rigid_baseline_skips_what_it_cannot_run(tmp_path):
    code, rows, _ = _validate(
        tmp_path, "--quick", "--method", "pinocchio-rigid", "--only", "order_k,energy_balance"
    )
    reasons = {r["check"]: (r["passed"], r["reason"]) for r in rows}
    assert reasons["order in k"] == (None, "no discretisation parameter (rigid links)")
    assert reasons["energy balance"][0] is None and "total energy" in reasons["energy balance"][1]
    assert code == V.EXIT_OK  # nothing ran, nothing failed


@pytest.mark.parametrize(
    "argv, names",
    [
        (["--method", "no_such_pkg.solver:simulate"], "--method = 'no_such_pkg.solver:simulate'"),
        (["--method", "missing/file.py:simulate"], "no such file"),
        (["--only", "no_such_check"], "--only = 'no_such_check'"),
        (["--timeout", "0"], "--timeout = '0'"),
    ],
)
def test_bad_input_is_exit_2_with_one_line(argv, names, capsys, tmp_path):
    assert cli.main(["validate", *argv, "--out", str(tmp_path)]) == cli.EXIT_INPUT
    err = capsys.readouterr().err.strip()
    assert names in err and "\n" not in err


def test_worker_returns_value_error_and_timeout():
    w = V.Worker("dttmm", timeout=5)
    try:
        value, cpu, why = w.call(abs, -3)
        assert (value, why) == (3, "") and cpu >= 0
        value, _, why = w.call(int, "x")
        assert value is None and why.startswith("ValueError: invalid literal")
        value, _, why = w.call(__import__("time").sleep, 60)
        assert value is None and "per-run timeout of 5 s" in why
        assert w.call(abs, -1)[0] == 1  # a fresh worker after the kill
    finally:
        w.stop()


def test_closed_forms():
    # β1 L of the clamped-free beam: cos βL cosh βL = −1
    import math

    for bl in V.BETA_L:
        assert math.cos(bl) * math.cosh(bl) == pytest.approx(-1.0, abs=1e-9)
    case = V.static_case()
    b, m = case.model.links[0].beam, case.model.links[0].payload.mass
    w = V.static_closed_form(case)
    assert w == pytest.approx(-V.STATIC_G * (b.rhoA / (8 * b.EI) + m / (3 * b.EI)))


@pytest.mark.slow
def test_quick_suite_planted_error(tmp_path, cleanup):
    """The whole quick suite: the planted error fails exactly the checks gravity decides."""
    good = _file(tmp_path, "good_arm.py", GOOD)
    bad = _file(tmp_path, "half_gravity.py", HALF_GRAVITY)
    code, rows, _ = _validate(tmp_path, "--quick", "--method", good, "--method", bad)
    assert code == V.EXIT_FAILED
    good_v, bad_v = _passed(_by_check(rows, "good-arm")), _passed(_by_check(rows, "half-gravity"))
    assert all(good_v.values()), {c for c, ok in good_v.items() if not ok}
    decided = {"cantilever_self_weight", "elastica_tip_load", "static deflection", "rigid limit"}
    assert {c for c, ok in bad_v.items() if not ok} == decided
    assert set(good_v) == set(bad_v)


def test_report_links_section(tmp_path):
    from reports.validate_page import links_section

    rows = [V._row("m-1", "energy balance", "p", "q", passed=True, label="M one")]
    rows += [V._row("m-1", "order in h", "p", "q", passed=False, label="M one")]
    V.write(rows, tmp_path / "validate")
    sec = links_section(tmp_path / "validate", tmp_path / "report")
    (_, table, _) = sec.tables[0]
    assert table.to_dict("records") == [
        {"method": "M one", "passed": 1, "failed": 1, "not run": 0, "scorecard": "../validate/m-1.html"}
    ]
    assert "Failed a check: M one." in sec.text
    assert links_section(tmp_path / "nothing", tmp_path) is None
