"""Linearisation and natural modes of spatial arms (dttmm.linearize / modes / frequencies on a
spatial case; docs/modes.md "Spatial arms").

Closed forms of the clamped 3-D cantilever (EIy ≠ EIz, torsion GJ): the cubic Hermite bending
element with consistent mass overestimates a frequency by ≈ (β_n l)⁴/1440 (l = L/k), so at
k = 16 the first three bending frequencies of each plane must lie above the closed form and
within 1.1× that bound (1.31e-7, 5.11e-6, 3.98e-5); the linear torsion element with consistent
mass overestimates by ≈ ((2n − 1)π/2k)²/24 (4.02e-4, 3.62e-3, 1.01e-2), asserted within 2× of
it. A planar arm made spatial has the planar M, K and frequencies in its in-plane block.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm import Constant, Drive, InputError, Scenario
from dttmm.spatial import (
    SpatialCase,
    SpatialJoint,
    SpatialLink,
    SpatialManipulator,
    embed_planar,
    load_case,
)
from dttmm.spatial.linear import equilibrium

ROOT = Path(__file__).resolve().parent.parent
SPATIAL = ROOT / "experiments/cases/spatial"
BEAM = load_case(SPATIAL / "cantilever_3d.toml").model.links[0].beam
L = BEAM.length
BETA = np.array([1.8751040687, 4.6940911330, 7.8547574382])


def cantilever(beam=BEAM, gravity=(0.0, 0.0, 0.0)) -> SpatialCase:
    link = SpatialLink(beam, SpatialJoint(locked=True))
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.5, ()))


def families(m) -> dict:
    """Frequencies (Hz) sorted into bending along y, bending along z and torsion by the largest
    of each mode's node deflections (per unit length) and twists."""
    out = {"y": [], "z": [], "x": []}
    for i, f in enumerate(m.frequencies):
        d, tw = m.deflections[0][i], m.twists[0][i]
        share = {"y": np.abs(d[:, 0]).max() / L, "z": np.abs(d[:, 1]).max() / L, "x": np.abs(tw).max()}
        out[max(share, key=share.get)].append(f)
    return {k: np.array(v) for k, v in out.items()}


def test_cantilever_both_bending_families_and_torsion_against_closed_forms():
    k = 16
    m = dttmm.modes(cantilever(), k, n=12)
    fam = families(m)
    for name, ei in (("y", BEAM.EIz), ("z", BEAM.EIy)):
        exact = BETA**2 * np.sqrt(ei / (BEAM.rhoA * L**4)) / (2 * np.pi)
        err = fam[name][:3] / exact - 1
        bound = (BETA / k) ** 4 / 1440
        assert np.all(err > 0) and np.all(err <= 1.1 * bound), (name, err, bound)
    n = np.arange(1, 4)
    exact = (2 * n - 1) * np.pi / (2 * L) * np.sqrt(BEAM.GJ / BEAM.rhoJ) / (2 * np.pi)
    err = fam["x"][:3] / exact - 1
    bound = ((2 * n - 1) * np.pi / (2 * k)) ** 2 / 24
    assert np.all(err > 0) and np.all(err <= 2 * bound), (err, bound)
    # the frequencies call gives the same numbers, and the modes' record is complete
    np.testing.assert_array_equal(dttmm.frequencies(cantilever(), k, n=12), m.frequencies)
    assert m.shapes.shape == (m.linearization.n_free, 12) and m.damping_ratios is None
    assert m.linearization.coordinates[:2] == ("link 1, element 1, u", "link 1, element 1, v")


def test_bending_converges_at_fourth_order_in_both_planes():
    ks = np.array([4, 8, 16])
    errs = {"y": [], "z": []}
    for k in ks:
        fam = families(dttmm.modes(cantilever(), int(k), n=6))
        for name, ei in (("y", BEAM.EIz), ("z", BEAM.EIy)):
            exact = BETA[1] ** 2 * np.sqrt(ei / (BEAM.rhoA * L**4)) / (2 * np.pi)
            errs[name].append(fam[name][1] / exact - 1)
    for name in errs:
        order = -np.polyfit(np.log(ks), np.log(errs[name]), 1)[0]
        assert 3.7 < order < 4.3, (name, order)


def test_rest_matrices_are_the_consistent_elastic_ones():
    """At rest without gravity: K = the elastic stiffness (block diagonal over the elements,
    measured 2.3e-12 of its largest entry at k = 32), D = 0, M SPD."""
    import scipy.linalg

    from dttmm.spatial.build import stiffness

    k = 32
    lin = dttmm.linearize(cantilever(), k)
    Ke = scipy.linalg.block_diag(*[stiffness(BEAM, L / k)] * k)
    assert np.abs(lin.K - Ke).max() <= 1e-10 * np.abs(Ke).max()
    assert np.abs(lin.D).max() <= 1e-9 * np.sqrt(np.abs(lin.K).max() * np.abs(lin.M).max())
    assert np.all(np.linalg.eigvalsh(lin.M) > 0)
    assert lin.B.shape == (lin.n_free, 0) and lin.torque_joints == ()


def test_mass_matrix_equals_the_global_solvers():
    """M of three_joint_arm (k = 2) = the spatial global solver's M(q), assembled independently,
    at rest and at a deformed moving state (measured 1.0e-12 and 3.1e-11 of the largest entry;
    cond(M) ≈ 2e5)."""
    sg = pytest.importorskip("reference_models.spatial_global")
    case = load_case(SPATIAL / "three_joint_arm.toml")
    k = 2
    names = sg.coordinate_names(case, k)
    rng = np.random.default_rng(0)
    q = rng.normal(scale=1e-4, size=len(names))
    q[[0, 1 + 6 * k, 2 + 12 * k]] = rng.normal(size=3)
    qd = rng.normal(scale=0.5, size=len(names))
    for state, tol in ((None, 1e-11), ((q, qd), 1e-9)):
        lin = dttmm.linearize(case, k, state=state)
        M = sg.mass_matrix(case, k, lin.q)
        assert np.abs(lin.M - M).max() <= tol * np.abs(M).max()


def _in_plane(names) -> np.ndarray:
    """Indices of the in-plane coordinates (joint angles, u, v, φz) among ``names``."""
    keep = ("angle", ", u", ", v", ", phiz")
    return np.array([i for i, s in enumerate(names) if s.endswith(keep)])


@pytest.mark.parametrize("name", ["three_link.toml", "benchmarks/deluca_link2_clamped.toml"])
def test_planar_arm_made_spatial_has_the_planar_modes(name):
    """The in-plane block of the spatial M and K = the planar ones (three_link: gravity, at
    rest, so K holds the gravity terms too; tilted plane), no coupling to the out-of-plane
    block, and the in-plane frequencies = the planar dttmm.modes."""
    case = dttmm.load_case(ROOT / "experiments/cases" / name)
    k = 4
    sp = SpatialCase(embed_planar(case.model, (0.3, -0.5, 0.7)), case.scenario)
    lin_p = dttmm.linearize(case, k)
    lin_s = dttmm.linearize(sp, k)
    ip = _in_plane(lin_s.coordinates)
    op = np.setdiff1d(np.arange(lin_s.n_free), ip)
    assert ip.size == lin_p.n_free
    assert np.abs(lin_s.M[np.ix_(ip, ip)] - lin_p.M).max() <= 1e-9 * np.abs(lin_p.M).max()
    assert np.abs(lin_s.K[np.ix_(ip, ip)] - lin_p.K).max() <= 1e-8 * np.abs(lin_p.K).max()
    assert lin_s.B.shape == (lin_s.n_free, lin_p.B.shape[1])
    assert np.abs(lin_s.B[ip] - lin_p.B).max(initial=0.0) <= 1e-9
    for mat in (lin_s.M, lin_s.K):
        assert np.abs(mat[np.ix_(ip, op)]).max() <= 1e-8 * np.abs(mat).max()
    m_s = dttmm.modes(sp, k)
    in_plane = [
        f for f, v in zip(m_s.frequencies, m_s.shapes.T) if np.linalg.norm(v[ip]) > np.linalg.norm(v[op])
    ]
    f_p = dttmm.modes(case, k).frequencies
    np.testing.assert_allclose(np.sort(in_plane), np.sort(f_p), rtol=1e-7, atol=1e-9 * f_p.max())


def test_hanging_stiff_link_is_a_pendulum_at_its_equilibrium():
    """A stiff link on a free pitch joint, turned to hang down (initial angle π/2 about y):
    at the static equilibrium the holding torque is 0 and the lowest mode is the compound
    pendulum, ω² = m g (L/2) / (m L²/3 + L ρIz) (the section's rotary inertia about the pitch
    axis), to the links' flexibility (EI × 1e4)."""
    beam = dc.replace(BEAM, EIy=BEAM.EIy * 1e4, EIz=BEAM.EIz * 1e4, GJ=BEAM.GJ * 1e4, rhoIz=1e-3, rhoIy=1e-3)
    g = 9.81
    link = SpatialLink(beam, SpatialJoint(axis=(0.0, 1.0, 0.0)))
    drive = Drive("torque", Constant(0.0), initial_angle=np.pi / 2)
    case = SpatialCase(SpatialManipulator((link,), gravity=(0.0, 0.0, -g)), Scenario(1.0, 0.5, (drive,)))
    q, hold = equilibrium(case, 4)
    assert abs(hold[0]) <= 1e-9 * BEAM.rhoA * L * g * L
    lin = dttmm.linearize(case, 4, state="equilibrium")
    assert np.abs(lin.qdd).max() <= 1e-8
    m = dttmm.modes(case, 4, state="equilibrium", n=2)
    mass = BEAM.rhoA * L
    exact = np.sqrt(mass * g * L / 2 / (mass * L**2 / 3 + L * 1e-3)) / (2 * np.pi)
    assert m.frequencies[0] == pytest.approx(exact, rel=1e-5)
    assert lin.torque_joints == (0,) and lin.B.shape == (lin.n_free, 1)


def test_equilibrium_of_the_shipped_cantilever_under_gravity():
    """cantilever_3d.toml sags 0.37 m under its gravity: at the equilibrium q̈ = 0, K is
    symmetric (a conservative load: the Hessian of the potential) and equals the statics'
    tangent, and the first bending frequencies move from their rest values."""
    case = load_case(SPATIAL / "cantilever_3d.toml")
    lin = dttmm.linearize(case, 4, state="equilibrium")
    a_rest = np.abs(dttmm.linearize(case, 4).qdd).max()
    assert np.abs(lin.qdd).max() <= 1e-8 * a_rest
    assert np.abs(lin.K - lin.K.T).max() <= 1e-6 * np.abs(lin.K).max()
    # K = the statics' tangent: the elastic K_T(q) minus the load stiffness ∂Q_g/∂q (central
    # differences of the statics' generalized gravity loads); the load part measured to 6.5e-9
    # of its own size (it is 1e-6 of the axial stiffness)
    from dttmm.spatial.statics import elastic_forces, generalized_loads

    _, KT = elastic_forces(case, 4, lin.q)
    dQ = np.zeros_like(KT)
    for j in range(lin.q.size):
        dq = np.zeros(lin.q.size)
        dq[j] = 1e-6
        dQ[:, j] = (
            generalized_loads(case, 4, lin.q + dq)[0] - generalized_loads(case, 4, lin.q - dq)[0]
        ) / 2e-6
    assert np.abs(lin.K - (KT - dQ)).max() <= 1e-6 * np.abs(dQ).max()
    f_eq = dttmm.modes(case, 4, state="equilibrium", n=2).frequencies
    f_rest = dttmm.modes(case, 4, n=2).frequencies
    assert np.all(np.isfinite(f_eq)) and np.abs(f_eq / f_rest - 1).max() > 1e-3


def test_motion_joint_held_and_torque_joint_input():
    """A motion-driven joint is held on its law (not a coordinate, no column of B); a torque
    joint is free, its torque an input."""
    case = load_case(SPATIAL / "two_joint_arm.toml")
    drives = (Drive("motion", Constant(0.3)), case.scenario.drives[1])
    case = dc.replace(case, scenario=dc.replace(case.scenario, drives=drives))
    lin = dttmm.linearize(case, 2)
    assert lin.torque_joints == (1,) and lin.B.shape == (lin.n_free, 1)
    assert "joint 1 angle" not in lin.coordinates and "joint 2 angle" in lin.coordinates
    assert lin.q[0] == 0.3 and lin.n_free == lin.q.size - 1


def test_closed_loop_joints_are_free_joints_with_torque_inputs():
    """pd drives: the linearisation is that of the arm with the controller removed (planar
    rule), each joint free with its torque a column of B; B = M ∂q̈/∂τ is the unit column of
    the joint's angle (a joint torque does work only through its own angle)."""
    from dttmm.drives import PD

    case = load_case(SPATIAL / "three_joint_arm.toml")
    drives = tuple(Drive("torque", PD(20.0, 2.0, Constant(0.1 * j))) for j in range(3))
    case = dc.replace(case, scenario=dc.replace(case.scenario, drives=drives))
    lin = dttmm.linearize(case, 2)
    assert lin.torque_joints == (0, 1, 2)
    cols = [lin.coordinates.index(f"joint {j + 1} angle") for j in range(3)]
    expected = np.zeros((lin.n_free, 3))
    expected[cols, [0, 1, 2]] = 1.0
    np.testing.assert_allclose(lin.B, expected, rtol=0, atol=1e-9)


def test_bad_input_names_the_field():
    with pytest.raises(InputError, match="state"):
        dttmm.linearize(cantilever(), 2, state="rest")
    with pytest.raises(InputError, match="state"):
        dttmm.linearize(dttmm.load_case(ROOT / "experiments/cases/three_link.toml"), 2, state="equilibrium")
    with pytest.raises(InputError, match="torque"):
        dttmm.linearize(load_case(SPATIAL / "three_joint_arm.toml"), 2, torque=[1.0])
    with pytest.raises(InputError, match="n"):
        dttmm.modes(cantilever(), 2, n=0)


def test_cli_modes_of_a_spatial_case(tmp_path, capsys):
    from dttmm.cli import main

    out = tmp_path / "m"
    argv = ["modes", str(SPATIAL / "cantilever_3d.toml"), "-k", "4", "--n", "4", "--equilibrium"]
    rc = main([*argv, "--out", str(out)])
    assert rc == 0, capsys.readouterr().err
    text = capsys.readouterr().out
    assert "frequency" in text
    for suffix in ("modes.csv", "shapes.csv", "deflections.csv", "modes.png"):
        assert (out / f"cantilever_3d_{suffix}").is_file()
    import pandas as pd

    d = pd.read_csv(out / "cantilever_3d_deflections.csv")
    assert {"link", "s_m", "component", "mode_1"} <= set(d.columns)
    assert set(d.component) == {"y", "z", "twist"}


def test_spatial_section_roll_turns_the_bending_families():
    """A rolled section (roll = 90°) swaps which link axis each bending stiffness acts about,
    so the spatial frequencies are those of the unrolled beam (the modes' order is the same)."""
    rolled = dc.replace(BEAM, roll=np.pi / 2)
    f0 = dttmm.frequencies(cantilever(), 4, n=6)
    f1 = dttmm.frequencies(cantilever(rolled), 4, n=6)
    np.testing.assert_allclose(f1, f0, rtol=1e-9)


# ------------------------------------------------------------------ the Exudyn 3-D beam peer
def _richardson(case, k, n):
    """Exudyn's frequencies at k and 2k extrapolated in k (its element converges as 1/k²)."""
    ex = pytest.importorskip("reference_models.exudyn_modes3d")
    pytest.importorskip("exudyn")
    f1, f2 = ex.frequencies(case, k, n), ex.frequencies(case, 2 * k, n)
    return (4 * f2 - f1) / 3


def test_cantilever_against_exudyn_eigenvalues():
    """Same beam with a small rotary inertia (ρIy = ρIz = 1e-4 kg·m: the GE beam's nodes need
    one) in both. Bending: DT-TMM k = 16 against Exudyn extrapolated from k = 32, 64, ≤ 5e-5
    (measured ≤ 1.4e-5); torsion: the DT-TMM linear element's error ((2n−1)π/2k)²/24 on top
    of Exudyn's (one-point torsion converges fast)."""
    beam = dc.replace(BEAM, rhoIy=1e-4, rhoIz=1e-4)
    c = cantilever(beam)
    k = 16
    m = dttmm.modes(c, k, n=10)
    fam = families(m)
    ref = _richardson(c, 32, 10)
    bending = np.sort(np.concatenate([fam["y"][:3], fam["z"][:3]]))
    near = lambda f: ref[np.argmin(np.abs(ref - f))]
    for f in bending:
        assert abs(f / near(f) - 1) <= 5e-5, (f, near(f))
    err = fam["x"][0] / near(fam["x"][0]) - 1
    bound = (np.pi / (2 * k)) ** 2 / 24
    assert 0 < err <= 2 * bound, (err, bound)


def test_three_joint_arm_without_gravity_against_exudyn_eigenvalues():
    """three_joint_arm (hubs, off-axis payload, rolled section, pitched joint origin) without
    gravity, all three joints free: three rigid modes, then the elastic ones; DT-TMM k = 8
    against Exudyn extrapolated from k = 16, 32: ≤ 1e-4 on the first nine elastic modes
    (measured ≤ 3.8e-5; Exudyn's own k = 32 differs by up to 7.6e-4)."""
    case = load_case(SPATIAL / "three_joint_arm.toml")
    case = dc.replace(case, model=dc.replace(case.model, gravity=(0.0, 0.0, 0.0)))
    f = dttmm.frequencies(case, 8, n=12)
    ref = _richardson(case, 16, 12)
    assert np.all(f[:3] == 0.0) and np.all(ref[:3] == 0.0)
    np.testing.assert_allclose(f[3:], ref[3:], rtol=1e-4)
