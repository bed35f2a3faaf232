"""The report end to end at tiny sizes: every figure, table, page and the --from-data rebuild,
on a shipped case and a case file from outside the repository."""

from __future__ import annotations

import json
import re

import _report_browser as report_browser
import matplotlib.image as mpimg
import pytest

from experiments.plan import Plan
from experiments.references import RefSpec
from reports import cli

CASES = ["spinner", "three_link"]
FLEX = ["dttmm", "exudyn-ancf"]
# A case that is not in the repository: the single-link strip, motion-driven (spin-up law), so
# its joint torque is an output and is compared between methods.
SPINNER = """
name = "spinner"
[model]
gravity = [0.0, 0.0]
[[model.links]]
length = 1.0
EI = 2.3333333333333335
rhoA = 0.27
EA = 7.0e6
hub = { mass = 0.0, inertia = 0.01 }
[scenario]
duration = 2.0
output_step = 1e-3
[[scenario.drives]]
kind = "motion"
law = "spin_up"
rate = 2.0
ramp_time = 0.05
"""


def tiny_plan(folder) -> Plan:
    (folder / "spinner.toml").write_text(SPINNER)
    dur = dict.fromkeys(CASES, 0.04)
    ref = [RefSpec("exudyn-ancf", 4, 5e-4)]
    chk = [RefSpec("dttmm", 4, 1e-3)]
    return Plan(
        "tiny",
        dur,
        dict.fromkeys(dur, ref),
        dict.fromkeys(dur, chk),
        {
            "convergence_k": {"cases": CASES, "methods": FLEX, "ks": [1, 2, 4], "h": 2e-3},
            "convergence_h": {
                "cases": CASES,
                "methods": [*FLEX, "dttmm-rk4"],
                "hs": [4e-3, 2e-3, 1e-3],
                "k": 2,
                "explicit_hs": [1e-3],
            },
            "work_precision": {
                "cases": CASES,
                "methods": [*FLEX, "pinocchio-rigid"],
                "path": [(1, 4e-3), (2, 2e-3)],
                "rigid_h": [2e-3],
            },
            "scheme": {
                "cases": CASES,
                "variants": [{"sweep": "riccati", "iterations": None}, {"sweep": "plain", "iterations": 0}],
                "ks": [1, 2, 4],
                "h": 2e-3,
                "hs": [4e-3, 2e-3],
                "k": 2,
            },
            "paper": {
                "cases": CASES,
                "methods": FLEX + ["pinocchio-rigid", "dttmm-rk4"],
                "k": 2,
                "h": 2e-3,
                "explicit_h": 1e-3,
                "energy_reference": {"method": "dttmm", "k": 4, "h": 1e-3},
            },
            "cost": {"case": "three_link", "methods": FLEX, "ks": [1, 2, 4], "h": 2e-3},
        },
        "tiny test size",
        output_step=4e-3,
        case_files={"spinner": str(folder / "spinner.toml")},
    )


EXPECTED_ROWS = {
    "convergence_k": 12,
    "convergence_h": 14,
    "work_precision": 10,
    "scheme": 20,
    "paper": 10,
    "cost": 6,
    "convergence_k_orders": 4,
    "cost_exponents": 2,
    "paper_summary": 10,
    "paper_loads": 6,  # the two diverged RK4 runs have no histories
}
FIGURES = (
    [
        f"{s}_{c}.png"
        for s in ("convergence_k", "convergence_h", "work_precision", "scheme", "paper", "loads")
        for c in CASES
    ]
    + ["cost.png"]
    + [f"motion_{c}.png" for c in CASES]
)  # the still frames of the Motion section's videos


def _bench_json(folder):
    folder.mkdir()
    benches = [
        {
            "name": f"test_step[dttmm-{k}]",
            "group": "dttmm three_link",
            "params": {"k": k},
            "stats": {"mean": 1e-4 * k},
            "extra_info": {"n_steps": 10},
        }
        for k in (2, 4, 8)
    ]
    (folder / "bench-1.json").write_text(
        json.dumps(
            {
                "benchmarks": benches,
                "datetime": "2025-01-01",
                "machine_info": {"node": "test"},
                "commit_info": {"id": "abc"},
            }
        )
    )


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    _bench_json(root / "bench")
    cli.run_report(
        tiny_plan(root),
        root / "out",
        data=root / "data",
        scheduler="serial",
        progress=False,
        command="test",
        bench_dir=root / "bench",
        log=lambda *a: None,
    )
    return root


def test_every_figure_is_a_png_and_referenced(report):
    out = report / "out"
    html, md = (out / "index.html").read_text(), (out / "REPORT.md").read_text()
    for f in FIGURES:
        img = mpimg.imread(out / "figures" / f)
        assert img.ndim == 3 and img.shape[0] > 100 and img.shape[1] > 100
        assert f"figures/{f}" in html and f"figures/{f}" in md
    assert sorted(p.name for p in (out / "figures").glob("*.png")) == sorted(FIGURES)
    assert set(re.findall(r"figures/[\w.]+png", html)) == {f"figures/{f}" for f in FIGURES}


def test_tables_have_the_planned_rows(report):
    import pandas as pd

    data = report / "out" / "data"
    for name, n in EXPECTED_ROWS.items():
        assert len(pd.read_parquet(data / f"{name}.parquet")) == n, name
        assert len(pd.read_csv(data / f"{name}.csv")) == n, name


def test_cost_section_names_its_case(report):
    import pandas as pd

    ex = pd.read_parquet(report / "out" / "data" / "cost_exponents.parquet")
    assert list(ex.columns[:2]) == ["case", "method"] and set(ex.case) == {"three_link"}
    md = (report / "out" / "REPORT.md").read_text()
    assert "Fitted exponents of CPU time ∝ k^p (k ≥ 2): on three_link (planar) DT-TMM (Newmark) p = " in md
    assert "figures/cost.png" in md and "three_link: CPU time of the solve" in md


def test_failures_are_listed_with_reasons(report):
    import pandas as pd

    om = pd.read_csv(report / "out" / "data" / "omissions.csv")
    rk4 = om[om.method == "dttmm-rk4"]
    # explicit RK4 at 1 ms is unstable here: one omission per case (shared by two studies)
    assert sorted(rk4.case) == sorted(CASES) and rk4.reason.str.contains("diverged").all()
    md = (report / "out" / "REPORT.md").read_text()
    assert "## Omissions" in md and "dttmm-rk4" in md


def test_summary_interpretation_and_provenance(report):
    md = (report / "out" / "REPORT.md").read_text()
    assert (
        md.index("## Summary") < md.index("## Convergence in elements per link") < md.index("## Provenance")
    )
    assert re.search(r"Observed orders in k .*DT-TMM \(Newmark\) \d", md)
    assert "Reference three_link: exudyn-ancf k=4" in md and "cross-check dttmm" in md
    for key in ("machine", "python", "packages", "git commit", "rebuild"):
        assert f"**{key}**" in md


def test_rebuild_from_data_without_simulating(report, tmp_path):
    import shutil

    out = tmp_path / "out"
    shutil.copytree(report / "out", out)
    for f in (out / "figures").glob("*.png"):
        f.unlink()
    assert cli.main(["--from-data", "--out", str(out), "--bench", str(tmp_path / "no-bench")]) == 0
    assert (out / "figures" / "paper_three_link.png").exists()
    assert (out / "figures" / "loads_spinner.png").exists()
    assert "Skipped: no pytest-benchmark JSON" in (out / "REPORT.md").read_text()


def test_sections_drawn_in_parallel_equal_those_drawn_here(report, tmp_path, monkeypatch):
    """The report's sections are drawn in forked processes; drawn in this process instead, every
    figure and the text are the same (but for the measured drawing time)."""
    import functools
    import shutil

    from reports import build

    out = tmp_path / "out"
    shutil.copytree(report / "out", out)
    monkeypatch.setattr(build, "_sections", functools.partial(build._sections, workers=1))
    bench = str(report / "bench")
    assert cli.main(["--from-data", "--out", str(out), "--bench", bench]) == 0
    for f in (report / "out" / "figures").glob("*.png"):
        assert (out / "figures" / f.name).read_bytes() == f.read_bytes(), f.name

    def text(path):
        drop = ("Drawn and encoded in", "**figures rebuilt**")
        return [ln for ln in path.read_text().splitlines() if not any(d in ln for d in drop)]

    assert text(out / "REPORT.md") == text(report / "out" / "REPORT.md")


def test_old_benchmark_file_is_skipped_with_the_reason(report):
    md = (report / "out" / "REPORT.md").read_text()
    assert "bench-1.json has no scaling-suite groups" in md


def methods_label(name):
    from experiments.methods import label

    return label(name)


def test_front_page_scoreboard_and_contents(report):
    import pandas as pd

    md = (report / "out" / "REPORT.md").read_text()
    assert md.index("## Scoreboard") < md.index("## Contents") < md.index("## Summary")
    assert "Robotics and Computer-Integrated Manufacturing 49 (2018) 181–193" in md
    assert "experimental data are not available" in md
    board = pd.read_csv(report / "out" / "data" / "scoreboard_three_link.csv")
    assert set(board.method) >= {"DT-TMM (Newmark)", "Exudyn ANCF", "Pinocchio rigid"}
    row = board.set_index("method").loc["DT-TMM (Newmark)"]
    paper = pd.read_csv(report / "out" / "data" / "paper_summary.csv")
    ee = paper[(paper.case == "three_link") & (paper.method == "dttmm")].ee_l2.iloc[0]
    assert float(row["end-effector error (m)"]) == pytest.approx(ee, rel=1e-6)
    assert row["status"] == "ok"
    # no bare NaN: a missing number says why
    assert not board.isna().any().any()
    rigid = board.set_index("method").loc["Pinocchio rigid"]
    assert rigid["order in k"].startswith("not run: rigid links")
    # the front page opens with one verdict sentence per case, computed from the numbers
    wp = pd.read_csv(report / "out" / "data" / "work_precision_summary.csv")
    first = wp[wp.case == "three_link"].sort_values("cpu_time_to_target").iloc[0]
    assert f"three_link: {methods_label(first.method)} reaches the common end-effector error" in md
    html = (report / "out" / "index.html").read_text()
    assert "<nav id='contents'>" in html and "href='report.css'" in html
    assert (report / "out" / "report.css").exists()
    # every figure has a numbered caption
    assert html.count("<figure>") == html.count("<figcaption>Figure ") == len(FIGURES)


def test_case_tables_carry_the_toml_parameters(report):
    import pandas as pd

    tab = pd.read_csv(report / "out" / "data" / "case_three_link.csv", dtype=str)
    # values as written in experiments/cases/three_link.toml
    assert list(tab["L (m)"]) == ["0.5"] * 3 and list(tab["ρA (kg/m)"]) == ["0.27"] * 3
    assert list(tab["EI (N·m²)"]) == ["2.333"] * 3 and list(tab["EA (N)"]) == ["7e+06"] * 3
    assert tab["payload m (kg), J (kg·m²)"].iloc[2] == "0.1, 0"
    assert tab["drive of joint"].iloc[0] == "torque (N·m), sine (amplitude = 1, frequency = 1, until = 1)"
    sp = pd.read_csv(report / "out" / "data" / "case_spinner.csv", dtype=str)
    assert sp["drive of joint"].iloc[0].startswith("motion (rad), spin_up (rate = 2")
    md = (report / "out" / "REPORT.md").read_text()
    assert "spinner from " in md and "gravity (0, -9.81) m/s²" in md


def test_error_histories_and_loads(report):
    import numpy as np
    import pandas as pd

    data = report / "out" / "data"
    s = pd.read_parquet(data / "paper_series.parquet")
    ref = s[(s.case == "three_link") & (s.method == "reference")]
    assert ref["d_tip_deflection_3"].isna().all()
    runs = pd.read_parquet(data / "paper.parquet")
    for m in ("dttmm", "exudyn-ancf"):
        d = s[(s.case == "three_link") & (s.method == m)]
        r = runs[(runs.case == "three_link") & (runs.method == m) & (runs.role == "compared")].iloc[0]
        # the largest plotted difference is the run's max error (all samples are kept at this size)
        assert np.nanmax(np.abs(d["d_tip_deflection_3"])) == pytest.approx(r["tip3_linf"], rel=1e-9)
        assert np.nanmax(d["d_ee"]) == pytest.approx(r["ee_linf"], rel=1e-9)
    loads = pd.read_csv(data / "paper_loads.csv").set_index(["case", "method"])
    # the spinner's joint is motion-driven: its torque is an output of every method
    assert np.isfinite(loads.loc[("spinner", "exudyn-ancf"), "torque1_l2"])
    assert "torque1_l2" in loads and not np.isfinite(
        loads.loc[("three_link", "dttmm")].get("torque1_l2", np.nan)
    )
    assert np.isfinite(loads.loc[("three_link", "dttmm"), "moment1_l2"])
    # Exudyn records no energy; DT-TMM's energy is compared with the energy reference run
    assert np.isnan(loads.loc[("three_link", "exudyn-ancf"), "energy_l2"])
    assert np.isfinite(loads.loc[("three_link", "dttmm"), "energy_l2"])
    assert loads.loc[("three_link", "dttmm"), "energy_reference"] == "dttmm k=4 h=0.001"


@pytest.mark.skipif(not report_browser.available(), reason="chromium is not installed")
def test_page_in_a_real_browser_every_image_loads_no_section_empty(report):
    seen = report_browser.probe(report / "out" / "index.html")
    assert len(seen["imgs"]) == len(FIGURES)
    bad = [i["src"] for i in seen["imgs"] if not (i["complete"] and i["w"] > 100)]
    assert not bad, f"images that did not load: {bad}"
    titles = [s["title"] for s in seen["secs"]]
    assert titles[:3] == ["Scoreboard", "Summary", "Cases"] and titles[-2:] == ["Omissions", "Provenance"]
    empty = [s["title"] for s in seen["secs"] if s["text"] < 40 and not s["imgs"] and not s["tables"]]
    assert not empty, f"empty sections: {empty}"


def test_prune_cache_keeps_the_runs_a_report_uses_and_deletes_the_rest(report, tmp_path):
    import os

    stores = [p for p in (report / "data" / "cache" / "runs").iterdir() if p.is_dir()]
    assert len(stores) == 1
    before = sorted(p.relative_to(stores[0]) for p in stores[0].rglob("*.json"))
    stale = stores[0] / before[0].parent / "old-code@0123456789abcdef.json"
    stale.write_text("{}")
    os.utime(stale, (1.0e9, 1.0e9))
    msgs = []
    cli.run_report(
        tiny_plan(report),
        tmp_path / "out",
        data=report / "data",
        scheduler="serial",
        progress=False,
        command="test",
        bench_dir=report / "bench",
        log=msgs.append,
        prune_cache=True,
    )
    assert not stale.exists()
    assert sorted(p.relative_to(stores[0]) for p in stores[0].rglob("*.json")) == before
    assert any(m.startswith("pruned 1 cached-run files") for m in msgs)


def test_prune_cache_with_from_data_is_refused(capsys):
    with pytest.raises(SystemExit) as exc:
        cli.main(["--from-data", "--prune-cache"])
    assert exc.value.code == 2
    assert "--prune-cache" in capsys.readouterr().err
