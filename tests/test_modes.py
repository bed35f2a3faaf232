"""Linearisation and natural modes: closed forms, published values, the global solver, Exudyn."""

import dataclasses as dc

import numpy as np
import pytest
from conftest import CASES, case
from scipy.optimize import brentq

import dttmm
from dttmm import Case, Constant, Drive, InputError, Link, Manipulator, Scenario, Section, Sine
from dttmm.linear import _STENCIL, linearize, modes
from reference_models import global_newmark as G

L, EI, RHOA = 1.0, 2.3333, 0.27


def clamped(ea=None, payload=None, damping=0.0) -> Case:
    link = Link(Section(L, EI, RHOA, ea, damping))
    if payload is not None:
        link = dc.replace(link, payload=dttmm.Payload(*payload))
    return Case(Manipulator((link,), (0.0, 0.0)), Scenario(0.5, 0.01, (Drive("motion", Constant(0.0)),)))


def cantilever_roots(n: int) -> np.ndarray:
    """β_m L of the clamped-free beam: roots of cos x cosh x = −1, bracketed near (m − ½)π."""
    f = lambda x: np.cos(x) * np.cosh(x) + 1.0
    return np.array(
        [brentq(f, (m + 0.5) * np.pi - 1.0, (m + 0.5) * np.pi + 1.0, xtol=1e-15) for m in range(n)]
    )


def rel(a, b) -> float:
    """max abs difference / max abs entry of b."""
    return float(np.abs(np.asarray(a) - b).max() / np.abs(b).max())


# ----------------------------------------------------------------------------- closed forms
def test_cantilever_roots_are_the_textbook_ones():
    assert cantilever_roots(3) == pytest.approx([1.8751, 4.6941, 7.8548], abs=1e-4)


@pytest.mark.parametrize("ea", [None, 7e6])
def test_cantilever_frequencies_closed_form(ea):
    """β_m² √(EI/ρA L⁴)/2π for the first three modes within 1e-4 at k = 16 (extensible: the
    axial modes lie far above, the bending ones are the same)."""
    exact = cantilever_roots(3) ** 2 * np.sqrt(EI / (RHOA * L**4)) / (2 * np.pi)
    f = modes(clamped(ea), 16, n=3).frequencies
    np.testing.assert_allclose(f, exact, rtol=1e-4)


def test_cantilever_converges_at_fourth_order():
    """Cubic Hermite elements: frequency errors fall as k⁻⁴ (observed order of f_2 in k = 4…16)."""
    exact = cantilever_roots(2)[1] ** 2 * np.sqrt(EI / (RHOA * L**4)) / (2 * np.pi)
    ks = np.array([4, 8, 16])
    err = np.array([modes(clamped(), int(k), n=2).frequencies[1] / exact - 1 for k in ks])
    order = -np.polyfit(np.log(ks), np.log(err), 1)[0]
    assert 3.8 < order < 4.2


def test_deluca_published_link_frequencies():
    """De Luca & Siciliano's clamped-link frequencies (0.48, 1.80 / 2.18, 15.91 Hz) to ±0.005 Hz."""
    for name, quoted in (("deluca_link1_clamped", [0.48, 1.80]), ("deluca_link2_clamped", [2.18, 15.91])):
        c = dttmm.load_case(CASES / "benchmarks" / f"{name}.toml")
        f = modes(c, 16, n=2).frequencies
        assert np.all(np.abs(f - quoted) <= 0.005), (name, f)


# ----------------------------------------------------------------------------- matrices
def test_rest_matrices_equal_the_global_solvers():
    """At rest without gravity M, K equal the global solver's mass and stiffness matrices
    (≤ 1e-10 relative), and D = 0, B a unit column on the free joint."""
    c = case("three_link")
    c = dc.replace(c, model=dc.replace(c.model, gravity=(0.0, 0.0)))
    k = 4
    lin = linearize(c, k)
    q = lin.q
    assert rel(lin.M, G.mass_matrix(c, k, q)) <= 1e-10
    assert rel(lin.K, G.stiffness_matrix(c, k)) <= 1e-10
    assert np.abs(lin.D).max() == 0.0
    assert lin.coordinates == tuple(dttmm.structure.build_structure(c, k).coordinate_names())
    expect = np.zeros_like(lin.B)
    expect[lin.free.searchsorted(dttmm.structure.build_structure(c, k).alpha_index), [0, 1, 2]] = 1.0
    np.testing.assert_allclose(lin.B, expect, atol=1e-10)


@pytest.mark.slow
def test_clamped_fine_mesh_matrices():
    """The single clamped link at k = 32: M and K to the global solver's within 1e-10 (the
    default tier checks the same at k = 4 on three links: test_rest_matrices_equal_the_global_solvers)."""
    c = clamped()
    lin = linearize(c, 32)
    F = lin.free
    assert rel(lin.M, G.mass_matrix(c, 32, lin.q)[np.ix_(F, F)]) <= 1e-10
    assert rel(lin.K, G.stiffness_matrix(c, 32)[np.ix_(F, F)]) <= 1e-10


def _general_case() -> Case:
    """Three damped extensible links under gravity: joint 2 motion-driven (a sine), joints 1, 3
    torque-driven."""
    c = case("three_link")
    links = tuple(dc.replace(lk, beam=dc.replace(lk.beam, damping=2e-3)) for lk in c.model.links)
    drives = list(c.scenario.drives)
    drives[1] = Drive("motion", Sine(0.3, 1.5))
    return dc.replace(
        c,
        model=dc.replace(c.model, links=links),
        scenario=dc.replace(c.scenario, drives=tuple(drives)),
    )


def _general_state(c, k, seed=3):
    """Joint angles ~0.5 rad, element deflections ~1e-2 l and rotations ~1e-2 rad, axial
    stretch ~1e-6 l (a physical strain for these strips), rates ~20× those per second."""
    rng = np.random.default_rng(seed)
    st = dttmm.structure.build_structure(c, k)
    scale = np.full(st.n_dof, 0.5)
    for lk in st.links:
        scale[lk.e_slice] = np.tile([1e-6 * lk.et.l, 1e-2 * lk.et.l, 1e-2], lk.k)
    return rng.normal(size=st.n_dof) * scale, rng.normal(size=st.n_dof) * scale * 20


def _global_tangent(c, k, lin):
    """−M ∂q̈/∂q and −M ∂q̈/∂q̇ of the global solver at lin's point, same 8th-order stencil."""
    F, t = lin.free, lin.t
    M = G.mass_matrix(c, k, lin.q)[np.ix_(F, F)]
    scale = dttmm.linear._scales(dttmm.structure.build_structure(c, k))

    def jac(which):
        cols = []
        for j in F:
            h = 2e-4 * scale[j]
            col = 0.0
            for m, cm in _STENCIL:
                xs = []
                for sgn in (1, -1):
                    q, qd = lin.q.copy(), lin.qd.copy()
                    (q if which == "q" else qd)[j] += sgn * m * h
                    xs.append(G.accelerations(c, k, q, qd, t)[F])
                col = col + cm * (xs[0] - xs[1])
            cols.append(col / h)
        return np.column_stack(cols)

    return M, -M @ jac("q"), -M @ jac("qd")


def test_general_state_matches_global_tangent():
    """At a deformed, moving state under gravity with a moving motion joint: M, K, D equal the
    global solver's forward dynamics differentiated the same way (≤ 1e-10 relative)."""
    c, k = _general_case(), 2
    lin = linearize(c, k, t=0.37, state=_general_state(c, k))
    assert 1 not in lin.torque_joints and len(lin.free) == len(lin.q) - 1
    M, K, D = _global_tangent(c, k, lin)
    assert rel(lin.M, M) <= 1e-10
    assert rel(lin.K, K) <= 1e-10
    assert rel(lin.D, D) <= 1e-10
    # K really holds state terms here: it differs from the elastic stiffness
    F = lin.free
    assert rel(lin.K, G.stiffness_matrix(c, k)[np.ix_(F, F)]) > 1e-6


def test_general_state_difference_is_converged():
    """The 8th-order tangent agrees with a 2nd-order one at a 10× smaller step to the latter's
    truncation error (~h²), so the stencil's own error is far below it."""
    c, k = _general_case(), 2
    state = _general_state(c, k)
    lin = linearize(c, k, t=0.37, state=state)
    lin2 = linearize(c, k, t=0.37, state=state, step=2e-3)
    assert rel(lin2.K, lin.K) <= 1e-9 and rel(lin2.D, lin.D) <= 1e-9


def test_mass_spd_and_modes_m_orthonormal():
    """At rest without gravity (K symmetric): M symmetric positive definite, shapes M-orthonormal."""
    c = case("three_link")
    m = modes(dc.replace(c, model=dc.replace(c.model, gravity=(0.0, 0.0))), 3)
    assert np.all(m.frequencies[:3] == 0.0) and m.frequencies[3] > 0  # three free joints
    M, V = m.linearization.M, m.shapes
    np.testing.assert_allclose(M, M.T, rtol=0, atol=1e-14 * np.abs(M).max())
    assert np.linalg.eigvalsh(M).min() > 0
    np.testing.assert_allclose(V.T @ M @ V, np.eye(V.shape[1]), atol=1e-9)


# ----------------------------------------------------------------------------- modes
def test_free_joint_gives_rigid_mode_and_pinned_frequencies():
    """A torque-driven link without gravity: one 0 Hz rigid mode, then the hub-beam frequencies;
    with a zero hub inertia those are the pinned-free beam's, roots of tan x = tanh x."""
    c = dc.replace(clamped(), scenario=Scenario(0.5, 0.01, (Drive("torque", Constant(0.0)),)))
    m = modes(c, 16, n=3)
    assert m.frequencies[0] == 0.0
    x = np.array([brentq(lambda x: np.tan(x) - np.tanh(x), a, a + 0.5) for a in (3.9, 7.0)])
    exact = x**2 * np.sqrt(EI / (RHOA * L**4)) / (2 * np.pi)
    np.testing.assert_allclose(m.frequencies[1:], exact, rtol=1e-4)


def test_deflections_of_the_first_cantilever_mode():
    """Mode 1's node deflections follow the analytic clamped-free shape (normalised at the tip)."""
    k = 16
    m = modes(clamped(), k, n=1)
    s, w = m.s[0], m.deflections[0][0]
    b = cantilever_roots(1)[0] / L
    sig = (np.cosh(b * L) + np.cos(b * L)) / (np.sinh(b * L) + np.sin(b * L))
    phi = np.cosh(b * s) - np.cos(b * s) - sig * (np.sinh(b * s) - np.sin(b * s))
    assert s.shape == (k + 1,) and w[0] == 0.0
    np.testing.assert_allclose(w / w[-1], phi / phi[-1], atol=2e-5)


def test_damping_ratios_of_kelvin_voigt_link():
    """D = μK (Kelvin-Voigt): each mode's ζ = μω/2 exactly; undamped: None."""
    mu = 1e-3
    m = modes(clamped(damping=mu), 8, n=3)
    w = 2 * np.pi * m.frequencies
    np.testing.assert_allclose(m.damping_ratios, mu * w / 2, rtol=1e-8)
    assert modes(clamped(), 4, n=2).damping_ratios is None


def test_bad_input_names_the_field():
    with pytest.raises(InputError, match="state"):
        linearize(clamped(), 2, state=(np.zeros(3), np.zeros(5)))
    with pytest.raises(InputError, match="n"):
        modes(clamped(), 2, n=0)
    with pytest.raises(InputError, match="elements_per_link"):
        linearize(clamped(), 0)


# ----------------------------------------------------------------------------- Exudyn
def _exudyn_cases():
    yield (
        "cantilever with hub and payload",
        dc.replace(
            clamped(payload=(0.3, 2e-3)),
            model=Manipulator(
                (Link(Section(L, EI, RHOA, 7e6), dttmm.Hub(0.5, 0.01), dttmm.Payload(0.3, 2e-3)),), (0.0, 0.0)
            ),
        ),
    )
    for name in ("deluca_link1_clamped", "deluca_link2_clamped"):
        yield name, dttmm.load_case(CASES / "benchmarks" / f"{name}.toml")
    # the three-link arm's converged comparison (Exudyn at k = 32) is a slow run; the default tier
    # compares it at equal k (test_three_free_joints_match_exudyn_at_equal_k)
    yield pytest.param("three_link, free joints", _three_free(), marks=pytest.mark.slow)


def _three_free() -> Case:
    c = case("three_link")
    return dc.replace(c, model=dc.replace(c.model, gravity=(0.0, 0.0)))


@pytest.mark.parametrize("name, c", list(_exudyn_cases()), ids=lambda x: x if isinstance(x, str) else "")
def test_frequencies_against_exudyn_eigenvalues(name, c):
    """Exudyn's ComputeODE2Eigenvalues of an ANCF cable model (k = 64) and DT-TMM (k = 16; the
    three-link arm k = 8) agree to 1e-4 on the first four elastic frequencies, each converged
    to that level (measured: Exudyn k = 32 vs 64 ≤ 5.5e-5, DT-TMM vs Exudyn k = 64 ≤ 4e-5).
    At equal k (4) they agree to 1e-6: the cable's transverse field is the same cubic Hermite
    interpolation, so what remains is the eigen solvers' round-off and the cable's finite EA."""
    pytest.importorskip("exudyn")
    from reference_models.exudyn_modes import frequencies as exudyn_frequencies

    k, ke = (8, 32) if c.model.n_links > 1 else (16, 64)  # three links: Exudyn k = 32 vs 64 ≤ 5e-7
    n_rigid = sum(d.kind == "torque" for d in c.scenario.drives)
    n = n_rigid + 4
    f, fe = modes(c, k, n=n).frequencies, exudyn_frequencies(c, ke, n=n)
    assert np.all(f[:n_rigid] == 0) and np.all(fe[:n_rigid] == 0) and np.all(f[n_rigid:] > 0)
    np.testing.assert_allclose(fe[n_rigid:], f[n_rigid:], rtol=1e-4)
    f4, fe4 = modes(c, 4, n=n).frequencies, exudyn_frequencies(c, 4, n=n)
    np.testing.assert_allclose(fe4[n_rigid:], f4[n_rigid:], rtol=1e-6)


def test_three_free_joints_match_exudyn_at_equal_k():
    """The three-link arm, joints free: three rigid modes at zero in both, and at equal k (4) the
    first four elastic frequencies agree to 1e-6 (same cubic Hermite transverse field, see
    test_frequencies_against_exudyn_eigenvalues)."""
    pytest.importorskip("exudyn")
    from reference_models.exudyn_modes import frequencies as exudyn_frequencies

    c = _three_free()
    n_rigid = sum(d.kind == "torque" for d in c.scenario.drives)
    assert n_rigid == 3
    f4, fe4 = modes(c, 4, n=n_rigid + 4).frequencies, exudyn_frequencies(c, 4, n=n_rigid + 4)
    assert np.all(f4[:n_rigid] == 0) and np.all(fe4[:n_rigid] == 0) and np.all(f4[n_rigid:] > 0)
    np.testing.assert_allclose(fe4[n_rigid:], f4[n_rigid:], rtol=1e-6)


def test_exudyn_modes_refuse_gravity():
    pytest.importorskip("exudyn")
    from reference_models.exudyn_modes import frequencies as exudyn_frequencies

    with pytest.raises(InputError, match="gravity"):
        exudyn_frequencies(case("three_link"), 2)


# ----------------------------------------------------------------------------- command line
def test_cli_modes_writes_table_csv_and_plot(tmp_path, capsys):
    import pandas as pd

    from dttmm.cli import main

    path = CASES / "benchmarks" / "deluca_link2_clamped.toml"
    out = tmp_path / "m"
    assert main(["modes", str(path), "-k", "8", "--n", "3", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "frequency [Hz]" in printed and "2.17833" in printed and "15.9146" in printed
    freq = pd.read_csv(out / "deluca_link2_clamped_modes.csv")
    np.testing.assert_allclose(
        freq["frequency_hz"], modes(dttmm.load_case(path), 8, n=3).frequencies, rtol=1e-12
    )
    shapes = pd.read_csv(out / "deluca_link2_clamped_shapes.csv")
    assert list(shapes.columns) == ["coordinate", "mode_1", "mode_2", "mode_3"] and len(shapes) == 16
    defl = pd.read_csv(out / "deluca_link2_clamped_deflections.csv")
    assert len(defl) == 9 and defl["s_m"].iloc[-1] == pytest.approx(0.5)
    assert (out / "deluca_link2_clamped_modes.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "argv, field",
    [(["-k", "0"], "elements_per_link"), (["-k", "2", "--n", "0"], "--n"), (["-k", "x"], "--elements")],
)
def test_cli_modes_bad_input_exit_2(tmp_path, capsys, argv, field):
    from dttmm.cli import main

    path = CASES / "benchmarks" / "deluca_link2_clamped.toml"
    assert main(["modes", str(path), *argv, "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert field in err and len(err.strip().splitlines()) == 1


def test_cli_modes_missing_case_exit_2(tmp_path, capsys):
    from dttmm.cli import main

    assert main(["modes", str(tmp_path / "none.toml"), "-k", "2", "--out", str(tmp_path / "o")]) == 2


def test_closed_loop_joint_is_a_free_joint_with_torque_input():
    """A pd-driven joint linearises as a free joint whose torque is an input: the same M, K, D,
    B as with an open-loop zero torque on it."""
    c = dttmm.load_case(CASES / "control" / "closed_loop_three_link.toml")
    assert any(d.closed_loop for d in c.scenario.drives)
    opened = tuple(
        Drive("torque", Constant(0.0), initial_angle=d.initial_angle) if d.closed_loop else d
        for d in c.scenario.drives
    )
    a = linearize(c, 2)
    b = linearize(dc.replace(c, scenario=dc.replace(c.scenario, drives=opened)), 2)
    assert a.torque_joints == b.torque_joints
    for x, y in ((a.M, b.M), (a.K, b.K), (a.D, b.D), (a.B, b.B)):
        np.testing.assert_array_equal(x, y)


def test_state_space_pair():
    """A = [[0, I], [−M⁻¹K, −M⁻¹D]], B_ss = [[0], [M⁻¹B]] (to round-off), and the undamped
    clamped link's eigenvalues of A are ±iω of its modes."""
    lin = linearize(_general_case(), 2, t=0.37, state=_general_state(_general_case(), 2))
    nf = lin.n_free
    assert rel(lin.A[nf:, :nf], -np.linalg.solve(lin.M, lin.K)) <= 1e-9
    assert rel(lin.A[nf:, nf:], -np.linalg.solve(lin.M, lin.D)) <= 1e-9
    assert rel(lin.B_ss[nf:], np.linalg.solve(lin.M, lin.B)) <= 1e-9
    assert np.all(lin.A[:nf, nf:] == np.eye(nf)) and np.all(lin.B_ss[:nf] == 0)
    m = modes(clamped(), 4)
    w = np.sort(np.abs(np.linalg.eigvals(m.linearization.A).imag))[::2]
    np.testing.assert_allclose(w, 2 * np.pi * m.frequencies, rtol=1e-8)
