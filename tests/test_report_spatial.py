"""A spatial arm through the report at a tiny size: the studies run it with the methods that
have a spatial engine, score it against its own reference, and draw its figures."""

from __future__ import annotations

import numpy as np
import pytest

from experiments import methods
from experiments.plan import Plan
from experiments.references import RefSpec
from reports import cli

CASE = "three_joint_arm"
SPATIAL = ["dttmm", "exudyn-beam"]


def tiny_spatial_plan() -> Plan:
    dur = {CASE: 0.04}
    # the first is planar only; the reference records cut loads (the root bending moment needs them)
    ref = [RefSpec("exudyn-ancf", 4, 5e-4), RefSpec("dttmm", 4, 5e-4, (("cut_loads", True),))]
    chk = [RefSpec("dttmm", 4, 5e-4), RefSpec("exudyn-beam", 4, 5e-4)]
    return Plan(
        "tiny-spatial",
        dur,
        dict.fromkeys(dur, ref),
        dict.fromkeys(dur, chk),
        {
            "convergence_k": {"cases": [CASE], "methods": [*SPATIAL, "amm"], "ks": [1, 2], "h": 2e-3},
            "convergence_h": {
                "cases": [CASE],
                "methods": SPATIAL,
                "hs": [4e-3, 2e-3],
                "k": 2,
                "explicit_hs": [],
            },
            "work_precision": {
                "cases": [CASE],
                "methods": [*SPATIAL, "mujoco-chain", "pinocchio-rigid"],
                "path": [(1, 4e-3), (2, 2e-3)],
                "rigid_h": [2e-3],
            },
            "paper": {
                "cases": [CASE],
                "methods": [*SPATIAL, "pinocchio-rigid"],
                "k": 2,
                "h": 2e-3,
                "energy_reference": {"method": "dttmm", "k": 4, "h": 5e-4},
            },
            # the arm alone in the cost study (its planar case: none in this plan)
            "cost": {"case": CASE, "methods": [*SPATIAL, "amm", "global"], "ks": [1, 2, 4], "h": 2e-3},
        },
        "tiny spatial test size",
        output_step=4e-3,
    )


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("report_spatial")
    plan = tiny_spatial_plan()
    html, md = cli.run_report(
        plan, root / "out", data=root / "data", scheduler="serial", progress=False, bench_dir=root / "bench"
    )
    from experiments.study import load_tables

    return root, load_tables(root / "out" / "data"), md.read_text(), plan


def test_spatial_runs_only_with_spatial_methods(report):
    _, tables, _, _ = report
    ck = tables["convergence_k"]
    assert set(ck.method) == set(SPATIAL)  # the assumed modes have no spatial engine: not run
    assert (ck.status == "ok").all()
    # errors against the reference fall with k for DT-TMM (the reference is DT-TMM at k = 4)
    d = ck[ck.method == "dttmm"].sort_values("k")
    assert d.ee_l2.iloc[0] > d.ee_l2.iloc[1] > 0


def test_spatial_reference_and_cross_check(report):
    import json

    root, _, _, _ = report
    prov = json.loads(next((root / "data").rglob(f"{CASE}_T*.json")).read_text())
    assert prov["method"] == "dttmm"  # the planar-only first candidate is passed over, with the reason
    assert "does not run this case" in prov["failures"][0]
    cc = prov["cross_check"]
    assert cc["method"] == "exudyn-beam"  # not the reference's own method
    # Exudyn's 3-D beam at the same k agrees with the spatial DT-TMM to a fraction of a millimetre
    assert 0 < cc["errors"]["ee_l2"] < 1e-3


def test_spatial_rigid_baseline_and_explicit_chain(report):
    _, tables, _, _ = report
    wp = tables["work_precision"]
    rigid = wp[wp.method == "pinocchio-rigid"]
    assert len(rigid) == 1 and rigid.status.iloc[0] == "ok"
    # the MuJoCo chain runs at its spatial step rule (stable on this arm), not the planar one
    mj = wp[wp.method == "mujoco-chain"].sort_values("k")
    assert list(mj.h) == [methods.get("mujoco-chain").spatial_max_step(k) for k in (1, 2)] == [2e-3, 1e-3]
    assert (mj.status == "ok").all() and (mj.ee_l2 < 0.05).all()


def test_runs_on_rules():
    import dttmm

    arm = dttmm.load_case(f"experiments/cases/spatial/{CASE}.toml")
    planar = dttmm.load_case("experiments/cases/three_link.toml")
    assert methods.runs_on("amm", planar) and not methods.runs_on("amm", arm)
    assert methods.runs_on("dttmm", arm, 64)
    assert methods.runs_on("global", arm, 2) and methods.runs_on("global", arm, 32)  # compiled: no k limit


def test_spatial_paper_series(report):
    _, tables, md, _ = report
    summ = tables["paper_summary"]
    assert set(summ.method) == {*SPATIAL, "pinocchio-rigid", "reference"}
    # energy against the reference's (DT-TMM records it): the coarse DT-TMM run is off by a
    # small fraction of it, the rigid arm (which has no strain energy) by far more
    loads = tables["paper_loads"].set_index("method")
    assert 0 < loads.energy_rel["dttmm"] < 1e-3
    assert loads.energy_rel["pinocchio-rigid"] > 10 * loads.energy_rel["dttmm"]
    assert "paper_three_joint_arm.png" in md


def test_spatial_root_bending_moment_in_the_loads_section(report):
    _, tables, md, _ = report
    paper = tables["paper"]
    runs = paper[paper.role == "compared"].set_index("method")
    assert runs.options["dttmm"] == "cut_loads=True" and runs.options["exudyn-beam"] == ""
    loads = tables["paper_loads"].set_index("method")
    # DT-TMM at k = 2 against the DT-TMM reference at k = 4: a few per cent of the peak moment
    assert loads.moment1_note["dttmm"] == "" and 0 < loads.moment1_rel["dttmm"] < 0.1
    for m in ("exudyn-beam", "pinocchio-rigid"):
        assert (
            np.isnan(loads.moment1_l2[m]) and loads.moment1_note[m] == methods.get(m).why_no_spatial_moment()
        )
    assert "the torsion about the link's axis left out" in md
    assert (
        f"not compared for {methods.label('exudyn-beam')} ({methods.get('exudyn-beam').spatial_loads_note})"
        in md
    )
    assert "magnitude of the bending part of the root cut load" in md  # the figure's caption


def test_methods_sitting_a_spatial_arm_out_say_why(report):
    import dttmm

    _, _, md, _ = report
    assert "amm sits it out (no spatial engine (planar arms only))" in md
    # the ANCF cable has one bending stiffness: the arm's EIy ≠ EIz is the reason it sits out
    assert "exudyn-ancf sits it out (model.links[0].beam.EIy" in md
    twin = dttmm.load_case("experiments/cases/spatial/two_joint_arm.toml")  # EIy = EIz
    assert methods.runs_on("exudyn-ancf", twin)


def test_spatial_cost_study(report):
    _, tables, md, _ = report
    c = tables["cost"]
    # the methods with a spatial engine, the spatial global solver (compiled) at every k
    runs = {(m, int(k)) for m, k in zip(c.method, c.k)}
    assert runs == {(m, k) for m in (*SPATIAL, "global") for k in (1, 2, 4)}
    assert (c.status == "ok").all() and (c.space == "spatial").all() and (c.repeats >= 3).all()
    ex = tables["cost_exponents"]
    assert set(ex.case) == {CASE} and set(ex.method) == {*SPATIAL, "global"}
    assert "Fitted exponents of CPU time ∝ k^p (k ≥ 2): on three_joint_arm (spatial) " in md
    assert "runs it up to k = " not in md  # no method sits larger k out on this arm
    assert "DT-TMM (Newmark) against the spatial global solver" in md
