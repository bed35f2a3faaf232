"""The spatial benchmark problems in the benchmark-problems study, its report section and
``dttmm validate`` (experiments/cases/spatial/princeton_beam.toml, bend_45deg.toml,
right_angle_cantilever.toml; docs/benchmarks.md, docs/validate.md).

Default tier: the provenance tables in the study's format and their targets, the extrema
extractor on a sampled parabola, the grouped summaries of the report, the methods that run each
problem, the static rows of DT-TMM at small k, the spatial closed forms, a tiny outside spatial
method (a wrapper around dttmm.spatial.simulate with its own statics) validated on the spatial
checks, and a planar-only method's rows that say why they are not run. Slow tier: the study and
its section on the spatial problems with DT-TMM and the Exudyn GE beam, and the outside method
on every spatial problem.
"""

from __future__ import annotations

import json
import math
import textwrap

import numpy as np
import pandas as pd
import pytest

from experiments import methods
from experiments import validate as V
from experiments.studies import problems as B

SPATIAL = list(B.SPATIAL_PROBLEMS)


# ----------------------------------------------------------------------------- provenance
@pytest.mark.parametrize("name", SPATIAL)
def test_spatial_provenance_in_the_study_format(name):
    case, prov = B.problems([name])[name]
    assert methods.is_spatial(case) and case.name == name and case.provenance is None
    assert B.missing_provenance(prov) == []
    assert prov["quantity"] in B.SETTINGS
    assert prov["tolerance"] > 0 and prov["tolerance_kind"] in ("relative", "absolute")
    src = prov["source"]
    assert len(src) > 60 and any(str(y) in src for y in range(1940, 2030))
    rows = B.target_rows(prov)
    assert rows and all(math.isfinite(t["target"]) for t in rows)
    assert len({t["quantity"] for t in rows}) == len(rows)


def test_princeton_targets_are_the_ansys_table():
    _, prov = B.problems(["princeton_beam"])["princeton_beam"]
    rows = {t["quantity"]: t for t in B.target_rows(prov)}
    assert len(rows) == 2 * 2 * 7
    assert rows["u_z F=13.345 N β=45°"]["target"] == 0.15647
    assert (
        rows["|u_y| F=8.896 N β=0°"]["target"] == 1.0714e-2 and rows["|u_y| F=8.896 N β=0°"]["scale"] is None
    )
    # the zero entries are measured against the component's other end of the sweep
    assert rows["u_z F=8.896 N β=0°"]["scale"] == 0.14625
    assert rows["|u_y| F=13.345 N β=90°"]["scale"] == 1.6064e-2
    r = B._row(
        "p", prov, "u_z F=8.896 N β=0°", 0.0, {"method": "m", "k": 1, "h": 0, "status": "ok"}, 1e-3, 0.14625
    )
    assert r["rel_error"] == pytest.approx(1e-3 / 0.14625) and r["passed"]


def test_bend_targets_and_tolerance_per_quantity():
    _, prov = B.problems(["bend_45deg"])["bend_45deg"]
    assert B.targets(prov) == [(f"tip position error P={P:g}", 0.0) for P in (300, 450, 600)]
    assert B.tolerance_of(prov, "tip position error P=300") == (0.01, "absolute")
    _, ra = B.problems(["right_angle_cantilever"])["right_angle_cantilever"]
    assert B.tolerance_of(ra, "tip_z max") == (0.02, "absolute")
    assert B.tolerance_of(ra, "tip_z max time") == (ra["time_tolerance"], "absolute")
    assert {t["group"] for t in B.target_rows(ra)} == {"extremum", "extremum time"}


def test_bend_load_times_are_the_published_loads():
    """The file's load ramp at the provenance's load times gives P = 300, 450, 600 lbf, in steps of 75."""
    case, prov = B.problems(["bend_45deg"])["bend_45deg"]
    (ld,) = case.scenario.loads
    for P, t, n in zip(prov["P"], prov["load_time"], prov["load_steps"]):
        assert ld.value(t)[0][2] == pytest.approx(P) and P / n == 75.0


def test_tip_extrema_of_a_sampled_parabola():
    """The parabola refinement recovers an extremum between the samples exactly; an extremum
    at the end of the run is the sample."""
    from types import SimpleNamespace

    t = np.arange(0.0, 2.0001, 0.05)
    z = 3.0 - 4.0 * (t - 0.7321) ** 2
    ee = np.zeros((t.size, 3))
    ee[:, 2] = z
    res = SimpleNamespace(t=t, end_effector=ee, link_tip=ee[:, None, :])
    got = B.tip_extrema(res)
    v, tm = got["tip_z"]["max"]
    assert v == pytest.approx(3.0 - z[0], abs=1e-12) and tm == pytest.approx(0.7321, abs=1e-12)
    # the smallest value is the last sample: no refinement past the end of the run
    assert got["elbow_z"]["min"] == (pytest.approx(z[-1] - z[0], abs=1e-15), 2.0)


def test_right_angle_recorded_value_within_the_exudyn_example():
    """The recorded converged values agree with Exudyn's own example (10 elements per leg,
    tip 8.24 at 7.40, −9.75 at 15.85, elbow −4.07 at 10.85: its 'also' entry) to its coarser grid."""
    _, prov = B.problems(["right_angle_cantilever"])["right_angle_cantilever"]
    e = {(x["signal"], x["kind"]): (x["value"], x["time"]) for x in prov["extrema"]}
    for key, (v, t) in {
        ("tip_z", "max"): (8.24, 7.40),
        ("tip_z", "min"): (-9.75, 15.85),
        ("elbow_z", "min"): (-4.07, 10.85),
    }.items():
        assert abs(e[key][0] - v) <= 0.03 and abs(e[key][1] - t) <= 0.05, key


# ----------------------------------------------------------------------------- the study
def test_methods_of_the_spatial_problems():
    """Every method that runs spatial arms takes part where it can: the static problems need the
    method's statics, the rigid baseline sits the right-angle cantilever out (it runs the bang-bang
    arm, where it shows what the links' flexibility does), planar-only methods run none."""
    p = B.ProblemsParams()
    for name in SPATIAL:
        case, prov = B.problems([name])[name]
        got = B._methods(p, prov["quantity"], "full", case)
        assert "dttmm" in got and "exudyn-beam" in got
        assert not {"amm", "mujoco-chain"} & set(got)
        assert ("pinocchio-rigid" in got) == (name == "bang_bang_arm"), name
        assert all(methods.get(m).spatial for m in got)
    assert B.statics_of("dttmm-2nd").keywords == {"strain": "second-order"}
    assert B.statics_of("pinocchio-rigid") is None and B.statics_of("amm") is None


def test_static_rows_dttmm_princeton_k4_and_bend():
    """The default tier's share of :func:`test_static_rows_dttmm_princeton_and_bend` (slow tier):
    the Princeton sweep at k = 4 (measured 2026-12-03: worst of its 28 rows 2.25 %, at F =
    13.345 N, β = 75°, above the study's 2 %, so two rows fail; 0.39 % at k = 8, 12.9 % at k = 2)
    within 3 %, and the bend at k = 1 passing as there (0.61 % of R)."""
    p = B.ProblemsParams(methods=["dttmm"])
    case, prov = B.problems(["princeton_beam"])["princeton_beam"]
    rows = pd.DataFrame(B.static_rows("princeton_beam", case, prov, [4], p, "quick"))
    assert len(rows) == len(B.targets(prov)) and set(rows.method) == {"dttmm"}
    assert (rows.status == "ok").all() and rows.rel_error.max() <= 0.03, rows.rel_error.max()
    case, prov = B.problems(["bend_45deg"])["bend_45deg"]
    rows = pd.DataFrame(B.static_rows("bend_45deg", case, prov, [1], p, "quick"))
    assert len(rows) == len(B.targets(prov)) and (rows.status == "ok").all() and rows.passed.all(), rows


@pytest.mark.slow
def test_static_rows_dttmm_princeton_and_bend():
    """DT-TMM's statics on the Princeton sweep at k = 8 (within 2 %, measured ≤ 0.39 % with the
    case's Saint-Venant torsion constant) and the bend at k = 1 (≤ 0.61 % of R, measured): rows
    in the study's format, every one passing."""
    p = B.ProblemsParams(methods=["dttmm"])
    for name, k in (("princeton_beam", 8), ("bend_45deg", 1)):
        case, prov = B.problems([name])[name]
        rows = pd.DataFrame(B.static_rows(name, case, prov, [k], p, "quick"))
        assert len(rows) == len(B.targets(prov)) and set(rows.method) == {"dttmm"}
        assert (rows.status == "ok").all() and rows.passed.all(), rows[~rows.passed]


def test_grouped_summary_of_a_sweep():
    from reports import problems as RB

    base = {"problem": "p", "method": "m", "h": 0.0, "status": "ok", "reason": "", "tolerance": 0.02}
    rows = []
    for k, errs in ((4, (0.01, 0.03)), (8, (0.005, 0.015))):
        for i, e in enumerate(errs):
            rows.append({**base, "quantity": f"u{i}", "group": "u", "k": k, "target": 1.0, "value": 1 + e,
                         "error": e, "rel_error": e, "tolerance_kind": "relative", "passed": e <= 0.02,
                         "order_error": e})  # fmt: skip
    res = pd.DataFrame(rows)
    g = RB.grouped(res)
    assert list(g.k) == [4, 8] and list(g.quantity) == ["u", "u"]
    assert list(g.rel_error) == [0.03, 0.015] and list(g.passed) == [False, True]
    o = RB.overview_table(res, pd.DataFrame(columns=["problem", "quantity", "method", "order"]))
    assert o.quantity.iloc[0] == "u (worst of 2)" and o.m.iloc[0].startswith("0.015 (k≥8")


# ----------------------------------------------------------------------------- validate
def test_spatial_closed_forms_and_cases():
    cases = V.spatial_static_cases()
    ref = V.spatial_static_closed_forms(cases)
    assert cases["y"].model.gravity == pytest.approx((0.0, -9.81e-3, 0.0), rel=1e-15, abs=1e-18)
    assert cases["z"].model.gravity == pytest.approx((0.0, 0.0, -4e-3), rel=1e-15, abs=1e-18)
    b = cases["y"].model.links[0].beam
    assert ref["u_y"] == pytest.approx(-9.81e-3 * (2.0 * 1.2**4 / (8 * 20.0) + 0.5 * 1.2**3 / (3 * 20.0)))
    assert ref["twist"] == pytest.approx(0.05 * 0.5 * -4e-3 * 1.2 / 30.0) and b.EIz == 20.0
    c = V.spatial_rigid_case(0.5)
    assert c.model.links[0].beam.GJ == 40.0 * V.RIGID_STIFFEN and c.scenario.duration == 0.5


GOOD_SPATIAL = '''
import dttmm
import dttmm.spatial


def spatial(case, *, elements_per_link, h, **options):
    """The spatial kernel behind a plain function."""
    return dttmm.spatial.simulate(case, elements_per_link=elements_per_link, h=h)


def _statics(case, k, steps):
    r = dttmm.spatial.statics(case, elements_per_link=k, steps=steps)
    from dttmm.spatial.rotation import log_so3

    return {"tip": r.tip_position, "twist": float(log_so3(r.tip_rotation)[0])}


spatial.statics = _statics


def simulate(case, *, elements_per_link, h, **options):
    return dttmm.simulate(case, elements_per_link=elements_per_link, h=h, progress=False)


simulate.method = {"spatial": "dttmm_outside_good_spatial:spatial"}
'''

# the same with a planted error: the bending stiffness EIz it simulates is 10 % high
STIFF_SPATIAL = (
    GOOD_SPATIAL.replace(
        '''def spatial(case, *, elements_per_link, h, **options):
    """The spatial kernel behind a plain function."""
    return dttmm.spatial.simulate(case, elements_per_link=elements_per_link, h=h)''',
        """import dataclasses


def _stiff(case):
    links = tuple(
        dataclasses.replace(ln, beam=dataclasses.replace(ln.beam, EIz=1.1 * ln.beam.EIz)) for ln in case.model.links
    )
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=links))


def spatial(case, *, elements_per_link, h, **options):
    return dttmm.spatial.simulate(_stiff(case), elements_per_link=elements_per_link, h=h)""",
    )
    .replace("dttmm.spatial.statics(case,", "dttmm.spatial.statics(_stiff(case),")
    .replace("dttmm_outside_good_spatial", "dttmm_outside_stiff_spatial")
)


def _validate(tmp_path, *args):
    out = tmp_path / "out"
    code = V.main([*args, "--out", str(out)])
    return code, json.loads((out / "scorecard.json").read_text())


def test_outside_spatial_method_static_row_catches_a_planted_error(tmp_path, cleanup):
    """The default tier's share of :func:`test_outside_spatial_method_is_validated` (slow tier:
    its spatial rigid limit, 0.5 s at h = 1e-4 per method against Pinocchio's RK4 at h = 1e-5,
    took 280 of its 323 s on a loaded 2-core machine; this check 11 s there): the outside method
    with EIz 10 % high, static deflection only, fails u_y (bending about z) alone, by 1/1.1
    (measured 1.1 u_y/u_ref − 1 = 9e-6 at k = 32), and passes u_z and the twist."""
    bad = tmp_path / "stiff_spatial.py"
    bad.write_text(textwrap.dedent(STIFF_SPATIAL))
    code, rows = _validate(tmp_path, "--quick", "--method", str(bad), "--only", "spatial_static_deflection")
    assert code == V.EXIT_FAILED
    assert len(rows) == 3 and {r["method"] for r in rows} == {"stiff-spatial"}, rows
    assert {r["quantity"] for r in rows if r["passed"] is False} == {"tip u_y at rest (m)"}, rows
    assert sum(r["passed"] is True for r in rows) == 2, rows
    r = next(r for r in rows if r["quantity"] == "tip u_y at rest (m)")
    assert r["value"] == pytest.approx(r["reference"] / 1.1, rel=1e-3)


@pytest.mark.slow
def test_outside_spatial_method_is_validated(tmp_path, cleanup):
    """A tiny outside spatial method (its traits name a spatial function with a statics
    attribute) passes the spatial checks; the same with EIz 10 % high fails the static
    deflection in u_y (bending about z) only, and the spatial rigid limit passes for both."""
    good = tmp_path / "good_spatial.py"
    good.write_text(textwrap.dedent(GOOD_SPATIAL))
    bad = tmp_path / "stiff_spatial.py"
    bad.write_text(textwrap.dedent(STIFF_SPATIAL))
    code, rows = _validate(
        tmp_path, "--quick", "--method", str(good), "--method", str(bad),
        "--only", "spatial_rigid_limit,spatial_static_deflection",
    )  # fmt: skip
    assert code == V.EXIT_FAILED
    by = {(r["method"], r["check"], r["quantity"]): r for r in rows}
    good_rows = [r for r in rows if r["method"] == "good-spatial"]
    assert len(good_rows) == 4 and all(r["passed"] is True for r in good_rows), good_rows
    failed = {q for (m, _, q), r in by.items() if m == "stiff-spatial" and r["passed"] is False}
    assert failed == {"tip u_y at rest (m)"}
    r = by[("stiff-spatial", "spatial static deflection", "tip u_y at rest (m)")]
    assert r["value"] == pytest.approx(r["reference"] / 1.1, rel=1e-3)


def test_planar_method_gets_spatial_rows_not_run(tmp_path, cleanup):
    """A method without a spatial entry: every spatial row is not run, with the reason."""
    code, rows = _validate(
        tmp_path,
        "--quick",
        "--method",
        "amm",
        "--only",
        "spatial_rigid_limit,spatial_static_deflection,bend_45deg",
    )
    assert code == V.EXIT_OK and rows
    assert all(r["passed"] is None and "no spatial engine (planar arms only)" in r["reason"] for r in rows)


def test_no_statics_and_rigid_rows_say_why():
    """MuJoCo's spatial chain has no statics for the study; the rigid baseline no deformation."""
    run = V.Runner("pinocchio-rigid", V.SIZES["quick"])
    try:
        case, prov = B.problems(["princeton_beam"])["princeton_beam"]
        rows = V._spatial_problem(run, "princeton_beam", case, prov)
        assert all(r["passed"] is None and "rigid links" in r["reason"] for r in rows)
        run2 = V.Runner("global", V.SIZES["quick"])
        rows = V._spatial_problem(run2, "princeton_beam", case, prov)
        assert all(r["passed"] is None and "no spatial statics" in r["reason"] for r in rows)
    finally:
        run.worker.stop()


# ----------------------------------------------------------------------------- slow tier
@pytest.mark.slow
def test_outside_spatial_method_on_the_spatial_problems(tmp_path, cleanup):
    """The outside wrapper on the three spatial problems at the quick ladders: all pass (the
    Princeton beam within 2 % at k = 8 with the case's Saint-Venant torsion constant; with
    Exudyn's G (Iyy + Izz) 0.198 its |u_y| at large β would not, docs/spatial.md)."""
    good = tmp_path / "good_spatial.py"
    good.write_text(textwrap.dedent(GOOD_SPATIAL))
    code, rows = _validate(tmp_path, "--quick", "--method", str(good), "--only", ",".join(SPATIAL))
    by = {}
    for r in rows:
        by.setdefault(r["problem"], []).append(r)
    assert all(r["passed"] for r in by["bend_45deg"] + by["right_angle_cantilever"] + by["princeton_beam"])
    assert code == V.EXIT_OK


@pytest.mark.slow
def test_study_and_section_on_the_spatial_problems(tmp_path):
    from experiments.context import Context
    from experiments.plan import PLANS, Plan
    from experiments.runs import RunStore
    from experiments.study import add_cases
    from experiments.sweep import run_sweep
    from reports import problems as RB

    ks = PLANS["quick"].studies[B.NAME].ks_by_problem
    params = {"problems": SPATIAL, "ks": [4], "ks_by_problem": {n: ks[n] for n in SPATIAL}}
    plan = Plan("t", {}, {}, {}, {B.NAME: {**params, "methods": ["dttmm", "exudyn-beam"]}})
    ctx = Context(plan, {}, {}, {}, RunStore(tmp_path / "runs"), tmp_path)
    add_cases(ctx, [B.NAME])
    assert set(ctx.cases) == {"right_angle_cantilever"}  # the static problems run no sweep
    tasks = [t for t in B.tasks(ctx) if methods.runs_on(t.method, ctx.cases[t.case], t.k)]
    table = run_sweep(tasks, ctx.cases, ctx.store, scheduler="serial", progress=False)
    tables = B.analyse(ctx, table)
    res = tables[B.NAME]
    assert set(res.problem) == set(SPATIAL) and set(res.method) == {"dttmm", "exudyn-beam"}
    dt = res[res.method == "dttmm"]
    ra = dt[(dt.problem == "right_angle_cantilever") & (dt.k == 8)]
    assert len(ra) == 8 and (ra.status == "ok").all() and ra[ra.group == "extremum"].passed.all()
    assert dt[dt.problem == "bend_45deg"].passed.all()
    secs = RB.sections(tables, tmp_path / "figures")
    names = {t[0] for t in secs[0].tables}
    assert {f"benchmarks_{n}" for n in SPATIAL} <= names
    assert all((tmp_path / f).exists() for f, _ in secs[0].figures)
    over = {t[0]: t[1] for t in secs[0].tables}["benchmarks_overview"]
    assert "|u_y| (worst of 14)" in set(over.quantity)


# ----------------------------------------------------------------------------- the bang-bang arm
def test_bang_bang_arm_tasks_carry_its_step_and_peer_options():
    """The problem's own step and the Exudyn settings its case file gives (peer_options) reach the
    study's runs and its reference run; other methods get none."""
    from types import SimpleNamespace

    case, prov = B.problems(["bang_bang_arm"])["bang_bang_arm"]
    assert B.step_of(prov) == 5e-4 and B.step_of({"quantity": "tip_path_rms"}) == 1e-3
    X = (("rho_inf", 0.8), ("shear_ratio", 0.32))
    assert B.peer_options(prov, "exudyn-beam") == X and B.peer_options(prov, "dttmm") == ()
    ref = B._ref_task("bang_bang_arm", case, prov)
    assert (ref.method, ref.k, ref.h, ref.options) == ("exudyn-beam", 32, 5e-4, X)
    p = B.ProblemsParams(problems=["bang_bang_arm"], ks_by_problem={"bang_bang_arm": [4]})
    ctx = SimpleNamespace(
        plan=SimpleNamespace(name="quick", studies={"benchmarks": p}, case_files=None),
        cases={"bang_bang_arm": case},
    )
    got = {t.method: t for t in B.tasks(ctx)}
    assert got["exudyn-beam"].options == X and got["exudyn-beam"].h == 5e-4
    assert got["dttmm-2nd"].options == () and got["pinocchio-rigid"].k == 0
    # the right-angle cantilever gives the GE beam the source's GA = EA and the recorded values' tolerance
    _, ra = B.problems(["right_angle_cantilever"])["right_angle_cantilever"]
    assert B.peer_options(ra, "exudyn-beam") == (("newton_abs_tol", 1e-5), ("shear_ratio", 1.0))
    with pytest.raises(ValueError, match="peer_options"):
        B.peer_options({"peer_options": {"exudyn-beam": 0.8}}, "exudyn-beam")
    with pytest.raises(ValueError, match="step"):
        B.step_of({"quantity": "tip_path_rms", "step": -1.0})


@pytest.mark.parametrize("k", [8])
def test_bang_bang_arm_dttmm_against_exudyn_and_the_rigid_arm(k):
    """DT-TMM (second-order strain, the problem's h = 5e-4) against Exudyn's 3-D beam at the case
    file's settings, both at k = 8: end effectors within the problem's tolerance of each other
    (measured 1.4e-3 of the reach RMS; 2.8e-3 at k = 4); the rigid Pinocchio arm far off (0.13,
    measured): the links' flexibility is what the problem measures. At the adapter's defaults
    Exudyn fails Newton (why the case file gives its settings)."""
    case, prov = B.problems(["bang_bang_arm"])["bang_bang_arm"]
    h = B.step_of(prov)
    dt = methods.run("dttmm-2nd", case, k, h)
    ex = methods.run("exudyn-beam", case, k, h, **dict(B.peer_options(prov, "exudyn-beam")))
    rigid = methods.run("pinocchio-rigid", case, 0, h)
    gap = B.tip_path_rms(dt, ex, B.reach(case))
    assert B.reach(case) == pytest.approx(1.4)
    assert gap <= prov["tolerance"], gap
    assert B.tip_path_rms(rigid, ex, B.reach(case)) > 20 * prov["tolerance"]
    with pytest.raises(Exception, match="[Nn]ewton"):  # the adapter's defaults: why peer_options exist
        methods.run("exudyn-beam", case, 4, h)
