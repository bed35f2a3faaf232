"""The report end to end at tiny sizes: every figure, table, page and the --from-data rebuild."""

from __future__ import annotations

import json
import re

import matplotlib.image as mpimg
import pytest

from experiments.plan import Plan
from experiments.references import RefSpec
from reports import cli

CASES = ["single_link", "three_link"]
FLEX = ["dttmm", "exudyn-ancf"]


def tiny_plan() -> Plan:
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
                "methods": FLEX,
                "hs": [4e-3, 2e-3, 1e-3],
                "k": 2,
                "hs_by_method": {"dttmm-rk4": [1e-3]},
            },
            "work_precision": {
                "cases": CASES,
                "methods": FLEX,
                "path": [(1, 4e-3), (2, 2e-3)],
                "rigid": {"method": "pinocchio-rigid", "h": [2e-3]},
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
                "h_by_method": {"dttmm-rk4": 1e-3},
            },
            "cost": {"case": "three_link", "methods": FLEX, "ks": [1, 2, 4], "h": 2e-3},
        },
        "tiny test size",
        output_step=4e-3,
    )


EXPECTED_ROWS = {
    "convergence_k": 12,
    "convergence_h": 14,
    "work_precision": 10,
    "scheme": 20,
    "paper": 8,
    "cost": 6,
    "convergence_k_orders": 4,
    "cost_exponents": 2,
    "paper_summary": 10,
}
FIGURES = [
    f"{s}_{c}.png"
    for s in ("convergence_k", "convergence_h", "work_precision", "scheme", "paper")
    for c in CASES
] + ["cost.png", "bench_scaling.png"]


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
    import dttmm

    try:
        dttmm.simulate(
            dttmm.load_case(cli.__file__.rsplit("/", 2)[0] + "/experiments/cases/single_link.toml"),
            elements_per_link=1,
            h=1e-3,
            integrator="newmark",
        )
    except NotImplementedError:
        pytest.skip("dttmm.simulate not implemented yet")
    except Exception:
        pass
    root = tmp_path_factory.mktemp("report")
    _bench_json(root / "bench")
    cli.run_report(
        tiny_plan(),
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


def test_failures_are_listed_with_reasons(report):
    import pandas as pd

    om = pd.read_csv(report / "out" / "data" / "omissions.csv")
    rk4 = om[om.method == "dttmm-rk4"]
    # explicit RK4 at 1 ms is unstable here: one omission per case (shared by two studies)
    assert sorted(rk4.case) == CASES and rk4.reason.str.contains("diverged").all()
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
    out = report / "out"
    for f in (out / "figures").glob("*.png"):
        f.unlink()
    assert cli.main(["--from-data", "--out", str(out), "--bench", str(tmp_path / "no-bench")]) == 0
    assert (out / "figures" / "paper_three_link.png").exists()
    assert not (out / "figures" / "bench_scaling.png").exists()
    assert "Skipped: no pytest-benchmark JSON" in (out / "REPORT.md").read_text()
