"""The report's cost-scaling section from pytest-benchmark JSON: fitted exponents, tables,
ratios and figures from a synthetic file with known power laws, and the real file if present."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from reports import bench, build

KS = [1, 2, 4, 8, 16, 32, 64]
NS = [1, 2, 3, 5, 8]
# time per step (s) = c · x^p, so the fitted exponents and the ratios are known exactly
LAWS = {"dttmm-converged": (1e-6, 1), "dttmm-2nd": (2e-6, 1), "global": (1e-6, 3), "exudyn-ancf": (2e-5, 1)}
REAL = sorted(Path(__file__).resolve().parents[1].glob("data/bench/*.json"))


def _bench(group, k, tps, n_links=3, method=None, case="three_link", n_steps=100):
    extra = {
        "method": method,
        "case": case,
        "elements_per_link": k,
        "n_links": n_links,
        "n_steps": n_steps,
        "time_per_step": tps,
        "time_per_element_step": tps / (k * n_links) if k else None,
    }
    return {
        "name": f"t[{group}-{k}]",
        "group": group,
        "params": {},
        "extra_info": extra,
        "stats": {"mean": 10 * tps * n_steps},
    }  # the mean includes set-up: it must not be used


def _write(folder, benches, name="bench-1.json"):
    folder.mkdir(parents=True, exist_ok=True)
    doc = {
        "benchmarks": benches,
        "datetime": "2026-01-02T03:04:05+00:00",
        "machine_info": {
            "node": "box",
            "python_version": "3.11.7",
            "cpu": {"brand_raw": "Test CPU", "count": 2},
        },
        "commit_info": {"id": "0123456789abcdef", "dirty": False},
    }
    (folder / name).write_text(json.dumps(doc))
    return folder


def synthetic(folder):
    b = []
    for case in ("three_link", "single_link"):
        for m, (c, p) in LAWS.items():
            b += [
                _bench(f"elements:{case}:{m}", k, c * k**p, 3 if case == "three_link" else 1, case=case)
                for k in KS
            ]
    b.append(_bench("elements:three_link:pinocchio-rigid", None, 3e-5))
    for m, p in (("dttmm", 1), ("global", 3)):
        b += [_bench(f"links:{m}", 8, 1e-6 * n**p, n, method=m, case=f"chain{n}") for n in NS]
    for k in (4, 16):
        b += [
            _bench(f"one-step:k={k}", k, c * k**p, method=m.split("-conv")[0], n_steps=10)
            for m, (c, p) in LAWS.items()
        ]
    b.append({"name": "odd", "group": "kernel:exponent", "stats": {"mean": 1.0}})  # no k: ignored
    return _write(folder, b)


def _build(tmp_path, bench_dir, tables=None):
    out = tmp_path / "out"
    build.build(dict(tables or {}), {}, out, bench_dir=bench_dir)
    return out


def _is_png(path):
    import matplotlib.image as mpimg

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 200


def test_exponents_tables_and_figures_from_known_power_laws(tmp_path):
    out = _build(tmp_path, synthetic(tmp_path / "bench"))
    for f in ("bench_elements.png", "bench_links.png"):
        _is_png(out / "figures" / f)
    assert not (out / "figures" / "bench_scaling.png").exists()
    ex = pd.read_csv(out / "data" / "bench_exponents.csv")
    el = ex[ex.scan == "elements per link"].set_index(["case", "method"]).exponent
    for case in ("three_link", "single_link"):
        for m, (_, p) in LAWS.items():
            assert el[(case, m)] == pytest.approx(p, abs=0.05)
    assert (ex[ex.scan == "elements per link"].fit_from == bench.K_MIN).all()
    ln = ex[ex.scan.str.startswith("links")].set_index("method").exponent
    assert ln["dttmm"] == pytest.approx(1, abs=0.05) and ln["global"] == pytest.approx(3, abs=0.05)
    per = pd.read_csv(out / "data" / "bench_element_step_us.csv")
    assert list(per.k) == KS and list(per.columns) == ["k", *LAWS]
    # µs per element-step of the k-linear law on three_link: 1e-6 k / (3 k) s
    assert np.allclose(per["dttmm-converged"], 1e6 * 1e-6 / 3)


def test_ratios_equal_the_known_values(tmp_path):
    """Ratios only between runs of the same element strain, stated with 2 significant digits."""
    eq = pd.DataFrame(
        {
            "case": ["three_link"] * 5,
            "target_error": [1e-4] * 5,
            "method": ["dttmm", "global", "dttmm-2nd", "exudyn-ancf", "exudyn-beam"],
            "cpu_time": [0.5, 50.0, 1.0, 28.0, np.nan],
        }
    )
    out = _build(tmp_path, synthetic(tmp_path / "bench"), {"work_precision_equal_accuracy": eq})
    r = pd.read_csv(out / "data" / "bench_ratios.csv")
    assert [c for c in r.columns if "/" in c] == [
        "global/dttmm",
        "global-2nd/dttmm-2nd",
        "exudyn-ancf/dttmm-2nd",
        "exudyn-beam/dttmm-2nd",
        "mujoco-chain/dttmm",  # a linear-strain peer: measured against DT-TMM's linear element
        "amm/dttmm-2nd",  # the consistent assumed modes keep the second-order foreshortening
        "amm-ruthless/dttmm",
        "amm-premature/dttmm",
    ]
    size = r[r.basis.str.startswith("equal size") & (r.case == "three_link")]
    assert sorted(size.k[size.basis.str.contains("elements")]) == [4, 16, 64]
    for _, row in size[size.basis.str.contains("elements")].iterrows():
        assert row["global/dttmm"] == pytest.approx(row.k**2)  # k³ / k, linear element against linear
        assert row["exudyn-ancf/dttmm-2nd"] == pytest.approx(10.0)  # 2e-5 / 2e-6, nonlinear strain pair
        assert np.isnan(row["exudyn-beam/dttmm-2nd"])  # did not run
    assert len(r[r.basis.str.contains("one-step")]) == 2
    acc = r[r.basis.str.startswith("equal accuracy")].iloc[0]
    assert acc["global/dttmm"] == pytest.approx(100.0) and acc["exudyn-ancf/dttmm-2nd"] == pytest.approx(28.0)
    assert np.isnan(acc["exudyn-beam/dttmm-2nd"]) and acc.target_error_m == pytest.approx(1e-4)
    md = (out / "REPORT.md").read_text()
    sec = md[md.index("## Cost scaling (pytest-benchmark)") : md.index("## Omissions")]
    assert "global/dttmm = 4100, exudyn-ancf/dttmm-2nd = 10." in sec  # k = 64: 4096 to 2 digits
    assert "three_link at 1e-04 m: global/dttmm = 100, exudyn-ancf/dttmm-2nd = 28" in sec
    assert "exudyn-beam (three_link)" in sec  # listed as absent
    assert "2026-01-02 03:04:05" in sec and "Test CPU" in sec and "0123456789" in sec
    assert "shared 2-core machine" in sec and "k ≥ 8" in sec
    # the synthetic file names another commit than the code's
    assert "Warning: this pytest-benchmark file was made at commit 0123456789" in sec
    for t in ("bench_exponents", "bench_element_step_us", "bench_ratios"):
        assert f"data/{t}.csv" in md
    assert "## Peer configuration" in md and "SetPreStepUserFunction" in md


def test_provenance_warns_only_for_another_commit():
    info = {
        "file": "b.json",
        "date": "2026-01-02T03:04:05",
        "machine": "M",
        "node": "",
        "cores": 2,
        "python": "3.11",
        "commit": "abcdef0123",
        "dirty": False,
    }
    assert len(bench.provenance(info, "abcdef0123456789")) == 1
    warn = bench.provenance(info, "99999999")
    assert len(warn) == 2 and "abcdef0123" in warn[1] and "99999999" in warn[1]


def test_two_significant_digits():
    from reports.peers import sig2

    assert [sig2(x) for x in (8031.0, 2304.4, 2.84, 0.0456, 4096.0)] == [
        "8000",
        "2300",
        "2.8",
        "0.046",
        "4100",
    ]
    assert sig2(float("nan")) == "n/a" and sig2(None) == "n/a"


def test_equal_accuracy_absent_without_work_precision(tmp_path):
    out = _build(tmp_path, synthetic(tmp_path / "bench"))
    assert "work-precision equal-accuracy table is absent" in (out / "REPORT.md").read_text()


def test_partial_and_old_files_do_not_crash(tmp_path):
    links_only = _write(tmp_path / "links", [_bench("links:dttmm", 8, 1e-6 * n, n, "dttmm") for n in NS])
    out = _build(tmp_path / "a", links_only)
    md = (out / "REPORT.md").read_text()
    assert (out / "figures" / "bench_links.png").exists() and not (
        out / "figures" / "bench_elements.png"
    ).exists()
    assert "global (links scan)" in md and "dttmm-converged (three_link)" in md
    old = _write(
        tmp_path / "old",
        [
            {
                "name": f"s[{k}]",
                "group": "dttmm three_link",
                "params": {"k": k},
                "stats": {"mean": 1e-4 * k},
                "extra_info": {"n_steps": 10},
            }
            for k in (2, 4, 8)
        ],
    )
    out = _build(tmp_path / "b", old)
    assert not (out / "figures" / "bench_scaling.png").exists()  # files without scans are skipped
    assert "has no scaling-suite groups" in (out / "REPORT.md").read_text()
    out = _build(tmp_path / "c", tmp_path / "none")
    assert "Skipped: no pytest-benchmark JSON" in (out / "REPORT.md").read_text()
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "x.json").write_text("{not json")
    assert "Skipped: cannot read" in (_build(tmp_path / "d", tmp_path / "bad") / "REPORT.md").read_text()


@pytest.mark.skipif(not REAL, reason="no data/bench/*.json")
def test_real_benchmark_file_gives_finite_dttmm_exponents():
    rec, info = bench.read(max(REAL, key=lambda p: p.stat().st_mtime))
    assert bench.has_scans(rec) and info["commit"]
    ex = bench.scaling_exponents(rec)
    d = ex[ex.method.str.startswith("dttmm") & (ex.method != "dttmm-rk4")]
    assert len(d) and np.isfinite(d.exponent).all()


def test_crossover_text_names_where_dttmm_overtakes_the_global_solver(tmp_path):
    import pandas as pd

    from reports.peers import crossover_text

    ok = pd.DataFrame(
        {
            "method": ["dttmm"] * 3 + ["global"] * 3,
            "k": [1, 4, 16] * 2,
            "cpu_time": [2.0, 3.0, 4.0, 1.0, 6.0, 40.0],
        }
    )
    text = crossover_text(ok, scaling_csv=tmp_path / "absent.csv")
    assert len(text) == 1 and "cheaper from k = 4 on" in text[0] and "0.5 at k = 1" in text[0]
    sc = pd.DataFrame(
        {"study": ["k", "k", "n"], "size": [1, 8, 2], "ratio_global_over_dttmm": [0.8, 3.0, 1.5]}
    )
    sc.to_csv(tmp_path / "s.csv", index=False)
    text = crossover_text(ok[ok.k > 1], scaling_csv=tmp_path / "s.csv")
    assert "at every k measured" in text[0]
    assert "cheaper up to k = 1" in text[1] and "no crossover" in text[2]


def test_code_changed_looks_at_the_timed_code_only(tmp_path):
    import shutil
    import subprocess

    if shutil.which("git") is None:
        pytest.skip("git is not installed")
    git = lambda *a: subprocess.run(
        ["git", "-c", "user.name=t", "-c", "user.email=t@t", *a],
        cwd=tmp_path,
        check=True,
        capture_output=True,
        text=True,
    ).stdout.strip()
    git("init", "-q")
    (tmp_path / "dttmm").mkdir()
    (tmp_path / "dttmm" / "a.py").write_text("x = 1\n")
    (tmp_path / "README.md").write_text("a\n")
    git("add", "-A")
    git("commit", "-qm", "one")
    first = git("rev-parse", "HEAD")
    (tmp_path / "README.md").write_text("b\n")
    git("commit", "-qam", "docs only")
    docs = git("rev-parse", "HEAD")
    (tmp_path / "dttmm" / "a.py").write_text("x = 2\n")
    git("commit", "-qam", "code")
    code = git("rev-parse", "HEAD")
    assert not bench.code_changed(first, docs, root=tmp_path)
    assert bench.code_changed(docs, code, root=tmp_path)
    assert bench.code_changed("0123456789", code, root=tmp_path)  # unknown commit: cannot tell


def test_spatial_kernel_table_from_the_benchmark_file(tmp_path):
    """The spatial-vs-planar group of a pytest-benchmark file becomes one row per k with both
    kernels' CPU µs per element-step and their ratio; the text fits both exponents."""
    import json

    from reports import bench as B

    benches = []
    for k in (4, 8, 16):
        for kernel, us in (("planar", 0.3), ("spatial", 3.0 * (4 / k) ** 0.1)):
            benches.append(
                {
                    "name": f"test_element_step[{k}-{kernel}]",
                    "group": B.SPATIAL_GROUP,
                    "stats": {"mean": 1.0},
                    "extra_info": {
                        "kernel": kernel,
                        "elements_per_link": k,
                        "cpu_us_per_element_step": us,
                        "sweeps_per_step": 4.5,
                    },
                }
            )
    benches.append(
        {"name": "other", "group": "elements:three_link:dttmm", "stats": {"mean": 1.0}, "extra_info": {}}
    )
    p = tmp_path / "bench.json"
    p.write_text(json.dumps({"benchmarks": benches}))
    t = B.spatial_table(p)
    assert list(t.k) == [4, 8, 16]
    assert np.allclose(t["spatial / planar"], [10.0, 10.0 * 2**-0.1, 10.0 * 4**-0.1])
    (text,) = B.spatial_text(t)
    # planar cost per element-step constant: p = 1; spatial ∝ k^-0.1 per element: p = 0.9
    assert "p = 0.90 (planar 1.00)" in text and "over k = 4…16" in text
    assert B.spatial_table(tmp_path / "bench.json").shape[0] == 3
    q = tmp_path / "none.json"
    q.write_text(json.dumps({"benchmarks": benches[-1:]}))
    assert B.spatial_table(q).empty and B.spatial_text(B.spatial_table(q)) == []
