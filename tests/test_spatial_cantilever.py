"""A clamped spatial beam against closed forms (EIy ≠ EIz, so the two bending families differ).

Statics by Newton's method on the forward dynamics, q̈(q, 0) = 0 (the Jacobian by finite
differences of the acceleration solver); frequencies from the linearisation of the acceleration
solver at rest, ∂q̈/∂q = −M⁻¹K. Cubic Hermite bending elements with consistent loads are nodally
exact for a tip force and for a uniform load, and the linear twist element for a tip torque, so
the static tolerances are those of the geometric nonlinearity at the tiny loads used
((δ/L)² ≈ 1e-10, asserted ≤ 1e-8). Frequencies: the Hermite bending element with consistent mass
overestimates by ≈ (βl)⁴/1440 (measured 1.3e-7, 5.1e-6, 4.0e-5 for the first three at k = 16;
asserted positive and within 1.1× that); the linear twist element with consistent mass
overestimates by ≈ (ωl/c)²/24 = ((2n−1)π/2k)²/24, asserted within twice that.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dttmm import Scenario
from dttmm.spatial import (
    SpatialCase,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    SpatialPayload,
    accelerations,
    load_case,
    simulate,
)
from dttmm.spatial.build import build_model

#: the beam of experiments/cases/spatial/cantilever_3d.toml
BEAM = (
    load_case(Path(__file__).resolve().parent.parent / "experiments/cases/spatial/cantilever_3d.toml")
    .model.links[0]
    .beam
)
L = BEAM.length
G = 9.81
K = 16


def case(gravity=(0.0, 0.0, 0.0), payload=None, beam=BEAM):
    link = SpatialLink(beam, SpatialJoint(locked=True), None, payload)
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.5, ()))


def statics(c, k=K, forces=None):
    """q with q̈(q, 0) = 0, by Newton's method."""
    md = build_model(c.model, k)
    n = md.ndof
    q = np.zeros(n)
    z = np.zeros(n)
    f = lambda x: accelerations(c, k, x, z, forces=forces)
    a0 = np.abs(f(q)).max()
    for _ in range(4):
        a = f(q)
        eps = 1e-7
        J = np.column_stack([(f(q + eps * np.eye(n)[j]) - a) / eps for j in range(n)])
        q = q - np.linalg.solve(J, a)
    assert np.abs(f(q)).max() <= 1e-9 * a0
    return q, md


def tip_state(c, q, k=K):
    """(tip deflections y, z; twist) at q from the kernel's outputs (a one-sample run)."""
    from dttmm.spatial.build import make_work
    from dttmm.spatial.kernel import core
    from dttmm.spatial.rotation import log_so3

    md = build_model(c.model, k)
    ws = make_work(md)
    core.kinematics(md, ws, q, np.zeros(md.ndof))
    d = ws.pT[1] - ws.pw[0]
    R0 = ws.Rw[0] @ md.Q[0].T
    return d @ R0[:, 1], d @ R0[:, 2], log_so3(R0.T @ ws.RT[1])[0]


@pytest.mark.parametrize("axis", ["y", "z"])
def test_static_tip_load_and_self_weight(axis):
    ei = BEAM.EIz if axis == "y" else BEAM.EIy
    g = np.zeros(3)
    g[1 if axis == "y" else 2] = -G * 1e-4  # tiny loads: linear statics
    gl = float(-g.min())
    mp = 1.5
    # self-weight alone: ρA g L⁴ / 8EI
    c = case(tuple(g))
    q, _ = statics(c)
    dy, dz, _ = tip_state(c, q)
    d = dy if axis == "y" else dz
    ref = -BEAM.rhoA * gl * L**4 / (8 * ei)
    assert abs(d - ref) <= 1e-8 * abs(ref)
    assert abs(dz if axis == "y" else dy) <= 1e-12 * abs(ref)
    # plus a tip payload: F L³/3EI by superposition
    c = case(tuple(g), SpatialPayload(mp))
    q, md = statics(c)
    dy, dz, tw = tip_state(c, q)
    d = dy if axis == "y" else dz
    ref = -mp * gl * L**3 / (3 * ei) - BEAM.rhoA * gl * L**4 / (8 * ei)
    assert abs(d - ref) <= 1e-8 * abs(ref)
    assert abs(tw) <= 1e-12
    # the root cut carries the weight and its moment
    _, _, loads = accelerations(c, K, q, np.zeros(md.ndof), loads=True)
    m = BEAM.rhoA * L + mp
    assert np.allclose(loads[0, :3], -m * g, rtol=1e-9, atol=1e-10 * m * gl)
    arm = np.array([(BEAM.rhoA * L * L / 2 + mp * L) / m, 0.0, 0.0])
    assert np.allclose(loads[0, 3:], -np.cross(arm, m * g), rtol=1e-6, atol=1e-9 * m * gl * L)
    # and the tip cut the payload's weight
    assert np.allclose(loads[K, :3], -mp * g, rtol=1e-9, atol=1e-10 * m * gl)


def test_static_tip_torque_twists_by_TL_over_GJ():
    c = case()
    md = build_model(c.model, K)
    T = 1e-4
    f = np.zeros(md.ndof)
    # a tip torque about the (nearly straight) axis does the virtual work T Σ_j δφx_j
    f[md.ie + 3] = T
    q, _ = statics(c, forces=f)
    dy, dz, tw = tip_state(c, q)
    ref = T * L / BEAM.GJ
    assert abs(tw - ref) <= 1e-8 * ref
    assert max(abs(dy), abs(dz)) <= 1e-12


def _families(c, k):
    md = build_model(c.model, k)
    n = md.ndof
    z = np.zeros(n)
    eps = 1e-7
    A = np.column_stack([accelerations(c, k, eps * np.eye(n)[j], z) / eps for j in range(n)])
    lam, vec = np.linalg.eig(-A)
    fam = {"y": [], "z": [], "x": [], "u": []}
    for i in range(n):
        v = np.abs(vec[:, i].real).reshape(k, 6)
        share = {
            "u": v[:, 0].sum(),
            "y": v[:, 1].sum() / L + v[:, 5].sum(),
            "z": v[:, 2].sum() / L + v[:, 4].sum(),
            "x": v[:, 3].sum(),
        }
        fam[max(share, key=share.get)].append(np.sqrt(lam[i].real))
    return {f: np.sort(np.array(w)) for f, w in fam.items()}


def test_natural_frequencies_of_both_bending_families_and_torsion():
    c = case()
    w = _families(c, K)
    beta = np.array([1.8751040687, 4.6940911330, 7.8547574382])
    for fam, ei in (("y", BEAM.EIz), ("z", BEAM.EIy)):
        ref = beta**2 * np.sqrt(ei / (BEAM.rhoA * L**4))
        err = w[fam][:3] / ref - 1
        # the Hermite element with consistent mass overestimates by ≈ (βl)⁴/1440
        bound = (beta / K) ** 4 / 1440
        assert np.all(err > 0) and np.all(err <= 1.1 * bound), (fam, err, bound)
    n = np.arange(1, 4)
    ref = (2 * n - 1) * np.pi / 2 * np.sqrt(BEAM.GJ / (BEAM.rhoJ * L**2))
    err = w["x"][:3] / ref - 1
    bound = ((2 * n - 1) * np.pi / (2 * K)) ** 2 / 24
    assert np.all(err > 0) and np.all(err <= 2 * bound), (err, bound)
    # axial: (2n−1)π/2 √(EA/ρA L²) with the same linear-element bound
    ref = (2 * n - 1) * np.pi / 2 * np.sqrt(BEAM.EA / (BEAM.rhoA * L**2))
    err = w["u"][:3] / ref - 1
    assert np.all(err > 0) and np.all(err <= 2 * bound)


def test_free_vibration_run_is_bounded_and_keeps_its_energy():
    """A short undamped run of the pre-bent beam under gravity (Newmark): energy to 1e-9."""
    c = case((0.0, -G, 0.0))
    res = simulate(c, elements_per_link=4, h=2e-4, cut_loads=False)
    e = res.energy
    assert np.isfinite(e).all()
    scale = BEAM.rhoA * L * G * L
    assert np.abs(e - e[0]).max() <= 1e-6 * scale
    assert res.end_effector.shape == (res.t.size, 3)
