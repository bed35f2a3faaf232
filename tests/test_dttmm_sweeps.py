"""Plain (paper) vs Riccati sweep: constant 3×3 final system, agreement where the plain sweep is
well conditioned, and its measured loss of accuracy as the mesh is refined."""

import itertools

import numpy as np
import pytest
from conftest import case, shortened

import dttmm
from dttmm import Case, Drive, Hub, Link, Manipulator, Payload, Scenario, Section, Sine
from dttmm.kernel.driver import drive_values
from dttmm.structure import build_structure, kinematics
from dttmm.sweeps import SWEEPS


def chain(n, *, extensible=True, motion_joint=None):
    """n equal aluminium-strip links, hubs, payload, gravity; joint `motion_joint` is motion-driven."""
    sec = Section(0.5, 2.3333, 0.27, 7e6 if extensible else None)
    links = tuple(
        Link(sec, Hub(0.1 if i else 0.0, 0.005), Payload(0.1, 1e-4) if i == n - 1 else None) for i in range(n)
    )
    drives = tuple(
        Drive("motion", Sine(0.3, 1.0)) if i == motion_joint else Drive("torque", Sine(0.5 / (i + 1), 1.0))
        for i in range(n)
    )
    return Case(Manipulator(links, (0.0, -9.81)), Scenario(0.1, 1e-3, drives))


def step_systems(c, k, seed=0, h=1e-3):
    """The same frozen step system for both sweeps at a random state."""
    rng = np.random.default_rng(seed)
    st = build_structure(c, k)
    q = rng.normal(size=st.n_dof) * 0.02
    qd = rng.normal(size=st.n_dof) * 0.2
    split = lambda x: [x[lk.e_slice].reshape(lk.k, lk.et.ne) for lk in st.links]
    tau, mot = drive_values(st, 0.3)
    kin = kinematics(st, q, qd)
    out = {
        sw: SWEEPS[sw](st, kin, 0.25 * h * h, 0.5 * h, split(q), split(qd), tau, mot[:, 2])
        for sw in ("riccati", "plain")
    }
    return out["riccati"], out["plain"]


@pytest.mark.parametrize("n", [1, 2, 3, 5])
@pytest.mark.parametrize("k", [1, 4, 32])
def test_plain_final_system_is_3x3(n, k):
    c = chain(n, motion_joint=1 if n > 2 else None)
    _, p = step_systems(c, k)
    assert p.final_system.shape == (3, 3)


@pytest.mark.parametrize("n, k", [(1, 1), (1, 2), (2, 1), (3, 1), (5, 1)])
def test_plain_equals_riccati_where_well_conditioned(n, k):
    c = chain(n, extensible=False, motion_joint=1 if n > 2 else None)
    r, p = step_systems(c, k)
    assert p.cond < 1e3
    scale = np.max(np.abs(r.qdd))
    assert np.max(np.abs(r.qdd - p.qdd)) <= 1e-10 * scale
    np.testing.assert_allclose(p.torque, r.torque, rtol=1e-10)
    np.testing.assert_allclose(p.loads, r.loads, atol=1e-10 * np.max(np.abs(r.loads)))


def test_plain_accuracy_degrades_with_k_and_is_recorded():
    """The plain sweep's final system grows ill-conditioned exponentially in k (the implicit
    step operator is a beam on an elastic foundation); its error vs Riccati follows."""
    c = case("single_link")
    conds, errs = [], []
    for k in (1, 2, 4, 8):
        r, p = step_systems(c, k)
        conds.append(p.cond)
        errs.append(np.max(np.abs(r.qdd - p.qdd)) / np.max(np.abs(r.qdd)))
    assert all(b > 5 * a for a, b in itertools.pairwise(conds))  # grows fast with k
    assert errs[0] < 1e-12 and errs[-1] > 1e3 * errs[0]
    # and a simulation records it
    res = dttmm.simulate(shortened(c, 0.01), elements_per_link=4, h=1e-3, sweep="plain")
    assert res.meta["final_system_cond"] > 1e5


def test_plain_simulation_equals_riccati_at_k1():
    c = shortened(case("three_link"), 0.05)
    a = dttmm.simulate(c, elements_per_link=1, h=1e-3)
    b = dttmm.simulate(c, elements_per_link=1, h=1e-3, sweep="plain")
    np.testing.assert_allclose(b.joint_angle, a.joint_angle, rtol=0, atol=1e-10)
    np.testing.assert_allclose(b.tip_deflection, a.tip_deflection, rtol=0, atol=1e-10)


def test_plain_breakdown_is_reported_not_hidden():
    """At k = 16 on three links the plain sweep cannot be solved: a clear SimulationError."""
    c = shortened(case("three_link"), 0.01)
    with pytest.raises(dttmm.SimulationError) as exc:
        dttmm.simulate(c, elements_per_link=16, h=1e-3, sweep="plain")
    assert exc.value.partial is not None and exc.value.t >= 0.0
    assert "step system" in str(exc.value)
