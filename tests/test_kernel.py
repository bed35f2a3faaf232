"""The DT-TMM kernel (dttmm.kernel): compiled (numba) against uncompiled (python), and against
the readable numpy one-step reference (dttmm.sweeps.accelerations).

numba and python run the same source, so they differ only by the floating-point contraction
(a·b + c → FMA) the compiled sweeps are allowed: 1e-12 relative on joint angles, tips, torques
and cut loads (energy, a sum with cancellation: 1e-10; the axial cut loads of second-order
elements, a difference of nearly cancelling terms: 1e-9). The plain sweep amplifies round-off
by the condition of its final system, so there the bound is scaled by the condition number the
run records.
"""

from __future__ import annotations

import dataclasses as dc
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.kernel import driver, layout, recorder
from dttmm.structure import build_structure, energy, kinematics
from dttmm.sweeps import accelerations as oracle
from dttmm.verdict import ILL_CONDITIONED

pytest.importorskip("numba")

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
RTOL = 1e-12
SO = "second-order"
SO_LOAD_RTOL = 1e-9


def _case(name, duration, output_step=None):
    c = dttmm.load_case(CASES / f"{name}.toml")
    s = c.scenario
    return dc.replace(c, scenario=dc.replace(s, duration=duration, output_step=output_step or s.output_step))


def mixed_case(duration=0.02, output_step=0.0025):
    """Torque and motion joints, an inextensible middle link, hubs, payloads, gravity, damping,
    a torque jump inside a step (restart) and an output grid off the step grid (Hermite)."""
    al = {"EI": 2.3333333333333335, "rhoA": 0.27}
    links = (
        dttmm.Link(dttmm.Section(0.5, EA=7e6, damping=2e-4, **al), hub=dttmm.Hub(0.0, 0.01)),
        dttmm.Link(
            dttmm.Section(0.4, EA=None, damping=1e-4, **al),
            hub=dttmm.Hub(0.2, 0.005),
            payload=dttmm.Payload(0.05, 1e-4),
        ),
        dttmm.Link(
            dttmm.Section(0.3, EA=5e6, **al), hub=dttmm.Hub(0.1, 0.002), payload=dttmm.Payload(0.1, 2e-4)
        ),
    )
    drives = (
        dttmm.Drive("torque", dttmm.Sine(1.0, 2.0), initial_rate=0.3),
        dttmm.Drive("motion", dttmm.Sine(0.3, 1.5, phase=0.2)),
        dttmm.Drive("torque", dttmm.BangBang((0.2, -0.3, 0.1), (0.0105, 0.016)), initial_angle=0.4),
    )
    return dttmm.Case(
        dttmm.Manipulator(links, gravity=(0.0, -9.81)),
        dttmm.Scenario(duration, output_step, drives),
        name="mixed",
    )


@pytest.fixture(scope="module")
def mixed():
    return mixed_case()


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
    r0 = dttmm.simulate(case, engine="python", **kw)
    assert r1.meta["engine"] == "numba" and r0.meta["engine"] == "python"
    np.testing.assert_array_equal(r1.t, r0.t)
    assert r1.n_steps == r0.n_steps
    errs = {
        "angle": _rel(r1.joint_angle, r0.joint_angle),
        "tip": _rel(r1.tip_deflection, r0.tip_deflection),
        "torque": _rel(r1.joint_torque, r0.joint_torque),
        "energy": _rel(r1.energy, r0.energy),
        "loads": _rel(r1.cut_loads, r0.cut_loads),
    }
    bounds = dict.fromkeys(errs, rtol)
    bounds.update(energy=100 * rtol, loads=load_rtol or rtol)
    bad = {key: v for key, v in errs.items() if not v <= bounds[key]}
    assert not bad, f"numba vs python: {errs}"
    # iteration counts are not compared: a tolerance-driven stop may flip by one sweep in a step
    # where |Δq̈| sits at the threshold, and round-off (processor-dependent) decides which way
    return r1, r0


MODES = {"converged": None, "fixed": 1, "auto": "auto"}
INTEGRATORS = {"newmark": {}, "generalized-alpha": {"rho_inf": 0.8}}


@pytest.mark.parametrize("mode", sorted(MODES))
@pytest.mark.parametrize("integrator", sorted(INTEGRATORS))
@pytest.mark.parametrize("sweep", ["riccati", "plain"])
@pytest.mark.parametrize("strain", ["linear", SO])
def test_engines_agree(mixed, strain, sweep, integrator, mode):
    """numba and python on the mixed arm (k = 1: the plain sweep stays well conditioned)."""
    kw = dict(
        elements_per_link=1,
        h=1e-3,
        strain=strain,
        sweep=sweep,
        integrator=integrator,
        iterations=MODES[mode],
        **INTEGRATORS[integrator],
    )
    rtol, load_rtol = RTOL, SO_LOAD_RTOL if strain == SO else None
    if sweep == "plain":
        amp = max(1.0, dttmm.simulate(mixed, engine="numba", **kw).meta["final_system_cond"])
        rtol, load_rtol = RTOL * amp, max(10 * RTOL * amp, load_rtol or 0.0)
    _compare(mixed, rtol=rtol, load_rtol=load_rtol, **kw)


@pytest.mark.parametrize("strain", ["linear", SO])
def test_engines_agree_rk4(strain):
    _compare(
        mixed_case(0.0005, 1e-4),
        elements_per_link=2,
        h=1e-5,
        integrator="rk4",
        strain=strain,
        load_rtol=SO_LOAD_RTOL if strain == SO else None,
    )


def _random_states(case, k, strain, rng, n=3):
    st = build_structure(case, k, strain)
    for _ in range(n):
        yield (
            st,
            rng.normal(scale=0.02, size=st.n_dof),
            rng.normal(scale=0.5, size=st.n_dof),
            float(rng.uniform(0, 0.05)),
        )


@pytest.mark.parametrize("strain", ["linear", SO])
@pytest.mark.parametrize("sweep", ["riccati", "plain"])
def test_kernel_accelerations_match_numpy_reference(strain, sweep):
    """q̈ of the compiled kernel at random states against the readable numpy sweeps. The plain
    sweep's round-off is its own error against the stable Riccati sweep, e_p = |q̈_plain −
    q̈_riccati| (numpy): the two plain implementations must agree within 100·e_p (the
    condition number of the 3×3 final system alone does not capture the loss in the transfer
    chain: e_p reaches 1e-10 at κ = 30 here)."""
    rng = np.random.default_rng(7)
    for case in (mixed_case(), _case("three_link", 0.1), _case("spin_up", 0.1)):
        for k in (1, 2) if sweep == "plain" else (1, 3, 8):
            for st, q, qd, t in _random_states(case, k, strain, rng):
                tau, mot = driver.drive_values(st, t)
                ref = oracle(st, q, qd, tau, mot, sweep)
                a = dttmm.accelerations(case, k, q, qd, t, sweep=sweep, engine="numba", strain=strain)
                bound = RTOL
                if sweep == "plain":
                    bound += 100 * _rel(ref.qdd, oracle(st, q, qd, tau, mot, "riccati").qdd)
                assert _rel(a, ref.qdd) <= bound, (case.name, k, ref.cond)


def test_second_order_forces_act_at_random_states():
    rng = np.random.default_rng(11)
    for _st, q, qd, t in _random_states(mixed_case(), 3, SO, rng):
        a_so = dttmm.accelerations(mixed_case(), 3, q, qd, t, strain=SO)
        a_lin = dttmm.accelerations(mixed_case(), 3, q, qd, t)
        assert _rel(a_lin, a_so) > 1e-6


@pytest.mark.parametrize("strain", ["linear", SO])
def test_kernel_kinematics_and_energy_match_structure(strain):
    """The kernel's output sampling (kinematics and energy at a state) against the numpy
    structure (kinematics, energy)."""
    rng = np.random.default_rng(3)
    for k in (1, 5):
        st = build_structure(mixed_case(), k, strain)
        md = layout.build_model(st)
        rec = driver.new_record(st, np.zeros(1), False, True)
        for _ in range(4):
            q, qd = rng.normal(scale=0.05, size=st.n_dof), rng.normal(scale=0.5, size=st.n_dof)
            recorder.sample(md, q, qd, 0, rec)
            kin = kinematics(st, q, qd)
            np.testing.assert_allclose(rec.root[0], [lk.r[0] for lk in kin.links], rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(rec.tip[0], [lk.tip for lk in kin.links], rtol=1e-13, atol=1e-15)
            np.testing.assert_allclose(rec.root_angle[0], [lk.theta[0] for lk in kin.links], rtol=1e-13)
            assert rec.energy[0] == pytest.approx(energy(st, kin), rel=1e-12)


def test_thinned_cut_loads_are_every_stride_th_sample(monkeypatch):
    """Long runs keep every load_stride-th sample of the cut loads: forced to 3 with an output
    grid off the step grid, the kept rows equal those of the full record."""
    c = mixed_case(0.03, 0.0013)
    full = dttmm.simulate(c, elements_per_link=2, h=1e-3)
    make = driver.new_record

    def thinned(st, times, want_loads, want_energy):
        rec = make(st, times, want_loads, want_energy)
        return rec._replace(
            loads=np.full(((times.size - 1) // 3 + 1, *rec.loads.shape[1:]), np.nan), load_stride=3
        )

    monkeypatch.setattr(driver, "new_record", thinned)
    r = dttmm.simulate(c, elements_per_link=2, h=1e-3)
    assert r.cut_loads.shape[0] == (r.t.size - 1) // 3 + 1
    np.testing.assert_array_equal(r.cut_loads, full.cut_loads[::3])
    np.testing.assert_array_equal(r.cut_load_t, full.t[::3])


def test_divergence_reported_alike_by_both_engines():
    c = _case("single_link", 0.01)
    errs = []
    for engine in ("numba", "python"):
        with pytest.raises(dttmm.SimulationError) as ei:
            dttmm.simulate(c, elements_per_link=2, h=1e-3, integrator="rk4", engine=engine)
        errs.append(ei.value)
    assert str(errs[0]) == str(errs[1])
    assert errs[0].partial is not None and errs[0].partial.status == "failed"
    np.testing.assert_allclose(errs[0].partial.joint_angle, errs[1].partial.joint_angle, rtol=1e-12)


def test_engine_selection_and_meta():
    c = _case("single_link", 0.005)
    assert dttmm.simulate(c, elements_per_link=1, h=1e-3).meta["engine"] == "numba"
    assert isinstance(driver.warmup(), float)
    with pytest.raises(dttmm.InputError, match="engine"):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, engine="fortran")
    with pytest.raises(dttmm.InputError, match="iterations"):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, iterations="fast")
    with pytest.raises(dttmm.InputError, match="strain"):
        dttmm.simulate(c, elements_per_link=1, h=1e-3, strain="cubic")
    with pytest.warns(DeprecationWarning, match="python"):
        r = dttmm.simulate(c, elements_per_link=1, h=1e-3, engine="numpy")
    assert r.meta["engine"] == "python"


def _run_python(code: str, env_extra=None):
    import os

    env = dict(os.environ, **(env_extra or {}))
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env, check=False
    )


def test_runs_without_numba():
    """With numba unimportable the kernel runs uncompiled, with the same numbers."""
    code = (
        "import sys; sys.modules['numba'] = None\n"
        "import dataclasses as dc, numpy as np, dttmm\n"
        f"c = dttmm.load_case(r'{CASES / 'single_link.toml'}')\n"
        "c = dc.replace(c, scenario=dc.replace(c.scenario, duration=0.003))\n"
        "r = dttmm.simulate(c, elements_per_link=2, h=1e-3)\n"
        "assert r.meta['engine'] == 'python', r.meta\n"
        "np.save(sys.stdout.buffer, r.tip_deflection)\n"
        "try:\n"
        "    dttmm.simulate(c, elements_per_link=1, h=1e-3, engine='numba')\n"
        "except dttmm.InputError:\n"
        "    pass\n"
        "else:\n"
        "    raise SystemExit('engine=numba accepted without numba')\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, timeout=300, check=False)
    assert out.returncode == 0, out.stderr.decode()
    import io

    tip = np.load(io.BytesIO(out.stdout))
    ref = dttmm.simulate(_case("single_link", 0.003), elements_per_link=2, h=1e-3)
    assert _rel(tip, ref.tip_deflection) <= RTOL


def test_cache_folder_named_by_source_hash():
    from dttmm.kernel import _jit

    h = _jit.source_hash()
    assert len(h) == 16 and h in _jit.CACHE_DIR
    assert Path(_jit.CACHE_DIR).exists()


def test_auto_iterations_two_sweeps_and_close_to_converged():
    c = _case("three_link", 0.2)
    conv = dttmm.simulate(c, elements_per_link=4, h=1e-3)
    auto = dttmm.simulate(c, elements_per_link=4, h=1e-3, iterations="auto")
    assert auto.meta["iterations_mean"] < conv.meta["iterations_mean"]
    assert auto.meta["iterations_max"] >= 2 and auto.meta["unconverged_steps"] == 0
    half = dttmm.simulate(c, elements_per_link=4, h=5e-4)
    disc = np.max(np.abs(conv.tip_deflection - half.tip_deflection))
    assert np.max(np.abs(auto.tip_deflection - conv.tip_deflection)) < 0.05 * disc


# ---------------------------------------------------------------------------------------------
# Result.status of a finished run
def test_status_ok_on_every_shipped_case_at_default_settings():
    for path in sorted(CASES.glob("*.toml")):
        r = dttmm.simulate(dttmm.load_case(path), elements_per_link=8, h=1e-3, cut_loads=False, energy=False)
        assert r.status == "ok" and r.warnings == (), (path.name, r.warnings)


def test_status_unconverged_when_max_iterations_is_exhausted():
    r = dttmm.simulate(_case("three_link", 0.05), elements_per_link=4, h=1e-3, max_iterations=1)
    assert r.status == "unconverged" and not r.success
    assert r.meta["unconverged_steps"] == r.n_steps
    assert "max_iterations = 1" in r.warnings[0]


def test_status_ill_conditioned_for_the_plain_sweep_at_k4():
    """three_link, k = 4: the plain sweep's final system reaches κ ≈ 1e14 (the paper's form
    loses digits exponentially in k); k = 1 stays well conditioned."""
    c = _case("three_link", 0.05)
    r = dttmm.simulate(c, elements_per_link=4, h=1e-3, sweep="plain")
    assert r.status == "ill-conditioned" and r.meta["final_system_cond"] > ILL_CONDITIONED
    assert "riccati" in r.warnings[-1]
    assert dttmm.simulate(c, elements_per_link=1, h=1e-3, sweep="plain").status == "ok"
