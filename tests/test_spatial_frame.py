"""SpatialResult.to_frame: the tidy table of a spatial run (one column per scalar quantity, cut
loads included when recorded), its columns equal to the Result's arrays, and back (from_frame)."""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest

from dttmm.drives import Constant, Drive, Sine
from dttmm.spatial import SpatialJoint, SpatialResult, load_case, simulate

pd = pytest.importorskip("pandas")

ARM = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "three_joint_arm.toml"


def _run(cut_loads):
    """The three-joint arm with its second joint locked (m = 2 joints, n = 3 links), k = 2."""
    case = load_case(ARM)
    links = list(case.model.links)
    links[1] = dc.replace(links[1], joint=SpatialJoint(axis=links[1].joint.axis, locked=True))
    model = dc.replace(case.model, links=tuple(links))
    drives = (Drive("torque", Sine(2.0, 2.0)), Drive("torque", Constant(-0.5)))
    sc = dc.replace(case.scenario, drives=drives, duration=0.01, output_step=2e-3)
    return simulate(
        dc.replace(case, model=model, scenario=sc), elements_per_link=2, h=1e-3, cut_loads=cut_loads
    )


@pytest.mark.parametrize("cut_loads", [False, True])
def test_columns_equal_the_arrays(cut_loads):
    r = _run(cut_loads)
    df = r.to_frame()
    nt, m, n, k = r.t.size, 2, 3, 2
    assert r.joint_angle.shape == (nt, m) and r.link_root.shape == (nt, n, 3)
    np.testing.assert_array_equal(df["t"], r.t)
    for j in range(m):
        for f in ("joint_angle", "joint_rate", "joint_torque"):
            np.testing.assert_array_equal(df[f"{f}_{j + 1}"], getattr(r, f)[:, j])
    assert "joint_angle_3" not in df
    for i in range(n):
        for a, c in enumerate("xyz"):
            np.testing.assert_array_equal(df[f"link_root_{c}_{i + 1}"], r.link_root[:, i, a])
            np.testing.assert_array_equal(df[f"link_tip_{c}_{i + 1}"], r.link_tip[:, i, a])
        np.testing.assert_array_equal(df[f"tip_deflection_y_{i + 1}"], r.tip_deflection[:, i, 0])
        np.testing.assert_array_equal(df[f"tip_deflection_z_{i + 1}"], r.tip_deflection[:, i, 1])
        np.testing.assert_array_equal(df[f"twist_{i + 1}"], r.twist[:, i])
        for a in range(3):
            for b in range(3):
                rc = f"{a + 1}{b + 1}_{i + 1}"
                np.testing.assert_array_equal(df[f"link_rotation_{rc}"], r.link_rotation[:, i, a, b])
                np.testing.assert_array_equal(df[f"tip_rotation_{rc}"], r.tip_rotation[:, i, a, b])
    for a, c in enumerate("xyz"):
        np.testing.assert_array_equal(df[f"end_effector_{c}"], r.end_effector[:, a])
    np.testing.assert_array_equal(df["energy"], r.energy)
    n_cols = 1 + 3 * m + n * (6 + 3 + 18) + 3 + 1
    if cut_loads:
        cuts = n * (k + 1)
        assert r.cut_loads.shape == (nt, cuts, 6)
        for c in range(cuts):
            for a, x in enumerate("xyz"):
                np.testing.assert_array_equal(df[f"cut_force_{x}_{c + 1}"], r.cut_loads[:, c, a])
                np.testing.assert_array_equal(df[f"cut_moment_{x}_{c + 1}"], r.cut_loads[:, c, 3 + a])
        n_cols += 6 * cuts
    assert df.shape == (nt, n_cols)
    assert df.attrs["status"] == r.status and df.attrs["method"] == "dttmm-spatial"
    # and back
    b = SpatialResult.from_frame(df)
    for f in ("t", "joint_angle", "joint_rate", "joint_torque", "link_root", "link_tip", "tip_deflection"):
        np.testing.assert_array_equal(getattr(b, f), getattr(r, f))
    np.testing.assert_array_equal(b.twist, r.twist)
    np.testing.assert_array_equal(b.link_rotation, r.link_rotation)
    np.testing.assert_array_equal(b.tip_rotation, r.tip_rotation)
    np.testing.assert_array_equal(b.end_effector, r.end_effector)
    if cut_loads:
        np.testing.assert_array_equal(b.cut_loads, r.cut_loads)
    assert b.status == r.status and b.n_steps == r.n_steps


def test_closure_columns_and_back():
    """The four-bar (one revolute closure): the closure loads and gaps become columns
    closure_{force,moment}_{x,y,z}_1, closure_residual_1, closure_angle_residual_1, equal to the
    arrays, and come back through from_frame (a chain has none of them)."""
    case = load_case(ARM.parent / "topology" / "four_bar.toml")
    case = dc.replace(case, scenario=dc.replace(case.scenario, duration=0.01, output_step=2e-3))
    r = simulate(case, elements_per_link=2, h=1e-3)
    df = r.to_frame()
    assert r.closure_loads.shape == (r.t.size, 1, 6)
    for a, x in enumerate("xyz"):
        np.testing.assert_array_equal(df[f"closure_force_{x}_1"], r.closure_loads[:, 0, a])
        np.testing.assert_array_equal(df[f"closure_moment_{x}_1"], r.closure_loads[:, 0, 3 + a])
    np.testing.assert_array_equal(df["closure_residual_1"], r.closure_residual[:, 0])
    np.testing.assert_array_equal(df["closure_angle_residual_1"], r.closure_angle_residual[:, 0])
    b = SpatialResult.from_frame(df)
    for f in ("closure_loads", "closure_residual", "closure_angle_residual"):
        np.testing.assert_array_equal(getattr(b, f), getattr(r, f))
    assert not any(c.startswith("closure_") for c in _run(False).to_frame().columns)
