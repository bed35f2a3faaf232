"""One case model: a planar case is a spatial case (docs/spatial.md §1).

``SpatialCase.from_planar`` carries a planar :class:`dttmm.Case` into the spatial records
(gravity turned by the base rotation, hub and payload inertias about z, payload offsets in the
plane, the same scenario, name and provenance); ``dttmm.spatial.load_case`` reads a case file of
any kind as a :class:`SpatialCase` (a planar one embedded). Checked against hand-computed values
and, for shipped planar files, against the planar kernel's run of the same file."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm import Drive, Hub, InputError, Link, Manipulator, Payload, RigidBody, Scenario, Section
from dttmm.drives import Constant, Sine
from dttmm.spatial import SpatialCase, SpatialHub, SpatialPayload, SpatialRigidBody, load_case, simulate
from dttmm.spatial.solver import as_spatial_case

ROOT = Path(__file__).resolve().parent.parent / "experiments" / "cases"


def _short(case, h, steps):
    sc = dataclasses.replace(case.scenario, duration=h * steps, output_step=h)
    return dataclasses.replace(case, scenario=sc)


def _mixed() -> dttmm.Case:
    """Rigid link with a hub, flexible link with an offset payload; gravity; provenance."""
    links = (
        Link(RigidBody(0.4, 2.0, (0.15, 0.03), 0.03), hub=Hub(0.3, 1e-3)),
        Link(Section(0.6, 30.0, 1.2, EA=2e5), payload=Payload(0.5, 2e-3, offset=(0.05, -0.03))),
    )
    drives = (Drive("torque", Sine(4.0, 1.5)), Drive("torque", Constant(0.2)))
    return dttmm.Case(
        Manipulator(links, (1.5, -9.81)), Scenario(0.3, 0.01, drives), "mixed", {"source": "hand"}
    )


def _assert_same_motion(rs, rp, scale):
    """The spatial run (plane = world x–y) against the planar one: joint angles and link tips."""
    assert rs.status == rp.status == "ok"
    assert np.abs(rs.joint_angle - rp.joint_angle).max() <= 1e-12 * max(1.0, np.abs(rp.joint_angle).max())
    assert np.abs(rs.link_tip[..., :2] - rp.link_tip).max() <= 1e-12 * scale
    assert np.abs(rs.link_tip[..., 2]).max() <= 1e-15 * scale
    assert np.ptp(rp.joint_angle[:, 0]) > 1e-4  # the arm moves


# --- the planar file on the spatial kernel against the planar kernel ---------------------------
@pytest.mark.parametrize("name", ["three_link", "benchmarks/deluca_bang_bang"])
def test_planar_file_on_the_spatial_kernel_equals_the_planar_kernel(name):
    """Hubs at every joint and a tip payload (three_link also gravity), read by
    ``dttmm.spatial.load_case``, run by ``dttmm.spatial.simulate``: the planar kernel's motion
    of the same file (``dttmm.simulate``) to round-off."""
    path = ROOT / f"{name}.toml"
    h, steps = 1e-3, 25
    sp = _short(load_case(path), h, steps)
    pl = _short(dttmm.load_case(path), h, steps)
    assert isinstance(sp, SpatialCase) and isinstance(pl, dttmm.Case)
    assert any(lk.hub is not None for lk in sp.model.links) and sp.model.links[-1].payload is not None
    opts = dict(elements_per_link=3, h=h, integrator="newmark", tol=1e-12)
    rs = simulate(sp, **opts)
    rp = dttmm.simulate(pl, **opts, cut_loads=False, progress=False)
    assert rs.meta["method"] == "dttmm-spatial" and rp.meta["method"] != "dttmm-spatial"
    _assert_same_motion(rs, rp, sum(lk.beam.length for lk in pl.model.links))


def test_python_built_planar_case_with_a_rigid_link_on_the_spatial_kernel():
    """A planar Case built in Python (a rigid link, an offset payload, gravity along x and y)
    made spatial by ``from_planar``: the planar kernel's motion to round-off."""
    case = _short(_mixed(), 1e-3, 25)
    opts = dict(elements_per_link=2, h=1e-3, integrator="newmark", tol=1e-12)
    rs = simulate(SpatialCase.from_planar(case), **opts)
    rp = dttmm.simulate(case, **opts, cut_loads=False, progress=False)
    _assert_same_motion(rs, rp, 1.0)


# --- the conversion, field by field --------------------------------------------------------------
@pytest.mark.parametrize(
    ("rpy", "gravity"),
    [
        ((0.0, 0.0, 0.0), (1.5, -9.81, 0.0)),
        ((math.pi / 2, 0.0, 0.0), (1.5, 0.0, -9.81)),  # roll 90°: the plane's y is the world's z
        ((0.0, 0.0, math.pi / 2), (9.81, 1.5, 0.0)),  # yaw 90°: (g_x, g_y) → (−g_y, g_x)
    ],
)
def test_from_planar_carries_every_field(rpy, gravity):
    pc = _mixed()
    sc = SpatialCase.from_planar(pc, base_rpy=rpy, base_xyz=(0.1, 0.2, 0.3))
    m = sc.model
    np.testing.assert_allclose(m.gravity, gravity, rtol=0, atol=1e-15)
    assert m.base_rpy == rpy and m.base_xyz == (0.1, 0.2, 0.3)
    assert sc.scenario is pc.scenario and sc.name == "mixed" and sc.provenance == {"source": "hand"}
    assert [lk.joint.axis for lk in m.links] == [(0.0, 0.0, 1.0)] * 2
    rigid, flex = m.links
    assert rigid.beam == SpatialRigidBody(0.4, 2.0, (0.15, 0.03, 0.0), (0.03, 0.03, 0.03))
    assert rigid.hub == SpatialHub(0.3, ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1e-3)))
    assert flex.beam.EIz == 30.0 and flex.beam.rhoA == 1.2 and flex.beam.EA == 2e5
    assert flex.payload == SpatialPayload(0.5, (0.05, -0.03, 0.0), (0.0, 0.0, 2e-3))
    assert flex.payload.inertia[2][2] == 2e-3 and flex.payload.inertia[0][0] == 0.0


def test_from_planar_refuses_anything_but_a_planar_case():
    sc = SpatialCase.from_planar(_mixed())
    for bad, name in ((sc, "SpatialCase"), (_mixed().model, "Manipulator"), (None, "NoneType")):
        with pytest.raises(InputError) as exc:
            SpatialCase.from_planar(bad)
        assert exc.value.field == "case" and exc.value.value == name and "\n" not in str(exc.value)


def test_as_spatial_case_takes_a_planar_case():
    """``as_spatial_case`` (what dttmm.spatial's statics, linearisation and forward dynamics
    call) embeds a planar case; other types: one line naming the type. ``dttmm.spatial.simulate``
    still runs a planar Case on the planar kernel (the fast path)."""
    pc = _mixed()
    assert as_spatial_case(pc) == SpatialCase.from_planar(pc)
    sc = as_spatial_case(pc)
    assert as_spatial_case(sc) is sc
    assert as_spatial_case((sc.model, sc.scenario)).model == sc.model
    with pytest.raises(InputError, match=r"^case = 'str': must be .*dttmm\.Case") as exc:
        as_spatial_case("three_link.toml")
    assert "\n" not in str(exc.value)
    short = _short(pc, 1e-3, 3)
    r = dttmm.spatial.simulate(short, elements_per_link=2, h=1e-3)
    assert type(r) is dttmm.Result
    a = dttmm.spatial.statics(pc, elements_per_link=2)
    b = dttmm.statics(pc, elements_per_link=2)
    assert a.q.tobytes() == b.q.tobytes()


# --- load_case on every kind ---------------------------------------------------------------------
def test_load_case_reads_a_planar_file_embedded():
    for path in (ROOT / "three_link.toml", ROOT / "control" / "closed_loop_three_link.toml"):
        sp = load_case(path)
        assert isinstance(sp, SpatialCase) and sp.name == path.stem
        assert sp == SpatialCase.from_planar(dttmm.load_case(path))


def test_load_case_reads_a_spatial_file_as_before(tmp_path):
    path = ROOT / "spatial" / "three_joint_arm.toml"
    sp = load_case(path)
    assert sp == dttmm.load_case(path) and sp.model.gravity == (0.0, 0.0, -9.81)
    # the kind marker is optional here: a spatial file without it is still a spatial file
    text = path.read_text().replace('kind = "spatial"\n', "")
    (tmp_path / "unmarked.toml").write_text(text)
    assert load_case(tmp_path / "unmarked.toml").model == sp.model


def test_load_case_reads_a_urdf_case_document(tmp_path):
    inertial = (
        '<inertial><origin xyz="0.1 0 0" rpy="0 0 0"/><mass value="1.0"/>'
        '<inertia ixx="1e-3" ixy="0" ixz="0" iyy="2e-3" iyz="0" izz="2e-3"/></inertial>'
    )
    (tmp_path / "arm.urdf").write_text(
        f'<robot name="t"><link name="base"/><link name="a">{inertial}</link>'
        '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/>'
        '<origin xyz="0 0 0.2" rpy="0 0 0"/><axis xyz="0 1 0"/>'
        '<limit lower="-3" upper="3" effort="10" velocity="1"/></joint></robot>'
    )
    (tmp_path / "arm.toml").write_text(
        'kind = "spatial"\n[model]\nurdf = "arm.urdf"\n'
        "[scenario]\nduration = 0.1\noutput_step = 0.01\n"
        '[[scenario.drives]]\nkind = "torque"\nlaw = "constant"\nvalue = 0.0\n'
    )
    sp = load_case(tmp_path / "arm.toml")
    assert isinstance(sp, SpatialCase) and sp == dttmm.load_case(tmp_path / "arm.toml")
    assert sp.model.links[0].joint.axis == (0.0, 1.0, 0.0)


def test_load_case_errors_name_the_field(tmp_path):
    planar = (ROOT / "three_link.toml").read_text()
    (tmp_path / "bad.toml").write_text(planar.replace("EI = 2.3333333333333335", "EI = -1.0", 1))
    with pytest.raises(InputError) as exc:
        load_case(tmp_path / "bad.toml")
    assert exc.value.field == "model.links[0].EI" and exc.value.value == -1.0
    assert "\n" not in str(exc.value)
    (tmp_path / "kind.toml").write_text('kind = "planar"\n' + planar)
    with pytest.raises(InputError, match=r"^kind = 'planar'"):
        load_case(tmp_path / "kind.toml")
    with pytest.raises(InputError, match="does not exist"):
        load_case(tmp_path / "missing.toml")


def test_spatial_linearisation_and_forward_dynamics_take_a_planar_case():
    """``dttmm.spatial.linear.linearize`` of a planar Case (embedded): its in-plane mass and
    stiffness blocks are the planar linearisation's; ``dttmm.spatial.accelerations`` of a planar
    Case is that of its embedding (as ``dttmm.accelerations(..., kernel="spatial")``)."""
    from dttmm.spatial import linear

    case = dttmm.load_case(ROOT / "benchmarks" / "deluca_link2_clamped.toml")
    lin_s = linear.linearize(case, 2)
    lin_p = dttmm.linearize(case, 2)
    ip = np.array(
        [i for i, s in enumerate(lin_s.coordinates) if s.endswith(("angle", ", u", ", v", ", phiz"))]
    )
    assert ip.size == lin_p.n_free < lin_s.n_free
    assert np.abs(lin_s.M[np.ix_(ip, ip)] - lin_p.M).max() <= 1e-9 * np.abs(lin_p.M).max()
    assert np.abs(lin_s.K[np.ix_(ip, ip)] - lin_p.K).max() <= 1e-8 * np.abs(lin_p.K).max()
    n = lin_s.n_free + sum(not d.closed_loop and d.kind == "motion" for d in case.scenario.drives)
    q = np.linspace(0.0, 0.01, n)
    a = dttmm.spatial.accelerations(case, 2, q, np.zeros(n))
    assert a.tobytes() == dttmm.accelerations(case, 2, q, np.zeros(n), kernel="spatial").tobytes()
