"""Result.link_shapes: the deflected centre line of every link, in every method.

Checks against independent quantities: the shape's end points against the Result's link root
and tip positions (computed by each method's own kinematics), DT-TMM against the global solver
(same discretisation, independent code), DT-TMM against Exudyn's ANCF cable at a converged mesh,
straight links for the rigid baseline, and the static cantilever under its own weight against
the closed-form deflection curve.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd
import pytest
from conftest import case, shortened

import dttmm
from dttmm import shapes
from experiments import methods
from experiments.cachefiles import result_bytes, result_from_bytes

P = 9  # points per link in these tests


def _ends_match(res, atol):
    """Shape end points equal the Result's roots and tips; link i + 1 starts at link i's tip."""
    s = res.link_shapes
    assert s.shape == (res.t.size, res.n_joints, P, 2)
    np.testing.assert_allclose(s[:, :, 0], res.link_root, rtol=0, atol=atol)
    np.testing.assert_allclose(s[:, :, -1], res.link_tip, rtol=0, atol=atol)
    np.testing.assert_allclose(s[:, 1:, 0], s[:, :-1, -1], rtol=0, atol=atol)


@pytest.fixture(scope="module")
def three():
    return shortened(case("three_link"), 0.1)


@pytest.fixture(scope="module")
def dttmm_pair(three):
    kw = dict(elements_per_link=4, h=1e-3, progress=False)
    return dttmm.simulate(three, **kw), dttmm.simulate(three, shape_points=P, **kw)


def test_dttmm_shapes_end_at_root_and_tip_and_change_nothing_else(dttmm_pair):
    plain, res = dttmm_pair
    assert plain.link_shapes is None
    _ends_match(res, 1e-13)
    for f in ("joint_angle", "joint_rate", "joint_torque", "link_root", "link_tip", "energy", "cut_loads"):
        assert np.array_equal(getattr(plain, f), getattr(res, f)), f
    # the links bend: the midpoint leaves the chord (by more than round-off)
    mid = res.link_shapes[:, :, P // 2] - 0.5 * (res.link_root + res.link_tip)
    assert np.abs(mid).max() > 1e-6


def test_dttmm_equals_global_shapes(three, dttmm_pair):
    """Same discretisation, independent code: the trajectories agree to the iteration
    tolerance (≤ 1e-9, test_dttmm_vs_global), and so must the shapes."""
    res = dttmm_pair[1]
    for engine in ("numba", "python"):
        g = methods.run("global", three, 4, 1e-3, shape_points=P, engine=engine)
        _ends_match(g, 1e-13)
        assert np.abs(g.link_shapes - res.link_shapes).max() <= 1e-9, engine


def test_shapes_survive_the_parquet_round_trip(dttmm_pair):
    res = dttmm_pair[1]
    back = result_from_bytes(result_bytes(res))
    assert np.array_equal(back.link_shapes, res.link_shapes)
    # without shapes the table is the one of a run that did not ask for them (times in attrs aside)
    plain = dttmm_pair[0].to_frame()
    pd.testing.assert_frame_equal(plain, dc.replace(res, link_shapes=None).to_frame(), check_exact=True)
    extra = [c for c in res.to_frame().columns if c not in plain.columns]
    assert len(extra) == 3 * P * 2 and extra[0] == "link_shape_x_1_1"


def test_rigid_links_are_straight(three):
    res = methods.run("pinocchio-rigid", three, None, 1e-3, shape_points=P)
    _ends_match(res, 1e-13)
    u = np.linspace(0, 1, P)[None, None, :, None]
    line = res.link_root[:, :, None] + u * (res.link_tip - res.link_root)[:, :, None]
    np.testing.assert_allclose(res.link_shapes, line, rtol=0, atol=1e-15)


def test_mujoco_chain_shapes(three):
    pytest.importorskip("mujoco")
    res = methods.run("mujoco-chain", three, 4, 1e-4, shape_points=P)
    _ends_match(res, 1e-12)


@pytest.mark.parametrize("name", ["exudyn-ancf", "exudyn-beam"])
def test_exudyn_shapes_end_at_root_and_tip(three, name):
    pytest.importorskip("exudyn")
    res = methods.run(name, three, 4, 1e-3, shape_points=P)
    _ends_match(res, 1e-9)  # the beam nodes vs the hub and tip bodies clamped to them
    plain = methods.run(name, three, 4, 1e-3)
    assert np.array_equal(plain.link_tip, res.link_tip)


def test_dttmm_and_exudyn_ancf_shapes_agree_at_a_converged_mesh():
    """single_link for 0.3 s: the bending of the shape points (their deviation from the root–tip
    chord) of the two methods converges together as k grows — measured 8.3 %, 0.74 %, 0.11 % of
    its largest value (39 mm) at k = 4, 8, 16 — and at k = 16 they agree within 0.5 %, the
    positions themselves too (measured 0.23 %)."""
    pytest.importorskip("exudyn")
    c = shortened(case("single_link"), 0.3)

    def bend(r):
        return r.link_shapes - shapes.straight_shapes(r.link_root, r.link_tip, P)

    gap = {}
    for k in (8, 16):
        a = dttmm.simulate(c, elements_per_link=k, h=1e-3, shape_points=P, progress=False)
        b = methods.run("exudyn-ancf", c, k, 1e-3, shape_points=P)
        scale = np.abs(bend(a)).max()
        assert scale > 1e-2
        gap[k] = np.abs(bend(a) - bend(b)).max() / scale
    assert gap[16] <= 0.005 and gap[16] <= gap[8] / 4, gap
    assert np.abs(a.link_shapes - b.link_shapes).max() <= 0.005 * scale


def test_static_cantilever_shape_matches_the_closed_form_curve():
    """Clamped beam under its own weight, damped to rest: w(x) = q x²(6L² − 4Lx + x²)/(24 EI),
    q = ρA g (small deflection: w_tip/L = 1.2 %); within 0.1 % of w_tip at every point
    (measured 0.012 %)."""
    L, EI, rhoA, g = 1.0, 100.0, 1.0, 9.81
    link = dttmm.Link(dttmm.Section(L, EI, rhoA, None, damping=0.05))
    drive = dttmm.Drive("motion", dttmm.Constant(0.0))
    c = dttmm.Case(dttmm.Manipulator((link,), gravity=(0.0, -g)), dttmm.Scenario(1.0, 0.05, (drive,)))
    res = dttmm.simulate(c, elements_per_link=8, h=1e-3, shape_points=P, progress=False)
    x = np.linspace(0, L, P)
    w = -rhoA * g * x**2 * (6 * L**2 - 4 * L * x + x**2) / (24 * EI)
    y = res.link_shapes[-1, 0, :, 1]
    assert np.abs(y - w).max() <= 1e-3 * abs(w[-1]), (y, w)
    np.testing.assert_allclose(res.link_shapes[-1, 0, :, 0], x, atol=1e-3 * L)


@pytest.mark.parametrize("bad", [1, -2, 2.5, True, "9"])
@pytest.mark.parametrize("name", ["dttmm", "global", "pinocchio-rigid", "mujoco-chain", "exudyn-ancf"])
def test_bad_shape_points_is_refused_naming_the_option(three, name, bad):
    if name == "mujoco-chain":
        pytest.importorskip("mujoco")
    if name == "exudyn-ancf":
        pytest.importorskip("exudyn")
    with pytest.raises(dttmm.InputError, match="shape_points"):
        methods.run(name, three, None if name == "pinocchio-rigid" else 2, 1e-3, shape_points=bad)


def test_a_failed_run_keeps_the_shapes_of_what_it_computed(tmp_path):
    """A torque of 1e30 N·m from t = 0.06 s blows the run up: the partial Result carries the
    shapes of the samples before the failure, ending at the recorded roots and tips."""
    path = tmp_path / "blow.toml"
    path.write_text(
        "[model]\n[[model.links]]\nlength = 1.0\nEI = 2.0\nrhoA = 0.3\n[scenario]\nduration = 0.1\n"
        'output_step = 0.01\n[[scenario.drives]]\nkind = "torque"\nlaw = "table"\n'
        "times = [0.0, 0.05, 0.06]\nvalues = [0.0, 0.0, 1e30]\n"
    )
    with pytest.raises(dttmm.SimulationError) as err:
        dttmm.simulate(dttmm.load_case(path), elements_per_link=1, h=1e-3, shape_points=P, progress=False)
    part = err.value.partial
    assert 0 < part.t.size < 11 and part.link_shapes.shape == (part.t.size, 1, P, 2)
    np.testing.assert_allclose(part.link_shapes[:, :, -1], part.link_tip, rtol=0, atol=1e-12)
