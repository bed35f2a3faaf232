"""Load comparisons of the report and the case selection of ``dttmm report --case``.

The root bending moment every method gets from the hub balance (M = τ₁ − J₁θ̈₁, stored joint
torque and rate) is checked against the moment DT-TMM's transfer sweep carries across the root
cut, an independent computation of the same load.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import case, shortened

import dttmm
from dttmm.errors import InputError
from experiments import metrics
from experiments.plan import CASE_DIR, PLANS, load_cases, plan_for


@pytest.mark.parametrize("name", ["three_link", "single_link"])
def test_hub_balance_moment_equals_the_cut_load(name):
    c = shortened(case(name), 0.4, 1e-3)
    res = dttmm.simulate(c, elements_per_link=4, h=2.5e-4)
    from_cuts = metrics.load_series(res, c)["moment1"]
    from_hub = metrics.load_series(metrics.without_cut_loads(res), c)["moment1"]
    assert res.cut_loads is not None and np.abs(from_cuts).max() > 0.1
    # central differences of the rate on a 1 ms grid: O(dt²) away from the torque switch at 0.5 s
    assert np.abs(from_hub - from_cuts).max() < 2e-3 * np.abs(from_cuts).max()


def test_load_differences_of_a_result_with_itself_are_zero():
    c = shortened(case("spin_up"), 0.2, 1e-2)
    res = dttmm.simulate(c, elements_per_link=2, h=1e-3)
    err = metrics.load_errors(res, res, c)
    # spin_up is motion-driven: its joint torque is an output and is compared
    assert set(err) == {f"{q}_{k}" for q in ("moment1", "torque1", "energy") for k in ("l2", "linf", "scale")}
    assert err["torque1_l2"] == 0 and err["energy_linf"] == 0 and err["torque1_scale"] > 0


def _write(path, length=1.0):
    text = (CASE_DIR / "single_link.toml").read_text().replace("length = 1.0 ", f"length = {length} ")
    path.write_text(text)
    return path


def test_case_files_outside_the_repo_carry_a_fingerprint(tmp_path):
    a = _write(tmp_path / "arm.toml")
    plan = plan_for("quick", [a, CASE_DIR / "three_link.toml"])
    names = list(plan.durations)
    assert names[1] == "three_link" and names[0].startswith("single_link-") and len(names[0]) == 20
    assert plan.studies["convergence_k"].cases == names and plan.studies["cost"].case == "three_link"
    cases = load_cases(plan)
    assert cases[names[0]].model.links[0].beam.length == 1.0 and cases[names[0]].name == names[0]
    edited = plan_for("quick", [_write(tmp_path / "arm.toml", 1.2)])
    assert list(edited.durations) != names[:1]  # an edited file never reuses cached runs
    assert plan_for("quick", []) is PLANS["quick"]


def test_quick_size_shortens_long_cases_only(tmp_path):
    spin = plan_for("quick", [CASE_DIR / "spin_up.toml"])
    assert spin.durations == {"spin_up": 6.0}
    assert plan_for("full", [CASE_DIR / "spin_up.toml"]).durations == {"spin_up": None}


def test_bad_case_arguments_are_refused_with_the_path(tmp_path):
    with pytest.raises(InputError, match="nope.toml"):
        plan_for("quick", [tmp_path / "nope.toml"])
    (tmp_path / "bad.toml").write_text("[model]\n")
    with pytest.raises(InputError, match=r"bad.toml: (scenario|model)"):
        plan_for("quick", [tmp_path / "bad.toml"])
    a, b = _write(tmp_path / "a.toml"), _write(tmp_path / "b.toml")
    with pytest.raises(InputError, match="names the same case"):
        plan_for("quick", [a, b])
