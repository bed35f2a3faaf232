"""Pinocchio's rigid 3-D model of a spatial case (reference_models.pinocchio_spatial) against
the spatial global solver and the spatial DT-TMM: the rigid-body data at undeformed states, and
the rigid limit of the flexible solvers (every stiffness × 1e6 and × 1e7)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import dttmm  # noqa: E402
import dttmm.spatial  # noqa: E402
from dttmm import Constant, Drive, SpinUp  # noqa: E402
from dttmm.drives import PD, Sine  # noqa: E402
from reference_models import pinocchio_spatial as ps  # noqa: E402
from reference_models import spatial_global as sg  # noqa: E402
from tests.test_spatial_global import _case, _torque_drives, arm  # noqa: E402


def _locked(model, i):
    links = list(model.links)
    links[i] = dataclasses.replace(links[i], joint=dataclasses.replace(links[i].joint, locked=True))
    return dataclasses.replace(model, links=tuple(links))


def _alpha(case, k):
    return np.array([i for i, n in enumerate(sg.coordinate_names(case, k)) if n.startswith("alpha")])


@pytest.mark.parametrize("locked", [None, 1])
def test_rigid_model_equals_global_solver_at_undeformed_states(locked):
    """At undeformed links (e = ė = 0) the flexible model's joint-space mass matrix, velocity and
    gravity terms, energy and frames are those of the rigid arm: Pinocchio's crba,
    nonLinearEffects, computeMechanicalEnergy and frame placements agree with the global
    solver to round-off (rods by 4-point Gauss, rotary inertia with roll, full hub and payload
    inertia, payload offset, joint origins with rpy, a rotated base, a locked joint)."""
    model = arm(EA=7e6)
    if locked is not None:
        model = _locked(model, locked)
    case = _case(model, _torque_drives(model.n_joints))
    k = 2
    a = _alpha(case, k)
    pm = ps.build_model(case.model)
    pd = pm.createData()
    rng = np.random.default_rng(3)
    N = len(sg.coordinate_names(case, k))
    for _ in range(4):
        qa, va = 2 * rng.normal(size=a.size), rng.normal(size=a.size)
        q, qd = np.zeros(N), np.zeros(N)
        q[a], qd[a] = qa, va
        M = pin.crba(pm, pd, qa)
        M = np.triu(M) + np.triu(M, 1).T
        assert np.max(np.abs(sg.mass_matrix(case, k, q)[np.ix_(a, a)] - M)) < 1e-14
        b = pin.nonLinearEffects(pm, pd, qa, va)
        assert np.max(np.abs(sg.generalized_forces(case, k, q, qd)[a] + b)) < 1e-13 * np.max(np.abs(b))
        e = sg.energy(case, k, q, qd)
        E = pin.computeMechanicalEnergy(pm, pd, qa, va)
        assert abs(e["kinetic"] + e["gravity"] - E) < 1e-13 * max(1.0, abs(E))
        pin.updateFramePlacements(pm, pd)
        kin = sg.kinematics(case, k, q)
        for i in range(case.model.n_links):
            root, tip = pd.oMf[pm.getFrameId(f"link{i + 1}")], pd.oMf[pm.getFrameId(f"link{i + 1}_tip")]
            assert np.max(np.abs(kin["root"][i] - root.translation)) < 1e-14
            assert np.max(np.abs(kin["root_rotation"][i] - root.rotation)) < 1e-14
            assert np.max(np.abs(kin["tip"][i] - tip.translation)) < 1e-14
            assert np.max(np.abs(kin["tip_rotation"][i] - tip.rotation)) < 1e-14


def test_link_inertia_closed_form():
    """A link's rigid inertia: mass ρA L + m_hub + m_pay, centre of mass and the inertia about
    the link origin (parallel-axis theorem), by hand."""
    link = arm(EA=7e6).links[2]
    Y = ps.link_inertia(link)
    b = link.beam
    L, m = b.length, b.rhoA * b.length
    c = np.array([L, 0, 0]) + link.payload_offset
    mass = m + link.hub_mass + link.payload_mass
    assert abs(Y.mass - mass) < 1e-15
    com = (m * np.array([L / 2, 0, 0]) + link.payload_mass * c) / mass
    assert np.max(np.abs(Y.lever - com)) < 1e-15
    cr, sr = math.cos(b.roll), math.sin(b.roll)
    Rr = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    I0 = np.diag([0.0, m * L * L / 3, m * L * L / 3]) + L * Rr @ np.diag([b.rhoJ, b.rhoIy, b.rhoIz]) @ Rr.T
    I0 += link.hub_inertia
    I0 += link.payload_inertia + link.payload_mass * (c @ c * np.eye(3) - np.outer(c, c))
    about_origin = Y.inertia + Y.mass * (Y.lever @ Y.lever * np.eye(3) - np.outer(Y.lever, Y.lever))
    assert np.max(np.abs(about_origin - I0)) < 1e-15


def test_rk4_is_fourth_order_and_newmark_second():
    """Pinocchio-RK4 at h = 1e-3 and 5e-4 against h = 1e-4 (error ratio ≈ 16); Newmark ≈ 4."""
    case = _case(arm(EA=7e6), _torque_drives(3), duration=0.3, output_step=0.01)
    ref = ps.simulate(case, h=1e-4)
    err = {}
    for integ in ("rk4", "newmark"):
        err[integ] = [
            np.max(np.abs(ps.simulate(case, h=h, integrator=integ).joint_angle - ref.joint_angle))
            for h in (1e-3, 5e-4)
        ]
    assert 12 < err["rk4"][0] / err["rk4"][1] < 20 and err["rk4"][0] < 1e-9
    assert 3.5 < err["newmark"][0] / err["newmark"][1] < 4.5


def test_energy_conserved_and_motion_torque_is_rnea():
    """Free motion (no torque) conserves Pinocchio's energy under RK4; a motion-driven joint's
    torque is Pinocchio's RNEA of the sampled motion."""
    model = arm(EA=7e6)
    drives = [Drive("torque", Constant(0.0), initial_rate=w) for w in (2.0, -1.5, 3.0)]
    res = ps.simulate(_case(model, drives, duration=0.3, output_step=0.01), h=1e-3)
    assert np.max(np.abs(res.energy - res.energy[0])) < 1e-9 * np.max(np.abs(res.energy))
    drives = [Drive("motion", SpinUp(2.0, 0.2)), *_torque_drives(2)]
    case = _case(model, drives, duration=0.2, output_step=0.01)
    res = ps.simulate(case, h=1e-3)
    pm = ps.build_model(case.model)
    pd = pm.createData()
    j = 12
    t = res.t[j]
    q, v = res.joint_angle[j], res.joint_rate[j]
    a = np.zeros(3)
    a[0] = drives[0].motion(t)[2]
    b = pin.rnea(pm, pd, q, v, a)
    M = pin.crba(pm, pd, q)
    M = np.triu(M) + np.triu(M, 1).T
    a[1:] = np.linalg.solve(M[1:, 1:], res.joint_torque[j, 1:] - b[1:])
    tau = pin.rnea(pm, pd, q, v, a)
    assert abs(res.joint_torque[j, 0] - tau[0]) < 1e-12 * max(1.0, abs(tau[0]))
    assert abs(res.joint_angle[j, 0] - drives[0].motion(t)[0]) < 1e-15


def _rigid_limit_case(stiff, duration=0.5):
    return _case(arm(EA=7e6, stiff=stiff), _torque_drives(3), duration=duration, output_step=0.01)


def test_rigid_limit_global_solver():
    """The global solver with every stiffness (EA, GJ, EIy, EIz) × 1e6 and × 1e7 approaches
    Pinocchio's rigid arm as 1/stiffness over 0.5 s (same integrator: Newmark, h = 1e-3, so
    the time-discretisation error is common; the integrator error itself, Newmark against
    RK4, is 3e-5 rad at this h): 1.5e-6 rad at × 1e6 (the test arm's links deflect by 7 % of
    their length at × 1), 1.5e-7 rad at × 1e7."""
    errs = []
    for stiff in (1e6, 1e7):
        case = _rigid_limit_case(stiff)
        rig = ps.simulate(case, h=1e-3, integrator="newmark")
        res = sg.simulate(case, elements_per_link=1, h=1e-3)
        assert res.success
        errs.append(np.max(np.abs(res.joint_angle - rig.joint_angle)))
    assert errs[0] < 2e-6 and errs[1] < 2e-7
    assert 7 < errs[0] / errs[1] < 13


def test_bad_input():
    case = _case(arm(2), _torque_drives(2))
    with pytest.raises(dttmm.InputError, match="integrator"):
        ps.simulate(case, h=1e-3, integrator="euler")
    with pytest.raises(dttmm.InputError, match="tol"):
        ps.simulate(case, h=1e-3, tol=1e-9)
    with pytest.raises(dttmm.InputError, match="case"):
        ps.simulate(dttmm.load_case, h=1e-3)
    with pytest.raises(dttmm.InputError, match="h"):
        ps.simulate(case, h=0.0)


needs_kernel = pytest.mark.skipif(
    not hasattr(dttmm.spatial, "simulate"),
    reason="the spatial DT-TMM (dttmm.spatial.simulate) is not available",
)


@needs_kernel
@pytest.mark.parametrize("k", [2, 4])
def test_rigid_limit_dttmm_same_integrator(k):
    """The spatial DT-TMM with every stiffness × 1e6 and × 1e7 against Pinocchio's rigid arm,
    both by Newmark at h = 1e-3 over 0.5 s: the joint angles differ by 1.5e-6 and 1.6e-7 rad,
    falling as 1/stiffness (the residual flexibility of the test arm)."""
    errs = []
    for stiff in (1e6, 1e7):
        case = _rigid_limit_case(stiff)
        rig = ps.simulate(case, h=1e-3, integrator="newmark")
        res = dttmm.spatial.simulate(case, elements_per_link=k, h=1e-3)
        assert res.success
        errs.append(np.max(np.abs(res.joint_angle - rig.joint_angle)))
    assert errs[0] < 2e-6 and errs[1] < 2e-7
    assert 7 < errs[0] / errs[1] < 13


@needs_kernel
def test_rigid_limit_dttmm_against_pinocchio_rk4():
    """Pinocchio's forward dynamics (``pinocchio.aba``) by RK4 and the spatial DT-TMM by Newmark,
    both at h = 1e-4 over 0.5 s, k = 2: with every stiffness × 1e7 the joint angles agree within
    1e-6 rad (measured 3.1e-7: Newmark's O(h²) error 2.8e-7 and the flexibility 1.6e-7); × 1e6
    gives 1.3e-6 rad, the flexibility's 1.5e-6 (see the test above) less the integrator's part."""
    for stiff, bound in ((1e7, 1e-6), (1e6, 2e-6)):
        case = _rigid_limit_case(stiff)
        rig = ps.simulate(case, h=1e-4)
        res = dttmm.spatial.simulate(case, elements_per_link=2, h=1e-4)
        assert res.success
        assert np.max(np.abs(res.joint_angle - rig.joint_angle)) < bound


def test_an_arm_without_free_joints_runs_under_newmark_as_under_rk4():
    """The 3-D cantilever (its one joint clamped: no coordinates) under Pinocchio's Newmark: the
    rigid beam stays where it is, as under RK4 (the iteration's stop rule took the largest of an
    empty acceleration vector and raised)."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    case = dttmm.load_case(root / "experiments" / "cases" / "spatial" / "cantilever_3d.toml")
    case = dataclasses.replace(
        case, scenario=dataclasses.replace(case.scenario, duration=0.02, output_step=0.01)
    )
    newmark = ps.simulate(case, h=1e-3, integrator="newmark")
    rk4 = ps.simulate(case, h=1e-3)
    assert newmark.status == "ok" and newmark.joint_angle.shape == (3, 0)
    np.testing.assert_array_equal(newmark.link_tip, rk4.link_tip)
    np.testing.assert_allclose(newmark.link_tip[-1, -1], [1.2, 0.0, 0.0], atol=1e-15)


def test_dop853_agrees_with_rk4():
    """The adaptive DOP853 (rtol = atol = 1e-12) against RK4 at h = 1 ms on the 3-D arm over 0.3 s
    (joints turn by up to 1.1 rad): measured 3.6e-11 rad, RK4's own step error."""
    case = _case(arm(3), _torque_drives(3), duration=0.3)
    a = ps.simulate(case, h=1e-3)
    b = ps.simulate(case, h=1e-3, integrator="dop853")
    np.testing.assert_array_equal(a.t, b.t)
    assert np.abs(a.joint_angle - b.joint_angle).max() <= 1e-9
    assert b.meta["nfev"] > 0 and b.n_steps > 0


def test_closed_loop_drives_on_a_spatial_arm():
    """pd + computed-torque feedforward (the RNEA of this rigid model) holds the 3-D arm on its
    references from a start on them (measured 1.8e-8 rad over 0.5 s); pd alone lags (0.15 rad)."""
    refs = [Sine(0.4, 0.8), Sine(-0.3, 0.6, phase=0.2), Sine(0.2, 1.0, offset=0.1)]

    def run(feedforward):
        drives = [Drive("torque", PD(40.0, 6.0, r, feedforward), *r.motion(0.0)[:2]) for r in refs]
        return ps.simulate(_case(arm(3), drives, duration=0.5), h=2e-3)

    ct, pd = run({"law": "computed_torque"}), run(None)
    ref = np.array([[r.motion(t)[0] for r in refs] for t in ct.t])
    assert np.abs(ct.joint_angle - ref).max() <= 1e-6
    assert np.abs(pd.joint_angle - ref).max() > 0.05
    case = _case(arm(3), [Drive("torque", PD(40.0, 6.0, r)) for r in refs])
    with pytest.raises(dttmm.InputError, match="rk4 only"):
        ps.simulate(case, h=2e-3, integrator="newmark")
    case = _case(arm(3), [Drive("torque", PD(40.0, 6.0, r, moment_gain=0.1)) for r in refs])
    with pytest.raises(dttmm.InputError, match="moment_gain"):
        ps.simulate(case, h=2e-3)
