"""One public API for every arm: ``dttmm.simulate``, ``accelerations`` and ``statics`` take a
planar or a spatial case (the kernel chosen by the case, or by ``kernel=``); a wrong type is a
one-line error naming the type; spatial runs have the run-size guard and the progress bar of
planar ones, and the bar's chunked run is the one-call run bit for bit."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

import dttmm
from dttmm.spatial import SpatialCase, SpatialResult, embed_planar

CASES = Path(__file__).resolve().parent.parent / "experiments" / "cases"
SPATIAL = sorted((CASES / "spatial").glob("*.toml"))


def short(case, duration=0.02, output_step=0.01):
    sc = dataclasses.replace(case.scenario, duration=duration, output_step=output_step)
    return dataclasses.replace(case, scenario=sc)


@pytest.mark.parametrize("path", SPATIAL, ids=lambda p: p.stem)
def test_simulate_every_spatial_case(path):
    """``dttmm.simulate`` runs every shipped spatial case (shortened) on the spatial kernel, and
    gives what ``dttmm.spatial.simulate`` gives, bit for bit."""
    case = short(dttmm.load_case(path))
    assert isinstance(case, SpatialCase)
    r = dttmm.simulate(case, elements_per_link=2, h=1e-3, shape_points=3)
    assert isinstance(r, SpatialResult) and r.status == "ok", r.warnings
    assert r.meta["method"] == "dttmm-spatial"
    assert r.link_shapes.shape == (r.t.size, case.model.n_links, 3, 3)
    s = dttmm.spatial.simulate(case, elements_per_link=2, h=1e-3)
    assert s.end_effector.tobytes() == r.end_effector.tobytes()


def test_planar_case_on_either_kernel():
    """A planar case runs on the planar kernel by default and on the spatial one when asked,
    with the same motion to round-off (docs/spatial.md §1)."""
    case = short(dttmm.load_case(CASES / "three_link.toml"), duration=0.05)
    opts = dict(elements_per_link=2, h=1e-3)
    rp = dttmm.simulate(case, **opts)
    rs = dttmm.simulate(case, **opts, kernel="spatial")
    assert type(rp) is dttmm.Result and rp.meta["method"] != "dttmm-spatial"
    assert isinstance(rs, SpatialResult) and rs.meta["method"] == "dttmm-spatial"
    np.testing.assert_allclose(rs.end_effector[:, :2], rp.end_effector, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rs.joint_angle, rp.joint_angle, rtol=0, atol=1e-9)
    assert dttmm.simulate(case, **opts, kernel="planar").end_effector.tobytes() == rp.end_effector.tobytes()


def test_accelerations_of_either_kind():
    sc = dttmm.load_case(CASES / "spatial" / "two_joint_arm.toml")
    n = dttmm.spatial.simulate(short(sc), elements_per_link=2, h=1e-2).meta["n_dof"]
    q, qd = np.linspace(0.0, 0.1, n), np.zeros(n)
    a = dttmm.accelerations(sc, 2, q, qd)
    assert a.tobytes() == dttmm.spatial.accelerations(sc, 2, q, qd).tobytes()
    pc = dttmm.load_case(CASES / "single_link.toml")
    emb = SpatialCase(embed_planar(pc.model), pc.scenario)
    n = dttmm.spatial.simulate(short(emb), elements_per_link=2, h=1e-2).meta["n_dof"]
    q = np.zeros(n)
    a = dttmm.accelerations(pc, 2, q, q, kernel="spatial")
    assert a.tobytes() == dttmm.spatial.accelerations(emb, 2, q, q).tobytes()


def test_statics_of_either_kind():
    """``dttmm.statics``: the spatial statics; a planar case embedded (its plane is x–y)."""
    sc = dttmm.load_case(CASES / "spatial" / "cantilever_3d.toml")
    a = dttmm.statics(sc, elements_per_link=2)
    b = dttmm.spatial.statics(sc, elements_per_link=2)
    assert a.q.tobytes() == b.q.tobytes()
    pc = dttmm.load_case(CASES / "benchmarks" / "cantilever_self_weight.toml")
    r = dttmm.statics(pc, elements_per_link=4, steps=4)
    assert abs(r.tip_position[2]) < 1e-12 and r.tip_position[1] < 0.0  # sags in its plane


@pytest.mark.parametrize("call", ["simulate", "accelerations", "statics"])
def test_wrong_type_is_one_short_line(call):
    fn = getattr(dttmm, call)
    bad = {"model": list(range(2000))}
    with pytest.raises(dttmm.InputError) as exc:
        if call == "accelerations":
            fn(bad, 2, [0.0], [0.0])
        else:
            fn(bad, elements_per_link=2, h=1e-3) if call == "simulate" else fn(bad, elements_per_link=2)
    msg = str(exc.value)
    assert "dict" in msg and "\n" not in msg and len(msg) < 200, msg


def test_kernel_choice_checked():
    sc = short(dttmm.load_case(CASES / "spatial" / "two_joint_arm.toml"))
    with pytest.raises(dttmm.InputError, match="kernel"):
        dttmm.simulate(sc, elements_per_link=2, h=1e-3, kernel="planar")
    with pytest.raises(dttmm.InputError, match="kernel"):
        dttmm.simulate(sc, elements_per_link=2, h=1e-3, kernel="fast")
    with pytest.raises(dttmm.InputError, match="sweep"):
        dttmm.simulate(sc, elements_per_link=2, h=1e-3, sweep="plain")


def test_spatial_run_size_guard():
    """A spatial run whose tables would not fit is refused before anything is allocated."""
    sc = dttmm.load_case(CASES / "spatial" / "two_joint_arm.toml")
    with pytest.raises(dttmm.InputError, match=r"^h = 1e-09: gives 1e\+09 steps"):
        dttmm.simulate(sc, elements_per_link=2, h=1e-9)
    total = dttmm.check_run_size(sc, 4, 1e-3)
    with pytest.raises(dttmm.InputError, match="output_step|h"):
        dttmm.check_run_size(sc, 4, 1e-3, limit_bytes=total / 2)
    assert dttmm.check_run_size(sc, 4, 1e-3, shape_points=9, cut_loads=True) > total


@pytest.mark.parametrize("iterations", [None, "auto"])
def test_spatial_progress_bar_changes_nothing(iterations, capsys):
    """With the bar the loop runs in chunks (one step each here); the Result is the one-call
    run's bit for bit, the residual checks of ``iterations="auto"`` included."""
    sc = short(dttmm.load_case(CASES / "spatial" / "two_joint_arm.toml"), duration=0.05)
    opts = dict(elements_per_link=2, h=1e-3, iterations=iterations, cut_loads=True)
    quiet = dttmm.simulate(sc, **opts, progress=False)
    shown = dttmm.simulate(sc, **opts, progress=True)
    assert "dttmm" in capsys.readouterr().err
    for f in dataclasses.fields(quiet):
        a = getattr(quiet, f.name)
        if isinstance(a, np.ndarray):
            assert a.tobytes() == getattr(shown, f.name).tobytes(), f.name
    keep = lambda m: {k: v for k, v in m.items() if k not in ("cpu_time", "versions")}
    assert keep(quiet.meta) == keep(shown.meta)


def test_cli_simulates_a_spatial_case(tmp_path, capsys):
    """``dttmm simulate`` on a spatial case file: the spatial kernel, its table and plot."""
    import pandas as pd

    from dttmm.cli import main

    text = (CASES / "spatial" / "two_joint_arm.toml").read_text()
    src = tmp_path / "arm.toml"
    src.write_text(
        text.replace("duration = 1.0", "duration = 0.02").replace("output_step = 1e-3", "output_step = 0.01")
    )
    out = tmp_path / "out"
    code = main(
        ["simulate", str(src), "--elements", "2", "--h", "1e-3", "--shape-points", "3", "--out", str(out)]
    )
    assert code == 0, capsys.readouterr().err
    df = pd.read_csv(out / "two_joint_arm.csv")
    assert {"link_tip_z_2", "twist_1", "link_shape_z_2_3"} <= set(df.columns)
    assert (out / "two_joint_arm.png").exists()
