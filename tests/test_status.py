"""Result.status of fixed sweep counts and "auto" (residual check, energy check), and
divergence checks. References are the converged runs (tolerance 1e-10) of the same case."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import dttmm

pytest.importorskip("numba")

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"
SHIPPED = sorted(CASES.glob("*.toml"))
RUN = {"elements_per_link": 8, "h": 1e-3, "cut_loads": False}


@pytest.fixture(scope="module")
def three_link():
    c = dttmm.load_case(CASES / "three_link.toml")
    return c, dttmm.simulate(c, **RUN)


def test_one_shot_on_three_link_is_unconverged_and_far_from_the_converged_run(three_link):
    """iterations=0 (the one-shot scheme) is unstable here: the energy grows after the torques
    stop (t > 1 s) and the arm ends radians away from the converged run."""
    c, ref = three_link
    r = dttmm.simulate(c, iterations=0, **RUN)
    assert r.status == "unconverged" and not r.success
    assert np.max(np.abs(r.joint_angle - ref.joint_angle)) > 3.0
    assert r.meta["energy_growth"] > 0.01 and 1.0 < r.meta["energy_growth_t"] <= 2.0
    assert any("energy grew" in w for w in r.warnings)
    assert ref.meta["energy_growth"] < 1e-4


def test_two_sweeps_on_three_link_are_ok_and_close_to_the_converged_run(three_link):
    c, ref = three_link
    r = dttmm.simulate(c, iterations=1, **RUN)
    assert r.status == "ok" and r.warnings == ()
    assert np.max(np.abs(r.joint_angle - ref.joint_angle)) < 1e-5
    assert 0.0 < r.meta["residual_worst_ratio"] < 0.01
    assert r.meta["residual_checks"] == 33  # steps 0, 64, …, 1984 and the last


def test_one_shot_on_spin_up_fails_the_residual_check():
    """spin_up is smooth: its truncation error is tiny, and one sweep per step leaves an
    iteration error several times larger; the warning names the first and worst times."""
    r = dttmm.simulate(dttmm.load_case(CASES / "spin_up.toml"), iterations=0, **RUN)
    assert r.status == "unconverged"
    assert r.meta["residual_worst_ratio"] > 1.0 and r.meta["residual_flagged"] > 0
    w = r.warnings[0]
    assert f"first at t = {r.meta['residual_first_t']:.6g} s" in w and "worst at t = " in w


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_auto_is_ok_on_every_shipped_case(path):
    r = dttmm.simulate(dttmm.load_case(path), iterations="auto", **RUN)
    assert r.status == "ok" and r.warnings == (), r.warnings
    assert r.meta["residual_checks"] > 0 and r.meta["residual_worst_ratio"] < 0.1


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.stem)
def test_default_is_ok_with_energy_on_every_shipped_case(path):
    r = dttmm.simulate(dttmm.load_case(path), **RUN)
    assert r.status == "ok" and r.warnings == (), r.warnings
    assert "residual_checks" not in r.meta  # the tolerance is the check


# ---------------------------------------------------------------------------------------------
# divergence: the run stops at the first non-physical state and keeps what came before
def _diverging(engine="numba"):
    """iterations=0 on three_link at k = 4, h = 5e-4 blows up near t = 0.96 s."""
    c = dttmm.load_case(CASES / "three_link.toml")
    with pytest.raises(dttmm.SimulationError) as ei:
        dttmm.simulate(c, elements_per_link=4, h=5e-4, iterations=0, engine=engine)
    return c, ei.value


def test_divergence_stops_at_the_element_length_bound_and_keeps_a_physical_partial():
    c, err = _diverging()
    msg = str(err)
    assert "beyond 2 element lengths" in msg and "link 2, element 3, v" in msg, msg
    assert 0.9 < err.t < 1.0 and f"at t = {err.t:.6g} s" in msg
    p = err.partial
    assert p.status == "failed" and p.t[-1] < err.t and p.t.size > 900
    lengths = np.array([lk.beam.length for lk in c.model.links])
    assert np.all(np.isfinite(p.tip_deflection))
    assert np.all(np.abs(p.tip_deflection) < lengths), np.abs(p.tip_deflection).max(axis=0)


def test_divergence_message_is_the_same_for_both_engines():
    """(The partials agree in length only: round-off differences grow in the unstable run.)"""
    _, a = _diverging("numba")
    _, b = _diverging("python")
    assert str(a) == str(b)
    assert a.partial.t.size == b.partial.t.size


# ---------------------------------------------------------------------------------------------
# progress bar: decided by the run time estimated after the first chunk
def _short_run(**kw):
    c = dttmm.load_case(CASES / "single_link.toml")
    return dttmm.simulate(c, elements_per_link=2, h=1e-3, cut_loads=False, energy=False, **kw)


def test_no_progress_bar_for_a_short_run(capsys):
    _short_run()
    assert "dttmm" not in capsys.readouterr().err


def test_progress_bar_when_the_estimate_exceeds_the_threshold(monkeypatch, capsys):
    from dttmm.kernel import driver

    ref = _short_run()
    monkeypatch.setattr(driver, "PROGRESS_AFTER", 0.0)
    monkeypatch.setattr(driver, "SHORT_RUN", 0)
    capsys.readouterr()
    r = _short_run()
    err = capsys.readouterr().err
    assert "dttmm" in err and "step" in err, err
    np.testing.assert_array_equal(r.joint_angle, ref.joint_angle)  # chunking changes nothing
    _short_run(progress=False)
    assert "dttmm" not in capsys.readouterr().err


def test_energy_check_counts_growth_only_where_every_torque_is_zero():
    """Synthetic series: the energy rises while a torque acts (not counted), and by 0.3 J
    from the start of a torque-free stretch (counted); scale = the 2 J range (no gravity, no
    torque work since α̇ = 0)."""
    from dttmm.kernel import driver
    from dttmm.structure import build_structure

    st = build_structure(dttmm.load_case(CASES / "single_link.toml"), 1)
    st = type("NoGravity", (), {"links": st.links, "gravity": np.zeros(2)})()  # m|g|L = 0
    t = np.arange(8.0)
    energy = np.array([0.0, 1.0, 1.0, 0.8, 1.3, 2.0, 1.9, 1.95])
    torque = np.array([[1.0], [1.0], [0.0], [0.0], [0.0], [1.0], [0.0], [0.0]])
    meta = {}
    driver._energy_growth(meta, st, t, energy, torque, np.zeros_like(torque))
    assert meta["energy_growth_t"] == 4.0
    assert meta["energy_growth"] == pytest.approx(0.3 / 2.0)
