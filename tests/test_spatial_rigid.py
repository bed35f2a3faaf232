"""Rigid links (``SpatialRigidBody`` in place of a link's beam; docs/spatial.md §1, §5 "Rigid
links"): the model and case-file form, the spatial DT-TMM against the spatial global solver on a
mixed rigid-flexible arm, the all-rigid arm against Pinocchio's ABA, and a stiffened flexible
link against its rigid equivalent."""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

import dttmm
import dttmm.spatial as sp
from dttmm import Constant, Drive
from dttmm.spatial import SpatialCase, SpatialLink, SpatialRigidBody, SpatialSection
from dttmm.spatial.build import build_model
from dttmm.spatial.case import case_from_dict, case_to_dict
from reference_models import spatial_global as sg

RIGID = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial" / "rigid"
MIXED = RIGID / "mixed_arm.toml"
ALL_RIGID = RIGID / "rigid_arm.toml"


def _short(case, duration, output_step=None):
    sc = dataclasses.replace(case.scenario, duration=duration)
    if output_step is not None:
        sc = dataclasses.replace(sc, output_step=output_step)
    return dataclasses.replace(case, scenario=sc)


# ------------------------------------------------------------------ model and case file -------


def test_case_files_load_and_round_trip():
    """The shipped rigid cases load; a rigid link has no elastic coordinates (the mixed arm at
    k elements per link: 3 joint angles + 6k of its one extensible flexible link)."""
    for path in (MIXED, ALL_RIGID):
        case = sp.load_case(path)
        assert case_from_dict(case_to_dict(case)) == case
    mixed = sp.load_case(MIXED)
    assert mixed.model.rigid_links == (0, 2)
    b = mixed.model.links[0].beam
    assert isinstance(b, SpatialRigidBody) and b.length == 0.15 and b.mass == 2.0
    assert b.com == (0.05, 0.01, 0.08) and b.inertia[0][2] == -2e-3
    for k in (1, 3):
        assert build_model(mixed.model, k).ndof == 3 + 6 * k
        assert len(sg.coordinate_names(mixed, k)) == 3 + 6 * k
    assert build_model(sp.load_case(ALL_RIGID).model, 4).ndof == 3


def _doc(**link):
    base = {"length": 0.3, "rigid": {"mass": 1.0, "com": [0.1, 0.0, 0.0], "inertia": [1e-3, 2e-3, 2e-3]}}
    base.update(link)
    return {
        "model": {"links": [base]},
        "scenario": {
            "duration": 0.1,
            "output_step": 0.01,
            "drives": [{"kind": "torque", "law": "constant", "value": 0.0}],
        },
    }


@pytest.mark.parametrize(
    ("link", "field", "reason"),
    [
        ({"GJ": 1.0}, "model.links[0].GJ", "beam key"),
        ({"rigid": {"mass": -1.0}}, "model.links[0].rigid.mass", "must be"),
        (
            {"rigid": {"mass": 1.0, "inertia": [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]}},
            "rigid.inertia",
            "symmetric",
        ),
        ({"rigid": {"mass": 1.0, "inertia": [1e-3, -1e-3, 1e-3]}}, "rigid.inertia", "semi-definite"),
        ({"rigid": {"mass": 1.0, "com": [0.0, 1.0]}}, "rigid.com", "3"),
        ({"rigid": {"mass": 1.0, "size": 2.0}}, "size", "unknown key"),
        ({"length": -0.1}, "model.links[0].length", "must be"),
    ],
)
def test_case_file_refusals(link, field, reason):
    with pytest.raises(dttmm.InputError, match=reason) as err:
        case_from_dict(_doc(**link))
    assert field in str(err.value)


def test_flexible_link_still_needs_its_beam():
    doc = _doc()
    del doc["model"]["links"][0]["rigid"]
    doc["model"]["links"][0].update(EIy=1.0, EIz=1.0, rhoA=1.0, rhoJ=1e-3)
    with pytest.raises(dttmm.InputError, match=r"model\.links\[0\]\.GJ.*required"):
        case_from_dict(doc)


def test_python_refusals():
    with pytest.raises(dttmm.InputError, match=r"rigid\.mass"):
        SpatialRigidBody(0.1, -1.0)
    with pytest.raises(dttmm.InputError, match=r"rigid\.inertia.*symmetric"):
        SpatialRigidBody(0.1, 1.0, (0, 0, 0), ((1, 0, 0), (0.5, 1, 0), (0, 0, 1)))
    with pytest.raises(dttmm.InputError, match=r"rigid\.length"):
        SpatialRigidBody(-0.1, 1.0)
    with pytest.raises(dttmm.InputError, match=r"link\.beam.*SpatialRigidBody"):
        SpatialLink(beam=1.0)


# ------------------------------------------------------------------ DT-TMM = global solver ------


@pytest.mark.parametrize("k", [1, 2])
def test_accelerations_and_cut_loads_equal_global_solver(k):
    """q̈ and the cut loads of the mixed arm (rigid yaw link with an offset centre of mass and a
    full inertia, flexible rolled pitch link, rigid tilted link with a tip length and a
    payload) at random states: the DT-TMM (compiled and uncompiled) = the global solver."""
    case = sp.load_case(MIXED)
    rng = np.random.default_rng(5)
    md = build_model(case.model, k)
    scale = np.full(md.ndof, 0.05)  # elastic coordinates: centimetres, hundredths of a radian
    scale[md.ia] = 1.0  # joint angles: radians
    for _ in range(3):
        q, qd = scale * rng.normal(size=md.ndof), 3 * scale * rng.normal(size=md.ndof)
        ref = sg.accelerations(case, k, q, qd, 0.1)
        cuts = sg.cut_loads(case, k, q, qd, 0.1)
        for engine in ("python", "numba"):
            qdd, _, loads = sp.accelerations(case, k, q, qd, 0.1, engine=engine, loads=True)
            # measured ≤ 3.7e-13 and 1.5e-13 (the stiff axial coordinates' q̈ set the scale)
            assert np.max(np.abs(qdd - ref)) < 1e-11 * np.max(np.abs(ref))
            assert np.max(np.abs(loads - cuts)) < 1e-11 * np.max(np.abs(cuts))


def test_run_equals_global_solver():
    """Newmark, k = 2, h = 1e-3, 0.05 s: link tips, shapes, angles, energy and cut loads of the
    DT-TMM equal the global solver's; a rigid link's tip deflections and twist are zero and its
    shape is the straight segment from root to tip."""
    case = _short(sp.load_case(MIXED), 0.05, 0.005)
    opts = dict(elements_per_link=2, h=1e-3, cut_loads=True, shape_points=5)
    res = sp.simulate(case, **opts)
    ref = sg.simulate(case, **opts)
    assert res.success and ref.success
    assert np.max(np.abs(res.link_tip - ref.link_tip)) < 1e-12
    assert np.max(np.abs(res.link_shapes - ref.link_shapes)) < 1e-12
    assert np.max(np.abs(res.joint_angle - ref.joint_angle)) < 1e-12
    assert np.max(np.abs(res.energy - ref.energy)) < 1e-12 * np.max(np.abs(ref.energy))
    assert np.max(np.abs(res.cut_loads - ref.cut_loads)) < 1e-11 * np.max(np.abs(ref.cut_loads))
    for i in (0, 2):
        assert np.max(np.abs(res.tip_deflection[:, i])) < 1e-15
        assert np.max(np.abs(res.twist[:, i])) < 1e-15
        root, tip, shape = res.link_root[:, i], res.link_tip[:, i], res.link_shapes[:, i]
        L = case.model.links[i].beam.length
        assert np.max(np.abs(np.linalg.norm(tip - root, axis=-1) - L)) < 1e-15
        line = root[:, None] + np.linspace(0, 1, 5)[None, :, None] * (tip - root)[:, None]
        assert np.max(np.abs(shape - line)) < 1e-15
    assert np.max(np.abs(res.tip_deflection[:, 1])) > 1e-4  # the flexible link bends


def test_free_rigid_arm_conserves_energy():
    """The all-rigid arm with no torques and initial rates, RK4, h = 1e-3, 0.5 s: the kernel's
    energy (bodies, payload, gravity) is conserved to the integrator's error."""
    case = sp.load_case(ALL_RIGID)
    drives = tuple(Drive("torque", Constant(0.0), initial_rate=w) for w in (1.5, -2.0, 3.0))
    case = _short(dataclasses.replace(case, scenario=dataclasses.replace(case.scenario, drives=drives)), 0.5)
    res = sp.simulate(case, elements_per_link=1, h=1e-3, integrator="rk4")
    assert np.max(np.abs(res.energy - res.energy[0])) < 1e-8 * np.max(np.abs(res.energy))


# ------------------------------------------------------------------ Pinocchio ------------------


def _pinocchio_reference(case):
    """Joint angles (nt, 3) and rates of Pinocchio's ABA under the case's torques, by SciPy's
    DOP853 at rtol 1e-13, atol 1e-14, restarted at t = 0.5 (where a drive's sine ends)."""
    pin = pytest.importorskip("pinocchio")
    from scipy.integrate import solve_ivp

    from reference_models import pinocchio_spatial as ps

    model = ps.build_model(case.model)
    data = model.createData()
    drives = case.scenario.drives
    n = len(drives)

    def f(t, y):
        tau = np.array([d.torque(t, False) for d in drives])
        return np.concatenate([y[n:], pin.aba(model, data, y[:n], y[n:], tau)])

    t_out = case.scenario.output_times
    y = np.zeros((t_out.size, 2 * n))
    y0 = np.zeros(2 * n)
    for a, b in ((0.0, 0.5), (0.5, case.scenario.duration)):
        sel = (t_out >= a) & (t_out <= b)
        sol = solve_ivp(f, (a, b), y0, method="DOP853", rtol=1e-13, atol=1e-14, t_eval=t_out[sel])
        y[sel] = sol.y.T
        y0 = sol.y[:, -1]
    return y[:, :n], y[:, n:], model, data


def test_rigid_arm_forward_dynamics_is_aba():
    """At random states and torques the DT-TMM's q̈ of the all-rigid arm is Pinocchio's ABA (the
    model built by reference_models.pinocchio_spatial from the same case), and the global
    solver's mass matrix is Pinocchio's CRBA."""
    pin = pytest.importorskip("pinocchio")
    from reference_models import pinocchio_spatial as ps

    case = sp.load_case(ALL_RIGID)
    model = ps.build_model(case.model)
    data = model.createData()
    rng = np.random.default_rng(2)
    t = 0.7
    tau0 = np.array([d.torque(t, False) for d in case.scenario.drives])
    for _ in range(4):
        q, v, tau = 2 * rng.normal(size=3), rng.normal(size=3), 5 * rng.normal(size=3)
        ref = pin.aba(model, data, q, v, tau)
        for engine in ("python", "numba"):
            qdd = sp.accelerations(case, 1, q, v, t, forces=tau - tau0, engine=engine)
            assert np.max(np.abs(qdd - ref)) < 1e-13 * np.max(np.abs(ref))
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.max(np.abs(sg.mass_matrix(case, 1, q) - M)) < 1e-14


def test_rigid_arm_trajectory_against_pinocchio():
    """The all-rigid arm (tilted axes, offset origins and centres of mass, full inertias, a
    payload, gravity, a rotated base) under its torques over 1 s: the DT-TMM by RK4 at
    h = 2.5e-4 against Pinocchio's ABA integrated by DOP853 (rtol 1e-13): joint angles within
    1e-8 rad (measured 1.05e-9 rad, the RK4 error: 1.7e-8 at h = 5e-4, 6.2e-11 at h = 1.25e-4;
    the joints turn by up to 11 rad)."""
    case = sp.load_case(ALL_RIGID)
    qa, va, _, _ = _pinocchio_reference(case)
    res = sp.simulate(case, elements_per_link=1, h=2.5e-4, integrator="rk4")
    assert res.success
    assert np.max(np.abs(qa)) > 5.0
    assert np.max(np.abs(res.joint_angle - qa)) < 1e-8
    assert np.max(np.abs(res.joint_rate - va)) < 1e-7


# ------------------------------------------------------------------ the stiff limit -----------


def _rigid_equivalent(link: SpatialLink) -> SpatialLink:
    """The rigid link with the mass distribution of the undeformed beam: mass ρA L at (L/2, 0, 0),
    inertia about it diag(0, mL²/12, mL²/12) + L Rx(roll) diag(ρJ, ρIy, ρIz) Rx(roll)ᵀ."""
    b = link.beam
    L, m = b.length, b.rhoA * b.length
    c, s = math.cos(b.roll), math.sin(b.roll)
    Rr = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    J = np.diag([0.0, m * L * L / 12, m * L * L / 12]) + L * Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
    return dataclasses.replace(link, beam=SpatialRigidBody(L, m, (L / 2, 0.0, 0.0), J))


def _stiffened(link: SpatialLink, factor: float) -> SpatialLink:
    b = link.beam
    beam = dataclasses.replace(b, EA=b.EA * factor, GJ=b.GJ * factor, EIy=b.EIy * factor, EIz=b.EIz * factor)
    return dataclasses.replace(link, beam=beam)


def _with_link(case, i, link) -> SpatialCase:
    links = list(case.model.links)
    links[i] = link
    return dataclasses.replace(case, model=dataclasses.replace(case.model, links=tuple(links)))


def test_stiff_flexible_link_approaches_the_rigid_link():
    """The mixed arm's flexible link with every stiffness × 1e4 and × 1e5 against the same arm
    with that link rigid (its undeformed beam's mass, centre of mass and inertia), both by the
    DT-TMM, Newmark, k = 2, h = 1e-3, 0.5 s: the joint angles differ by 2.6e-6 and 2.9e-7 rad,
    falling as 1/stiffness (× 1e3: 2.9e-5, × 1e6: 2.9e-8; unstiffened 2.9e-2)."""
    case = _short(sp.load_case(MIXED), 0.5, 0.01)
    flex = case.model.links[1]
    assert isinstance(flex.beam, SpatialSection)
    rigid = sp.simulate(_with_link(case, 1, _rigid_equivalent(flex)), elements_per_link=2, h=1e-3)
    errs = []
    for factor in (1e4, 1e5):
        res = sp.simulate(_with_link(case, 1, _stiffened(flex, factor)), elements_per_link=2, h=1e-3)
        assert res.success
        errs.append(np.max(np.abs(res.joint_angle - rigid.joint_angle)))
    assert 7 < errs[0] / errs[1] < 13, errs


def test_statics_with_rigid_links():
    """``dttmm.spatial.statics`` of the mixed arm held at joint angles: the global solver's
    elastic and gravity forces balance at its q, and the root force carries the weight of
    everything outboard of link 1's root cut (all but link 1's hub), the rigid bodies' included."""
    case = sp.load_case(MIXED)
    res = sp.statics(case, elements_per_link=2, angles=[0.3, 0.4, -0.2], engine="python")
    names = sg.coordinate_names(case, 2)
    e = [i for i, n in enumerate(names) if not n.startswith("alpha")]
    f_el = sg.elastic_forces(case, 2, res.q)[1]
    resid = sg.generalized_forces(case, 2, res.q, np.zeros_like(res.q)) - f_el
    assert np.max(np.abs(resid[e])) < 1e-10 * np.max(np.abs(f_el[e]))
    links = case.model.links
    mass = sum(
        (lk.beam.mass if lk.rigid else lk.beam.rhoA * lk.beam.length) + lk.hub_mass + lk.payload_mass
        for lk in links
    )
    weight = (mass - links[0].hub_mass) * 9.81
    assert abs(res.root_loads[2] - weight) < 1e-12 * weight


def test_rigid_inverse_dynamics_is_rnea():
    """The rigid recursive Newton–Euler of ``dttmm.spatial.inverse_dynamics`` (the computed-torque
    feedforward) on the all-rigid and the mixed arm = Pinocchio's RNEA."""
    pin = pytest.importorskip("pinocchio")
    from dttmm.spatial.inverse_dynamics import rigid_inverse_dynamics
    from reference_models import pinocchio_spatial as ps

    rng = np.random.default_rng(7)
    for path in (ALL_RIGID, MIXED):
        m = sp.load_case(path).model
        model = ps.build_model(m)
        data = model.createData()
        q, v, a = rng.normal(size=(3, 3))
        ref = pin.rnea(model, data, q, v, a)
        tau = rigid_inverse_dynamics(m, q, v, a)
        assert np.max(np.abs(tau - ref)) < 1e-12 * np.max(np.abs(ref))


def test_urdf_of_rigid_links():
    """``dttmm urdf`` of the all-rigid and the mixed arm, read by Pinocchio's URDF parser: the
    joint-space mass matrix and the gravity torques equal those of Pinocchio's model built from
    the case (each rigid link's body written with its centre of mass and full inertia)."""
    pin = pytest.importorskip("pinocchio")
    from dttmm.urdf import case_to_urdf
    from reference_models import pinocchio_spatial as ps

    rng = np.random.default_rng(11)
    for path in (ALL_RIGID, MIXED):
        case = sp.load_case(path)
        ref = ps.build_model(case.model)
        urdf = pin.buildModelFromXML(case_to_urdf(case))
        urdf.gravity.linear = np.array(case.model.gravity)
        dr, du = ref.createData(), urdf.createData()
        q = rng.normal(size=3)
        Mr, Mu = pin.crba(ref, dr, q), pin.crba(urdf, du, q)
        assert np.max(np.abs(np.triu(Mr) - np.triu(Mu))) < 1e-12
        gr = pin.computeGeneralizedGravity(ref, dr, q)
        gu = pin.computeGeneralizedGravity(urdf, du, q)
        assert np.max(np.abs(gr - gu)) < 1e-12 * np.max(np.abs(gr))


@pytest.mark.parametrize("module", ["mujoco_spatial", "exudyn_ancf3d"])
def test_flexible_only_peers_refuse_rigid_links_by_name(module):
    """The peers that model flexible links only refuse a rigid link, naming it."""
    import importlib

    try:
        mod = importlib.import_module(f"reference_models.{module}")
    except ImportError as exc:  # the engine is an optional extra
        pytest.skip(str(exc))
    case = _short(sp.load_case(MIXED), 0.01)
    with pytest.raises(dttmm.InputError, match=r"model\.links\[0\]\.rigid.*not supported"):
        mod.simulate(case, elements_per_link=1, h=1e-3)


def test_zero_length_rigid_link_is_a_root_body():
    """A body at a flexible link's root (the outboard side of its joint) as a rigid link of
    length 0 carrying the joint, followed by the flexible link on a locked joint at a zero
    origin: with the body of the flexible link's hub (centre at the root) it runs as the hub
    itself (Newmark, k = 2, 0.05 s); with the centre moved off the root it moves differently."""
    case = _short(sp.load_case(MIXED), 0.05, 0.005)
    flex = case.model.links[1]
    body = SpatialRigidBody(0.0, flex.hub.mass, (0.0, 0.0, 0.0), flex.hub.inertia)
    split = (
        case.model.links[0],
        SpatialLink(body, flex.joint),
        dataclasses.replace(flex, joint=sp.SpatialJoint(locked=True), hub=None),
        case.model.links[2],
    )
    other = dataclasses.replace(case, model=dataclasses.replace(case.model, links=split))
    a = sp.simulate(case, elements_per_link=2, h=1e-3)
    b = sp.simulate(other, elements_per_link=2, h=1e-3)
    assert np.max(np.abs(a.joint_angle - b.joint_angle)) < 1e-13
    assert np.max(np.abs(a.end_effector - b.end_effector)) < 1e-13
    moved = dataclasses.replace(body, com=(0.05, 0.0, 0.02))
    links = (split[0], SpatialLink(moved, flex.joint), split[2], split[3])
    c = sp.simulate(
        dataclasses.replace(other, model=dataclasses.replace(case.model, links=links)),
        elements_per_link=2,
        h=1e-3,
    )
    assert np.max(np.abs(c.end_effector - a.end_effector)) > 1e-4


def test_frequencies_with_rigid_links():
    """``dttmm.frequencies`` of the mixed arm without gravity (the kernel's forward dynamics
    differentiated, dttmm/spatial/linear.py) = the generalized eigenvalues of the global solver's
    stiffness and mass matrices at rest, k = 3 (three rigid-body modes, then the flexible link's)."""
    import scipy.linalg

    case = sp.load_case(MIXED)
    case = dataclasses.replace(case, model=dataclasses.replace(case.model, gravity=(0.0, 0.0, 0.0)))
    k = 3
    f = dttmm.frequencies(case, elements_per_link=k)
    q = np.zeros(len(sg.coordinate_names(case, k)))
    lam = scipy.linalg.eigh(sg.elastic_forces(case, k, q)[2], sg.mass_matrix(case, k, q), eigvals_only=True)
    ref = np.sqrt(np.clip(lam, 0.0, None)) / (2 * np.pi)
    assert np.max(np.abs(f[:3])) < 1e-3 and 12.0 < ref[3] < 13.0
    assert np.max(np.abs(f[3:] / ref[3:] - 1.0)) < 1e-9  # measured 1.1e-11
