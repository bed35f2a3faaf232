"""Link shapes of spatial arms (``shape_points``): spatial DT-TMM and the spatial global solver.

Asking for shapes changes no other output (bitwise); point 1 is the link root and point p its
tip; DT-TMM's shapes equal the global solver's (the same discretisation, assembled
independently) to round-off; they survive the parquet round trip; and the shape of a static
cantilever matches the closed-form deflection curve: exactly (to the geometric nonlinearity of
the tiny load, (δ/L)² ≈ 1e-9) for a tip force, whose curve is a cubic the Hermite elements
hold, and at the element's fourth order in k for a uniform load (a quartic curve).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from dttmm import Scenario
from dttmm.spatial import (
    SpatialCase,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    link_shapes,
    load_case,
    simulate,
    statics,
)

CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases" / "spatial"
P = 7


def short(name, duration=0.05, output_step=0.01):
    c = load_case(CASES / f"{name}.toml")
    return dataclasses.replace(
        c, scenario=dataclasses.replace(c.scenario, duration=duration, output_step=output_step)
    )


@pytest.fixture(scope="module")
def runs():
    c = short("two_joint_arm")
    opts = dict(elements_per_link=2, h=1e-3, cut_loads=True)
    return c, simulate(c, **opts), simulate(c, **opts, shape_points=P)


def test_shapes_change_nothing(runs):
    _, plain, shaped = runs
    assert plain.link_shapes is None
    assert shaped.link_shapes.shape == (plain.t.size, 2, P, 3)
    for f in dataclasses.fields(plain):
        a, b = getattr(plain, f.name), getattr(shaped, f.name)
        if isinstance(a, np.ndarray):
            assert a.tobytes() == b.tobytes(), f.name


def test_root_and_tip(runs):
    _, _, r = runs
    np.testing.assert_allclose(r.link_shapes[:, :, 0], r.link_root, rtol=0, atol=1e-14)
    np.testing.assert_allclose(r.link_shapes[:, :, -1], r.link_tip, rtol=0, atol=1e-14)
    # equal reference arc lengths: the chord of a gently bent link is about its length
    seg = np.linalg.norm(np.diff(r.link_shapes, axis=2), axis=-1).sum(axis=-1)
    np.testing.assert_allclose(seg, [[0.6, 0.5]] * r.t.size, rtol=1e-3)


def test_equal_to_global_solver(runs):
    from reference_models import spatial_global

    c, _, r = runs
    g = spatial_global.simulate(c, elements_per_link=2, h=1e-3, shape_points=P)
    assert g.link_shapes.shape == r.link_shapes.shape
    np.testing.assert_allclose(g.link_shapes[:, :, 0], g.link_root, rtol=0, atol=1e-14)
    np.testing.assert_allclose(g.link_shapes[:, :, -1], g.link_tip, rtol=0, atol=1e-14)
    assert np.abs(g.link_shapes - r.link_shapes).max() <= 1e-9


def test_frame_round_trip(runs, tmp_path):
    import pandas as pd

    from dttmm.spatial import SpatialResult

    _, _, r = runs
    df = r.to_frame()
    assert {"link_shape_x_1_1", "link_shape_z_2_7"} <= set(df.columns)
    df.to_parquet(tmp_path / "r.parquet")
    back = SpatialResult.from_frame(pd.read_parquet(tmp_path / "r.parquet"))
    assert back.link_shapes.tobytes() == r.link_shapes.tobytes()


def cantilever(gravity=(0.0, 0.0, 0.0)):
    beam = load_case(CASES / "cantilever_3d.toml").model.links[0].beam
    link = SpatialLink(beam, SpatialJoint(locked=True))
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.5, ())), beam


def test_cantilever_tip_force_closed_form():
    """w(x) = F x²(3L − x)/(6 EIy) for a tip force F along z (EIy governs deflection along z)."""
    c, beam = cantilever()
    F, L, k = 1e-2, beam.length, 4
    st = statics(c, elements_per_link=k, loads={"force": (0.0, 0.0, F)})
    shp = link_shapes(c, k, st.q, 21)[0, 0]
    x = np.linspace(0.0, L, 21)
    w = F * x**2 * (3 * L - x) / (6 * beam.EIy)
    assert np.abs(shp[:, 2] - w).max() <= 1e-8 * w[-1]
    # the chord shortens by the second-order ½∫w′² dx ≤ w_tip²/L: the x of the points too
    np.testing.assert_allclose(shp[:, 0], x, rtol=0, atol=w[-1] ** 2 / L)


def test_cantilever_uniform_load_fourth_order():
    """Uniform load q = ρA g along −y (EIz governs): w(x) = −q x²(6L² − 4Lx + x²)/(24 EIz);
    the Hermite element's error between the nodes falls as k⁻⁴."""
    g = 1e-3
    c, beam = cantilever(gravity=(0.0, -g, 0.0))
    L = beam.length
    x = np.linspace(0.0, L, 33)
    w = -beam.rhoA * g * x**2 * (6 * L**2 - 4 * L * x + x**2) / (24 * beam.EIz)
    err = []
    for k in (2, 4):
        st = statics(c, elements_per_link=k)
        err.append(np.abs(link_shapes(c, k, st.q, 33)[0, 0, :, 1] - w).max() / abs(w[-1]))
    order = np.log2(err[0] / err[1])
    assert 3.7 <= order <= 4.3, (err, order)
    assert err[1] <= 1e-3


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_robot_shapes_with_links_of_zero_length(robot):
    """A URDF robot has bodies that sit on their joint (links of zero length): their shape
    points are all at the root, and every link's shape runs from its root to its tip (found
    when ``shape_points`` on a robot divided 0 by 0)."""
    import dttmm

    c = dttmm.load_case(CASES / "robots" / f"{robot}.toml")
    c = dataclasses.replace(c, scenario=dataclasses.replace(c.scenario, duration=0.004, output_step=0.002))
    r = simulate(c, elements_per_link=2, h=1e-3, shape_points=3, progress=False)
    assert np.all(np.isfinite(r.link_shapes))
    np.testing.assert_allclose(r.link_shapes[:, :, 0], r.link_root, rtol=0, atol=1e-12)
    np.testing.assert_allclose(r.link_shapes[:, :, -1], r.link_tip, rtol=0, atol=1e-12)
    lengths = np.array([link.beam.length for link in c.model.links])
    assert np.any(lengths == 0.0)
    flat = r.link_shapes[:, lengths == 0.0]
    np.testing.assert_array_equal(flat, np.repeat(flat[:, :, :1], 3, axis=2))
