"""The studies' typed parameter records (experiments/params.py): built by the plans, checked on
construction, read by attribute."""

from __future__ import annotations

import dataclasses

import pytest

from dttmm.errors import InputError
from experiments.params import PARAMS, ControlModes, CostParams, EnergyReference, study_params
from experiments.plan import PLANS, Plan
from experiments.studies import STUDIES


def test_every_study_has_a_record_and_the_plans_hold_records():
    assert set(PARAMS) == set(STUDIES)
    for plan in PLANS.values():
        assert set(plan.studies) == set(STUDIES)
        for name, p in plan.studies.items():
            assert isinstance(p, PARAMS[name]) and dataclasses.is_dataclass(p)
    full = PLANS["full"].studies
    assert full["paper"].energy_reference == EnergyReference(k=32, h=1e-4)
    assert full["control"].modes == ControlModes(k=32, exudyn_k=32, n=4)


def test_records_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        PLANS["quick"].studies["cost"].h = 2e-3


def test_a_dict_becomes_the_record_in_the_plan():
    plan = Plan("t", {}, {}, {}, {"cost": {"case": "single_link", "ks": [1, 2]}})
    assert plan.studies["cost"] == CostParams(case="single_link", ks=[1, 2], h=1e-3)
    assert study_params("cost", plan.studies["cost"]) is plan.studies["cost"]


def test_the_plans_time_the_spatial_arm_in_the_cost_study():
    for size, ks in (("quick", (1, 2, 4, 8, 16, 32)), ("full", (1, 2, 4, 8, 16, 32, 64))):
        cost = PLANS[size].studies["cost"]
        assert cost.case_ks() == [("three_link", ks), ("three_joint_arm", ks)], size
        assert cost.h == PLANS[size].studies["convergence_k"].h  # its runs are convergence_k's
        # the spatial ks reach at least convergence_k's: every spatial run of that study is timed
        assert set(PLANS[size].studies["convergence_k"].ks) <= set(cost.spatial_ks)
    # without a spatial case the record is the planar one alone, as before
    assert CostParams(case="single_link", ks=[1, 2], h=1e-3).case_ks() == [("single_link", (1, 2))]


def test_case_files_from_the_command_line_get_a_planar_only_cost_study():
    from experiments.plan import plan_for

    plan = plan_for("quick", ["experiments/cases/single_link.toml"])
    assert plan.studies["cost"].case_ks() == [("single_link", (1, 2, 4, 8, 16, 32))]


def test_spatial_references_record_cut_loads_and_user_spatial_cases_get_them_too():
    """The shipped spatial arm's reference candidates that record cut loads are asked for them
    (the loads comparison's root bending moment); a spatial case file given on the command line
    gets the spatial arm's references and cross-checks, a planar one the planar ones."""
    from experiments.plan import PLANS, plan_for

    q = PLANS["quick"]
    spatial = {r.method: r.options for r in q.reference["three_joint_arm"]}
    assert spatial["dttmm"] == (("cut_loads", True),) and spatial["exudyn-ancf"] == ()
    assert all(r.options == () for r in q.reference["three_link"])
    plan = plan_for(
        "quick", ["experiments/cases/spatial/two_joint_arm.toml", "experiments/cases/single_link.toml"]
    )
    arm = next(n for n in plan.reference if n.startswith("two_joint_arm"))
    assert (
        plan.reference[arm] == q.reference["three_joint_arm"]
        and plan.check[arm] == q.check["three_joint_arm"]
    )
    assert (
        plan.reference["single_link"] == q.reference["three_link"]
        and plan.check["single_link"] == q.check["three_link"]
    )


@pytest.mark.parametrize(
    "study, values, field, value",
    [
        ("cost", {"ks": [1, 0]}, "plan.studies.cost.ks", [1, 0]),
        ("convergence_k", {"h": -1e-3}, "plan.studies.convergence_k.h", -1e-3),
        ("work_precision", {"path": [(2, 0.0)]}, "plan.studies.work_precision.path", [(2, 0.0)]),
        ("control", {"modes": {"n": 0}}, "plan.studies.control.modes.n", 0),
        (
            "paper",
            {"energy_reference": {"k": 4, "h": "1e-3"}},
            "plan.studies.paper.energy_reference.h",
            "1e-3",
        ),
        ("cost", {"kss": [1]}, "plan.studies.cost", "kss"),
        ("cost", {"spatial_case": 3, "spatial_ks": [1]}, "plan.studies.cost.spatial_case", 3),
        ("cost", {"spatial_case": "three_link"}, "plan.studies.cost.spatial_case", "three_link"),
        ("cost", {"spatial_case": "three_joint_arm"}, "plan.studies.cost.spatial_ks", ()),
        ("cost", {"spatial_ks": [1, 2]}, "plan.studies.cost.spatial_ks", [1, 2]),
        (
            "cost",
            {"spatial_case": "three_joint_arm", "spatial_ks": [2, -1]},
            "plan.studies.cost.spatial_ks",
            [2, -1],
        ),
        ("costs", {}, "plan.studies", "costs"),
    ],
)
def test_a_bad_parameter_is_named_with_its_value(study, values, field, value):
    with pytest.raises(InputError) as err:
        Plan("t", {}, {}, {}, {study: values})
    assert err.value.field == field and err.value.value == value
