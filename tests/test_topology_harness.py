"""The harness on trees and closed loops: every method either runs a topology case or sits it out
with its reason, before it runs (no failure rows)."""

from __future__ import annotations

from pathlib import Path

import pytest

import dttmm
from experiments import methods

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "topology"


@pytest.mark.parametrize("name", ["four_bar", "five_bar"])
def test_a_loop_runs_on_the_implicit_solvers_and_the_rest_say_why_not(name):
    case = dttmm.load_case(CASES / f"{name}.toml")
    runs = {m for m in methods.names() if methods.get(m).runs_on(case)}
    assert {"dttmm", "global", "exudyn-beam"} <= runs
    assert "Newmark family only" in methods.get("dttmm-rk4").why_not_case(case)
    for m in ("exudyn-ancf", "mujoco-chain", "pinocchio-rigid"):
        assert "trees and closed loops are not supported" in methods.get(m).why_not_case(case), m


def test_a_tree_sits_out_the_serial_engines_with_the_link_that_branches():
    case = dttmm.load_case(CASES / "branched_arm.toml")
    for m in ("dttmm", "global", "exudyn-beam"):
        assert methods.get(m).runs_on(case), m
    for m in ("exudyn-ancf", "mujoco-chain", "pinocchio-rigid"):
        why = methods.get(m).why_not_case(case)
        assert why.startswith("model.links[") and ".parent" in why, (m, why)
