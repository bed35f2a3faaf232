"""The root bending moment of a spatial arm in the report's load comparison (``moment1``).

On a spatial arm ``metrics.load_series`` takes the moment of the cut load at link 1's root (cut 0:
the load the base, joint 1 and link 1's hub exert on link 1's beam, world components, about the
root point) and compares the magnitude of its bending part, the components along link 1's frame y
and z axes (torsion left out). Checked against an independent computation of the same load (the
spatial global solver's Newton–Euler of the outboard bodies), against the gravity moment of the
outboard masses computed here by hand for an arm held at rest, and for the peers without cut loads
(NaN, with the reason in the report's sentence).
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import dttmm
from dttmm import Constant, Drive
from dttmm.spatial import SpatialPayload
from dttmm.spatial import simulate as spatial_simulate
from experiments import methods, metrics
from experiments.studies import paper
from reports import interpret

ARM = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "three_joint_arm.toml"


def _arm(duration=0.1, output_step=2e-3):
    c = dttmm.load_case(ARM)
    return dc.replace(c, scenario=dc.replace(c.scenario, duration=duration, output_step=output_step))


@pytest.fixture(scope="module")
def short_runs():
    """three_joint_arm, 0.1 s, k = 2, h = 1e-3: the spatial DT-TMM and the spatial global solver
    (the same discretisation; its cut loads by Newton–Euler of the outboard bodies), both with cut
    loads, and the DT-TMM without them."""
    c = _arm()
    a = spatial_simulate(c, elements_per_link=2, h=1e-3, cut_loads=True)
    b = methods.run("global", c, 2, 1e-3, cut_loads=True)
    plain = spatial_simulate(c, elements_per_link=2, h=1e-3)
    return c, a, b, plain


def test_spatial_root_moment_dttmm_equals_the_global_solver(short_runs):
    c, a, b, _ = short_runs
    assert metrics.has_spatial_cut_loads(a) and metrics.has_spatial_cut_loads(b)
    ma, mb = metrics.load_series(a, c)["moment1"], metrics.load_series(b, c)["moment1"]
    assert ma.shape == a.t.shape and ma.max() > 10.0  # the pulses bend link 1 by up to ~15 N·m
    assert np.abs(ma - mb).max() < 1e-11 * ma.max()  # measured 4.5e-13 N·m of 14.8
    # the report's path: the moment is compared (against the global run as a reference here)
    _, row = paper._load_series(a, b, None, c, "three_joint_arm", "dttmm")
    assert row["moment1_note"] == "" and row["moment1_linf"] < 1e-11 * ma.max()
    # torsion is left out: the moment's full magnitude differs from the bending part
    R = a.link_rotation[:, 0]
    full = np.linalg.norm(a.cut_loads[:, 0, 3:], axis=1)
    torsion = np.einsum("ti,ti->t", R[:, :, 0], a.cut_loads[:, 0, 3:])
    assert np.abs(torsion).max() > 0.05 and np.allclose(ma**2 + torsion**2, full**2, rtol=1e-12, atol=1e-12)


def _rz(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _ry(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rx(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


ANGLES = (0.7, 0.4, -0.5)  # yaw, pitch, pitch: joints held here
BASE_RPY = (0.4, 0.3, 0.0)  # a tilted base: gravity has components along both bending axes
PAYLOAD = SpatialPayload(mass=1.0, offset=(0.05, 0.3, 0.02), inertia=(1e-3, 2e-3, 2e-3))  # off the plane


def _held_arm():
    """three_joint_arm with stiff, damped links (EI, GJ, EA × 1e4, μ = 2e-3 s), a tilted base, a
    payload off the links' plane and every joint held at ANGLES by a motion drive."""
    c = _arm(0.4, 0.01)
    links = tuple(
        dc.replace(
            link,
            beam=dc.replace(
                link.beam,
                EIy=link.beam.EIy * 1e4,
                EIz=link.beam.EIz * 1e4,
                GJ=link.beam.GJ * 1e4,
                EA=link.beam.EA * 1e4,
                damping=2e-3,
            ),
            payload=PAYLOAD if link.payload is not None else None,
        )
        for link in c.model.links
    )
    model = dc.replace(c.model, links=links, base_rpy=BASE_RPY)
    drives = tuple(Drive("motion", Constant(a)) for a in ANGLES)
    return dc.replace(c, model=model, scenario=dc.replace(c.scenario, drives=drives))


def _gravity_moment_by_hand():
    """(bending magnitude, torsion) of the moment that holds the outboard masses of link 1 against
    gravity, about link 1's root, from the case file's masses and the rigid arm's geometry (every
    link straight: the links are 1e4 times stiffer than the file's)."""
    g = np.array([0.0, 0.0, -9.81])
    L, rhoA, hub = (0.5, 0.5, 0.4), 1.0, 0.5  # three_joint_arm.toml
    R0 = _rz(BASE_RPY[2]) @ _ry(BASE_RPY[1]) @ _rx(BASE_RPY[0])  # URDF rpy
    p0 = np.array([0.0, 0.0, 0.3])
    R1 = R0 @ _rz(ANGLES[0])
    p2 = p0 + R1 @ [L[0], 0, 0]
    R2 = R1 @ _ry(ANGLES[1])
    p3 = p2 + R2 @ [L[1], 0, 0]
    R3 = R2 @ _ry(0.3) @ _ry(ANGLES[2])  # joint 3's origin is pitched by 0.3
    tip = p3 + R3 @ [L[2], 0, 0]
    masses = [
        (rhoA * L[0], p0 + R1 @ [L[0] / 2, 0, 0]),  # link 1's beam; its hub is at the root point
        (hub, p2),
        (rhoA * L[1], p2 + R2 @ [L[1] / 2, 0, 0]),
        (hub, p3),
        (rhoA * L[2], p3 + R3 @ [L[2] / 2, 0, 0]),
        (PAYLOAD.mass, tip + R3 @ np.array(PAYLOAD.offset)),
    ]
    M = -sum(np.cross(r - p0, m * g) for m, r in masses)  # at rest: what the root must supply
    local = R1.T @ M
    return float(np.hypot(local[1], local[2])), float(local[0]), R1


def test_spatial_root_moment_at_rest_is_the_gravity_moment():
    c = _held_arm()
    res = spatial_simulate(c, elements_per_link=2, h=1e-3, cut_loads=True, integrator="generalized-alpha")
    bending, torsion, R1 = _gravity_moment_by_hand()
    assert np.allclose(res.link_rotation[-1, 0], R1, atol=1e-12)  # joint 1 held at its angle
    m = metrics.load_series(res, c)["moment1"]
    # the transient has died away: the last samples agree, and equal the hand-computed moment
    assert abs(m[-1] - m[-5]) < 1e-9 * m[-1]
    tol = 1e-5  # the links' residual sag: measured 1.2e-6 of 30.34 N·m
    assert abs(m[-1] - bending) < tol * bending, (m[-1], bending)
    # the check can tell: the torsion (about link 1's axis) and the tilt (moments about both
    # bending axes) are large against the tolerance
    assert abs(torsion) > 0.1 * bending and np.hypot(bending, torsion) - bending > 100 * tol * bending
    local = R1.T @ res.cut_loads[-1, 0, 3:]
    assert min(abs(local[1]), abs(local[2])) > 0.2 * bending
    assert abs(local[0] - torsion) < tol * bending


@pytest.fixture(scope="module")
def peers(short_runs):
    """The same arm by the peers without the cut table: Exudyn's 3-D beam (with its section
    loads, which are not the root cut) and the rigid Pinocchio arm."""
    c = short_runs[0]
    pytest.importorskip("exudyn")
    pytest.importorskip("pinocchio")
    ex = methods.run("exudyn-beam", c, 2, 1e-3, section_loads=True)
    pin = methods.run("pinocchio-rigid", c, 0, 1e-3)
    return {"exudyn-beam": ex, "pinocchio-rigid": pin}


def _table(c, runs, ref):
    rows = []
    for name, res in runs.items():
        _, row = paper._load_series(res, ref, None, c, "three_joint_arm", name)
        rows.append({"case": "three_joint_arm", "method": name, **row, "energy_reference": "the reference"})
    return pd.DataFrame(rows)


def test_peers_without_cut_loads_give_nan_and_the_reason(short_runs, peers):
    c, a, b, plain = short_runs
    ex = peers["exudyn-beam"]
    assert ex.cut_loads is not None and not metrics.has_spatial_cut_loads(ex)  # midpoint sections only
    for res in peers.values():
        assert "moment1" not in metrics.load_series(res, c)
    table = _table(c, {"dttmm": a, **peers}, b)
    assert np.isfinite(table.moment1_l2[0]) and table.moment1_l2[1:].isna().all()
    text = " ".join(interpret.loads(table, "three_joint_arm"))
    assert "torsion about the link's axis left out" in text
    assert f"Exudyn GE beam ({methods.get('exudyn-beam').spatial_loads_note})" in text
    assert "Pinocchio rigid (its spatial engine records no cut loads)" in text
    assert "DT-TMM (Newmark) (" not in text  # compared, so not listed as left out
    # a reference without cut loads: the moment is compared for no method, and the text says why
    table = _table(c, {"dttmm": a, **peers}, plain)
    assert "moment1_l2" not in table or table.moment1_l2.isna().all()
    text = " ".join(interpret.loads(table, "three_joint_arm"))
    assert "not compared for DT-TMM (Newmark) (the reference was run without cut loads)" in text
    assert "Pinocchio rigid (its spatial engine records no cut loads)" in text
    only = table[table.method == "dttmm"]
    text = " ".join(interpret.loads(only, "three_joint_arm"))
    assert "it is compared for no method here: the reference was run without cut loads" in text


def test_spatial_runs_ask_for_cut_loads_and_planar_ones_stay_as_they_were(short_runs):
    c = short_runs[0]
    planar = dttmm.load_case(Path(ARM).parents[1] / "three_link.toml")
    asked = [m for m in methods.names() if paper._options(methods.get(m), c)]
    assert {"dttmm", "dttmm-2nd", "dttmm-rk4", "global", "global-2nd"} <= set(asked)
    assert not {"exudyn-beam", "mujoco-chain", "pinocchio-rigid"} & set(asked)
    assert all(paper._options(methods.get(m), planar) == () for m in methods.names())  # same task keys
    # planar: the moment still comes from the hub balance for every engine (cut loads dropped)
    p = dc.replace(planar, scenario=dc.replace(planar.scenario, duration=0.1))
    res = dttmm.simulate(p, elements_per_link=2, h=1e-3)
    assert res.cut_loads is not None and metrics.comparable_loads(res).cut_loads is None
    s = paper._load_series(res, None, None, p, "three_link", "dttmm")[0]
    hub = metrics.load_series(metrics.without_cut_loads(res), p)["moment1"]
    assert np.array_equal(s.moment1.to_numpy(), hub[:: max(1, len(hub) // paper.MAX_POINTS)])
    ref = dttmm.simulate(p, elements_per_link=2, h=5e-4)
    _, row = paper._load_series(res, ref, None, p, "three_link", "dttmm")
    old = metrics.load_errors(metrics.without_cut_loads(res), metrics.without_cut_loads(ref), p)
    assert "moment1_note" not in row and row["moment1_l2"] == old["moment1_l2"] > 0
