"""Exudyn's 3-D geometrically exact beam (reference_models/exudyn_beam3d.py) on spatial cases.

Statics against closed forms: Exudyn's element (linear interpolation on SE(3), one-point
integration) gives a cantilever's tip deflection under a tip force F L³/3EI·(1 − 1/(4k²))
plus the shear part F L/GA (measured: −1.5625e-2, −9.77e-4, −6.0e-5 relative at k = 4, 16, 64,
= −1/(4k²)); with GA = 1e3·EA the shear part is 3EI/(GA L²) = 4e-8 relative, and k = 64 is
within 1e-4 of the Euler–Bernoulli value. Twist under a tip torque: T L/GJ (one-point torsion
is exact: 2.7e-12 measured). Section loads against statics and the spatial DT-TMM's cut loads; the three-joint
arm against the spatial DT-TMM; the Simo–Vu-Quoc right-angle cantilever (slow).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.errors import InputError
from dttmm.spatial import (
    SpatialCase,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialSection,
    accelerations,
    load_case,
)
from dttmm.spatial import simulate as dttmm_simulate
from dttmm.spatial.build import build_model

pytest.importorskip("exudyn")
from reference_models import exudyn_beam3d as xb  # noqa: E402

CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases" / "spatial"
BEAM = load_case(CASES / "cantilever_3d.toml").model.links[0].beam  # EIy = 80 ≠ EIz = 20


def cantilever(beam=BEAM, payload=None, gravity=(0.0, 0.0, 0.0)):
    link = SpatialLink(beam, SpatialJoint(locked=True), None, payload)
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), dttmm.Scenario(1.0, 0.5, ()))


@pytest.mark.parametrize("k", [4, 16, 64])
def test_static_cantilever_both_planes_and_twist(k):
    L, F, T = BEAM.length, 1e-4, 1e-4  # small loads: linear statics ((δ/L)² < 1e-10)
    c = cantilever()
    out = {}
    for name, force, torque in (
        ("y", (0, F, 0), (0, 0, 0)),
        ("z", (0, 0, F), (0, 0, 0)),
        ("x", (0, 0, 0), (T, 0, 0)),
    ):
        out[name] = xb.statics(
            c, elements_per_link=k, tip_loads=[dict(link=0, force=force, torque=torque)], load_steps=1
        )
    shear = 1.0 / (xb.SHEAR_RATIO * BEAM.EA)
    for plane, ei, col in (("y", BEAM.EIz, 0), ("z", BEAM.EIy, 1)):
        d = out[plane]["tip_deflection"][0]
        eb = F * L**3 / (3 * ei)
        ge = eb * (1 - 1 / (4 * k * k)) + F * L * shear  # the element's closed form
        assert abs(d[col] - ge) <= 1e-5 * eb, (plane, d[col] / eb - 1)  # 1.4e-6 at k = 64: round-off
        assert abs(d[1 - col]) <= 1e-9 * eb
        if k == 64:  # converged to Euler–Bernoulli within 1e-4
            assert abs(d[col] / eb - 1) <= 1e-4
    lie = xb.statics(
        c, elements_per_link=k, node="RotVecLG", tip_loads=[dict(link=0, force=(0, 0, F))], load_steps=1
    )
    assert np.allclose(
        lie["tip_deflection"], out["z"]["tip_deflection"], rtol=1e-6, atol=1e-12 * F
    )  # 8e-8 measured
    tw = out["x"]["twist"][0]
    assert abs(tw / (T * L / BEAM.GJ) - 1) <= 1e-8
    assert np.abs(out["x"]["tip_deflection"]).max() <= 1e-12


def dttmm_statics(c, k):
    """q with q̈(q, 0) = 0 by Newton's method on the DT-TMM forward dynamics; its cut loads."""
    n = build_model(c.model, k).ndof
    q, z = np.zeros(n), np.zeros(n)

    def f(x):
        return accelerations(c, k, x, z)

    for _ in range(10):
        J = np.column_stack([(f(q + 1e-6 * e) - f(q - 1e-6 * e)) / 2e-6 for e in np.eye(n)])
        q = q - np.linalg.solve(J, f(q))
    assert np.abs(f(q)).max() <= 1e-7 * np.abs(f(np.zeros(n))).max(), np.abs(f(q)).max()
    return accelerations(c, k, q, z, loads=True)[2]


def section_loads_case():
    beam = SpatialSection(
        length=1.0, GJ=30.0, EIy=80.0, EIz=20.0, rhoA=1e-3, rhoJ=1e-5, rhoIy=1e-5, rhoIz=1e-5
    )
    return cantilever(beam, SpatialPayload(1.0, (0.0, 0.5, 0.0)), gravity=(0.0, 0.0, 1.0))


def test_section_loads_one_element_against_statics_and_dttmm_cut_loads():
    """The default tier's share of :func:`test_section_loads_against_statics_and_dttmm_cut_loads`
    (slow tier), one size down: Exudyn at k = 1 (its Gauss point at x = 0.5) against r × F =
    (0.5, −0.5, 0) and against the DT-TMM's cut at x = 0.5 (k = 2, the root of element 2).
    Measured (2026-12-03): section force (3.1e-3, 8.3e-3, 1.0006) N, moment (0.49993,
    −0.50020, 1.2e-3) N·m; against the DT-TMM, in world components: force 1.0e-4 N, moments
    1.6e-5, 1.0e-4 and 1.39e-3 N·m about x, y, z (about z the O(δ·F) offset of x = 0.5 in the
    two deformed beams, larger at k = 1 than the slow test's 3.5e-4 at k = 2). Tolerances
    1.7–5× these."""
    c = section_loads_case()
    ex = xb.statics(c, elements_per_link=1, load_steps=4)
    sec = ex["section_loads"][0]
    assert np.allclose(sec[:3], [0.0, 0.0, 1.0], atol=2e-2)  # the section frame is rotated by ≈ δ'
    assert np.allclose(sec[3:], [0.5, -0.5, 0.0], atol=2e-3)
    cut = dttmm_statics(c, 2)[1]  # the root of element 2: x = 0.5
    R = ex["section_rotation"][0]
    world = np.concatenate([R @ sec[:3], R @ sec[3:]])
    assert np.allclose(world[:5], -cut[:5], atol=5e-4), (world, -cut)
    assert abs(world[5] + cut[5]) <= 3e-3, (world, -cut)


@pytest.mark.slow
def test_section_loads_against_statics_and_dttmm_cut_loads():
    """1 m cantilever, k = 2: a tip force of 1 N along z and a torque of 0.5 N·m about x (a 1 kg
    payload 0.5 m off the axis along y, weight 1 N along z; the beam's own weight, 1e-3 N/m,
    changes the moment by 3e-4); the section moment at x = 0.25
    (element 1's Gauss point) is r × F = (0.5, −0.75, 0); the DT-TMM (k = 4) cut at x = 0.25
    is the load of the inboard part on the outboard part: the negative, in world components."""
    beam = SpatialSection(
        length=1.0, GJ=30.0, EIy=80.0, EIz=20.0, rhoA=1e-3, rhoJ=1e-5, rhoIy=1e-5, rhoIz=1e-5
    )
    c = cantilever(beam, SpatialPayload(1.0, (0.0, 0.5, 0.0)), gravity=(0.0, 0.0, 1.0))
    ex = xb.statics(c, elements_per_link=2, load_steps=4)
    sec = ex["section_loads"][0]
    assert np.allclose(sec[:3], [0.0, 0.0, 1.0], atol=2e-2)  # the section frame is rotated by ≈ δ'
    assert np.allclose(sec[3:], [0.5, -0.75, 0.0], atol=2e-3)
    cut = dttmm_statics(c, 4)[1]  # the root of element 2: x = 0.25
    R = ex["section_rotation"][0]
    world = np.concatenate([R @ sec[:3], R @ sec[3:]])
    # the same load (up to the positions of x = 0.25 in the two deformed beams, O(δ·F))
    assert np.allclose(world, -cut, atol=5e-4), (world, -cut)


def short_arm(duration=0.2):
    c = load_case(CASES / "three_joint_arm.toml")
    return SpatialCase(c.model, dttmm.Scenario(duration, 0.01, c.scenario.drives), c.name)


def test_three_joint_arm_agrees_with_dttmm():
    """Exudyn at k = 4, h = 1e-3 against the DT-TMM at k = 16, h = 2.5e-4 over 0.2 s (the
    end-effector moves 0.13 m). Against the DT-TMM at k = 32, h = 1.25e-4 (its own change from
    k = 16, h = 2.5e-4: 2.6e-6 m) the end-effector gap is 1.79e-4, 4.72e-5, 1.16e-5, 2.48e-6 m at
    k = 2, 4, 8, 16 with h = 4e-3/k: second order, the GE element's O(1/k²) error (its static tip
    deflection is F L³/3EI·(1 − 1/(4k²))); tip deflections 1.4e-3, 3.6e-4, 9.2e-5, 2.4e-5 m;
    twist 3.3e-4, 9.0e-5, 4.0e-5, 1.1e-5 rad; joint angles 6.5e-3, 1.9e-3, 7.5e-4, 3.3e-4 rad
    (the angle between a hub and the previous link's tip node carries the node rotations'
    element error). Tolerances: 1.5–2× the k = 4 gaps."""
    c = short_arm()
    ref = dttmm_simulate(c, elements_per_link=16, h=2.5e-4)
    r = xb.simulate(c, elements_per_link=4, h=1e-3)
    assert r.end_effector.shape == ref.end_effector.shape == (21, 3)
    gap = np.abs(r.end_effector - ref.end_effector).max()
    assert np.abs(ref.end_effector - ref.end_effector[0]).max() > 0.1
    assert gap <= 1e-4, gap
    assert np.abs(r.joint_angle - ref.joint_angle).max() <= 3e-3
    assert np.abs(r.tip_deflection - ref.tip_deflection).max() <= 5e-4
    assert np.abs(r.twist - ref.twist).max() <= 2e-4
    assert r.link_root.shape == ref.link_root.shape and r.twist.shape == ref.twist.shape


@pytest.mark.slow
def test_three_joint_arm_gap_converges_second_order():
    c = short_arm()
    ref = dttmm_simulate(c, elements_per_link=32, h=1.25e-4)
    gaps = [
        np.abs(xb.simulate(c, elements_per_link=k, h=h).end_effector - ref.end_effector).max()
        for k, h in ((2, 2e-3), (4, 1e-3), (8, 5e-4))
    ]
    rates = np.log2(np.array(gaps[:-1]) / np.array(gaps[1:]))
    assert (rates > 1.7).all(), (gaps, rates)


RIGHT_ANGLE = load_case(CASES / "right_angle_cantilever.toml")


def right_angle(k, h, **options):
    """The case file as it is: its elbow force is its own [[scenario.loads]] entry."""
    c = RIGHT_ANGLE
    return xb.simulate(
        c,
        elements_per_link=k,
        h=h,
        shear_ratio=c.provenance["shear_stiffness"] / c.model.links[0].beam.EA,  # GA = EA
        **options,
    )


def extrema(r):
    """(value, time) of the tip's z maximum and minimum and of the elbow's z minimum."""
    t, tip, elbow = r.t, r.end_effector[:, 2], r.link_tip[:, 0, 2]
    i, j, m = np.argmax(tip), np.argmin(tip), np.argmin(elbow)
    return (tip[i], t[i]), (tip[j], t[j]), (elbow[m], t[m])


def test_right_angle_cantilever_reproduces_exudyn_test_model():
    """Simo & Vu-Quoc (1988) Fig. 8 as Exudyn's TestModels/geometricallyExactBeamElbowCantilever.py
    runs it (10 elements per leg, h = 0.05, full Newton, spectral radius 1): its printed extrema,
    tip 8.24 at 7.40 and −9.75 at 15.85, elbow −4.07 at 10.85 (measured here: 8.2380 at 7.40,
    −9.7512 at 15.85, −4.0667 at 10.85)."""
    r = right_angle(10, 0.05, modified_newton=False, newton_abs_tol=1e-8)
    assert np.allclose(r.end_effector[0], [10.0, 10.0, 0.0]) and np.allclose(r.link_tip[0, 0], [10, 0, 0])
    golden = ((8.24, 7.40), (-9.75, 15.85), (-4.07, 10.85))
    for (v, t), (gv, gt) in zip(extrema(r), golden):
        assert abs(v - gv) <= 0.005 and abs(t - gt) <= 1e-9, (v, t, gv, gt)


@pytest.mark.slow
def test_right_angle_cantilever_k4_extrema_and_energy():
    """k = 4 per leg, h = 0.01 (default settings: modified Newton): tip 8.146 at 7.35 and −9.821
    at 15.55, elbow −4.061 at 10.65 (the O(1/k²) element error shifts the peaks); k = 8, h =
    0.005: 8.231 at 7.40, −9.769 at 15.80, −4.073 at 10.80. The energy after t = 2 (no load, no
    damping) is constant to 1.2e-4 of its value at k = 4 (3e-5 at k = 8)."""
    r = right_angle(4, 0.01, energy=True)
    (a, ta), (b, tb), (c, tc) = extrema(r)
    assert abs(a - 8.146) <= 2e-3 and abs(ta - 7.35) <= 1e-9
    assert abs(b + 9.821) <= 2e-3 and abs(tb - 15.55) <= 1e-9
    assert abs(c + 4.061) <= 2e-3 and abs(tc - 10.65) <= 1e-9
    e = r.energy[r.t >= 2.0]
    assert np.ptp(e) <= 2e-4 * e[0]
    # the work of the elbow force: the energy at t = 2 is of the order F·δ
    assert 50 < e[0] < 200


def test_motion_drive_follows_its_law_and_its_torque_converges():
    """two_joint_arm with joint 1 spun up by a motion law (spin_up, 4 rad/s over 0.3 s): the
    prescribed angle is exact; the end-effector and the motor torque approach the DT-TMM's
    (k = 16, h = 2.5e-4) as k grows (end-effector 1.7e-4 → 4.4e-5 m, torque at 0.2 s
    21.731 → 21.677 against 21.670 N·m at k = 4 → 8)."""
    import tomllib

    from dttmm.spatial import case_from_dict

    doc = tomllib.loads((CASES / "two_joint_arm.toml").read_text())
    doc["scenario"].update(duration=0.2, output_step=0.01)
    doc["scenario"]["drives"][0] = {"kind": "motion", "law": "spin_up", "rate": 4.0, "ramp_time": 0.3}
    c = case_from_dict(doc)
    ref = dttmm_simulate(c, elements_per_link=16, h=2.5e-4)
    gaps = []
    for k, h in ((4, 1e-3), (8, 5e-4)):
        r = xb.simulate(c, elements_per_link=k, h=h)
        assert np.abs(r.joint_angle[:, 0] - ref.joint_angle[:, 0]).max() <= 1e-12
        gaps.append(
            (
                np.abs(r.end_effector - ref.end_effector).max(),
                abs(r.joint_torque[-1, 0] - ref.joint_torque[-1, 0]),
            )
        )
    assert gaps[0][0] <= 2.5e-4 and gaps[1][0] <= 0.4 * gaps[0][0]
    assert gaps[1][1] <= 0.3 * gaps[0][1] and gaps[1][1] <= 1e-3 * abs(ref.joint_torque[-1, 0])


@pytest.mark.parametrize("frame", ["world", "tip"])
def test_static_case_loads_world_and_follower_at_k8(frame):
    """The default tier's share of the k = 16 check below (slow tier): the same loads at k = 8.
    Measured (2026-12-03): Exudyn 1.0e-3 m (world), 5.7e-4 m (follower) from the DT-TMM (k = 4:
    3.9e-3, 2.2e-3; k = 16: 2.5e-4, 1.5e-4: the GE element's O(1/k²)); the follower load ends
    0.085 m from the world one. Tolerance 2e-3 m."""
    from dttmm.spatial import SpatialLoad, SpatialScenario, statics

    def case(*loads):
        return SpatialCase(cantilever().model, SpatialScenario(1.0, 0.5, (), loads))

    load = SpatialLoad(force=(0.0, 8.0, 20.0), moment=(5.0, 0.0, 0.0), frame=frame)
    x = xb.statics(case(load), elements_per_link=8)["link_tip"][0]
    d = statics(case(load), elements_per_link=8, steps=4).tip_position
    assert np.linalg.norm(x - d) <= 2e-3
    flipped = SpatialLoad(load.force, load.moment, frame="world" if frame == "tip" else "tip")
    assert np.linalg.norm(statics(case(flipped), elements_per_link=8, steps=4).tip_position - d) > 0.05
    if frame == "world":
        opt = xb.statics(
            case(), elements_per_link=8, tip_loads=[dict(link=0, force=load.force, torque=load.moment)]
        )
        assert np.array_equal(opt["link_tip"][0], x)


@pytest.mark.slow
@pytest.mark.parametrize("frame", ["world", "tip"])
def test_static_case_loads_world_and_follower_against_the_dttmm(frame):
    """A tip force (0, 8, 20) N and moment (5, 0, 0) N·m on the cantilever, large enough to turn
    the tip (the follower load ends 0.08 m away from the world one): the case's load
    (SpatialLoad, world or tip frame) in Exudyn's SolveStatic equals the DT-TMM's statics at
    k = 16 to 3e-4 m (measured 2.5e-4 m world, 1.5e-4 m follower: the GE element's O(1/k²);
    6.4e-5 and 3.7e-5 at k = 32); the world load equals the ``tip_loads`` option's."""
    from dttmm.spatial import SpatialLoad, SpatialScenario, statics

    def case(*loads):
        c = cantilever()
        return SpatialCase(c.model, SpatialScenario(1.0, 0.5, (), loads))

    load = SpatialLoad(force=(0.0, 8.0, 20.0), moment=(5.0, 0.0, 0.0), frame=frame)
    x = xb.statics(case(load), elements_per_link=16)["link_tip"][0]
    d = statics(case(load), elements_per_link=16, steps=4).tip_position
    assert np.linalg.norm(x - d) <= 3e-4
    other = statics(
        case(SpatialLoad(load.force, load.moment, frame="world" if frame == "tip" else "tip")),
        elements_per_link=16,
        steps=4,
    )
    assert np.linalg.norm(other.tip_position - d) > 0.05
    if frame == "world":
        opt = xb.statics(
            case(), elements_per_link=16, tip_loads=[dict(link=0, force=load.force, torque=load.moment)]
        )
        assert np.array_equal(opt["link_tip"][0], x)


def test_bad_input_is_refused():
    c = cantilever()
    with pytest.raises(InputError, match="node"):
        xb.simulate(c, elements_per_link=2, h=0.1, node="Rxyz")
    with pytest.raises(InputError, match="Lie-group"):
        xb.simulate(c, elements_per_link=2, h=0.1, node="RotVecLG")
    with pytest.raises(InputError, match="shear_ratio"):
        xb.simulate(c, elements_per_link=2, h=0.1, shear_ratio=-1.0)
    with pytest.raises(InputError, match=r"tip_loads\[0\]\.link"):
        xb.simulate(c, elements_per_link=2, h=0.1, tip_loads=[dict(link=3, force=[0, 0, 1])])
    with pytest.raises(InputError, match="output step"):
        xb.simulate(c, elements_per_link=2, h=0.3)
    with pytest.raises(InputError, match="case"):
        xb.simulate(object(), elements_per_link=2, h=0.1)


def test_damped_links_are_refused_and_the_method_sits_them_out():
    """Exudyn's ObjectBeamGeometricallyExact ignores BeamSection.dampingMatrix: the peer refuses a
    damped link instead of running it undamped, and the harness lists the case as one it cannot
    run (the DT-TMM still runs it)."""
    from dataclasses import replace

    from experiments import methods

    arm = load_case(CASES / "three_joint_arm.toml")
    links = tuple(replace(l, beam=replace(l.beam, damping=0.01)) for l in arm.model.links)
    damped = replace(arm, model=replace(arm.model, links=links))
    with pytest.raises(InputError, match=r"model\.links\[0\]\.beam\.damping.*ignores"):
        xb.simulate(damped, elements_per_link=2, h=1e-3)
    assert methods.runs_on("exudyn-beam", arm) and not methods.runs_on("exudyn-beam", damped)
    assert "damping" in methods.get("exudyn-beam").why_not_case(damped)
    assert methods.runs_on("dttmm", damped)


# ------------------------------------------------------------------ rigid links -----------------
MIXED = CASES / "rigid" / "mixed_arm.toml"  # rigid, flexible, rigid (offset centres, payload)


def test_rigid_links_statics_converge_to_the_dttmm():
    """The mixed arm (a rigid yaw link with an offset centre of mass and a full inertia, a
    flexible pitch link, a tilted rigid link with a tip length and a payload) held at joint
    angles under gravity: Exudyn's tip of the last link against the DT-TMM's (k = 16; its cubic
    elements are exact for these loads) at k = 4, 8, 16 — 1.0e-4, 2.6e-5, 6.5e-6 m measured,
    second order (the GE element's 1/(4k²))."""
    case = load_case(MIXED)
    angles = (0.3, 0.4, -0.2)
    drives = tuple(dttmm.Drive("motion", dttmm.Constant(a)) for a in angles)
    held = SpatialCase(case.model, dttmm.Scenario(1.0, 0.5, drives))
    ref = dttmm.spatial.statics(held, elements_per_link=16, angles=list(angles)).tip_position
    gaps = [
        np.linalg.norm(xb.statics(held, elements_per_link=k, load_steps=2)["link_tip"][-1] - ref)
        for k in (4, 8, 16)
    ]
    assert gaps[0] < 2e-4 and 3.0 < gaps[0] / gaps[1] < 5.0 and 3.0 < gaps[1] / gaps[2] < 5.0, gaps
    out = xb.statics(held, elements_per_link=2, load_steps=2)
    assert np.all(np.isnan(out["section_loads"][[0, 2]])) and np.all(np.isfinite(out["section_loads"][1]))
    assert np.max(np.abs(out["twist"][[0, 2]])) < 1e-12


def test_rigid_links_dynamics_agree_with_dttmm():
    """The mixed arm under its torques for 0.2 s (the end-effector moves 0.13 m): Exudyn at
    k = 4, h = 1e-3 and k = 8, h = 5e-4 against the DT-TMM at k = 8, h = 2.5e-4: end-effector
    gaps 3.6e-5 and 1.0e-5 m measured; the rigid links' shapes are their straight segments."""
    case = load_case(MIXED)
    short = SpatialCase(case.model, dttmm.Scenario(0.2, 0.01, case.scenario.drives), case.name)
    ref = dttmm_simulate(short, elements_per_link=8, h=2.5e-4)
    assert np.abs(ref.end_effector - ref.end_effector[0]).max() > 0.1
    gaps = []
    for k, h in ((4, 1e-3), (8, 5e-4)):
        r = xb.simulate(short, elements_per_link=k, h=h, shape_points=3)
        gaps.append(np.abs(r.end_effector - ref.end_effector).max())
        mid = 0.5 * (r.link_root[:, 2] + r.link_tip[:, 2])
        assert np.max(np.abs(r.link_shapes[:, 2, 1] - mid)) < 1e-15
        assert np.max(np.abs(r.twist[:, [0, 2]])) < 1e-12
    assert gaps[0] < 6e-5 and gaps[1] < 0.5 * gaps[0], gaps
    with pytest.raises(InputError, match=r"section_loads.*model\.links\[0\] is rigid"):
        xb.simulate(short, elements_per_link=2, h=1e-3, section_loads=True)
