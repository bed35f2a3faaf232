"""Pinocchio rigid-link baseline (reference_models.pinocchio_rigid).

References: closed-form rotor and spin-up solutions, and an independent absolute-angle
Lagrangian model of the planar chain written here in numpy.
"""

import dataclasses
import math
from pathlib import Path

import numpy as np
import pytest

pin = pytest.importorskip("pinocchio")

import _pinocchio_newmark as newmark  # noqa: E402

import dttmm  # noqa: E402
from reference_models import pinocchio_rigid as pr  # noqa: E402

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"


def run(case, h, integrator):
    """The baseline's integrators, and the tests' Newmark step (tests/_pinocchio_newmark.py,
    the reference of the rigid-limit tests) on the same arm."""
    if integrator == "newmark":
        return newmark.simulate(case, h)
    return pr.simulate(case, h=h, integrator=integrator)


class NumpyChain:
    """Planar chain of rigid links in absolute angles φ_i = Σ_{j≤i} α_j (Lagrange).

    Link i with its hub (at the root) and payload (at the tip) is one rigid body of mass M_i,
    first moment s_i and inertia I_i about its root. With β_jj = I_j + L_j² Σ_{i>j} M_i and
    β_jk = L_j s_k + L_j L_k Σ_{i>k} M_i (j < k): T = ½ Σ β_jk cos(φ_j − φ_k) φ̇_j φ̇_k and
    V = −g·Σ (M_i r_i + s_i e(φ_i)). Joint torques enter through φ = S α (S lower ones).
    """

    def __init__(self, manipulator):
        links = manipulator.links
        self.n = n = len(links)
        self.L = np.array([lk.beam.length for lk in links])
        m = np.array([lk.beam.mass for lk in links])
        mh = np.array([lk.hub_mass for lk in links])
        Jh = np.array([lk.hub_inertia for lk in links])
        mp = np.array([lk.payload_mass for lk in links])
        Jp = np.array([lk.payload_inertia for lk in links])
        L = self.L
        self.Mb = m + mh + mp
        self.s = m * L / 2 + mp * L
        I = m * L**2 / 3 + Jh + Jp + mp * L**2
        outboard = np.array([self.Mb[i + 1 :].sum() for i in range(n)])  # Σ_{i>j} M_i
        self.beta = np.empty((n, n))
        for j in range(n):
            self.beta[j, j] = I[j] + L[j] ** 2 * outboard[j]
            for k in range(j + 1, n):
                self.beta[j, k] = self.beta[k, j] = L[j] * self.s[k] + L[j] * L[k] * outboard[k]
        self.grav_lever = L * outboard + self.s  # ∂V/∂φ_j = −grav_lever_j g·e⊥(φ_j)
        self.g = np.asarray(manipulator.gravity, float)
        self.S = np.tril(np.ones((n, n)))

    def mass(self, q):
        phi = self.S @ q
        Mphi = self.beta * np.cos(phi[:, None] - phi[None, :])
        return self.S.T @ Mphi @ self.S

    def nle(self, q, v):
        phi, w = self.S @ q, self.S @ v
        quad = (self.beta * np.sin(phi[:, None] - phi[None, :])) @ (w**2)
        eperp = np.stack([-np.sin(phi), np.cos(phi)], axis=1)
        return self.S.T @ (quad - self.grav_lever * (eperp @ self.g))

    def fd(self, q, v, tau):
        return np.linalg.solve(self.mass(q), tau - self.nle(q, v))

    def energy(self, q, v):
        phi, w = self.S @ q, self.S @ v
        T = 0.5 * w @ (self.beta * np.cos(phi[:, None] - phi[None, :])) @ w
        e = np.stack([np.cos(phi), np.sin(phi)], axis=1)
        roots = np.vstack([np.zeros(2), np.cumsum(self.L[:, None] * e, axis=0)[:-1]])
        V = -self.g @ (self.Mb @ roots + self.s @ e)
        return T + V


def random_arm(rng, n):
    links = []
    for _ in range(n):
        hub = dttmm.Hub(rng.uniform(0, 0.5), rng.uniform(0, 0.05)) if rng.random() < 0.8 else None
        pay = dttmm.Payload(rng.uniform(0, 0.5), rng.uniform(0, 0.02)) if rng.random() < 0.6 else None
        links.append(dttmm.Link(dttmm.Section(rng.uniform(0.2, 1.5), 1.0, rng.uniform(0.1, 2.0)), hub, pay))
    return dttmm.Manipulator(tuple(links), tuple(rng.normal(0, 6, 2)))


def with_scenario(case, duration, output_step, drives):
    return dataclasses.replace(case, scenario=dttmm.Scenario(duration, output_step, tuple(drives)))


@pytest.mark.parametrize("n", [1, 2, 3, 6])
def test_model_matches_numpy_lagrangian(n):
    rng = np.random.default_rng(n)
    arm = random_arm(rng, n)
    model = pr.build_model(arm)
    data = model.createData()
    ref = NumpyChain(arm)
    assert model.nq == model.nv == n
    for _ in range(5):
        q, v, tau = rng.normal(0, 2, (3, n))
        M = pin.crba(model, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(M, ref.mass(q), rtol=0, atol=1e-10)
        np.testing.assert_allclose(pin.nonLinearEffects(model, data, q, v), ref.nle(q, v), rtol=0, atol=1e-10)
        np.testing.assert_allclose(
            pin.aba(model, data, q, v, tau),
            ref.fd(q, v, tau),
            rtol=0,
            atol=1e-10 * (1 + np.abs(ref.fd(q, v, tau)).max()),
        )
        assert abs(pin.computeMechanicalEnergy(model, data, q, v) - ref.energy(q, v)) < 1e-10


def rotor_angle(t, J):
    """θ(t) = ∫∫ τ/J for τ = +1 on [0, 0.5), −1 on [0.5, 1), 0 afterwards (single_link.toml)."""
    t = np.asarray(t)
    return (
        np.where(t < 0.5, 0.5 * t**2, np.where(t < 1.0, 0.125 + 0.5 * (t - 0.5) - 0.5 * (t - 0.5) ** 2, 0.25))
        / J
    )


def rotor_rate(t, J):
    t = np.asarray(t)
    return np.where(t < 0.5, t, np.where(t < 1.0, 0.5 - (t - 0.5), 0.0)) / J


@pytest.mark.parametrize("integrator", ["rk4", "newmark", "dop853"])
@pytest.mark.parametrize("h", [1e-3, 3e-3])  # 3e-3: no step end on the output grid (Hermite output)
def test_single_link_rotor_closed_form(integrator, h):
    case = dttmm.load_case(CASES / "single_link.toml")
    link = case.model.links[0]
    J = link.hub.inertia + link.beam.rhoA * link.beam.length**3 / 3
    res = run(case, h, integrator)
    np.testing.assert_allclose(res.joint_angle[:, 0], rotor_angle(res.t, J), rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.joint_rate[:, 0], rotor_rate(res.t, J), rtol=0, atol=1e-9)
    assert res.joint_angle[-1, 0] == pytest.approx(0.25 / J, abs=1e-9)
    np.testing.assert_array_equal(res.joint_torque[:, 0], [case.scenario.drives[0].torque(t) for t in res.t])
    # rigid links: tip on the link axis
    assert np.abs(res.tip_deflection).max() < 1e-14
    tip = np.stack([np.cos(res.joint_angle[:, 0]), np.sin(res.joint_angle[:, 0])], axis=1) * link.beam.length
    np.testing.assert_allclose(res.end_effector, tip, rtol=0, atol=1e-14)
    assert res.meta["method"] == "pinocchio-rigid" and res.meta["success"] is True
    assert res.meta["elements_per_link"] is None and "pinocchio" in res.meta["versions"]


def free_three_link():
    case = dttmm.load_case(CASES / "three_link.toml")
    drives = [dttmm.Drive("torque", dttmm.Constant(0.0), a) for a in (0.4, 0.9, -0.6)]
    return with_scenario(case, 1.0, 0.02, drives)


@pytest.mark.parametrize("integrator, order", [("rk4", 4), ("newmark", 2)])
def test_energy_conservation_order(integrator, order):
    case = free_three_link()
    hs = np.array([1e-2, 5e-3, 2.5e-3])
    errs = []
    for h in hs:
        res = run(case, h, integrator)
        errs.append(np.abs(res.energy - res.energy[0]).max())
    fitted = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(fitted - order) < 0.5, (errs, fitted)
    q0 = np.array([d.initial_angle for d in case.scenario.drives])
    assert res.energy[0] == pytest.approx(NumpyChain(case.model).energy(q0, np.zeros(3)), abs=1e-12)


@pytest.mark.parametrize("integrator, order", [("rk4", 4), ("newmark", 2)])
def test_three_link_convergence_order(integrator, order):
    """Against DOP853 at 1e-12 on three_link (torque jump at 1 s); h = 2e-3 and 7e-4 do not
    divide the output step, so the Hermite output is part of what converges."""
    case = dttmm.load_case(CASES / "three_link.toml")
    ref = pr.simulate(case, h=1e-3, integrator="dop853")
    hs = np.array([2e-3, 1e-3, 7e-4])
    errs = [np.abs(run(case, h, integrator).joint_angle - ref.joint_angle).max() for h in hs]
    fitted = np.polyfit(np.log(hs), np.log(errs), 1)[0]
    assert abs(fitted - order) < 0.5, (errs, fitted)


def test_three_link_kinematics():
    case = dttmm.load_case(CASES / "three_link.toml")
    res = pr.simulate(case, h=2e-3, integrator="rk4")
    L = np.array([lk.beam.length for lk in case.model.links])
    phi = np.cumsum(res.joint_angle, axis=1)
    tips = np.cumsum(L * np.stack([np.cos(phi), np.sin(phi)], axis=-1).transpose(0, 2, 1), axis=2)
    np.testing.assert_allclose(res.link_tip, tips.transpose(0, 2, 1), rtol=0, atol=1e-14)
    np.testing.assert_allclose(res.link_root[:, 1:], res.link_tip[:, :-1], rtol=0, atol=1e-14)
    np.testing.assert_array_equal(res.link_root[:, 0], 0.0)
    np.testing.assert_array_equal(res.end_effector, res.link_tip[:, -1])
    assert np.abs(res.tip_deflection).max() < 1e-14
    q = res.joint_angle[-1]
    assert res.energy[-1] == pytest.approx(NumpyChain(case.model).energy(q, res.joint_rate[-1]), abs=1e-12)


def test_spin_up_torque_is_inertia_times_acceleration():
    case = dttmm.load_case(CASES / "spin_up.toml")
    beam = case.model.links[0].beam
    J = beam.rhoA * beam.length**3 / 3
    law = case.scenario.drives[0].law
    ws, T = law.rate, law.ramp_time
    res = pr.simulate(case, h=0.05, integrator="rk4")
    t = res.t
    other = pr.simulate(case, h=0.05, integrator="dop853")  # nothing to integrate: the same
    np.testing.assert_array_equal(other.joint_torque, res.joint_torque)
    acc = np.where(t < T, ws / T * (1 - np.cos(2 * np.pi * t / T)), 0.0)
    angle = np.where(
        t < T,
        ws / T * (t**2 / 2 + (T / (2 * np.pi)) ** 2 * (np.cos(2 * np.pi * t / T) - 1)),
        ws * (t - T / 2),
    )
    np.testing.assert_allclose(res.joint_torque[:, 0], J * acc, rtol=0, atol=1e-12 * J * ws / T * 2)
    np.testing.assert_allclose(res.joint_angle[:, 0], angle, rtol=1e-13, atol=1e-13)
    assert res.joint_torque[:, 0].max() == pytest.approx(2 * J * ws / T, rel=1e-6)  # peak at T/2


def mixed_case(output_step=0.01, until=1.2):
    """Joint 1 prescribed (smooth), joint 2 torque-driven with a torque jump at ``until``."""
    arm = random_arm(np.random.default_rng(7), 2)
    drives = [
        dttmm.Drive("motion", dttmm.Sine(0.8, 0.7)),
        dttmm.Drive("torque", dttmm.Sine(0.3, 1.3, until=until), initial_angle=0.5, initial_rate=-0.2),
    ]
    return dttmm.Case(arm, dttmm.Scenario(2.0, output_step, tuple(drives)))


@pytest.mark.parametrize("integrator", ["rk4", "dop853"])
def test_mixed_drives_consistent(integrator):
    case = mixed_case()
    ref = NumpyChain(case.model)
    res = pr.simulate(case, h=2e-3, integrator=integrator)
    law = case.scenario.drives[0]
    motion = np.array([law.motion(t) for t in res.t])
    np.testing.assert_allclose(res.joint_angle[:, 0], motion[:, 0], rtol=0, atol=1e-14)
    np.testing.assert_allclose(res.joint_rate[:, 0], motion[:, 1], rtol=0, atol=1e-14)
    np.testing.assert_allclose(
        res.joint_torque[:, 1], [case.scenario.drives[1].torque(t) for t in res.t], rtol=0, atol=0
    )
    # the torque reported for the motion joint, applied in the independent model at the same
    # state, reproduces the prescribed acceleration
    for s in range(0, res.t.size, 10):
        qdd = ref.fd(res.joint_angle[s], res.joint_rate[s], res.joint_torque[s])
        assert abs(qdd[0] - motion[s, 2]) < 1e-9 * (1 + abs(motion[s, 2]))


def test_mixed_drives_torque_fed_back():
    """The motion joint's torque history, fed back as a tabulated torque drive, gives back the
    motion; the table interpolates linearly between samples Δ apart, so the mismatch is O(Δ²)."""
    errs = []
    for dt in (2e-3, 1e-3):
        case = with_scenario(mixed_case(until=math.inf), 1.0, dt, mixed_case(until=math.inf).scenario.drives)
        res = pr.simulate(case, h=dt, integrator="rk4")
        d0, d1 = case.scenario.drives
        fed = dttmm.Drive(
            "torque",
            dttmm.Table(tuple(res.t), tuple(res.joint_torque[:, 0])),
            initial_angle=d0.initial_angle,
            initial_rate=d0.initial_rate,
        )
        back = pr.simulate(with_scenario(case, 1.0, dt, [fed, d1]), h=dt, integrator="rk4")
        errs.append(np.abs(back.joint_angle - res.joint_angle).max())
    assert errs[1] < 1e-3 and 1.5 < math.log2(errs[0] / errs[1]) < 2.5, errs


def test_all_motion_drives():
    arm = random_arm(np.random.default_rng(3), 2)
    drives = [dttmm.Drive("motion", dttmm.Sine(0.5, 1.0)), dttmm.Drive("motion", dttmm.Constant(0.3))]
    case = dttmm.Case(arm, dttmm.Scenario(1.0, 0.05, tuple(drives)))
    res = pr.simulate(case, h=1e-2)
    ref = NumpyChain(arm)
    for s, t in enumerate(res.t):
        m = np.array([d.motion(t) for d in drives])
        inverse = ref.mass(m[:, 0]) @ m[:, 2] + ref.nle(m[:, 0], m[:, 1])
        np.testing.assert_allclose(res.joint_torque[s], inverse, rtol=0, atol=1e-10)


@pytest.mark.parametrize("h", [0.0, -1e-3, 3.0, math.nan])
def test_bad_step(h):
    case = dttmm.load_case(CASES / "single_link.toml")
    with pytest.raises(dttmm.InputError) as exc:
        pr.simulate(case, h=h)
    assert exc.value.field == "h"


def test_bad_integrator_and_option():
    case = dttmm.load_case(CASES / "single_link.toml")
    with pytest.raises(dttmm.InputError, match="integrator = 'euler'"):
        pr.simulate(case, h=1e-3, integrator="euler")
    with pytest.raises(dttmm.InputError, match="rtol"):
        pr.simulate(case, h=1e-3, integrator="rk4", rtol=1e-9)
    with pytest.raises(dttmm.InputError, match="max_step"):
        pr.simulate(case, h=1e-3, integrator="dop853", max_step=0.0)


@pytest.mark.parametrize("integrator", ["rk4", "dop853"])
def test_overflow_raises_simulation_error_with_partial(integrator):
    case = dttmm.load_case(CASES / "single_link.toml")
    blow = dttmm.Drive("torque", dttmm.Table((0.0, 0.5, 0.6), (0.0, 0.0, 1e308)))
    case = with_scenario(case, 1.0, 0.01, [blow])
    with pytest.raises(dttmm.SimulationError) as exc:
        pr.simulate(case, h=1e-3, integrator=integrator)
    err = exc.value
    assert 0.49 <= err.t <= 0.6
    assert err.component in ("joint 1 angle", "joint 1 rate", "state")
    part = err.partial
    assert part.meta["success"] is False
    assert 0.49 <= part.t[-1] <= err.t + 1e-9
    np.testing.assert_array_equal(part.joint_angle[part.t <= 0.5], 0.0)  # no torque before 0.5 s


def test_elements_per_link_is_ignored():
    case = dttmm.load_case(CASES / "single_link.toml")
    a = pr.simulate(case, h=5e-3, elements_per_link=8)
    b = pr.simulate(case, h=5e-3)
    np.testing.assert_array_equal(a.joint_angle, b.joint_angle)
