"""``dttmm validate`` on the shipped robots and the trees and loops (docs/validate.md): the
robots' rigid limit against Pinocchio's own reading of the URDF, their tool sag against the
cantilever worked by hand, their free swing's energy; the trees and loops against the spatial
global solver, the closure gap, the stiff five-bar against its closed-form loop geometry. And
the studies' sit-outs that go with the loops: a study option a closed loop refuses, the scheme
study's planar-kernel variants."""

from __future__ import annotations

import json
import textwrap
from types import SimpleNamespace

import pytest

from experiments import validate as V
from experiments.plan import CASE_DIR, PLANS, Plan, load_cases, plan_for

TOPO = CASE_DIR / "spatial" / "topology"
TOPOLOGY_CHECKS = "topology_global,topology_closure,five_bar_rigid"
ROBOT_CHECKS = "robot_rigid_limit,robot_statics,robot_energy"


def _robots():
    """Skip unless example-robot-data (the URDFs) and Pinocchio are installed."""
    from importlib import metadata

    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'dttmm[robots]')")
    pytest.importorskip("pinocchio")


def _validate(tmp_path, *args):
    out = tmp_path / "out"
    code = V.main([*args, "--out", str(out)])
    return code, json.loads((out / "scorecard.json").read_text())


# an outside method: the spatial DT-TMM behind a plain function, with its statics
OUTSIDE = """
import dataclasses

import dttmm
import dttmm.spatial


def _edit(case):
    return case


def spatial(case, *, elements_per_link, h, **options):
    return dttmm.spatial.simulate(_edit(case), elements_per_link=elements_per_link, h=h)


def _statics(case, k, steps):
    r = dttmm.spatial.statics(_edit(case), elements_per_link=k, steps=steps)
    return {"tip": r.tip_position}


spatial.statics = _statics


def simulate(case, *, elements_per_link, h, **options):
    return dttmm.simulate(case, elements_per_link=elements_per_link, h=h, progress=False)


simulate.method = {"spatial": "dttmm_outside_NAME:spatial"}
"""

# planted errors: the loops cut open (the closures dropped); the tubes 10 % stiffer in bending
CUT_OPEN = """
def _edit(case):
    return dataclasses.replace(case, model=dataclasses.replace(case.model, closures=()))
"""
STIFF_TUBES = """
def _edit(case):
    links = tuple(
        lk if lk.rigid else dataclasses.replace(
            lk, beam=dataclasses.replace(lk.beam, EIy=1.1 * lk.beam.EIy, EIz=1.1 * lk.beam.EIz)
        )
        for lk in case.model.links
    )
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=links))
"""


def _outside(tmp_path, name, edit=""):
    text = OUTSIDE.replace("NAME", name)
    if edit:
        text = text.replace("def _edit(case):\n    return case\n", textwrap.dedent(edit).lstrip("\n"))
    path = tmp_path / f"{name}.py"
    path.write_text(text)
    return str(path)


# ----------------------------------------------------------------------------- trees and loops
def test_dttmm_passes_the_topology_checks(tmp_path):
    """``dttmm validate --quick --method dttmm``: the three topology cases equal the spatial
    global solver to ≤ 1e-9 m, the loops' closure gap ≤ 1e-10 × their size, the stiff five-bar
    follows the rigid loop geometry within 1e-6 m (measured values in docs/validate.md)."""
    code, rows = _validate(tmp_path, "--quick", "--method", "dttmm", "--only", TOPOLOGY_CHECKS)
    assert code == V.EXIT_OK, rows
    by = {(r["check"], r["problem"]): r for r in rows}
    assert set(by) == {
        ("topology vs global solver", "four_bar"),
        ("topology vs global solver", "five_bar"),
        ("topology vs global solver", "branched_arm"),
        ("topology closure", "four_bar"),
        ("topology closure", "five_bar"),
        ("five-bar rigid limit", "five_bar_stiff"),
    }
    assert all(r["passed"] is True and r["value"] is not None for r in rows), rows
    assert by[("five-bar rigid limit", "five_bar_stiff")]["value"] > 0  # the links still bend a little


def test_loops_cut_open_fail_exactly_the_loop_rows(tmp_path, cleanup):
    """An outside method that drops the closures (the loops cut open): the closure and the global
    solver's rows of the four-bar and the five-bar fail and so does the five-bar's rigid
    geometry; the branched arm (a tree, no closure) still equals the global solver."""
    spec = _outside(tmp_path, "cut_open", CUT_OPEN)
    code, rows = _validate(tmp_path, "--quick", "--method", spec, "--only", TOPOLOGY_CHECKS)
    assert code == V.EXIT_FAILED
    passed = {(r["check"], r["problem"]) for r in rows if r["passed"] is True}
    failed = {(r["check"], r["problem"]) for r in rows if r["passed"] is False}
    assert passed == {("topology vs global solver", "branched_arm")}, rows
    assert len(failed) == 5, rows


def test_topology_rows_not_run_say_why():
    """Before any run: a planar-only method has no spatial engine; the global solver is this
    check's reference; Exudyn's beam and the MuJoCo chain are other discretisations; the rigid
    baseline has no bending links (and refuses the tilted four-bar); the explicit DT-TMM refuses
    the loops (its RK4)."""
    size = V.SIZES["quick"]
    for name, words in (
        ("amm", "no spatial engine (planar arms only)"),
        ("global", "this check's reference"),
        ("exudyn-beam", "another discretisation (ge-beam)"),
        ("mujoco-chain", "another discretisation (hinge-chain)"),
    ):
        run = V.Runner(name, size)
        rows = V.topology_global(run)
        assert len(rows) == 3 and all(r["passed"] is None and words in r["reason"] for r in rows), (
            name,
            rows,
        )
        assert run.worker._proc is None  # nothing ran
    rows = V.topology_global(V.Runner("pinocchio-rigid", size))  # the tilted four-bar it refuses
    assert [r["passed"] for r in rows] == [None] * 3 and "5 equations" in rows[0]["reason"], rows
    assert all("rigid links" in r["reason"] for r in rows[1:]), rows
    rows = V.topology_closure(V.Runner("dttmm-rk4", size))
    assert len(rows) == 2 and all(r["passed"] is None and "rk4" in r["reason"] for r in rows), rows


# ----------------------------------------------------------------------------- robots
def test_robot_hand_checks_are_independent_values():
    """The hand checks need no method: the UR5's tool sag is the cantilever's 0.132713 mm
    (tests/test_urdf_import.py: the DT-TMM's statics 0.132711 mm); the Panda, laid on its back
    with its upper-arm tube horizontal, sags 0.0557 mm; Pinocchio's RNEA of the rigid UR5 holds
    it up against gravity at t = 0 (the shoulder-lift torque is the arm's weight times its lever)."""
    _robots()
    from experiments import handchecks

    ur5 = handchecks.tool_displacement("ur5")
    assert ur5["sag"] == pytest.approx(1.32713e-4, rel=1e-5)
    panda = handchecks.tool_displacement("panda")
    assert 5e-5 < panda["sag"] < 6e-5
    case = handchecks.rigid_robot_case("ur5", 0.01)
    assert all(lk.rigid for lk in case.model.links)
    ref = handchecks.robot_inverse_dynamics("ur5", case)
    assert ref["torque"].shape == (11, 6) and abs(ref["torque"][0, 1]) > 10.0


def test_stiffer_tubes_fail_the_robot_statics(tmp_path, cleanup):
    """The robots' tool sag by the method's own statics at k = 8, 16, 32: an outside DT-TMM
    with its tubes 10 % stiffer in bending fails both robots, by about 1/1.1 (the sag is
    bending; the unchanged DT-TMM passes, the slow tier's run below)."""
    _robots()
    stiff = _outside(tmp_path, "stiff_tubes", STIFF_TUBES)
    code, rows = _validate(tmp_path, "--quick", "--method", stiff, "--only", "robot_statics")
    assert code == V.EXIT_FAILED
    assert {r["problem"] for r in rows} == {"ur5_sag", "panda_sag"} and len(rows) == 2
    for r in rows:
        assert r["passed"] is False and 0.88 < r["value"] / r["reference"] < 0.95, r


@pytest.mark.slow
def test_dttmm_passes_the_robot_checks(tmp_path):
    """``dttmm validate --quick --method dttmm`` on the robots: the rigid URDF's torques and tool
    point = Pinocchio's, the sag = the hand check, the free swing keeps its energy."""
    _robots()
    code, rows = _validate(tmp_path, "--quick", "--method", "dttmm", "--only", ROBOT_CHECKS)
    assert code == V.EXIT_OK, rows
    assert len(rows) == 8 and all(r["passed"] is True for r in rows), rows


def test_robot_rows_not_run_say_why():
    """Before any run: the MuJoCo chain refuses rigid links; Exudyn's beam has no energy output;
    the rigid baseline has no deformation to sag; a planar-only method no spatial engine."""
    _robots()
    size = V.SIZES["quick"]
    rows = V.robot_rigid_limit(V.Runner("mujoco-chain", size))
    assert len(rows) == 4 and all(
        "rigid links are not supported by mujoco-spatial" in r["reason"] for r in rows
    )
    rows = V.robot_energy(V.Runner("exudyn-beam", size))
    assert len(rows) == 2 and all(r["passed"] is None and "total energy" in r["reason"] for r in rows), rows
    rows = V.robot_energy(V.Runner("amm", size))
    assert len(rows) == 2 and all("no spatial engine (planar arms only)" in r["reason"] for r in rows)
    run = V.Runner("pinocchio-rigid", size)
    rows = V.robot_statics(run)
    assert len(rows) == 2 and all(r["passed"] is None and "rigid links" in r["reason"] for r in rows), rows
    assert rows[0]["reference"] == pytest.approx(1.32713e-4, rel=1e-5) and run.worker._proc is None


# ----------------------------------------------------------------------------- the studies
def _ctx(plan):
    return SimpleNamespace(plan=plan, cases=load_cases(plan))


def test_a_loop_sits_out_a_study_option_it_refuses():
    """The work-precision study runs the second-order DT-TMM with iterations="auto", which a
    closed loop refuses: on the four-bar that run is sat out before it starts, with the
    reason; on the branched arm (a tree) it runs; DT-TMM's own runs stay."""
    from experiments.study import sitting_out, study_tasks

    plan = Plan(
        "tiny-topology",
        {"four_bar": 0.01, "branched_arm": 0.01},
        {},
        {},
        {
            "work_precision": {
                "cases": ["four_bar", "branched_arm"],
                "methods": ["dttmm", "dttmm-2nd"],
                "path": [(1, 2e-3)],
                "rigid_h": [2e-3],
            }
        },
        case_files={n: str(TOPO / f"{n}.toml") for n in ("four_bar", "branched_arm")},
    )
    ctx = _ctx(plan)
    tasks = {(t.case, t.method) for t in study_tasks(ctx, "work_precision")}
    assert tasks == {("four_bar", "dttmm"), ("branched_arm", "dttmm"), ("branched_arm", "dttmm-2nd")}
    why = sitting_out(ctx)["work_precision"]["four_bar"]["dttmm-2nd"]
    assert "iterations='auto'" in why and "stop rule" in why, why
    assert "branched_arm" not in sitting_out(ctx)["work_precision"]


def test_the_scheme_study_sits_out_a_spatial_case():
    """``dttmm report --case`` with a spatial file: the scheme study (planar-kernel variants)
    plans no run on it and says why; the plans name the three topology cases, found under
    ``spatial/topology/``, the quick size running their first 0.2 s."""
    from experiments.study import sitting_out, study_tasks

    plan = plan_for("quick", [TOPO / "five_bar.toml"])
    assert list(plan.durations) == ["five_bar"]
    ctx = _ctx(plan)
    assert study_tasks(ctx, "scheme") == []
    assert "planar kernel" in sitting_out(ctx)["scheme"]["five_bar"]["dttmm"]
    for size in ("quick", "full"):
        assert {"four_bar", "five_bar", "branched_arm"} <= set(PLANS[size].studies["convergence_k"].cases)
        assert "four_bar" not in PLANS[size].studies["scheme"].cases
    cases = load_cases(PLANS["quick"])
    assert all(cases[n].scenario.duration == 0.2 for n in ("four_bar", "five_bar", "branched_arm"))
