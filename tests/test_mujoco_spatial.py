"""MuJoCo spatial chain peer (reference_models.mujoco_spatial): input checks, the rigid-body
data against Pinocchio, statics and natural frequencies against closed forms, the rigid limit
against Pinocchio's rigid arm, and arm motions against the spatial DT-TMM."""

from __future__ import annotations

import dataclasses as dc
import functools
from pathlib import Path

import numpy as np
import pytest

import dttmm
import dttmm.spatial as ds
from dttmm import Constant, Drive, Scenario, SpinUp
from dttmm.drives import PD

ms = pytest.importorskip("reference_models.mujoco_spatial")

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial"
#: Euler–Bernoulli clamped-free roots βₙL
BETA = np.array([1.8751040687119611, 4.6940911329741745, 7.8547574382376126])


def spatial(name: str) -> ds.SpatialCase:
    return ds.load_case(CASES / f"{name}.toml")


def shortened(c, duration, output_step=None):
    s = c.scenario
    return dc.replace(c, scenario=dc.replace(s, duration=duration, output_step=output_step or s.output_step))


def stiffened(c, factor):
    """Every stiffness (GJ, EIy, EIz, EA) × factor."""

    def beam(b):
        return dc.replace(
            b,
            GJ=b.GJ * factor,
            EIy=b.EIy * factor,
            EIz=b.EIz * factor,
            EA=None if b.EA is None else b.EA * factor,
        )

    links = tuple(dc.replace(lk, beam=beam(lk.beam)) for lk in c.model.links)
    return dc.replace(c, model=dc.replace(c.model, links=links))


def clamped(beam, payload=None, gravity=(0.0, 0.0, 0.0)):
    link = ds.SpatialLink(beam, ds.SpatialJoint(locked=True), None, payload)
    return ds.SpatialCase(ds.SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.5, ()))


def stable_h(c, k, H=1e-3):
    """The largest H/2^m at or below 0.8·h_stable (the stable path of the chain)."""
    m, d, _ = ms.build(c.model, k)
    hs = ms.stability_limit(m, d)[1]
    return H / 2 ** max(0, int(np.ceil(np.log2(H / (0.8 * hs)))))


#: the beam of experiments/cases/spatial/cantilever_3d.toml (EIy = 80 ≠ EIz = 20, ρIy = ρIz = 0)
BEAM = spatial("cantilever_3d").model.links[0].beam


# ------------------------------------------------------------------------------ input checks
@pytest.mark.parametrize(
    "kw, field",
    [
        ({"elements_per_link": 0}, "elements_per_link"),
        ({"elements_per_link": 1.5}, "elements_per_link"),
        ({"h": -1e-3}, "h"),
        ({"h": 3e-4}, "h"),  # does not divide the output step 1e-3
        ({"integrator": "verlet"}, "integrator"),
        ({"tolerance": 1.0}, "tolerance"),
        ({"motion_max_iter": 0}, "motion_max_iter"),
        ({"station": "universal"}, "station"),
    ],
)
def test_bad_input_names_the_field(kw, field):
    c = shortened(spatial("two_joint_arm"), 0.01)
    args = {"elements_per_link": 2, "h": 2.5e-4, **kw}
    with pytest.raises(dttmm.InputError) as exc:
        ms.simulate(c, **args)
    assert exc.value.field == field


def test_planar_case_and_closed_loop_refused():
    with pytest.raises(dttmm.InputError) as exc:
        ms.simulate(dttmm.load_case(CASES.parent / "single_link.toml"), elements_per_link=2, h=1e-3)
    assert exc.value.field == "case"
    c = spatial("two_joint_arm")
    pd = Drive("torque", PD(1.0, 0.1, Constant(0.0)))
    c = dc.replace(c, scenario=dc.replace(c.scenario, drives=(pd, c.scenario.drives[1])))
    with pytest.raises(dttmm.InputError) as exc:
        ms.simulate(c, elements_per_link=2, h=2.5e-4)
    assert exc.value.field == "scenario.drives[0].law"
    assert "not supported by mujoco-spatial" in str(exc.value)


def test_statics_bad_loads():
    c = clamped(BEAM)
    with pytest.raises(dttmm.InputError) as exc:
        ms.statics(c, 2, loads={"torque": (1.0, 0.0, 0.0)})
    assert exc.value.field == "loads.torque"
    with pytest.raises(dttmm.InputError) as exc:
        ms.statics(c, 2, loads={"force": (1.0, 0.0)})
    assert exc.value.field == "loads.force"


def test_unstable_step_fails_with_partial_result():
    """A step above the explicit bound: a warning, then SimulationError with the partial run."""
    c = shortened(spatial("two_joint_arm"), 0.2)
    with pytest.raises(dttmm.SimulationError) as exc:
        ms.simulate(c, elements_per_link=8, h=1e-3)
    part = exc.value.partial
    assert part.status == "failed" and part.t.size < c.scenario.output_times.size
    assert any("exceeds the explicit stability limit" in w for w in part.warnings)


# ------------------------------------------------------------------------------ rigid-body data
@pytest.mark.parametrize("k", [1, 3])
def test_rigid_body_data_equal_pinocchio(k):
    """At straight links the joint-space mass matrix and the link frames are Pinocchio's rigid arm
    (the lumping keeps every link's inertia exact at any k): three_joint_arm (base offset, rolled
    section, pitched joint origin, full hub inertias, off-axis payload) and a locked joint."""
    pin = pytest.importorskip("pinocchio")
    ps = pytest.importorskip("reference_models.pinocchio_spatial")
    base = spatial("three_joint_arm").model
    links = list(base.links)
    links[1] = dc.replace(
        links[1], hub=ds.SpatialHub(0.4, ((2e-3, 1e-4, -2e-4), (1e-4, 3e-3, 5e-5), (-2e-4, 5e-5, 4e-3)))
    )
    four = dc.replace(
        links[2], joint=ds.SpatialJoint((0.0, 0.0, 1.0), (0.05, 0.02, 0.0), (0.1, 0.0, 0.4), locked=True)
    )
    model = dc.replace(base, links=(*links, four), base_rpy=(0.2, -0.3, 0.5))
    pm = ps.build_model(model)
    pd = pm.createData()
    m, d, lay = ms.build(model, k)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q = rng.uniform(-2, 2, size=lay.arm_qpos.size)
        d.qpos[:] = 0.0
        d.qpos[lay.arm_qpos] = q
        ms.mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        ms.mujoco.mj_fullM(m, d, M)
        P = pin.crba(pm, pd, q)
        P = np.triu(P) + np.triu(P, 1).T
        assert np.max(np.abs(M[np.ix_(lay.arm_dof, lay.arm_dof)] - P)) < 1e-12 * np.abs(P).max()
        pin.framesForwardKinematics(pm, pd, q)
        for i in range(model.n_links):
            root, tip = pd.oMf[pm.getFrameId(f"link{i + 1}")], pd.oMf[pm.getFrameId(f"link{i + 1}_tip")]
            assert np.max(np.abs(d.xpos[lay.hub_body[i]] - root.translation)) < 1e-13
            assert np.max(np.abs(d.xmat[lay.hub_body[i]].reshape(3, 3) - root.rotation)) < 1e-13
            assert np.max(np.abs(d.site_xpos[lay.tip_site[i]] - tip.translation)) < 1e-13
            assert np.max(np.abs(d.xmat[lay.tip_body[i]].reshape(3, 3) - tip.rotation)) < 1e-13


# ------------------------------------------------------------------------------ statics
@pytest.mark.parametrize("roll", [0.0, 0.4])
def test_static_tip_force_both_planes_and_twist(roll):
    """Clamped beam, EIy ≠ EIz. A dead tip force F: the chain's tip deflection is the midpoint
    rule of ∫ F(L − x)²/EI dx, F L³/(3EI)·(1 − 1/(4k²)) in each principal plane, exactly (to
    the geometric nonlinearity at the tiny load, (δ/L)² ≈ 1e-12; with roll, the force resolved on
    the rolled section axes); observed order 2. A tip torque T: twist T L/GJ at every k (the
    k springs GJ·k/L in series). Self-weight: ρA g L⁴/(8EI)·(1 − 1/(2k²))."""
    beam = dc.replace(BEAM, roll=roll)
    L = beam.length
    c = clamped(beam)
    R = np.array([[1, 0, 0], [0, np.cos(roll), -np.sin(roll)], [0, np.sin(roll), np.cos(roll)]])
    F = np.array([0.0, 1e-4, 2e-4])
    Fs = R.T @ F  # on the section axes
    exact = R @ np.array([0.0, Fs[1] * L**3 / (3 * beam.EIz), Fs[2] * L**3 / (3 * beam.EIy)])
    errs = []
    for k in (2, 4, 8, 16):
        s = ms.statics(c, k, loads={"force": F})
        got = np.array([0.0, *s["tip_deflection"][0]])
        assert np.allclose(got, exact * (1 - 1 / (4 * k * k)), rtol=1e-6, atol=1e-6 * np.abs(exact).max())
        errs.append(np.abs(got - exact).max() / np.abs(exact).max())
        t = ms.statics(c, k, loads={"moment": (2e-4, 0.0, 0.0)})
        assert abs(t["twist"][0] / (2e-4 * L / beam.GJ) - 1) < 1e-9
    assert np.allclose(np.array(errs[:-1]) / errs[1:], 4.0, rtol=1e-3)
    if roll == 0.0:
        g = (0.0, -1e-4, -2e-4)
        for k in (4, 8):
            s = ms.statics(clamped(beam, gravity=g), k)
            w = np.array([g[1] / beam.EIz, g[2] / beam.EIy]) * beam.rhoA * L**4 / 8
            assert np.allclose(s["tip_deflection"][0], w * (1 - 1 / (2 * k * k)), rtol=1e-6)


# ------------------------------------------------------------------------------ frequencies
def test_natural_frequencies_converge_to_euler_bernoulli():
    """Clamped beam (EIy = 4 EIz, no bending rotary inertia): the three lowest frequencies of
    both bending families and of torsion against βₙ² √(EI/ρA L⁴) and (2n − 1)π/2 √(GJ/ρJ L²).
    Bending lies above by ≈ c_n/k² (measured c = 0.23, 0.80, 1.31), torsion below (lumped
    inertia); the error falls by 4 per doubling of k (second order)."""
    L = BEAM.length
    exact = {
        "EIz": BETA**2 * np.sqrt(BEAM.EIz / (BEAM.rhoA * L**4)),
        "EIy": BETA**2 * np.sqrt(BEAM.EIy / (BEAM.rhoA * L**4)),
        "GJ": (2 * np.arange(1, 4) - 1) * np.pi / 2 * np.sqrt(BEAM.GJ / (BEAM.rhoJ * L**2)),
    }
    link = ds.SpatialLink(BEAM, ds.SpatialJoint(locked=True))
    err = {k: {f: ms.natural_frequencies(link, k)[f] / exact[f] - 1 for f in exact} for k in (8, 16, 32)}
    for f in ("EIz", "EIy"):
        assert np.all(err[8][f] > 0)
        assert np.allclose(err[32][f] * 32**2, [0.229, 0.797, 1.308], rtol=0.01)
    assert np.all(err[8]["GJ"] < 0)
    for f in exact:
        assert np.all(np.abs(err[16][f]) < 0.011)
        for a, b in ((8, 16), (16, 32)):
            assert np.all((err[a][f] / err[b][f] > 3.8) & (err[a][f] / err[b][f] < 4.2))


# ------------------------------------------------------------------------------ rigid limit
@pytest.mark.parametrize("name, hs", [("two_joint_arm", (2.5e-6, 1.25e-6)), ("three_joint_arm", (2.5e-6,))])
def test_rigid_limit_matches_pinocchio(name, hs):
    """Every stiffness × 1e6, gravity, sine torques, 0.5 s, k = 1: the joint angles and the end
    effector are Pinocchio's rigid arm (RK4, h = 1e-4) within 6e-6 rad / 3.5e-6 m at h = 2.5e-6
    (measured 5.7e-6, 2.5e-6 (two_joint_arm); 5.8e-6, 3.2e-6 (three_joint_arm)), the difference
    first order in h (semi-implicit Euler): halving h halves it (the residual flexibility,
    ∝ 1/stiffness, is below)."""
    ps = pytest.importorskip("reference_models.pinocchio_spatial")
    c = stiffened(shortened(spatial(name), 0.5, 1e-2), 1e6)
    b = ps.simulate(c, h=1e-4)
    errs = []
    for h in hs:
        r = ms.simulate(c, elements_per_link=1, h=h)
        errs.append(np.abs(r.joint_angle - b.joint_angle).max())
        assert errs[-1] < 6e-6 * h / 2.5e-6
        assert np.abs(r.end_effector - b.end_effector).max() < 3.5e-6 * h / 2.5e-6
        assert np.abs(r.tip_deflection).max() < 1e-6 and np.abs(r.twist).max() < 1e-6
    if len(errs) == 2:
        assert 1.8 < errs[0] / errs[1] < 2.2


# ------------------------------------------------------------------------------ arm motions
@functools.cache
def dttmm_ref(name):
    """The spatial DT-TMM at k = 16, h = 1.25e-4 (its own difference to k = 32: ≤ 1.6e-5 m on
    the end effector, 3.8e-5 rad on the joints)."""
    return ds.simulate(spatial(name), elements_per_link=16, h=1.25e-4)


def _errors(r, a):
    return {
        "q": np.abs(r.joint_angle - a.joint_angle).max(),
        "ee": np.abs(r.end_effector - a.end_effector).max(),
        "defl": np.abs(r.tip_deflection - a.tip_deflection).max() / np.abs(a.tip_deflection).max(),
        "twist": np.abs(r.twist[:, 0] - a.twist[:, 0]).max() / np.abs(a.twist[:, 0]).max(),
        "energy": np.abs(r.energy - a.energy).max() / np.abs(a.energy).max(),
    }


#: measured along the stable path (k = 2, 4, 8): the end-effector
#: error (m) at k = 8 and the least ratio of the errors per doubling of k
ARM = {
    "two_joint_arm": {"ee8": 5.5e-4, "ratio": 3.9},  # ee 8.6e-3, 2.2e-3, 5.5e-4
    "three_joint_arm": {"ee8": 1.3e-3, "ratio": 2.8},  # ee 1.3e-2, 4.4e-3, 1.3e-3
}


@pytest.mark.parametrize("name", ["two_joint_arm", "three_joint_arm"])
def test_arm_motion_converges_to_dttmm(name):
    """Torque-driven arms with gravity against the spatial DT-TMM: every error falls as k grows
    on the stable path (h ∝ 1/ω_max; the time error is < 2 % of the total there). End effector,
    joint angles, tip deflections (both planes), the first link's twist and the energy."""
    c, a = spatial(name), dttmm_ref(name)
    errs = []
    for k in (2, 4, 8):
        r = ms.simulate(c, elements_per_link=k, h=stable_h(c, k))
        assert r.success and r.cut_loads is None
        errs.append(_errors(r, a))
    assert errs[-1]["ee"] < 1.1 * ARM[name]["ee8"]
    assert errs[-1]["defl"] < 1.5e-2
    for e0, e1 in zip(errs[:-1], errs[1:]):
        assert e0["ee"] / e1["ee"] > 0.95 * ARM[name]["ratio"]
        for key in ("q", "defl", "twist", "energy"):
            assert e0[key] / e1[key] > 2.5, key


@pytest.mark.slow
@pytest.mark.parametrize("name", ["two_joint_arm", "three_joint_arm"])
def test_arm_motion_fine_chain(name):
    """k = 16 (h = 6.25e-5 / 3.125e-5): end effector within 1.5e-4 m / 3.8e-4 m (measured
    1.4e-4, 3.6e-4: a further factor 3.9 / 3.5 from k = 8)."""
    c, a = spatial(name), dttmm_ref(name)
    r = ms.simulate(c, elements_per_link=16, h=stable_h(c, 16))
    e = _errors(r, a)
    assert e["ee"] < {"two_joint_arm": 1.5e-4, "three_joint_arm": 3.8e-4}[name]
    assert e["defl"] < 4e-3


def test_energy_conserved_after_the_torques_stop():
    """two_joint_arm, undamped: the torques end at 0.5 s, after which MuJoCo's kinetic +
    gravity + spring energy stays constant up to the symplectic Euler step's O(h) oscillation."""
    c = spatial("two_joint_arm")
    r = ms.simulate(c, elements_per_link=4, h=2.5e-4)
    e = r.energy[r.t > 0.5]
    assert np.ptp(e) < 2e-3 * np.abs(e).max()


def test_motion_drive_follows_the_law_and_converges():
    """Joint 1 spun up by a motion law, joint 2 torque-driven: the prescribed angle equals the
    law at every output to 1e-12 rad; end effector and motor torque against the spatial DT-TMM
    (k = 8, h = 2.5e-4; its own difference to k = 16, h = 1.25e-4 is 8e-5 m) fall with k
    (measured ee 9.6e-3, 2.4e-3; torque 5.5 %, 1.2 % of its peak)."""
    c = spatial("two_joint_arm")
    drives = (Drive("motion", SpinUp(3.0, 0.4)), c.scenario.drives[1])
    c = dc.replace(c, scenario=Scenario(0.6, 1e-3, drives))
    a = ds.simulate(c, elements_per_link=8, h=2.5e-4)
    law = drives[0].law
    err = []
    for k, h in ((2, 2.5e-4), (4, 1.25e-4)):
        r = ms.simulate(c, elements_per_link=k, h=h)
        assert np.abs(r.joint_angle[:, 0] - [law.motion(t)[0] for t in r.t]).max() < 1e-12
        tau = np.abs(r.joint_torque[:, 0] - a.joint_torque[:, 0]).max() / np.abs(a.joint_torque[:, 0]).max()
        err.append((np.abs(r.end_effector - a.end_effector).max(), tau))
    assert err[1][0] < 2.6e-3 and err[1][1] < 1.3e-2
    assert err[0][0] / err[1][0] > 3.5 and err[0][1] / err[1][1] > 3.5
