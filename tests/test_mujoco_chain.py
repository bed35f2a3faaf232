"""MuJoCo hinge-chain peer: input checks, rigid limit, motion drives, natural frequencies,
convergence to the Exudyn ANCF reference, failures."""

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest
from conftest import case, shortened, with_links

import dttmm

mc = pytest.importorskip("reference_models.mujoco_chain")

REFS = Path(__file__).resolve().parents[1] / "data" / "references" / "quick"


def rigid(c, factor):
    return with_links(c, EI=lambda b: b.EI * factor, EA=lambda b: None if b.EA is None else b.EA * factor)


# ------------------------------------------------------------------------------ input checks
@pytest.mark.parametrize(
    "kw, field",
    [
        ({"elements_per_link": 0}, "elements_per_link"),
        ({"elements_per_link": 2.5}, "elements_per_link"),
        ({"h": -1e-3}, "h"),
        ({"h": 3e-4}, "h"),  # does not divide the output step 1e-3
        ({"integrator": "verlet"}, "integrator"),
        ({"tolerance": 1.0}, "tolerance"),
        ({"motion_max_iter": 0}, "motion_max_iter"),
    ],
)
def test_bad_input_names_the_field(kw, field):
    c = shortened(case("single_link"), 0.01)
    args = {"elements_per_link": 2, "h": 1e-3, **kw}
    with pytest.raises(dttmm.InputError) as exc:
        mc.simulate(c, **args)
    assert exc.value.field == field


def test_registered_and_available():
    from experiments.methods import available, label

    assert available(["mujoco-chain"]) == {"mujoco-chain": None}
    assert label("mujoco-chain") == "MuJoCo hinge chain"


# ------------------------------------------------------------------------------ rigid limit
def test_rigid_rotor_closed_form_first_order():
    """EI × 1e6, bang-bang torque on the hub: the rotor θ(t) is piecewise quadratic with
    J = J_hub + ρA L³/3 (the lumped pieces reproduce it exactly). MuJoCo's semi-implicit Euler
    (q_{n+1} = q_n + h v_{n+1}, exact v for a piecewise-constant torque sampled at the step
    midpoint) is off by exactly (h/2)·(v(t) − v(0)) at the nodes: the error bound below, with
    1 % plus 1e-6 rad for the stiff residual flexibility (deflections ∝ 1/EI)."""
    c = rigid(shortened(case("single_link"), 1.2, 1e-2), 1e6)
    J = 0.01 + 0.27 * 1.0**3 / 3

    def closed(t):
        a = 1.0 / J
        s1, s2, s3 = np.minimum(t, 0.5), np.clip(t - 0.5, 0, 0.5), np.clip(t - 1.0, 0, None)
        w = a * 0.5
        return a * s1**2 / 2 + w * s2 - a * s2**2 / 2 + (w - a * 0.5) * s3, a * s1 - a * s2

    errs = []
    for h in (1e-5, 5e-6):
        r = mc.simulate(c, elements_per_link=2, h=h)
        th, w = closed(r.t)
        err = np.abs(r.joint_angle[:, 0] - th)
        assert np.all(err <= 1.01 * h / 2 * np.abs(w) + 1e-6)
        assert np.max(np.abs(r.tip_deflection)) < 1e-6
        errs.append(err.max())
    assert 1.9 < errs[0] / errs[1] < 2.1  # first order: the integrator, not the model


def test_rigid_limit_three_link_matches_pinocchio():
    """EI × 1e6, gravity, three sine torques: joint angles and end-effector approach Pinocchio's
    rigid arm (RK4, h = 1e-4, error < 1e-8) at first order in h; at h = 5e-6 within 2e-5."""
    pr = pytest.importorskip("reference_models.pinocchio_rigid")
    c = rigid(shortened(case("three_link"), 0.5, 1e-2), 1e6)
    b = pr.simulate(c, h=1e-4, integrator="rk4")
    errs = []
    for h in (5e-6, 2.5e-6):
        r = mc.simulate(c, elements_per_link=2, h=h)
        errs.append(
            max(np.abs(r.joint_angle - b.joint_angle).max(), np.abs(r.end_effector - b.end_effector).max())
        )
    assert errs[0] < 2e-5
    assert 1.8 < errs[0] / errs[1] < 2.2


def test_motion_drive_rigid_torque_closed_form():
    """Spin-up law on a stiffened beam (EI × 1e4): the joint follows the law to round-off and
    the motor torque is J α̈ with J = ρA L³/3. Measured 1.9e-4 of max|τ| (flexible residual
    ∝ 1/EI and the O(h) step); asserted 1e-3."""
    c = rigid(shortened(case("spin_up"), 2.0, 0.1), 1e4)
    r = mc.simulate(c, elements_per_link=2, h=2e-4)
    law = c.scenario.drives[0].law
    alpha = np.array([law.motion(t) for t in r.t])
    tau = 1.2 * 10.0**3 / 3 * alpha[:, 2]
    assert np.max(np.abs(r.joint_angle[:, 0] - alpha[:, 0])) < 1e-12
    assert np.max(np.abs(r.joint_torque[:, 0] - tau)) < 1e-3 * np.max(np.abs(tau))


def test_motion_drive_flexible_spin_up_matches_dttmm():
    """Flexible spin-up beam (4 s): tip deflection against DT-TMM at k = 16 within 1 % of its
    peak at k = 8 (measured 0.64 %; the time error is below 1e-6 of the peak at h = 1e-3) and
    falling as 1/k² from k = 4 (measured ratio 3.95); motor torque within 2e-3 of its peak."""
    c = shortened(case("spin_up"), 4.0, 0.1)
    a = dttmm.simulate(c, elements_per_link=16, h=1e-3, cut_loads=False, energy=False)
    peak = np.max(np.abs(a.tip_deflection))
    err = {}
    for k in (4, 8):
        r = mc.simulate(c, elements_per_link=k, h=1e-3)
        err[k] = np.max(np.abs(r.tip_deflection - a.tip_deflection)) / peak
    assert err[8] < 1e-2
    assert err[4] / err[8] > 3.5
    assert np.max(np.abs(r.joint_torque - a.joint_torque)) < 2e-3 * np.max(np.abs(a.joint_torque))


def test_mixed_drives_match_dttmm():
    """three_link (0.5 s, gravity), joint 2 motion-driven (smooth spin-up), joints 1 and 3
    torque-driven, k = 16 against DT-TMM at k = 16: torque-joint angles within 1e-3 rad
    (measured 6.8e-4), tip deflections within 1 % of their peaks (measured 0.5 %), the motion
    joint's torque within 3 % RMS of its peak (measured 1.9 %; it carries the links' high
    frequencies, and DT-TMM's own value moves by 1.4 % of the peak when its step is halved)."""
    c = shortened(case("three_link"), 0.5, 1e-3)
    drives = list(c.scenario.drives)
    drives[1] = dttmm.Drive("motion", dttmm.SpinUp(1.5, 0.8))
    c = dc.replace(c, scenario=dc.replace(c.scenario, drives=tuple(drives)))
    a = dttmm.simulate(c, elements_per_link=16, h=2.5e-4, cut_loads=False, energy=False)
    r = mc.simulate(c, elements_per_link=16, h=6.25e-5)
    assert np.max(np.abs(r.joint_angle - a.joint_angle)[:, [0, 2]]) < 1e-3
    assert np.max(np.abs(r.joint_angle[:, 1] - a.joint_angle[:, 1])) < 1e-12  # the law, at nodes
    peaks = np.max(np.abs(a.tip_deflection), axis=0)
    assert np.all(np.max(np.abs(r.tip_deflection - a.tip_deflection), axis=0) < 1e-2 * peaks)
    e = r.joint_torque[:, 1] - a.joint_torque[:, 1]
    assert np.sqrt(np.mean(e**2)) < 3e-2 * np.max(np.abs(a.joint_torque[:, 1]))


def test_off_grid_breakpoint_splits_the_step():
    """A torque switch between step nodes: the step is split there, so the stiff rotor still
    obeys the closed form within the O(h) bound of the on-grid case."""
    law = dttmm.BangBang((1.0, -1.0), (0.500033,))
    c = rigid(shortened(case("single_link"), 0.6, 1e-2), 1e6)
    c = dc.replace(c, scenario=dc.replace(c.scenario, drives=(dttmm.Drive("torque", law),)))
    r = mc.simulate(c, elements_per_link=2, h=1e-5)
    a = 1.0 / (0.01 + 0.09)
    ts = 0.500033
    th = np.where(r.t <= ts, a * r.t**2 / 2, a * ts**2 / 2 + a * ts * (r.t - ts) - a * (r.t - ts) ** 2 / 2)
    assert np.max(np.abs(r.joint_angle[:, 0] - th)) < 1e-5 / 2 * a * ts * 1.01 + 1e-6
    assert r.n_steps == 60001


# ------------------------------------------------------------------------------ small deflections
def test_first_natural_frequency_converges_to_closed_form():
    """Clamped-free link: ω1 of the chain → 1.8751² √(EI/(ρA L⁴)) at second order in 1/k
    (measured relative error ≈ 0.23/k²: 1.45e-2, 3.6e-3, 9.0e-4, 2.2e-4 for k = 4 … 32)."""
    link = case("single_link").model.links[0]
    b = link.beam
    exact = 1.875104068711961**2 * np.sqrt(b.EI / (b.rhoA * b.length**4))
    ks = np.array([4, 8, 16, 32])
    err = np.array([mc.natural_frequencies(link, int(k), 1)[0] / exact - 1 for k in ks])
    assert np.all(err > 0)  # the chain is too stiff: the midpoint rule overestimates
    order = -np.polyfit(np.log(ks), np.log(err), 1)[0]
    assert 1.95 < order < 2.05
    assert err[-1] < 3e-4


@pytest.mark.parametrize("k", [1, 4, 16])
def test_static_tip_compliance_is_the_midpoint_rule(k):
    """Clamped link, tip force F: the hinge springs EI·k/L at x_j = (j − ½)L/k give the midpoint
    rule of ∫ F (L − x)²/EI dx, i.e. exactly F L³/(3EI)·(1 − 1/(4k²)). Checked on the compiled
    model: tip Jacobian J (rows of d tip/d q) and joint stiffnesses K, compliance J K⁻¹ Jᵀ."""
    import mujoco

    from dttmm.model import Manipulator

    link = case("single_link").model.links[0]
    b = link.beam
    m, d, lay = mc.build(Manipulator((link,)), k, 1e-3, clamp_first=True)
    mujoco.mj_forward(m, d)
    jacp = np.zeros((3, m.nv))
    mujoco.mj_jacSite(m, d, jacp, None, int(lay.tip_site[0]))
    compliance = jacp[1] @ (jacp[1] / m.jnt_stiffness[m.dof_jntid])
    exact = b.length**3 / (3 * b.EI) * (1 - 1 / (4 * k * k))
    assert compliance == pytest.approx(exact, rel=1e-12)


def test_energy_equals_motor_work_rk4():
    """Undamped link, no gravity, bang-bang torque until t = 1 s (RK4, k = 8): the energy
    (kinetic + spring) equals the motor work ∫ τ·α̇ dt (trapezoid on the 0.1 ms output grid:
    measured 2.8e-7 relative, falling as the grid step squared) and
    is constant once the torque is off; semi-implicit Euler keeps it within 1 % (symplectic)."""
    c = shortened(case("single_link"), 1.5, 1e-4)
    r = mc.simulate(c, elements_per_link=8, h=1e-4, integrator="rk4")
    drive, w = c.scenario.drives[0], r.joint_rate[:, 0]
    # each interval sees the torque of its own side of a switch (right limit at its start)
    p0 = np.array([drive.torque(t) for t in r.t[:-1]]) * w[:-1]
    p1 = np.array([drive.torque(t, True) for t in r.t[1:]]) * w[1:]
    work = np.concatenate([[0.0], np.cumsum(0.5 * (p0 + p1) * np.diff(r.t))])
    on = r.t <= 1.0
    assert np.max(np.abs(r.energy[on] - work[on])) < 1e-6 * np.max(work)
    after = r.energy[r.t >= 1.0]
    assert np.ptp(after) < 1e-8 * after.mean()
    e = mc.simulate(c, elements_per_link=8, h=1e-4).energy[r.t >= 1.0]
    assert np.ptp(e) < 1e-2 * e.mean()


# ------------------------------------------------------------------------------ failures
def test_unstable_step_fails_with_partial_result():
    """h far above the explicit stability limit: a SimulationError with the time, a partial
    Result ending before it and the warning about h in the partial's warnings."""
    c = shortened(case("single_link"), 1.0, 1e-3)
    with pytest.raises(dttmm.SimulationError) as exc:
        mc.simulate(c, elements_per_link=16, h=1e-3)
    e = exc.value
    assert 0 < e.t < 1.0
    p = e.partial
    assert p is not None and p.status == "failed" and p.t[-1] < e.t
    assert np.isfinite(p.joint_angle).all()
    assert any("stability limit" in w for w in p.warnings)


# ------------------------------------------------------------------------------ convergence (slow)
def _reference(name):
    from experiments.plan import PLANS
    from experiments.references import load_reference, reference_key

    c = case(name)
    c = dc.replace(c, scenario=dc.replace(c.scenario, output_step=4e-3))
    plan = PLANS["quick"]
    ref, prov = load_reference(REFS, c, reference_key(c, plan.reference[name], plan.check[name]))
    if ref is None:
        pytest.skip(f"no stored reference for {name}")
    return c, ref, prov


@pytest.mark.slow
@pytest.mark.parametrize(
    "name, h, ks, min_order",
    [
        ("single_link", 2.5e-5, (2, 4, 8, 16, 32), 1.8),
        ("three_link", 1.25e-5, (2, 4, 8, 16, 32), 1.7),
    ],
)
def test_converges_to_ancf_reference(name, h, ks, min_order):
    """Tip deflection of the first link against the stored Exudyn ANCF reference (k = 32,
    h = 2.5e-4; it agrees with DT-TMM at k = 32 to 1.9e-4 m / 5e-5 m RMS): the relative RMS
    error falls with k = 2 … 32 at an observed order ≥ min_order (measured 1.96 on single_link,
    1.83 on three_link; the rule is second order, the bang-bang torques of single_link make the
    decay irregular), h small enough for the time error not to count; at k = 32 below 5e-3
    (measured 1.2e-3 and 2.6e-3)."""
    c, ref, prov = _reference(name)
    assert prov["method"] == "exudyn-ancf"
    scale = np.sqrt(np.mean(ref.tip_deflection[:, 0] ** 2))
    err = []
    for k in ks:
        r = mc.simulate(c, elements_per_link=k, h=h)
        err.append(np.sqrt(np.mean((r.tip_deflection[:, 0] - ref.tip_deflection[:, 0]) ** 2)) / scale)
    order = -np.polyfit(np.log(ks), np.log(err), 1)[0]
    assert np.all(np.diff(err) < 0)
    assert order > min_order, (err, order)
    assert err[-1] < 5e-3


def test_work_precision_study_runs_the_mujoco_path():
    """The work-precision study runs mujoco-chain along the plan's path at its record's stable
    step (max_step: 0.016/k² s, at most 2 ms); a task of it runs through the sweep's executor to an
    'ok' outcome."""
    from types import SimpleNamespace

    from experiments import methods
    from experiments.plan import PLANS
    from experiments.runs import execute
    from experiments.studies import work_precision

    p = PLANS["quick"].studies["work_precision"]
    c = shortened(case("three_link"), 0.02, 4e-3)
    plan = SimpleNamespace(name="quick", studies={"work_precision": dc.replace(p, cases=["three_link"])})
    tasks = work_precision.tasks(SimpleNamespace(plan=plan, cases={"three_link": c}))
    mine = [t for t in tasks if t.method == "mujoco-chain"]
    assert [t.h for t in mine] == [2e-3, 1e-3, 2.5e-4, 6.25e-5]  # the quick path's k = 2, 4, 8, 16
    out = execute(methods.resolve("mujoco-chain"), c, mine[2])
    assert out.status == "ok", out.reason
    assert out.result.meta["h"] <= out.result.meta["h_stable"]
