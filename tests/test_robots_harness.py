"""The shipped robots (experiments/cases/spatial/robots/, docs/urdf.md) in the harness: the
methods that cannot model them sit them out before they run, with the reason; the plans find
them; a tiny plan runs them with the methods that can; and the tool point's deviation from the
rigid arm agrees between the DT-TMM and Exudyn's 3-D geometrically exact beam."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import dttmm
from experiments import methods
from experiments.plan import CASE_DIR, PLANS, Plan, load_cases, plan_for

ROBOTS = CASE_DIR / "spatial" / "robots"


def _robots():
    """Skip unless example-robot-data (the URDFs) is installed."""
    from importlib import metadata

    try:
        metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (pip install 'dttmm[robots]')")


def _case(name: str, duration: float | None = None, output_step: float | None = None):
    _robots()
    case = dttmm.load_case(ROBOTS / f"{name}.toml")
    changes = {k: v for k, v in (("duration", duration), ("output_step", output_step)) if v is not None}
    return dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, **changes))


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_methods_that_cannot_model_a_robot_say_why(name):
    """``why_not_case`` before any run: the MuJoCo chain and the ANCF cable refuse rigid links,
    the assumed modes have no spatial engine, the explicit DT-TMM's stable step on the tubes is
    below the studies' steps; the others run the robot."""
    case = _case(name)
    why = {m: methods.get(m).why_not_case(case) for m in methods.names()}
    assert "rigid links are not supported by mujoco-spatial" in why["mujoco-chain"]
    assert "rigid links are not supported by exudyn-ancf" in why["exudyn-ancf"]
    assert why["amm"] == "no spatial engine (planar arms only)"
    assert "explicit: its stable step on this arm at k = 8 is" in why["dttmm-rk4"]
    for m in ("dttmm", "dttmm-2nd", "global", "global-2nd", "exudyn-beam", "pinocchio-rigid"):
        assert why[m] == "", (m, why[m])
    # what the check refuses, the run refuses too
    from reference_models import mujoco_spatial

    with pytest.raises(dttmm.InputError, match="rigid links are not supported by mujoco-spatial"):
        mujoco_spatial.simulate(case, elements_per_link=1, h=1e-3)


def test_pinocchio_check_refuses_what_its_run_refuses():
    """Pinocchio's spatial baseline refuses a case with external loads before it runs, with
    the message its run gives; the shipped arm passes."""
    pytest.importorskip("pinocchio")
    from reference_models import pinocchio_spatial

    arm = dttmm.load_case(CASE_DIR / "spatial" / "three_joint_arm.toml")
    loaded = dttmm.load_case(CASE_DIR / "spatial" / "right_angle_cantilever.toml")
    assert methods.get("pinocchio-rigid").why_not_case(arm) == ""
    why = methods.get("pinocchio-rigid").why_not_case(loaded)
    assert why
    with pytest.raises(dttmm.InputError) as err:
        pinocchio_spatial.simulate(loaded, h=1e-3)
    assert str(err.value) == why


def test_the_plans_find_the_robots():
    """The quick and full plans name the robots; their files are found under
    ``spatial/robots/``; the quick size runs their first 0.1 s; a robot file given on the command
    line keeps its shipped name."""
    _robots()
    for size in ("quick", "full"):
        assert {"ur5", "panda"} <= set(PLANS[size].durations)
        assert {"ur5", "panda"} <= set(PLANS[size].studies["convergence_k"].cases)
        assert "ur5" not in PLANS[size].studies["scheme"].cases  # planar-kernel variants
    plan = dataclasses.replace(PLANS["quick"], durations={"ur5": 0.1, "panda": 0.1})
    cases = load_cases(plan)
    assert cases["ur5"].scenario.duration == 0.1 and cases["panda"].model.n_links == 10
    assert list(plan_for("quick", [ROBOTS / "ur5.toml"]).durations) == ["ur5"]


def test_a_tiny_plan_runs_a_robot_with_the_methods_that_can(tmp_path):
    """The UR5's first 20 ms through the studies: the DT-TMM, Exudyn's beam and Pinocchio run
    it; the MuJoCo chain and the explicit DT-TMM, though named, have no run."""
    from experiments.context import prepare
    from experiments.references import RefSpec
    from experiments.study import run_studies

    _robots()
    pytest.importorskip("exudyn")
    dur = {"ur5": 0.02}
    named = ["dttmm", "exudyn-beam", "mujoco-chain", "dttmm-rk4"]
    plan = Plan(
        "tiny-robot",
        dur,
        {"ur5": [RefSpec("exudyn-ancf", 4, 5e-4), RefSpec("dttmm", 4, 5e-4)]},
        {"ur5": [RefSpec("exudyn-beam", 4, 5e-4)]},
        {
            "convergence_k": {"cases": ["ur5"], "methods": named, "ks": [1, 2], "h": 2e-3},
            "work_precision": {
                "cases": ["ur5"],
                "methods": [*named, "pinocchio-rigid"],
                "path": [(1, 4e-3), (2, 2e-3)],
                "rigid_h": [2e-3],
            },
        },
        "tiny robot test size",
        output_step=4e-3,
    )
    ctx = prepare(plan, tmp_path / "data")
    tables = run_studies(ctx, scheduler="serial", progress=False)
    ck, wp = tables["convergence_k"], tables["work_precision"]
    assert set(ck.method) == {"dttmm", "exudyn-beam"} and (ck.status == "ok").all()
    assert set(wp.method) == {"dttmm", "exudyn-beam", "pinocchio-rigid"} and (wp.status == "ok").all()
    # scored against the DT-TMM reference at k = 4, h = 5e-4 (the ANCF cable passed over):
    # within 30 µm (measured: DT-TMM 7.2e-6 m at k = 1 and 2, the step error of h = 2e-3 s;
    # Exudyn's beam 1.6e-5, 6e-6 m)
    assert ((ck.ee_l2 > 0) & (ck.ee_l2 < 3e-5)).all(), ck[["method", "k", "ee_l2"]]


# The tool point's deviation from the rigid arm, |tool_flexible(t) − tool_rigid(t)|, on the
# shipped pick-and-place move (released under gravity at t = 0, the move starting): the
# DT-TMM's and the Exudyn GE beam's agree within 2 % of the peak deviation. Exudyn's
# shear-flexible element converges at second order: measured over 0.3 s at h = 5e-4, UR5
# 3.5 %, 0.88 % at k = 4, 8; Panda 11.7 %, 3.5 %, 1.1 % at k = 4, 8, 16 (the peak deviation
# 0.39 mm, 0.14 mm). The rigid arm is Pinocchio's run of the same case: every joint is
# motion-driven, so its tool point is the forward kinematics of the laws.
@pytest.mark.parametrize(("name", "k"), [("ur5", 8), ("panda", 16)])
def test_tool_deviation_from_the_rigid_arm_dttmm_against_exudyn(name, k):
    pytest.importorskip("exudyn")
    pytest.importorskip("pinocchio")
    import dttmm.spatial as sp
    from reference_models import exudyn_beam3d, pinocchio_spatial

    case = _case(name, duration=0.2, output_step=5e-3)
    h = 5e-4
    rigid = pinocchio_spatial.simulate(case, h=h).end_effector
    dev = {
        "dttmm": sp.simulate(case, elements_per_link=k, h=h).end_effector,
        "exudyn": exudyn_beam3d.simulate(case, elements_per_link=k, h=h).end_effector,
    }
    dev = {m: np.linalg.norm(x - rigid, axis=1) for m, x in dev.items()}
    peak = dev["dttmm"].max()
    assert peak > 5e-5  # a clear deviation: the tubes bend by a tenth of a millimetre
    assert np.abs(dev["dttmm"] - dev["exudyn"]).max() < 0.02 * peak
