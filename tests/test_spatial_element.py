"""The spatial element and the one-step dynamics (docs/spatial.md §2-3).

* the element mass matrix of the 4-point Gauss bodies: symmetric positive definite, and at
  rest the consistent 3-D beam mass (closed forms of the Hermite / linear elements);
* the rotation helpers of the kernel against finite differences of the SO(3) exponential;
* the Riccati sweep's forward dynamics against Lagrange's equations assembled by finite
  differences from the kernel's energy (a separate code path: T, V and U summed body by body)
  on a 3-D arm with joint origins, roll, rotary inertia, a payload off the axis, full hub
  inertias, a locked joint, an inextensible link and a motion-driven joint;
* a cantilever at rest without gravity stays at rest; the cut loads at the root of a clamped
  beam under gravity equal its weight.
"""

from __future__ import annotations

import numpy as np
import pytest

from dttmm import Constant, Drive, Scenario, Sine
from dttmm.errors import InputError
from dttmm.spatial import (
    SpatialCase,
    SpatialHub,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    SpatialSection,
    accelerations,
    exp_so3,
    left_jacobian,
)
from dttmm.spatial.build import build_model, make_work
from dttmm.spatial.element import element_mass
from dttmm.spatial.kernel import core

BEAM = SpatialSection(
    length=0.8, EA=3.0e6, GJ=9.0, EIy=14.0, EIz=5.0, rhoA=0.9, rhoJ=2e-4, rhoIy=1.5e-4, rhoIz=0.5e-4
)


def test_element_mass_is_symmetric_positive_definite_and_consistent_at_rest():
    l = 0.2
    b = BEAM
    rng = np.random.default_rng(3)
    for e in (np.zeros(6), rng.normal(size=6) * np.array([1e-3, 2e-2, 2e-2, 0.1, 0.1, 0.1])):
        M = element_mass(b, l, e)
        assert np.allclose(M, M.T, rtol=0, atol=1e-15 * np.abs(M).max())
        assert np.linalg.eigvalsh(M).min() > 0.0
    M = element_mass(b, l, np.zeros(6))
    m = b.rhoA * l
    Mee = M[6:, 6:]
    ref = np.zeros((6, 6))
    ref[0, 0] = m / 3  # u: linear axial shape
    ref[3, 3] = b.rhoJ * l / 3  # φx: linear twist
    tz = m / 420 * np.array([[156, -22 * l], [-22 * l, 4 * l * l]])
    rz = b.rhoIz / (30 * l) * np.array([[36, -3 * l], [-3 * l, 4 * l * l]])
    ty = m / 420 * np.array([[156, 22 * l], [22 * l, 4 * l * l]])
    ry = b.rhoIy / (30 * l) * np.array([[36, 3 * l], [3 * l, 4 * l * l]])
    ref[np.ix_([1, 5], [1, 5])] = tz + rz
    ref[np.ix_([2, 4], [2, 4])] = ty + ry
    assert np.allclose(Mee, ref, rtol=1e-13, atol=1e-16)
    # rigid block: mass, first moment about the origin, inertia about the origin
    assert np.allclose(M[:3, :3], m * np.eye(3), rtol=1e-14)
    c = np.array([l / 2, 0, 0])
    from dttmm.spatial import hat

    assert np.allclose(M[:3, 3:6], -m * hat(c), rtol=1e-13, atol=1e-16)
    J = np.diag([b.rhoJ * l, m * l * l / 3 + b.rhoIy * l, m * l * l / 3 + b.rhoIz * l])
    assert np.allclose(M[3:6, 3:6], J, rtol=1e-13, atol=1e-18)


def test_rotation_helpers_match_finite_differences():
    rng = np.random.default_rng(5)
    for scale in (1e-4, 0.3, 2.5):
        psi = rng.normal(size=3) * scale
        psid = rng.normal(size=3)
        E, J, jd = core.exp_jl(psi, psid)
        assert np.allclose(E, exp_so3(psi), atol=1e-15)
        assert np.allclose(J, left_jacobian(psi), atol=1e-15)
        d = 1e-6
        Ed = (exp_so3(psi + d * psid) - exp_so3(psi - d * psid)) / (2 * d)
        W = Ed @ E.T
        w = np.array([W[2, 1], W[0, 2], W[1, 0]])
        assert np.allclose(w, J @ psid, atol=1e-8)
        Jd = (left_jacobian(psi + d * psid) - left_jacobian(psi - d * psid)) / (2 * d)
        assert np.allclose(jd, Jd @ psid, atol=1e-7)
        assert np.allclose(E @ E.T, np.eye(3), atol=1e-15)


def arm(strain_ext=True):
    """A 3-D arm: joint about z, about a tilted y with an offset and a rolled section, a locked
    third link; rotary inertia, full hub inertias, a payload off the axis, 3-D gravity."""
    b1 = SpatialSection(
        length=0.6,
        EA=2e5 if strain_ext else None,
        GJ=3.0,
        EIy=6.0,
        EIz=4.0,
        rhoA=1.2,
        rhoJ=3e-3,
        rhoIy=2e-3,
        rhoIz=1e-3,
    )
    b2 = SpatialSection(
        length=0.5, GJ=2.0, EIy=3.0, EIz=5.0, rhoA=0.8, rhoJ=2e-3, rhoIy=1e-3, rhoIz=2e-3, roll=0.3
    )
    b3 = SpatialSection(length=0.3, EA=1e5, GJ=1.0, EIy=2.0, EIz=2.5, rhoA=0.5, rhoJ=1e-3, roll=-0.2)
    hub = SpatialHub(0.3, ((2e-3, 1e-4, 0.0), (1e-4, 3e-3, 2e-4), (0.0, 2e-4, 4e-3)))
    pay = SpatialPayload(0.4, (0.03, -0.02, 0.05), ((1e-3, 0, 1e-4), (0, 2e-3, 0), (1e-4, 0, 1.5e-3)))
    links = (
        SpatialLink(b1, SpatialJoint(origin_rpy=(0.1, -0.2, 0.3)), hub),
        SpatialLink(
            b2,
            SpatialJoint(axis=(0.0, 0.6, 0.8), origin_xyz=(0.02, 0.01, -0.03), origin_rpy=(0.4, 0.1, -0.3)),
            hub,
        ),
        SpatialLink(b3, SpatialJoint(origin_rpy=(0.2, 0.5, 0.0), locked=True), None, pay),
    )
    return SpatialManipulator(
        links, gravity=(0.5, -9.81, 1.2), base_xyz=(0.1, 0.2, 0.3), base_rpy=(0.2, -0.1, 0.4)
    )


def _lagrange(md, q, qd, Q, motion_index=None, motion_acc=None):
    """q̈ from Lagrange's equations with M, Ṁq̇, ∂T/∂q and ∂V/∂q by finite differences of the
    kernel's energy; with a motion-driven coordinate its row is replaced by q̈ = given, and the
    joint torque it needs is returned."""
    ws = make_work(md)
    n = q.size

    def E(qq, vv):
        core.kinematics(md, ws, qq, vv)
        return core.energy(md, ws)

    def T(qq, vv):
        return E(qq, vv) - E(qq, np.zeros(n))

    def mass(qq):
        M = np.empty((n, n))
        Ti = np.array([T(qq, np.eye(n)[i]) for i in range(n)])
        for i in range(n):
            for j in range(i, n):
                M[i, j] = M[j, i] = (
                    T(qq, np.eye(n)[i] + np.eye(n)[j]) - Ti[i] - Ti[j] if i != j else 2 * Ti[i]
                )
        return M

    M = mass(q)
    eps = 1e-6
    Mdq = (mass(q + eps * qd) @ qd - mass(q - eps * qd) @ qd) / (2 * eps)
    dT = np.empty(n)
    dV = np.empty(n)
    for k in range(n):
        d = np.zeros(n)
        d[k] = eps
        dT[k] = (T(q + d, qd) - T(q - d, qd)) / (2 * eps)
        dV[k] = (E(q + d, np.zeros(n)) - E(q - d, np.zeros(n))) / (2 * eps)
    rhs = Q - Mdq + dT - dV
    if motion_index is None:
        return np.linalg.solve(M, rhs), None
    A = M.copy()
    b = rhs.copy()
    A[motion_index] = 0.0
    A[motion_index, motion_index] = 1.0
    b[motion_index] = motion_acc
    qdd = np.linalg.solve(A, b)
    tau = M[motion_index] @ qdd - rhs[motion_index]
    return qdd, tau


def _state(md, rng):
    q = np.zeros(md.ndof)
    qd = np.zeros(md.ndof)
    for i in range(md.n):
        ne = 6 if md.ext[i] else 5
        scale = np.array([1e-3, 0.02, 0.02, 0.05, 0.05, 0.05])[6 - ne :]
        for j in range(md.k[i]):
            r = md.ie[md.el0[i] + j]
            q[r : r + ne] = rng.normal(size=ne) * scale * np.where(np.arange(6 - ne, 6) < 3, md.l[i], 1.0)
            qd[r : r + ne] = rng.normal(size=ne) * scale * 5
        if md.ia[i] >= 0:
            q[md.ia[i]] = rng.uniform(-3, 3)
            qd[md.ia[i]] = rng.normal()
    return q, qd


@pytest.mark.parametrize("strain", ["linear", "second-order"])
def test_forward_dynamics_matches_lagrange_equations(strain):
    manip = arm()
    sc = Scenario(1.0, 0.1, (Drive("torque", Constant(0.7)), Drive("torque", Constant(-0.3))))
    case = SpatialCase(manip, sc)
    md = build_model(manip, 2, strain, np.zeros(3, np.int64))
    rng = np.random.default_rng(11)
    q, qd = _state(md, rng)
    Q = np.zeros(md.ndof)
    Q[md.ia[0]], Q[md.ia[1]] = 0.7, -0.3
    ref, _ = _lagrange(md, q, qd, Q)
    qdd = accelerations(case, 2, q, qd, strain=strain)
    scale = np.abs(ref).max()
    assert np.abs(qdd - ref).max() <= 1e-6 * scale
    # generalized forces on the coordinates enter as Qᵀδq
    f = rng.normal(size=md.ndof) * 0.1
    ref_f, _ = _lagrange(md, q, qd, Q + f)
    assert np.abs(accelerations(case, 2, q, qd, strain=strain, forces=f) - ref_f).max() <= 1e-6 * scale


def test_motion_joint_acceleration_and_torque_match_lagrange():
    manip = arm(strain_ext=False)
    law = Sine(amplitude=0.4, frequency=1.3)
    sc = Scenario(1.0, 0.1, (Drive("torque", Constant(0.2)), Drive("motion", law)))
    case = SpatialCase(manip, sc)
    md = build_model(manip, 2, "linear", np.array([0, 1, 0]))
    rng = np.random.default_rng(2)
    q, qd = _state(md, rng)
    t = 0.37
    a, ad, add = law.motion(t)
    q[md.ia[1]], qd[md.ia[1]] = a, ad
    Q = np.zeros(md.ndof)
    Q[md.ia[0]] = 0.2
    ref, tau = _lagrange(md, q, qd, Q, md.ia[1], add)
    qdd, torque, _ = accelerations(case, 2, q, qd, t, loads=True)
    assert np.abs(qdd - ref).max() <= 1e-6 * np.abs(ref).max()
    assert qdd[md.ia[1]] == add
    assert abs(torque[1] - tau) <= 1e-6 * max(1.0, abs(tau))


def _clamped(beam, gravity=(0.0, 0.0, 0.0), payload=None):
    link = SpatialLink(beam, SpatialJoint(locked=True), None, payload)
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.1, ()))


def test_cantilever_at_rest_without_gravity_stays_at_rest():
    for beam in (BEAM, SpatialSection(length=1.0, GJ=1.0, EIy=2.0, EIz=3.0, rhoA=1.0, rhoJ=1e-3, roll=0.4)):
        case = _clamped(beam)
        md = build_model(case.model, 4)
        z = np.zeros(md.ndof)
        assert np.abs(accelerations(case, 4, z, z)).max() == 0.0


def test_bad_input_is_refused_naming_the_field():
    case = _clamped(BEAM)
    with pytest.raises(InputError, match="q/qd"):
        accelerations(case, 2, np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="elements_per_link"):
        accelerations(case, 0, np.zeros(3), np.zeros(3))
    with pytest.raises(InputError, match="strain"):
        accelerations(case, 2, np.zeros(3), np.zeros(3), strain="cubic")
    with pytest.raises(InputError, match=r"joint\.axis"):
        SpatialJoint(axis=(1.0, 1.0, 0.0))
    with pytest.raises(InputError, match=r"model\.links\[1\]\.joint\.axis"):
        SpatialJoint(axis=(0.0, 0.0, float("nan")), _where="model.links[1].joint")
    with pytest.raises(InputError, match=r"hub\.inertia"):
        SpatialHub(1.0, (1.0, -1.0, 1.0))
    with pytest.raises(InputError, match=r"scenario\.drives"):
        SpatialCase(case.model, Scenario(1.0, 0.1, (Drive("torque", Constant(0.0)),)))
