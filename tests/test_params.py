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
        ("costs", {}, "plan.studies", "costs"),
    ],
)
def test_a_bad_parameter_is_named_with_its_value(study, values, field, value):
    with pytest.raises(InputError) as err:
        Plan("t", {}, {}, {}, {study: values})
    assert err.value.field == field and err.value.value == value
