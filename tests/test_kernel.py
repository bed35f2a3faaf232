"""The compiled engine (dttmm._kernel, numba) against the numpy reference path.

Both engines run the same algorithm (same sweeps, same frozen-coefficient iteration, same
recorder), so they must agree to round-off: 1e-12 relative on joint angles, tip deflections,
joint torques and cut loads (energy, a sum with cancellation: 1e-10). The plain sweep
amplifies round-off by the condition of its transfer chain, so there the bound is scaled by
the final-system condition number and it is only compared where that is small (k ≤ 2;
METHOD.md §6).
"""
from __future__ import annotations

import dataclasses as dc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dttmm

pytest.importorskip("numba")
from dttmm import _kernel  # noqa: E402
from dttmm.structure import build_structure  # noqa: E402

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
RTOL = 1e-12


def _case(name, duration, output_step=None):
    c = dttmm.load_case(CASES / f"{name}.toml")
    s = c.scenario
    return dc.replace(c, scenario=dc.replace(s, duration=duration, output_step=output_step or s.output_step))


def _rel(a, b):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    assert np.array_equal(np.isnan(a), np.isnan(b))
    a, b = a[~np.isnan(b)], b[~np.isnan(b)]
    if b.size == 0:
        return 0.0
    return float(np.max(np.abs(a - b)) / max(float(np.max(np.abs(b))), 1e-300))


def _compare(case, rtol=RTOL, load_rtol=None, **kw):
    r1 = dttmm.simulate(case, engine="numba", **kw)
    r0 = dttmm.simulate(case, engine="numpy", **kw)
    assert r1.meta["engine"] == "numba" and r0.meta["engine"] == "numpy"
    np.testing.assert_array_equal(r1.t, r0.t)
    assert r1.n_steps == r0.n_steps
    errs = {"angle": _rel(r1.joint_angle, r0.joint_angle), "tip": _rel(r1.tip_deflection, r0.tip_deflection),
            "torque": _rel(r1.joint_torque, r0.joint_torque), "root": _rel(r1.link_root, r0.link_root)}
    assert (r1.energy is None) == (r0.energy is None) and (r1.cut_loads is None) == (r0.cut_loads is None)
    if r0.energy is not None:
        errs["energy"] = _rel(r1.energy, r0.energy)
    bounds = {key: rtol for key in errs}
    bounds["energy"] = 100 * rtol  # a sum of kinetic, elastic and gravity terms with cancellation
    if r0.cut_loads is not None:
        errs["loads"] = _rel(r1.cut_loads, r0.cut_loads)
        bounds["loads"] = load_rtol or rtol
    bad = {key: v for key, v in errs.items() if not v <= bounds[key]}
    assert not bad, f"numba vs numpy: {errs}"
    # a tolerance-driven stop may flip by one sweep in a step where |Δq̈| sits at the threshold
    assert r1.meta["iterations_mean"] == pytest.approx(r0.meta["iterations_mean"], rel=0.05)
    assert r1.meta["unconverged_steps"] == r0.meta["unconverged_steps"]
    return r1, r0


CASE_SETUPS = {  # name: (duration, h, output_step)
    "single_link": (0.1, 1e-3, None),
    "three_link": (0.1, 1e-3, None),
    "spin_up": (0.2, 1e-2, None),
}


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
@pytest.mark.parametrize("k", [1, 2, 4])
def test_riccati_newmark_matches_numpy(name, k):
    dur, h, out = CASE_SETUPS[name]
    _compare(_case(name, dur, out), elements_per_link=k, h=h)


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
@pytest.mark.parametrize("iterations", [0, 1, "auto"])
def test_fixed_and_auto_iterations_match_numpy(name, iterations):
    dur, h, out = CASE_SETUPS[name]
    _compare(_case(name, dur, out), elements_per_link=2, h=h, iterations=iterations)


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
def test_generalized_alpha_matches_numpy(name):
    dur, h, out = CASE_SETUPS[name]
    _compare(_case(name, dur, out), elements_per_link=2, h=h, integrator="generalized-alpha", rho_inf=0.8)
    _compare(_case(name, dur / 2, out), elements_per_link=1, h=h, integrator="generalized-alpha",
             iterations=1)


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
@pytest.mark.parametrize("k", [1, 2])
def test_rk4_matches_numpy(name, k):
    dur, h, _ = CASE_SETUPS[name]
    # explicit: the axial modes need a small step
    hh = 2.5e-4 if name == "spin_up" else 2.5e-5
    _compare(_case(name, min(dur, 40 * hh), hh * 4), elements_per_link=k, h=hh, integrator="rk4")


@pytest.mark.parametrize("name,k", [("single_link", 1), ("single_link", 2), ("spin_up", 1), ("spin_up", 2),
                                    ("three_link", 1)])
@pytest.mark.parametrize("iterations", [None, 1])
def test_plain_matches_numpy(name, k, iterations):
    dur, h, out = CASE_SETUPS[name]
    case = _case(name, dur / 2, out)
    ref = dttmm.simulate(case, elements_per_link=k, h=h, sweep="plain", iterations=iterations, engine="numpy")
    amp = max(1.0, ref.meta["final_system_cond"])
    r1, _ = _compare(case, rtol=RTOL * amp, load_rtol=10 * RTOL * amp, elements_per_link=k, h=h,
                     sweep="plain", iterations=iterations)
    assert r1.meta["final_system_cond"] == pytest.approx(ref.meta["final_system_cond"], rel=1e-6)


def mixed_case(duration=0.08, output_step=0.0025):
    """Torque and motion joints, an inextensible middle link, hubs, payloads, gravity, damping,
    a torque jump inside a step (restart) and an output grid off the step grid (Hermite)."""
    al = dict(EI=2.3333333333333335, rhoA=0.27)
    links = (dttmm.Link(dttmm.Section(0.5, EA=7e6, damping=2e-4, **al), hub=dttmm.Hub(0.0, 0.01)),
             dttmm.Link(dttmm.Section(0.4, EA=None, damping=1e-4, **al), hub=dttmm.Hub(0.2, 0.005),
                        payload=dttmm.Payload(0.05, 1e-4)),
             dttmm.Link(dttmm.Section(0.3, EA=5e6, **al), hub=dttmm.Hub(0.1, 0.002),
                        payload=dttmm.Payload(0.1, 2e-4)))
    drives = (dttmm.Drive("torque", dttmm.Sine(1.0, 2.0), initial_rate=0.3),
              dttmm.Drive("motion", dttmm.Sine(0.3, 1.5, phase=0.2)),
              dttmm.Drive("torque", dttmm.BangBang((0.2, -0.3, 0.1), (0.0405, 0.061)), initial_angle=0.4))
    return dttmm.Case(dttmm.Manipulator(links, gravity=(0.0, -9.81)),
                      dttmm.Scenario(duration, output_step, drives), name="mixed")


@pytest.mark.parametrize("k", [1, 2, 4])
@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
def test_mixed_arm_matches_numpy(k, integrator):
    r1, r0 = _compare(mixed_case(), elements_per_link=k, h=1e-3, integrator=integrator)
    assert r1.meta["n_dof"] == 3 + k * (3 + 2 + 3)


def test_mixed_arm_rk4_and_plain():
    _compare(mixed_case(0.002, 1e-4), elements_per_link=1, h=1e-5, integrator="rk4")
    c = mixed_case(0.05)
    ref = dttmm.simulate(c, elements_per_link=1, h=1e-3, sweep="plain", engine="numpy")
    amp = max(1.0, ref.meta["final_system_cond"])
    _compare(c, rtol=RTOL * amp, load_rtol=10 * RTOL * amp, elements_per_link=1, h=1e-3, sweep="plain")


def test_loads_thinned_and_switches():
    c = mixed_case(0.03, 0.001)
    _compare(c, elements_per_link=2, h=7e-4, cut_loads=False, energy=False)
    _compare(c, elements_per_link=2, h=7e-4, iterations=3, tol=1e-6)


def test_auto_iterations_two_sweeps_and_close_to_converged():
    c = _case("three_link", 0.2)
    conv = dttmm.simulate(c, elements_per_link=4, h=1e-3)
    auto = dttmm.simulate(c, elements_per_link=4, h=1e-3, iterations="auto")
    assert auto.meta["iterations_mean"] < conv.meta["iterations_mean"]
    assert auto.meta["iterations_max"] >= 2 and auto.meta["unconverged_steps"] == 0
    half = dttmm.simulate(c, elements_per_link=4, h=5e-4)
    disc = np.max(np.abs(conv.tip_deflection - half.tip_deflection))
    assert np.max(np.abs(auto.tip_deflection - conv.tip_deflection)) < 0.05 * disc


@pytest.mark.parametrize("sweep", ["riccati", "plain"])
def test_accelerations_match_numpy_at_random_states(sweep):
    rng = np.random.default_rng(7)
    for case in (mixed_case(), _case("three_link", 0.1), _case("spin_up", 0.1)):
        for k in (1, 2) if sweep == "plain" else (1, 3, 8):
            nd = build_structure(case, k).n_dof
            for _ in range(3):
                q = rng.normal(scale=0.01, size=nd)
                qd = rng.normal(scale=0.5, size=nd)
                t = float(rng.uniform(0, 0.05))
                a1 = dttmm.accelerations(case, k, q, qd, t, sweep=sweep, engine="numba")
                a0 = dttmm.accelerations(case, k, q, qd, t, sweep=sweep, engine="numpy")
                bound = RTOL
                if sweep == "plain":  # within the plain sweep's own round-off (vs the Riccati sweep)
                    bound += 10 * _rel(a0, dttmm.accelerations(case, k, q, qd, t, engine="numpy"))
                assert _rel(a1, a0) <= bound


def test_divergence_reported_like_numpy():
    c = _case("single_link", 0.01)
    errs = []
    for engine in ("numba", "numpy"):
        with pytest.raises(dttmm.SimulationError) as ei:
            dttmm.simulate(c, elements_per_link=2, h=1e-3, integrator="rk4", engine=engine)
        errs.append(ei.value)
    assert (errs[0].step, errs[0].component) == (errs[1].step, errs[1].component)
    assert errs[0].partial is not None and errs[0].partial.meta["success"] is False
    np.testing.assert_allclose(errs[0].partial.joint_angle, errs[1].partial.joint_angle, rtol=1e-12)


def test_engine_selection_and_meta(monkeypatch):
    c = _case("single_link", 0.005)
    r = dttmm.simulate(c, elements_per_link=1, h=1e-3)
    assert r.meta["engine"] == "numba"
    assert isinstance(_kernel.warmup(), float)
    with pytest.raises(dttmm.InputError):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, engine="fortran")
    with pytest.raises(dttmm.InputError):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, iterations="fast")
    monkeypatch.setattr(_kernel, "HAVE_NUMBA", False)
    assert dttmm.simulate(c, elements_per_link=1, h=1e-3).meta["engine"] == "numpy"
    with pytest.raises(dttmm.InputError, match="numba"):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, engine="numba")
    with pytest.raises(dttmm.InputError, match="numba"):
        dttmm.accelerations(c, 1, np.zeros(4), np.zeros(4), engine="numba")


def test_import_and_run_without_numba():
    code = ("import sys; sys.modules['numba'] = None\n"
            "import dttmm\n"
            f"c = dttmm.load_case(r'{CASES / 'single_link.toml'}')\n"
            "import dataclasses as dc\n"
            "c = dc.replace(c, scenario=dc.replace(c.scenario, duration=0.003))\n"
            "r = dttmm.simulate(c, elements_per_link=1, h=1e-3)\n"
            "assert r.meta['engine'] == 'numpy', r.meta\n"
            "try:\n"
            "    dttmm.simulate(c, elements_per_link=1, h=1e-3, engine='numba')\n"
            "except dttmm.InputError:\n"
            "    print('ok')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_compiled_kinematics_and_energy_match_structure():
    from dttmm.structure import energy, kinematics

    rng = np.random.default_rng(3)
    case = mixed_case()
    for k in (1, 5):
        st = build_structure(case, k)
        pk = _kernel.pack(st)
        Q = rng.normal(scale=0.05, size=(4, st.n_dof))
        QD = rng.normal(scale=0.5, size=(4, st.n_dof))
        root, tip = np.empty((4, pk.n, 2)), np.empty((4, pk.n, 2))
        ang, en = np.empty((4, pk.n)), np.empty(4)
        _kernel.sample_outputs(pk.LC, pk.LI, pk.grav, pk.n, pk.k, Q, QD, root, tip, ang, en, True)
        for j in range(4):
            kin = kinematics(st, Q[j], QD[j])
            np.testing.assert_allclose(root[j], [lk.r[0] for lk in kin.links], rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(tip[j], [lk.tip for lk in kin.links], rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(ang[j], [lk.theta[0] for lk in kin.links], rtol=1e-13, atol=1e-15)
            assert en[j] == pytest.approx(energy(st, kin), rel=1e-12)


def test_thinned_cut_loads_match_numpy(monkeypatch):
    """Long runs keep every load_stride-th sample of the cut loads; force a stride of 3 with an
    output grid off the step grid (samples interpolated between step ends)."""
    import math

    from dttmm import solver

    class Thinned(solver._Recorder):
        def __init__(self, sysm, times, want_loads, want_energy):
            super().__init__(sysm, times, want_loads, want_energy)
            if want_loads:
                self.load_stride = 3
                nt, ncuts = times.size, sysm.st.n_elements + sysm.st.n_links
                self.loads = np.full(((nt - 1) // 3 + 1, ncuts, 3), math.nan)

    monkeypatch.setattr(solver, "_Recorder", Thinned)
    r1, r0 = _compare(mixed_case(0.03, 0.0013), elements_per_link=2, h=1e-3)
    assert r1.cut_loads.shape[0] == (r1.t.size - 1) // 3 + 1


# ---------------------------------------------------------------------------------------------
# strain="second-order": the elastic forces f(e) and their tangent K_T(e) at each iterate
SO = "second-order"
# The axial cut loads carry f_u = EA ε, ε = u/l + ½ wᵀGw: a small difference of nearly
# cancelling terms (the chord's shortening by bending against u/l). Their round-off floor is set
# by the problem, not by the engine: changing EA by one ulp moves the numpy path's own axial cut
# load on single_link (k = 1) by 4e-11 relative; numba vs numpy differ by 3e-11 there. Joint
# angles, tips, torques and energy stay at 1e-12 (1e-10 energy).
SO_LOAD_RTOL = 1e-9


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
@pytest.mark.parametrize("k", [1, 3])
def test_second_order_riccati_newmark_matches_numpy(name, k):
    dur, h, out = CASE_SETUPS[name]
    r1, r0 = _compare(_case(name, dur, out), elements_per_link=k, h=h, strain=SO, load_rtol=SO_LOAD_RTOL)
    assert r1.meta["strain"] == r0.meta["strain"] == SO
    lin = dttmm.simulate(_case(name, dur, out), elements_per_link=k, h=h, engine="numba")
    assert lin.meta["strain"] == "linear"
    if name != "spin_up":  # the term acts (spin_up barely bends: ~1e-12 there)
        assert _rel(r1.tip_deflection, lin.tip_deflection) > 1e-6


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
@pytest.mark.parametrize("iterations", [None, 0, 1])
def test_second_order_iterations_match_numpy(name, iterations):
    dur, h, out = CASE_SETUPS[name]
    _compare(_case(name, dur / 2, out), elements_per_link=2, h=h, iterations=iterations, strain=SO,
             load_rtol=SO_LOAD_RTOL)


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
def test_second_order_generalized_alpha_matches_numpy(name):
    dur, h, out = CASE_SETUPS[name]
    _compare(_case(name, dur / 2, out), elements_per_link=2, h=h, integrator="generalized-alpha", rho_inf=0.8,
             strain=SO, load_rtol=SO_LOAD_RTOL)


@pytest.mark.parametrize("name", sorted(CASE_SETUPS))
def test_second_order_rk4_matches_numpy(name):
    dur, h, _ = CASE_SETUPS[name]
    hh = 2.5e-4 if name == "spin_up" else 2.5e-5
    _compare(_case(name, min(dur, 40 * hh), hh * 4), elements_per_link=2, h=hh, integrator="rk4", strain=SO,
             load_rtol=SO_LOAD_RTOL)


@pytest.mark.parametrize("name,k", [("single_link", 1), ("single_link", 2), ("spin_up", 2),
                                    ("three_link", 1)])
@pytest.mark.parametrize("iterations", [None, 1])
def test_second_order_plain_matches_numpy(name, k, iterations):
    dur, h, out = CASE_SETUPS[name]
    case = _case(name, dur / 2, out)
    ref = dttmm.simulate(case, elements_per_link=k, h=h, sweep="plain", iterations=iterations, engine="numpy",
                         strain=SO)
    amp = max(1.0, ref.meta["final_system_cond"])
    _compare(case, rtol=RTOL * amp, load_rtol=max(10 * RTOL * amp, SO_LOAD_RTOL), elements_per_link=k, h=h,
             sweep="plain", iterations=iterations, strain=SO)


@pytest.mark.parametrize("integrator", ["newmark", "generalized-alpha"])
def test_second_order_mixed_arm_matches_numpy(integrator):
    """Extensible links with the second-order strain next to an inextensible one (unchanged),
    a motion joint, hubs, payloads, a restart at a torque jump and Hermite outputs."""
    kw = dict(integrator=integrator, strain=SO, load_rtol=SO_LOAD_RTOL)
    _compare(mixed_case(), elements_per_link=3, h=1e-3, **kw)
    _compare(mixed_case(0.03), elements_per_link=2, h=1e-3, iterations=1, **kw)


def test_second_order_mixed_arm_rk4_and_plain():
    _compare(mixed_case(0.002, 1e-4), elements_per_link=2, h=1e-5, integrator="rk4", strain=SO,
             load_rtol=SO_LOAD_RTOL)
    c = mixed_case(0.05)
    ref = dttmm.simulate(c, elements_per_link=1, h=1e-3, sweep="plain", engine="numpy", strain=SO)
    amp = max(1.0, ref.meta["final_system_cond"])
    _compare(c, rtol=RTOL * amp, load_rtol=max(10 * RTOL * amp, SO_LOAD_RTOL), elements_per_link=1, h=1e-3,
             sweep="plain", strain=SO)


@pytest.mark.parametrize("sweep", ["riccati", "plain"])
def test_second_order_accelerations_match_numpy_at_random_states(sweep):
    rng = np.random.default_rng(11)
    for case in (mixed_case(), _case("three_link", 0.1), _case("spin_up", 0.1)):
        for k in (1, 2) if sweep == "plain" else (1, 3, 8):
            nd = build_structure(case, k, SO).n_dof
            for _ in range(3):
                q = rng.normal(scale=0.02, size=nd)
                qd = rng.normal(scale=0.5, size=nd)
                t = float(rng.uniform(0, 0.05))
                kw = dict(sweep=sweep, strain=SO)
                a1 = dttmm.accelerations(case, k, q, qd, t, engine="numba", **kw)
                a0 = dttmm.accelerations(case, k, q, qd, t, engine="numpy", **kw)
                bound = RTOL
                if sweep == "plain":
                    bound += 10 * _rel(a0, dttmm.accelerations(case, k, q, qd, t, engine="numpy", strain=SO))
                assert _rel(a1, a0) <= bound
                lin = dttmm.accelerations(case, k, q, qd, t, engine="numba", sweep=sweep)
                assert _rel(lin, a0) > 1e-6  # the second-order forces act at these states


def test_second_order_compiled_energy_matches_structure():
    from dttmm.element import strain_energy
    from dttmm.structure import energy, kinematics

    rng = np.random.default_rng(5)
    case = mixed_case()
    for k in (1, 4):
        st = build_structure(case, k, SO)
        lin = build_structure(case, k)
        pk = _kernel.pack(st)
        Q = rng.normal(scale=0.05, size=(4, st.n_dof))
        QD = rng.normal(scale=0.5, size=(4, st.n_dof))
        root, tip = np.empty((4, pk.n, 2)), np.empty((4, pk.n, 2))
        ang, en = np.empty((4, pk.n)), np.empty(4)
        _kernel.sample_outputs(pk.LC, pk.LI, pk.grav, pk.n, pk.k, Q, QD, root, tip, ang, en, True)
        for j in range(4):
            kin = kinematics(st, Q[j], QD[j])
            e_so, e_lin = energy(st, kin), energy(lin, kinematics(lin, Q[j], QD[j]))
            assert en[j] == pytest.approx(e_so, rel=1e-12)
            assert abs(e_so - e_lin) > 1e-6 * abs(e_lin)
            # the strain energy alone, element by element
            for lk, lkn in zip(st.links, kin.links):
                assert lk.et.second_order == (lk.et.ne == 3)
                assert strain_energy(lk.et, lkn.e) >= 0.0


def test_second_order_strain_validated_on_both_engines():
    c = _case("single_link", 0.003)
    for engine in ("numba", "numpy"):
        with pytest.raises(dttmm.InputError):
            dttmm.simulate(c, elements_per_link=1, h=1e-3, engine=engine, strain="cubic")
        with pytest.raises(dttmm.InputError):
            dttmm.accelerations(c, 1, np.zeros(4), np.zeros(4), engine=engine, strain="cubic")
