"""The spatial global solver's compiled mechanics (reference_models._spatial_numba: composite
inertias along the chain, O(N²)) against its readable numpy mechanics (dense Jacobians of every
body, M = Σ m J_vᵀJ_v + J_ωᵀ I J_ω, checked in tests/test_spatial_global.py against Lagrange's
equations, the potential's gradient and closed forms).

* M(q) and f = Q_g − h(q, q̇) at random states, on every shipped spatial case (chains, trees,
  closed loops, rigid links, robots from URDF, hubs and payloads), to round-off;
* the frames, their Jacobians and J̇q̇ that the loads, closures and closed-loop laws read;
* the energy and cut-load outputs;
* whole runs, engine "numba" against engine "numpy": a chain with cut loads and link shapes, a
  closed loop (Newton on the multipliers), closed-loop drive laws, external loads.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.drives import PD, Constant, Drive, Table
from dttmm.errors import InputError
from dttmm.jit import HAVE_NUMBA
from reference_models import _spatial_numba as sn
from reference_models import _spatial_numpy as sgm
from reference_models import spatial_global as sg

pytestmark = pytest.mark.skipif(not HAVE_NUMBA, reason="the compiled engine needs numba")

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases" / "spatial"
SHIPPED = sorted(p.relative_to(CASES).as_posix() for p in CASES.rglob("*.toml"))


def _case(name, duration=None, output_step=None, **scenario):
    case = dttmm.load_case(CASES / name)
    if duration is None:
        return case
    sc = dc.replace(case.scenario, duration=duration, output_step=output_step or duration, **scenario)
    return dc.replace(case, scenario=sc)


def _state(lay, seed):
    rng = np.random.default_rng(seed)
    return 0.3 * rng.standard_normal(lay.n_dof), rng.standard_normal(lay.n_dof)


def _rel(a, b):
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


@pytest.mark.parametrize("name", SHIPPED)
def test_mass_matrix_and_forces_equal_the_numpy_mechanics(name):
    case = _case(name)
    for k in (1, 3):
        lay = sgm._layout(case, k)
        packed = sn.pack(lay)
        q, qd = _state(lay, k)
        M0, f0 = sgm._assemble(lay, q, qd)
        M, f = np.empty_like(M0), np.empty_like(f0)
        sn.assemble(packed[0], q, qd, packed[1], M, f)
        assert _rel(M, M0) <= 1e-13, (name, k)
        assert _rel(f, f0) <= 1e-13, (name, k)
        assert np.array_equal(M, M.T)


@pytest.mark.parametrize("name", ["three_joint_arm.toml", "topology/five_bar.toml", "robots/ur5.toml"])
def test_frames_jacobians_and_their_rates_equal_the_numpy_frames(name):
    lay = sgm._layout(_case(name), 2)
    packed = sn.pack(lay)
    q, qd = _state(lay, 7)
    fields = ("R_link", "p_link", "R_tip", "p_tip", "Jr_link", "Jw_link", "Jr_tip", "Jw_tip")
    a, b = sgm._frames(lay, q), sn.Frames(packed, q)
    for f in (*fields, "RI", "rI", "nodes", "e"):
        assert np.abs(getattr(a, f) - getattr(b, f)).max() <= 1e-14, f
    # complex step along q̇: the imaginary parts over ε are the rates J̇q̇ of the loads and closures
    a, b = sgm._frames(lay, q + 1j * sgm._EPS * qd), sn.Frames(packed, q + 1j * sgm._EPS * qd, qd)
    for f in fields:
        x, y = getattr(a, f), getattr(b, f)
        assert np.abs(x.real - y.real).max() <= 1e-14, f
        assert np.abs(x.imag - y.imag).max() / sgm._EPS <= 1e-13 * max(
            1.0, np.abs(x.imag).max() / sgm._EPS
        ), f


def test_energy_and_cut_loads_equal_the_numpy_mechanics():
    case = _case("three_joint_arm.toml")
    lay = sgm._layout(case, 3)
    comp = dc.replace(lay, compiled=sn.pack(lay))
    q, qd = _state(lay, 3)
    qdd = np.random.default_rng(4).standard_normal(lay.n_dof)
    e0, e1 = sgm._energy(lay, q, qd), sgm._energy(comp, q, qd)
    for key in ("kinetic", "gravity"):
        assert e1[key] == pytest.approx(e0[key], rel=1e-13, abs=1e-13)
    c0, c1 = sgm._cut_loads(lay, q, qd, qdd), sgm._cut_loads(comp, q, qd, qdd)
    assert _rel(c1, c0) <= 1e-12


def _runs(case, **kw):
    return sg.simulate(case, engine="numpy", **kw), sg.simulate(case, engine="numba", **kw)


def test_chain_run_with_cut_loads_and_shapes_equals_the_numpy_engine():
    case = _case("three_joint_arm.toml", 0.05, 0.01)
    a, b = _runs(case, elements_per_link=3, h=1e-3, cut_loads=True, shape_points=4)
    assert a.meta["engine"] == "numpy" and b.meta["engine"] == "numba"
    assert a.meta["iterations_mean"] == b.meta["iterations_mean"]
    assert np.abs(a.link_tip - b.link_tip).max() <= 1e-13
    assert np.abs(a.joint_angle - b.joint_angle).max() <= 1e-13
    assert np.abs(a.link_shapes - b.link_shapes).max() <= 1e-13
    assert _rel(b.energy, a.energy) <= 1e-12
    assert _rel(b.cut_loads, a.cut_loads) <= 1e-10


def test_closed_loop_mechanism_run_equals_the_numpy_engine():
    case = _case("topology/four_bar.toml", 0.03, 0.01)
    a, b = _runs(case, elements_per_link=2, h=1e-3)
    assert np.abs(a.link_tip - b.link_tip).max() <= 1e-12
    # the multipliers are iterated to the step's tolerance on q̈, not beyond
    assert _rel(b.closure_loads, a.closure_loads) <= 1e-7
    assert b.closure_residual.max() <= 1e-12


def test_closed_loop_drive_laws_run_equal_the_numpy_engine():
    drives = (
        Drive("torque", PD(20.0, 2.0, Table((0.0, 0.02), (0.0, 0.5)), moment_gain=0.5)),
        Drive("torque", PD(30.0, 2.0, Constant(-0.2), limit=8.0)),
        Drive("torque", PD(5.0, 0.5, Constant(0.1))),
    )
    case = _case("three_joint_arm.toml", 0.03, 0.01, drives=drives)
    a, b = _runs(case, elements_per_link=2, h=1e-3, integrator="generalized-alpha")
    assert np.abs(a.joint_angle - b.joint_angle).max() <= 1e-12
    assert _rel(b.joint_torque, a.joint_torque) <= 1e-10


def test_bad_engine_is_a_one_line_input_error():
    with pytest.raises(InputError, match="engine") as info:
        sg.simulate(_case("cantilever_3d.toml", 0.01), elements_per_link=1, h=1e-3, engine="fortran")
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("name", ["three_joint_arm.toml", "rigid/mixed_arm.toml", "bend_45deg.toml"])
def test_second_order_strain_forces_equal_the_numpy_mechanics(name):
    lay = sgm._layout(_case(name), 2, "second-order")
    comp = dc.replace(lay, compiled=sn.pack(lay))
    q, qd = _state(lay, 5)
    q *= 0.1  # moderate strains
    U0, f0, K0 = sgm._elastic(lay, q)
    U1, f1, K1 = sgm._elastic(comp, q)
    assert U1 == pytest.approx(U0, rel=1e-13)
    assert _rel(f1, f0) <= 1e-13 and _rel(K1, K0) <= 1e-13
    d0, D0 = sgm._damping(lay, q, qd)
    d1, D1 = sgm._damping(comp, q, qd)
    assert _rel(d1, d0) <= 1e-13 and _rel(D1, D0) <= 1e-13


@pytest.mark.parametrize("name", ["three_link", "benchmarks/deluca_bang_bang"])
def test_a_planar_case_runs_as_its_embedding_and_equals_the_planar_global_solver(name):
    """A planar dttmm.Case runs on the spatial global solver as its embedding
    (SpatialCase.from_planar); the planar global solver (its own planar formulation) agrees."""
    from reference_models import global_newmark

    case = dttmm.load_case(CASES.parent / f"{name}.toml")
    case = dc.replace(case, scenario=dc.replace(case.scenario, duration=0.05, output_step=0.01))
    a = global_newmark.simulate(case, elements_per_link=2, h=1e-3)
    b = sg.simulate(case, elements_per_link=2, h=1e-3)
    assert np.abs(a.joint_angle - b.joint_angle).max() <= 1e-12
    assert np.abs(a.end_effector - b.end_effector[:, :2]).max() <= 1e-12
    assert np.abs(b.end_effector[:, 2]).max() == 0.0
    assert np.abs(a.joint_torque - b.joint_torque).max() <= 1e-9 * max(1.0, np.abs(a.joint_torque).max())
