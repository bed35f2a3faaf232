"""Rung (c), energy: a yaw + pitch + pitch arm with gravity, hubs and a payload off the axis.

* Undamped free motion (zero torques, initial rates): the energy is conserved to the order of
  the integrator — Newmark (trapezoidal) drifts as O(h²) (measured |ΔE|/E₀ = 5.1e-5, 1.3e-5,
  3.5e-6 at h = 1e-3, 5e-4, 2.5e-4 over 0.5 s; asserted ≤ 1e-4 at 1e-3 and a ratio 3…5 per
  halving), RK4 as O(h⁴) (measured 4e-11 relative at h = 4e-5 over 0.1 s; asserted ≤ 1e-9).
* Every joint turned through several full turns by motion drives (spin-up to 2π, 2.5π and 3π
  rad/s, 2.2 to 3.5 turns): no singularity at any angle (the orientations are rebuilt from the joint angles), and
  the energy balance E(t) − E(0) = ∫ Σ τ α̇ dt holds (trapezoidal quadrature of the drives'
  power on the step grid, error O(h²): measured 2.5e-5 and 6.9e-6 of the energy turned over,
  ∫|Σ τ α̇| dt, at h = 1e-3 and 5e-4; asserted ≤ 5e-5 at 5e-4).
"""

from __future__ import annotations

import numpy as np
import pytest

from dttmm import Constant, Drive, Scenario, SpinUp
from dttmm.spatial import (
    SpatialCase,
    SpatialHub,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialSection,
    simulate,
)


def yaw_pitch_pitch(stiffness=1.0):
    def beam(L):
        s = stiffness
        return SpatialSection(
            length=L, GJ=40.0 * s, EIy=60.0 * s, EIz=40.0 * s, rhoA=1.0, rhoJ=1e-3, rhoIy=5e-4, rhoIz=5e-4
        )

    hub = SpatialHub(0.5, (2e-3, 2e-3, 3e-3))
    pay = SpatialPayload(0.4, (0.05, 0.0, 0.02), (1e-3, 2e-3, 2e-3))
    links = (
        SpatialLink(beam(0.6), SpatialJoint(axis=(0.0, 0.0, 1.0)), hub),
        SpatialLink(beam(0.5), SpatialJoint(axis=(0.0, 1.0, 0.0)), hub),
        SpatialLink(beam(0.4), SpatialJoint(axis=(0.0, 1.0, 0.0), origin_rpy=(0.0, 0.3, 0.0)), hub, pay),
    )
    return SpatialManipulator(links, gravity=(0.0, 0.0, -9.81))


def free_case(duration):
    drives = tuple(
        Drive("torque", Constant(0.0), initial_angle=a, initial_rate=r)
        for a, r in [(0.0, 2.0), (0.5, 3.0), (-0.3, 4.0)]
    )
    return SpatialCase(yaw_pitch_pitch(), Scenario(duration, 0.01, drives))


def drift(case, h, integrator):
    r = simulate(case, elements_per_link=2, h=h, integrator=integrator)
    assert r.status == "ok"
    assert np.isfinite(r.energy).all()
    return np.abs(r.energy - r.energy[0]).max() / r.energy[0]


def test_newmark_conserves_energy_to_second_order():
    case = free_case(0.5)
    d = [drift(case, h, "newmark") for h in (1e-3, 5e-4)]
    assert d[0] <= 1e-4
    assert 3.0 <= d[0] / d[1] <= 5.0, d


def test_rk4_conserves_energy_to_fourth_order():
    assert drift(free_case(0.1), 4e-5, "rk4") <= 1e-9


@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
def test_several_full_turns_of_every_joint_without_singularity(integrator):
    rates = (2 * np.pi, 2.5 * np.pi, 3 * np.pi)
    drives = tuple(Drive("motion", SpinUp(w, 0.5)) for w in rates)
    h = 5e-4
    case = SpatialCase(yaw_pitch_pitch(100.0), Scenario(2.5, h, drives))
    r = simulate(case, elements_per_link=2, h=h, integrator=integrator)
    assert r.status == "ok"
    for arr in (r.joint_angle, r.end_effector, r.tip_deflection, r.twist, r.energy, r.joint_torque):
        assert np.isfinite(arr).all()
    turns = (r.joint_angle[-1] - r.joint_angle[0]) / (2 * np.pi)
    assert np.all(turns >= 2.2), turns
    # the motion is that of the laws
    for j, d in enumerate(drives):
        assert np.allclose(r.joint_angle[:, j], [d.motion(t)[0] for t in r.t], rtol=0, atol=1e-12)
    # the links stay elastic (small deflections) and the energy balance holds
    assert np.abs(r.tip_deflection).max() < 0.02
    power = np.sum(r.joint_torque * r.joint_rate, axis=1)
    work = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(r.t))])
    turned = np.abs(power).sum() * h
    if integrator == "newmark":
        assert np.abs(r.energy - r.energy[0] - work).max() <= 5e-5 * turned
