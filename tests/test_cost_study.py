"""The cost study (experiments/studies/cost.py) on a planar and a spatial arm: its runs, its
exponents per case, and the report's figure and text (reports/peers.py)."""

from __future__ import annotations

import dataclasses as dc
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from experiments import methods
from experiments.plan import PLANS, load_cases
from experiments.studies import cost
from experiments.study import study_tasks
from reports import peers

PLANAR, SPATIAL = "three_link", "three_joint_arm"


@pytest.fixture(scope="module")
def quick():
    plan = PLANS["quick"]
    return SimpleNamespace(plan=plan, cases=load_cases(plan))


def test_quick_cost_runs_on_the_spatial_arm_with_the_methods_that_can(quick):
    runs = study_tasks(quick, "cost")
    on_arm = {(t.method, t.k) for t in runs if t.case == SPATIAL}
    ks = (1, 2, 4, 8, 16, 32)
    # the spatial DT-TMM kernel and Exudyn's 3-D beam at every k; the global solver (compiled in
    # both spaces) up to its cost@quick limit 16; no spatial engine (assumed modes), or refused
    # (the ANCF cable: the arm's EIy ≠ EIz), no run at all
    want = {(m, k) for m in ("dttmm", "dttmm-2nd", "exudyn-beam") for k in ks}
    want |= {("global", k) for k in ks if k <= 16}
    assert on_arm == want
    assert dict(methods.get("global").max_k) == {"cost@quick": 16}
    planar = {t.method for t in runs if t.case == PLANAR}
    assert {"amm", "exudyn-ancf"} <= planar  # they do run the planar arm
    # one step and the arm's quick duration: up to k = 16 these are convergence_k's own runs
    conv = set(study_tasks(quick, "convergence_k"))
    arm = [t for t in runs if t.case == SPATIAL]
    assert {t.h for t in arm} == {1e-3} and {t.duration for t in arm} == {0.6}
    assert {t for t in arm if t.k <= 16} <= conv
    assert all(t not in conv for t in arm if t.k == 32)


def _runs(case, space, method, ks, p, a=1e-3, noisy=False):
    """Run rows of a synthetic cost table: CPU time a·k^p (s), 3 calls each."""
    return [
        {
            "case": case,
            "space": space,
            "method": method,
            "k": k,
            "h": 1e-3,
            "duration": 0.1,
            "options": "",
            "status": "ok",
            "wall_time": a * k**p,
            "n_steps": 100,
            "timing_cpu_min": a * k**p,
            "timing_wall_min": a * k**p,
            "timing_cpu_median": 1.01 * a * k**p,
            "timing_repeats": 3,
            "timing_noisy": noisy,
            "timing_noise": "",
        }
        for k in ks
    ]


def _table(spatial=True, spatial_global=True):
    rows = (
        _runs(PLANAR, "planar", "dttmm", (1, 2, 4, 8), 1.0)
        + _runs(PLANAR, "planar", "global", (1, 2, 4, 8), 2.0)
        + _runs(PLANAR, "planar", "amm", (1, 2, 4, 8), 1.5)
    )
    if spatial:
        rows += _runs(SPATIAL, "spatial", "dttmm", (1, 2, 4, 8), 0.5, a=4e-3)
        rows += _runs(SPATIAL, "spatial", "exudyn-beam", (1, 2, 4, 8), 1.25)
        if spatial_global:
            rows += _runs(SPATIAL, "spatial", "global", (1, 2), 0.5, a=0.2)  # 50× DT-TMM's
    return pd.DataFrame(rows)


def test_exponents_are_fitted_per_case():
    tables = cost.analyse(None, _table())
    ex = tables["cost_exponents"]
    assert list(ex.columns[:2]) == ["case", "method"]
    assert {"exponent", "n_points", "noisy_points", "k_max", "cpu_time_at_k_max"} <= set(ex.columns)
    got = {(r.case, r.method): r.exponent for r in ex.itertuples()}
    # the synthetic times are a·k^p exactly: the fit returns each p, per case
    want = {
        (PLANAR, "dttmm"): 1.0,
        (PLANAR, "global"): 2.0,
        (PLANAR, "amm"): 1.5,
        (SPATIAL, "dttmm"): 0.5,
        (SPATIAL, "exudyn-beam"): 1.25,
    }
    for key, p in want.items():
        assert got[key] == pytest.approx(p, abs=1e-12), key
    # the spatial global solver has one point at k ≥ 2: no exponent
    assert np.isnan(got[(SPATIAL, "global")])
    # planar arms first, then spatial ones (alphabetically three_joint_arm < three_link)
    assert list(dict.fromkeys(ex.case)) == [PLANAR, SPATIAL]
    assert ex[ex.case == PLANAR].n_points.tolist() == [3, 3, 3]


def test_the_figure_has_one_panel_per_case():
    t = _table()
    tables = cost.analyse(None, t)
    fig = peers.cost_figure(tables["cost"], tables["cost_exponents"])
    titles = [ax.get_title() for ax in fig.axes]
    assert len(titles) == 2
    assert titles[0].startswith(f"{PLANAR} (planar)") and titles[1].startswith(f"{SPATIAL} (spatial)")
    # each panel's legend carries that case's exponent
    legend = [[x.get_text() for x in ax.get_legend().get_texts()] for ax in fig.axes]
    assert "DT-TMM (Newmark) (∝ k^1.00)" in legend[0] and "DT-TMM (Newmark) (∝ k^0.50)" in legend[1]
    # the global solver is compiled on both arms (one point at k ≥ 2 on the spatial one: no exponent)
    assert "global equations (Newmark, compiled) (∝ k^2.00)" in legend[0]
    assert "global equations (Newmark, compiled)" in legend[1]
    one = cost.analyse(None, _table(spatial=False))
    fig = peers.cost_figure(one["cost"], one["cost_exponents"])
    assert [ax.get_title() for ax in fig.axes] == [f"{PLANAR} (planar): CPU time against k (hollow: noisy)"]


def test_the_text_gives_exponents_and_crossover_per_case(monkeypatch):
    # a method with a spatial k limit (Method.spatial_max_k; no built-in method has one now)
    limited, real_get = dc.replace(methods.get("global"), spatial_max_k=2), methods.get
    monkeypatch.setattr(methods, "get", lambda m: limited if m == "global" else real_get(m))
    tables = cost.analyse(None, _table())
    text = peers.cost_text(tables["cost"], tables["cost_exponents"])
    assert text[0].startswith("Fitted exponents of CPU time ∝ k^p (k ≥ 2): on three_link (planar) ")
    assert "; on three_joint_arm (spatial) DT-TMM (Newmark) p = 0.50, Exudyn GE beam p = 1.25." in text[0]
    joined = " ".join(text)
    # the planar crossover: global / DT-TMM = k (times k^2 against k)
    assert "three_link (planar): DT-TMM (Newmark) against the compiled global solver" in joined
    assert "time ratio global / DT-TMM 1 at k = 1, 2 at k = 2, 4 at k = 4, 8 at k = 8." in joined
    # the spatial one, from the global solver's two points (0.2·k^0.5 against 4e-3·k^0.5: 50×)
    assert "three_joint_arm (spatial): DT-TMM (Newmark) against the spatial global solver" in joined
    assert "50 at k = 1, 50 at k = 2." in joined
    # which planar methods the arm lacks, and which stop at their spatial k limit
    assert "assumed modes (consistent) sits it out" in joined
    assert "global equations (Newmark, compiled) runs it up to k = 2 only (its spatial k limit" in joined
    # without the spatial global solver's points, no spatial crossover sentence
    tables = cost.analyse(None, _table(spatial_global=False))
    joined = " ".join(peers.cost_text(tables["cost"], tables["cost_exponents"]))
    assert "against the compiled global solver" in joined
    assert "against the spatial global solver" not in joined


def test_loaded_check_keeps_the_planar_cost_study():
    from experiments import loaded_check

    plan = loaded_check.reduced_plan()
    assert plan.studies["cost"].case_ks() == [(PLANAR, (1, 2, 4, 8, 16, 32))]
    tables = cost.analyse(None, _table())
    tables["work_precision_equal_accuracy"] = pd.DataFrame(
        columns=["case", "against", "method", "target_error", "ratio"]
    )
    tables["work_precision_summary"] = pd.DataFrame(
        columns=["case", "method", "cpu_time_to_target", "wall_time_to_target"]
    )
    h = loaded_check.headlines(tables)
    ex = h[h.kind == "cost_exponent"]
    assert sorted(ex.method) == ["amm", "dttmm", "global"]  # three_link's alone
    assert ex.set_index("method").value["global"] == pytest.approx(2.0)
