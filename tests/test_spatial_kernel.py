"""The spatial kernel's engines and failure handling: the compiled kernel equals the same
source run uncompiled; a diverging run raises SimulationError with the partial result; bad
settings are refused naming the option; a planar Case runs on the planar kernel."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm import Constant, Drive, Scenario
from dttmm.errors import InputError, SimulationError
from dttmm.spatial import SpatialCase, SpatialResult, load_case, simulate

CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases"


def short(case, duration, step):
    return dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=duration, output_step=step)
    )


@pytest.mark.parametrize("integrator", ["newmark", "rk4"])
def test_compiled_equals_uncompiled(integrator):
    duration, step = (0.004, 1e-3) if integrator == "newmark" else (2e-5, 2e-6)
    case = short(load_case(CASES / "spatial" / "three_joint_arm.toml"), duration, step)
    h = 1e-3 if integrator == "newmark" else 2e-6
    opts = dict(elements_per_link=2, h=h, integrator=integrator, cut_loads=True)
    a = simulate(case, engine="numba", **opts)
    b = simulate(case, engine="python", **opts)
    assert a.meta["engine"] == "numba" and b.meta["engine"] == "python"
    for f in (
        "joint_angle",
        "joint_rate",
        "joint_torque",
        "end_effector",
        "tip_deflection",
        "twist",
        "energy",
    ):
        x, y = getattr(a, f), getattr(b, f)
        assert np.abs(x - y).max() <= 1e-12 * max(1.0, np.abs(y).max()), f
    assert np.abs(a.cut_loads - b.cut_loads).max() <= 1e-10 * np.abs(b.cut_loads).max()


def test_divergence_raises_with_the_partial_result():
    case = load_case(CASES / "spatial" / "two_joint_arm.toml")
    drives = (Drive("torque", Constant(1e9)), Drive("torque", Constant(-1e9)))
    bad = SpatialCase(case.model, Scenario(0.5, 0.01, drives))
    with pytest.raises(SimulationError) as exc:
        simulate(bad, elements_per_link=2, h=1e-3)
    part = exc.value.partial
    assert isinstance(part, SpatialResult) and part.status == "failed"
    assert 0 < part.t.size < 51 and part.t[-1] <= exc.value.t
    assert np.isfinite(part.end_effector).all()


def test_bad_settings_are_refused():
    case = load_case(CASES / "spatial" / "two_joint_arm.toml")
    for kw, field in [
        (dict(elements_per_link=0, h=1e-3), "elements_per_link"),
        (dict(elements_per_link=2, h=-1.0), "h"),
        (dict(elements_per_link=2, h=1e-3, integrator="euler"), "integrator"),
        (dict(elements_per_link=2, h=1e-3, strain="cubic"), "strain"),
        (dict(elements_per_link=2, h=1e-3, tol=2.0), "tol"),
        (dict(elements_per_link=2, h=1e-3, engine="gpu"), "engine"),
        (dict(elements_per_link=2, h=1e-3, sweep="plain"), "sweep"),
    ]:
        with pytest.raises(InputError) as exc:
            simulate(case, **kw)
        assert exc.value.field == field
    with pytest.raises(InputError, match="case"):
        simulate("three_joint_arm.toml", elements_per_link=2, h=1e-3)


def test_planar_case_keeps_the_planar_kernel_and_its_shapes():
    case = short(dttmm.load_case(CASES / "three_link.toml"), 0.01, 0.005)
    r = simulate(case, elements_per_link=2, h=1e-3)
    assert r.meta["method"] == "dttmm" and r.end_effector.shape == (3, 2)
    assert not isinstance(r, SpatialResult)


def test_pair_form_and_result_shapes():
    case = load_case(CASES / "spatial" / "three_joint_arm.toml")
    case = short(case, 0.01, 0.005)
    r = simulate((case.model, case.scenario), elements_per_link=3, h=1e-3, cut_loads=True)
    nt = 3
    assert r.end_effector.shape == (nt, 3)
    assert r.link_root.shape == r.link_tip.shape == (nt, 3, 3)
    assert r.tip_deflection.shape == (nt, 3, 2) and r.twist.shape == (nt, 3)
    assert r.joint_angle.shape == r.joint_torque.shape == (nt, 3)
    assert r.cut_loads.shape == (nt, 3 * 4, 6)
    assert np.allclose(r.end_effector, r.link_tip[:, -1])
