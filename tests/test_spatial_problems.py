"""Spatial benchmark problems (docs/spatial.md, "Spatial benchmark problems").

:func:`dttmm.spatial.statics` (Newton on the elastic coordinates, joints held, load stepping):
its elastic and gravity forces against the independent spatial global solver, small loads
against the closed forms F L³/3EI (both bending planes) and T L/GJ, the root section loads
against the global solver's cut loads; then the published problems of
experiments/cases/spatial/princeton_beam.toml and bend_45deg.toml, loaded by their own
``[[scenario.loads]]`` (the Princeton sweep replaces the file's load by each published point),
every expected value from the ``[provenance]`` table of the case file (sources cited there and
below); and the dynamics of right_angle_cantilever.toml (Simo & Vu-Quoc) through the DT-TMM
against the Exudyn 3-D beam peer running the same file.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import dttmm.spatial as dttmm_spatial
from dttmm import InputError, Scenario
from dttmm.spatial import (
    SpatialCase,
    SpatialJoint,
    SpatialLink,
    SpatialLoad,
    SpatialManipulator,
    load_case,
    statics,
)
from dttmm.spatial.statics import elastic_forces, generalized_loads
from reference_models import spatial_global as sg

CASES = Path(__file__).resolve().parent.parent / "experiments/cases/spatial"
PRINCETON = load_case(CASES / "princeton_beam.toml")
BEND = load_case(CASES / "bend_45deg.toml")
BEAM = load_case(CASES / "cantilever_3d.toml").model.links[0].beam


def _clamped(gravity=(0.0, 0.0, 0.0)):
    link = SpatialLink(BEAM, SpatialJoint(locked=True))
    return SpatialCase(SpatialManipulator((link,), gravity=gravity), Scenario(1.0, 0.5, ()))


# ------------------------------------------------------------------ forces and closed forms --


@pytest.mark.parametrize("name", ["cantilever_3d", "three_joint_arm"])
@pytest.mark.parametrize("strain", ["linear", "second-order"])
def test_elastic_and_gravity_forces_equal_the_global_solver(name, strain):
    """f_el, K_T and the gravity force Q_g (hubs, payloads off the axis, held joints at non-zero
    angles) equal reference_models/spatial_global.py's elastic_forces and generalized_forces at
    q̇ = 0 at a random deformed state."""
    case = load_case(CASES / f"{name}.toml")
    k = 3
    rng = np.random.default_rng(7)
    n = len(sg.coordinate_names(case, k))
    q = 0.05 * rng.standard_normal(n)
    f, KT = elastic_forces(case, k, q, strain=strain)
    _, f_ref, K_ref = sg.elastic_forces(case, k, q, strain=strain)
    names = sg.coordinate_names(case, k)
    el = np.array([not s.startswith("alpha") for s in names])
    assert np.abs(f - f_ref).max() <= 1e-10 * np.abs(f_ref).max()
    assert np.abs(KT - K_ref)[np.ix_(el, el)].max() <= 1e-10 * np.abs(K_ref).max()
    Q, _ = generalized_loads(case, k, q)
    Q_ref = sg.generalized_forces(case, k, q, np.zeros(n))
    assert np.abs(Q - Q_ref)[el].max() <= 1e-10 * np.abs(Q_ref).max()


@pytest.mark.parametrize("plane", ["y", "z"])
def test_small_tip_force_deflects_by_FL3_over_3EI(plane):
    """Tip force 1e-4 N along y (EIz) or z (EIy), EIy ≠ EIz: δ = F L³/3EI (cubic Hermite elements
    are nodally exact; the tolerance is the geometric nonlinearity, (δ/L)² ≈ 1e-11)."""
    F = np.zeros(3)
    F["yz".index(plane) + 1] = 1e-4
    r = statics(_clamped(), elements_per_link=4, loads={"force": F})
    ei = BEAM.EIz if plane == "y" else BEAM.EIy
    ref = 1e-4 * BEAM.length**3 / (3 * ei)
    d = r.tip_position - [BEAM.length, 0.0, 0.0]
    assert abs(d["yz".index(plane) + 1] - ref) <= 1e-8 * ref
    assert abs(d["zy".index(plane) + 1]) <= 1e-14
    # the base holds the force and its moment: −F and −L x̂ × F
    assert np.allclose(r.root_loads[:3], -F, rtol=0, atol=1e-15)
    assert np.allclose(r.root_loads[3:], -np.cross(r.tip_position, F), rtol=1e-12, atol=1e-18)


def test_small_tip_moment_twists_by_TL_over_GJ():
    """Tip moment T = 1e-4 N·m about x: twist T L/GJ (the linear torsion element is exact)."""
    from dttmm.spatial.rotation import log_so3

    r = statics(_clamped(), elements_per_link=4, loads={"moment": [1e-4, 0.0, 0.0]})
    ref = 1e-4 * BEAM.length / BEAM.GJ
    tw = log_so3(r.tip_rotation)
    assert abs(tw[0] - ref) <= 1e-10 * ref
    assert np.abs(tw[1:]).max() <= 1e-14
    assert np.abs(r.tip_position - [BEAM.length, 0.0, 0.0]).max() <= 1e-14


def test_equilibrium_under_gravity_has_the_global_solvers_cut_loads():
    """cantilever_3d (gravity in y and z, payload off the axis, large enough to rotate the tip
    visibly): at the equilibrium the global solver's accelerations vanish and its root cut load
    equals root_loads; the load stepping reaches the same state."""
    case = load_case(CASES / "cantilever_3d.toml")
    k = 4
    r = statics(case, elements_per_link=k, steps=3)
    r1 = statics(case, elements_per_link=k)
    assert np.abs(r.q - r1.q).max() <= 1e-9 * np.abs(r.q).max()
    z = np.zeros_like(r.q)
    assert np.abs(sg.accelerations(case, k, r.q, z)).max() <= 1e-6
    cut = sg.cut_loads(case, k, r.q, z)
    assert np.allclose(r.root_loads, cut[0], rtol=1e-8, atol=1e-9 * np.abs(cut[0]).max())
    assert r.shape.shape == (k + 1, 3) and np.allclose(r.shape[-1], r.tip_position)
    assert r.tip_path.shape == (3, 3) and np.allclose(r.tip_path[-1], r.tip_position)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"loads": {"force": [1.0, 0.0]}}, "loads['force']"),
        ({"loads": {"moment": "x"}}, "loads['moment']"),
        ({"loads": {"torque": [0.0, 0.0, 1.0]}}, "loads['torque']"),
        ({"loads": [0.0, 0.0, 1.0]}, "loads"),
        ({"steps": 0}, "steps"),
        ({"tol": -1.0}, "tol"),
        ({"max_iterations": 2.5}, "max_iterations"),
        ({"strain": "cubic"}, "strain"),
        ({"elements_per_link": 0}, "elements_per_link"),
        ({"angles": [0.1]}, "angles"),
    ],
)
def test_bad_input_is_one_line_input_error(kwargs, field):
    args = {"elements_per_link": 2, **kwargs}
    with pytest.raises(InputError) as exc:
        statics(_clamped(), **args)
    assert exc.value.field == field and "\n" not in str(exc.value)


# ------------------------------------------------------------------------ the Princeton beam --

PV = PRINCETON.provenance
#: measured gap of the model to ANSYS in |u_y| with GJ = G (Iyy + Izz) 0.198 (Exudyn's choice,
#: GJ_0198 of the provenance) at β ≥ 60° (F = 8.896 N) and β ≥ 30° (F = 13.345 N) (k = 32: up to
#: 2.3 % and 3.4 %; docs/spatial.md); the published 2 % target holds elsewhere, and everywhere
#: with the case file's Saint-Venant GJ
UY_GAP = 0.035


def _with_gj(gj, case=PRINCETON):
    link = case.model.links[0]
    assert link.beam.GJ == PV["GJ_saint_venant"]  # the case file's torsion stiffness
    if gj == "saint-venant":
        return case
    beam = replace(link.beam, GJ=PV["GJ_0198"])
    return replace(case, model=SpatialManipulator((replace(link, beam=beam),)))


def _princeton_case(F, beta_deg, gj):
    """The case file with its load replaced by F [0, −cos β, sin β] (world, fixed direction)."""
    b = np.radians(beta_deg)
    load = SpatialLoad(force=(0.0, -F * np.cos(b), F * np.sin(b)))
    return _with_gj(gj, replace(PRINCETON, scenario=replace(PRINCETON.scenario, loads=(load,))))


def _tip_displacement(r):
    u = r.tip_position - [PRINCETON.model.links[0].beam.length, 0.0, 0.0]
    return abs(u[1]), u[2]


def _princeton(F, beta_deg, k, gj, steps=4):
    return _tip_displacement(statics(_princeton_case(F, beta_deg, gj), elements_per_link=k, steps=steps))


def _princeton_errors(F, j, k, gj):
    """Relative errors (|u_y|, u_z) against the ANSYS values of the provenance table; the zero
    entries (u_z at β = 0, |u_y| at β = 90°) measured against the component's other end."""
    tag = "F8896" if F == PV["force"][0] else "F13345"
    uy_ref, uz_ref = PV[f"uy_abs_{tag}"], PV[f"uz_{tag}"]
    uy, uz = _princeton(F, PV["beta_deg"][j], k, gj)
    return (uy - uy_ref[j]) / (uy_ref[j] or uy_ref[0]), (uz - uz_ref[j]) / (uz_ref[j] or uz_ref[-1])


def _tolerance(F, beta, component, gj):
    heavy = F == PV["force"][1]
    if gj == "0.198" and component == "uy" and beta >= (30.0 if heavy else 60.0):
        return UY_GAP
    return PV["tolerance"]


@pytest.mark.parametrize("gj", ["0.198", "saint-venant"])
@pytest.mark.parametrize("F", [8.896, 13.345])
@pytest.mark.parametrize("j", [0, 4, 6])
def test_princeton_beam_against_ansys(F, j, gj):
    """Princeton beam (ANSYS beam values from Obrezkov, Mikkola, Matikainen et al., Nonlinear
    Dyn. 109 (2022), and Bauchau, Han, Mikkola, Matikainen, Gruber, Multibody Syst. Dyn. (2014),
    doi:10.1007/s11044-014-9430-y; provenance of princeton_beam.toml), β = 0, 60, 90°, k = 8,
    the case file's Saint-Venant GJ or Exudyn's G (Iyy + Izz) 0.198 (GJ_0198 of the provenance):
    within the published 2 %, except |u_y| with the second GJ at large β (the measured gap,
    UY_GAP)."""
    ey, ez = _princeton_errors(F, j, 8, gj)
    beta = PV["beta_deg"][j]
    assert abs(ey) <= _tolerance(F, beta, "uy", gj)
    assert abs(ez) <= _tolerance(F, beta, "uz", gj)


def test_princeton_case_file_carries_its_load():
    """The file's own [[scenario.loads]] entry is the published point F = 13.345 N, β = 45°
    (F [0, −cos β, sin β], world): statics of the file as it is equals the replaced-load run and
    is within the published 2 % of the ANSYS table (measured at k = 8: |u_y| +0.26 %, u_z +0.17 %)."""
    (ld,) = PRINCETON.scenario.loads
    b = np.radians(45.0)
    assert ld.frame == "world" and ld.link is None
    assert np.allclose(ld.force, [0.0, -13.345 * np.cos(b), 13.345 * np.sin(b)], rtol=1e-15)
    uy, uz = _tip_displacement(statics(PRINCETON, elements_per_link=8, steps=4))
    assert (uy, uz) == _princeton(13.345, 45.0, 8, "saint-venant")
    j = PV["beta_deg"].index(45.0)
    assert abs(uy / PV["uy_abs_F13345"][j] - 1) <= PV["tolerance"]
    assert abs(uz / PV["uz_F13345"][j] - 1) <= PV["tolerance"]


@pytest.mark.slow
@pytest.mark.parametrize("gj", ["0.198", "saint-venant"])
@pytest.mark.parametrize("F", [8.896, 13.345])
def test_princeton_beam_sweep_and_convergence(F, gj):
    """The full β sweep of the same ANSYS table at k = 8, 16, 32 within the tolerances above
    (k = 4 is reported in docs/spatial.md, up to 2.3 % off), converging at second order in k:
    |e(32) − e(16)| ≤ 0.3 |e(16) − e(8)|."""
    for j, beta in enumerate(PV["beta_deg"]):
        e = {k: np.array(_princeton_errors(F, j, k, gj)) for k in (8, 16, 32)}
        for k in e:
            assert abs(e[k][0]) <= _tolerance(F, beta, "uy", gj), (beta, k, e[k])
            assert abs(e[k][1]) <= _tolerance(F, beta, "uz", gj), (beta, k, e[k])
        assert np.all(np.abs(e[32] - e[16]) <= 0.3 * np.abs(e[16] - e[8]) + 1e-4), (beta, e)


# -------------------------------------------------------------------- the 45-degree bend ------

BV = BEND.provenance
R_BEND = 100.0


def test_bend_geometry_is_the_arc():
    """Undeformed tip of the 8 chords at (R sin 45°, R (1 − cos 45°), 0), the last chord at
    45° − 45°/16 from x, every node on the arc (the file's load ramp is 0 at t = 0)."""
    r = statics(BEND, elements_per_link=2, t=0.0)
    s = np.sqrt(0.5)
    assert np.allclose(r.tip_position, [R_BEND * s, R_BEND * (1 - s), 0.0], rtol=0, atol=1e-12)
    a = np.pi / 4 - np.pi / 64
    assert np.allclose(r.tip_rotation[:, 0], [np.cos(a), np.sin(a), 0.0], rtol=0, atol=1e-12)
    link_ends = r.shape[::2] - [0.0, R_BEND, 0.0]
    assert np.allclose(np.linalg.norm(link_ends, axis=1), R_BEND, rtol=1e-13)


@pytest.mark.parametrize("k", [1, pytest.param(4, marks=pytest.mark.slow)])
def test_bend_45deg_against_simo_vu_quoc(k):
    """Bathe–Bolourchi 45° bend, tip force P = 300, 450, 600 lbf along z (the file's own load at
    t = 1, one run, 8 load steps of 75 lbf): tip positions of Simo & Vu-Quoc, Comput. Methods
    Appl. Mech. Eng. 58 (1986), 8 elements (provenance of bend_45deg.toml), within 1 % of R
    (measured 0.42–0.57 %; of the tip displacement 0.7–1.3 %)."""
    (ld,) = BEND.scenario.loads
    assert ld.link == 7 and ld.frame == "world" and ld.value(1.0)[0][2] == BV["P"][-1]
    r = statics(BEND, elements_per_link=k, steps=8)
    for P, ref in zip(BV["P"], BV["tip_position"]):
        i = int(round(8 * P / BV["P"][-1])) - 1
        assert np.linalg.norm(r.tip_path[i] - ref) <= BV["tolerance"] * R_BEND, P


def test_bend_load_ramp_in_time_is_the_load_steps():
    """The file's load ramps 0 → 600 lbf over t ∈ [0, 1]: the statics at t = 0.5 (P = 300 lbf,
    4 steps of 75) is the 4th increment of the run at t = 1, to Newton's tolerance."""
    full = statics(BEND, elements_per_link=1, steps=8)
    half = statics(BEND, elements_per_link=1, steps=4, t=0.5)
    assert np.abs(half.tip_position - full.tip_path[3]).max() <= 1e-8 * R_BEND


# ------------------------------------------------- the right-angle cantilever (dynamics) ------

RIGHT = load_case(CASES / "right_angle_cantilever.toml")
#: measured differences DT-TMM − Exudyn (docs/spatial.md §9), k per leg: extrema of the tip
#: displacement components and the elbow's z (values in the file's units, times in s)
RIGHT_GAP = {16: (0.025, 0.05), 32: (0.005, 0.01)}


def _peaks(t, y):
    """(value, time) of the maximum and the minimum of y, refined by the parabola through the
    sample and its neighbours."""
    out = []
    for j in (int(np.argmax(y)), int(np.argmin(y))):
        j = min(max(j, 1), len(y) - 2)
        y0, y1, y2 = y[j - 1 : j + 2]
        d = (y0 - y2) / (2.0 * (y0 - 2.0 * y1 + y2))
        out.append((y1 - 0.25 * (y0 - y2) * d, t[j] + d * (t[1] - t[0])))
    return out


def _extrema(r):
    tip = r.end_effector - r.end_effector[0]
    elbow = r.link_tip[:, 0, 2] - r.link_tip[0, 0, 2]
    ys = {"tip_x": tip[:, 0], "tip_y": tip[:, 1], "tip_z": tip[:, 2], "elbow_z": elbow}
    return {name: _peaks(r.t, y) for name, y in ys.items()}


def _right_angle_exudyn(k, h, **options):
    xb = pytest.importorskip("reference_models.exudyn_beam3d")
    c = RIGHT
    ratio = c.provenance["shear_stiffness"] / c.model.links[0].beam.EA  # GA = EA, as the source
    return xb.simulate(c, elements_per_link=k, h=h, shear_ratio=ratio, energy=True, **options)


def test_right_angle_cantilever_loads_and_energy():
    """The file's elbow force (its [[scenario.loads]] entry: 50 along z, the hat 0 → 1 → 0 over
    t ∈ [0, 2]) through the DT-TMM (k = 16 per leg, h = 0.005, Newmark): the energy put in
    equals the force's work ∫ F·v_elbow dt (trapezoidal on the step grid: 1.0e-6 relative,
    measured; 3.9e-6 at k = 8, h = 0.01), and is conserved after t = 2 (no load, no damping)
    to 1e-5 of its value (measured 4.7e-6; 1.7e-5 at h = 0.01: O(h²))."""
    (ld,) = RIGHT.scenario.loads
    assert ld.link == 0 and ld.frame == "world" and ld.value(1.0)[0][2] == 50.0
    assert ld.value(0.5)[0][2] == 25.0 and ld.value(2.5)[0][2] == 0.0
    h = 0.005
    c = replace(RIGHT, scenario=replace(RIGHT.scenario, duration=2.5, output_step=h))
    r = dttmm_spatial.simulate(c, elements_per_link=16, h=h)
    F = np.array([ld.value(t, t > 0)[0] for t in r.t])
    dz = np.diff(r.link_tip[:, 0], axis=0)
    W = np.concatenate([[0.0], np.cumsum(np.einsum("ti,ti->t", 0.5 * (F[1:] + F[:-1]), dz))])
    assert r.energy[0] == 0.0
    assert np.abs(r.energy - W).max() <= 3e-6 * W[-1]
    full = dttmm_spatial.simulate(RIGHT, elements_per_link=16, h=h)
    e = full.energy[full.t >= 2.0]
    assert np.ptp(e) <= 1e-5 * e[0]
    assert abs(e[0] - W[-1]) <= 1e-5 * W[-1]


def _compare_right_angle(k, h, ex_options):
    dt = dttmm_spatial.simulate(RIGHT, elements_per_link=k, h=h)
    ex = _right_angle_exudyn(k, h, **ex_options)
    a, b = _extrema(dt), _extrema(ex)
    dv, dtime = RIGHT_GAP[k]
    for name in a:
        for (va, ta), (vb, tb) in zip(a[name], b[name]):
            assert abs(va - vb) <= dv and abs(ta - tb) <= dtime, (name, va, ta, vb, tb)
    e_dt, e_ex = dt.energy[dt.t >= 2.0], ex.energy[ex.t >= 2.0]
    assert abs(e_dt[0] - e_ex[0]) <= 1e-3 * e_ex[0]
    return dt, ex


def test_right_angle_cantilever_dynamics_against_exudyn():
    """Simo & Vu-Quoc's right-angle cantilever (right_angle_cantilever.toml: one file, its own
    elbow load, both engines): the DT-TMM (Euler–Bernoulli, k = 16 per leg, h = 0.01) against
    the Exudyn 3-D geometrically exact beam (shear-deformable, GA = EA, k = 16, h = 0.01):
    the extrema of the tip displacement's x, y, z and of the elbow's z (up to 9.7 for legs of
    10) within 0.025 and their times within 0.05 s (one output step; measured ≤ 0.013 and
    ≤ 0.028 s, the GE element's O(1/k²) error: halved and more at k = 32), the energy at t = 2
    within 1e-3 (measured 5.2e-4)."""
    _compare_right_angle(16, 0.01, dict(newton_abs_tol=1e-6))


@pytest.mark.slow
def test_right_angle_cantilever_dynamics_against_exudyn_k32():
    """As above at k = 32 per leg, h = 0.0025 in both: extrema within 0.005 and 0.01 s
    (measured ≤ 0.0030 and ≤ 0.007 s), the tip's whole history within 0.02 (measured 0.013),
    the energy at t = 2 within 1e-3 (measured 1.2e-4)."""
    dt, ex = _compare_right_angle(32, 0.0025, dict(newton_abs_tol=1e-5))
    assert np.abs(dt.end_effector - ex.end_effector).max() <= 0.02
