"""The harness on trees and closed loops: every method either runs a topology case or sits it out
with its reason, before it runs (no failure rows)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dttmm
from experiments import methods

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"


@pytest.mark.parametrize("name", ["four_bar", "five_bar"])
def test_a_loop_runs_on_the_implicit_solvers_and_the_rest_say_why_not(name):
    case = dttmm.load_case(CASES / f"{name}.toml")
    runs = {m for m in methods.names() if methods.get(m).runs_on(case)}
    assert {"dttmm", "global", "exudyn-beam", "mujoco-chain"} <= runs
    assert "Newmark family only" in methods.get("dttmm-rk4").why_not_case(case)
    assert "trees and closed loops are not supported" in methods.get("exudyn-ancf").why_not_case(case)
    why = methods.get("pinocchio-rigid").why_not_case(case)
    if name == "five_bar":  # every axis z: the rigid loop closes by a 3-D point contact
        assert why == ""
    else:  # the tilted joint C needs a 5-equation revolute, which Pinocchio's rigid constraints lack
        assert why.startswith("model.closures[0].axis") and "5 equations" in why and "\n" not in why, why


def test_a_tree_runs_on_mujoco_and_pinocchio_and_the_serial_engines_say_which_link_branches():
    case = dttmm.load_case(CASES / "branched_arm.toml")
    for m in ("dttmm", "global", "exudyn-beam", "mujoco-chain", "pinocchio-rigid"):
        assert methods.get(m).runs_on(case), m
    why = methods.get("exudyn-ancf").why_not_case(case)
    assert why.startswith("model.links[") and ".parent" in why, why


@pytest.mark.parametrize("name", ["branched_arm", "five_bar", "four_bar"])
def test_mujoco_runs_trees_and_loops_at_the_studies_step(name):
    """The studies' step for the MuJoCo chain on a tree or a loop (the chains' rule, 1 ms at
    k = 2, let the branched arm and the four-bar diverge) is below half the stable step of the
    case's own chain, and the run at it stays finite (k = 2, 0.02 s)."""
    import dataclasses

    from experiments.studies._common import step_for
    from reference_models import mujoco_spatial as ms

    case = dttmm.load_case(CASES / f"{name}.toml")
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.02, output_step=0.005)
    )
    h = step_for("mujoco-chain", 2, 1e-3, case)
    m, d, _ = ms.build(case.model, 2)
    assert h <= 0.5 * ms.stability_limit(m, d)[1]
    res = ms.simulate(case, elements_per_link=2, h=h)
    assert res.status == "ok" and np.all(np.isfinite(res.link_tip))
