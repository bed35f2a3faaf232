"""Link shapes from the spatial peers (``shape_points``): Pinocchio (straight rigid links),
MuJoCo (the polyline of its rigid pieces), Exudyn's 3-D geometrically exact beam and ANCF cable
(cubic Hermite between the beam nodes). Each: shape (nt, n, p, 3), point 1 the link root and
point p its tip, no other output changed (bitwise), and the shape close to DT-TMM's."""

from __future__ import annotations

import dataclasses
import importlib
from pathlib import Path

import numpy as np
import pytest

from dttmm.spatial import load_case, simulate

CASE = Path(__file__).resolve().parent.parent / "experiments" / "cases" / "spatial" / "two_joint_arm.toml"
P = 5

#: (module, engine, tolerance on root/tip (m), tolerance against DT-TMM's shapes (m)); the rigid
#: arm differs from the flexible one by the bending (2.5e-3 m measured at t = 0.02 s), the
#: flexible peers by their discretisations at k = 2 (≤ 1e-3 m)
PEERS = [
    ("pinocchio_spatial", "pinocchio", 1e-12, 5e-3),
    ("mujoco_spatial", "mujoco", 1e-12, 1e-3),
    ("exudyn_beam3d", "exudyn", 1e-12, 1e-3),
    ("exudyn_ancf3d", "exudyn", 1e-8, 1e-3),
]


@pytest.fixture(scope="module")
def case():
    c = load_case(CASE)
    return dataclasses.replace(c, scenario=dataclasses.replace(c.scenario, duration=0.02, output_step=0.01))


@pytest.mark.parametrize("module, engine, tol_ends, tol_dttmm", PEERS, ids=[p[0] for p in PEERS])
def test_peer_shapes(case, module, engine, tol_ends, tol_dttmm):
    pytest.importorskip(engine)
    mod = importlib.import_module(f"reference_models.{module}")
    opts = dict(elements_per_link=2, h=1e-3)
    plain = mod.simulate(case, **opts)
    r = mod.simulate(case, **opts, shape_points=P)
    assert plain.link_shapes is None
    assert r.link_shapes.shape == (r.t.size, 2, P, 3)
    for f in dataclasses.fields(plain):
        a = getattr(plain, f.name)
        if isinstance(a, np.ndarray):
            assert a.tobytes() == getattr(r, f.name).tobytes(), f.name
    np.testing.assert_allclose(r.link_shapes[:, :, 0], r.link_root, rtol=0, atol=tol_ends)
    np.testing.assert_allclose(r.link_shapes[:, :, -1], r.link_tip, rtol=0, atol=tol_ends)
    ref = simulate(case, **opts, shape_points=P)
    assert np.abs(r.link_shapes - ref.link_shapes).max() <= tol_dttmm
