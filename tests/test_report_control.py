"""The closed-loop study and its report section: the metrics on synthetic series with known
answers, the case variants, and the section built from a tiny plan in which methods that refuse
closed-loop drives appear as "not supported"."""

from __future__ import annotations

import math

import numpy as np
import pytest

from experiments.studies import control as C


# ----------------------------------------------------------------------------- metrics
@pytest.mark.parametrize("sigma, f, phase", [(0.8, 1.3, 0.0), (1.5, 0.7, 1.0), (0.2, 3.1, 2.5)])
def test_decay_rate_of_a_damped_sine(sigma, f, phase):
    t = np.arange(0.0, 3.0 + 1e-12, 1e-3)
    w = 0.01 * np.exp(-sigma * t) * np.sin(2 * np.pi * f * t + phase)
    rate, a_early, a_late = C.decay_rate(t, w, 1.0, 1.0)
    # successive peaks of |w| are spaced by half a period and differ by exactly exp(-σ Δt)
    assert rate == pytest.approx(sigma, rel=2e-3)
    assert a_early > a_late > 0
    assert a_early <= 0.01 * np.exp(-sigma * 1.0) * (1 + 1e-9)


def test_decay_rate_without_vibration_or_time_after_the_move():
    t = np.linspace(0.0, 3.0, 301)
    assert math.isnan(C.decay_rate(t, 1e-14 * np.sin(5 * t), 1.0)[0])
    assert math.isnan(C.decay_rate(t, np.sin(5 * t), 3.0)[0])


def test_windows_shrink_to_fit():
    assert C.windows(1.0, 4.0, 1.0) == ((1.0, 2.0), (3.0, 4.0))
    assert C.windows(1.0, 2.0, 1.0) == ((1.0, 1.5), (1.5, 2.0))


def test_peak_refines_a_sampled_parabola_exactly():
    t = np.linspace(0.0, 0.3, 31)
    tp, yp = C.peak(t, 2.0 - (t - 0.1234) ** 2)
    assert tp == pytest.approx(0.1234, abs=1e-12) and yp == pytest.approx(2.0, abs=1e-12)


def test_tracking_errors_and_residual():
    t = np.linspace(0.0, 2.0, 201)
    ref = np.column_stack([np.sin(t), np.full_like(t, np.nan)])  # joint 2 has no reference
    angle = ref.copy()
    angle[:, 0] += np.where(t <= 1.0, 0.3 * t, 0.05)
    angle[:, 1] = 7.0
    move, final = C.tracking(t, angle, ref, 1.0)
    assert move == pytest.approx(0.3) and final == pytest.approx(0.05)
    w = np.column_stack([np.exp(-t) * np.cos(20 * t), -0.5 * t])
    res = C.residual(t, w, 0.5)
    assert res[1] == pytest.approx(1.0) and res[0] <= np.exp(-1.5) + 1e-12


def test_refusal_is_not_supported():
    why = "InputError: scenario.drives[1].law = 'pd': closed-loop drive law 'pd' on joint 2 is not supported by x yet"
    assert C.status_of({"status": "failed", "reason": why}) == (
        C.NOT_SUPPORTED,
        why.removeprefix("InputError: "),
    )
    assert C.status_of({"status": "failed", "reason": "SimulationError: diverged"})[0] == "failed"
    assert C.status_of({"status": "ok", "reason": ""}) == ("ok", "")
    assert C.status_of({"status": "ok", "reason": math.nan}) == ("ok", "")


def test_elastic_frequencies_drop_rigid_body_modes():
    assert list(C.elastic([3.0, 0.0, 1e-9, 1.0, 2.0], 2)) == [1.0, 2.0]


# ----------------------------------------------------------------------------- cases
def test_gain_variants_and_move_end():
    base = C.load({})
    assert C.moment_gain(base) == 0.5 and C.move_end(base) == 1.0
    assert C.with_gain(base, 0.5) is base
    v = C.with_gain(base, 2.0)
    assert v.name == "closed_loop_three_link_gm2"
    assert [d.law.moment_gain for d in v.scenario.drives] == [2.0] * 3
    assert [d.law.kp for d in v.scenario.drives] == [d.law.kp for d in base.scenario.drives]
    ref = C.reference_angles(base, np.array([0.0, 1.0, 2.0]))
    assert ref[1:] == pytest.approx(np.array([[0.8, -0.6, 0.4]] * 2))


def test_quick_plan_holds_the_move_and_residual_vibration():
    from experiments.plan import PLANS
    from reports import cli

    for plan in PLANS.values():
        p = plan.studies[C.NAME]
        case = C.load(p)
        assert case.scenario.duration - C.move_end(case) >= 1.5
        assert {m for m, *_ in C._derived(p, plan.name)} >= {
            "dttmm",
            "global",
            "exudyn-ancf",
            "mujoco-chain",
            "pinocchio-rigid",
        }
        # the report's availability probe reads every study's parameters
        assert "mujoco-chain" in cli._methods_in(plan)


# ----------------------------------------------------------------------------- study + section
def _refuses(case, *, elements_per_link, h, **options):
    from dttmm.drives import require_open_loop

    require_open_loop(case, "open-loop-only")
    raise AssertionError("the closed-loop case must be refused")


@pytest.fixture(scope="module")
def tables(tmp_path_factory):
    from experiments import methods
    from experiments.context import Context
    from experiments.plan import Plan
    from experiments.runs import RunStore
    from experiments.study import add_cases
    from experiments.sweep import run_sweep

    methods.register("open-loop-only", _refuses)
    root = tmp_path_factory.mktemp("control")
    params = {
        "duration": 1.6,
        "runs": [("open-loop-only", 2, 1e-3), ("mujoco-chain", 2, 1e-3), ("pinocchio-rigid", 0, 2e-3)],
        "rigid_runs": [("pinocchio-rigid", 2e-3)],
        "reference": [("open-loop-only", 4, 1e-3), ("mujoco-chain", 4, 5e-4)],
        "gains": [0.0, 1.0],
        "gain_runs": [("open-loop-only", 2, 1e-3), ("mujoco-chain", 2, 1e-3)],
        "modes": {"k": 2, "exudyn_k": 2, "n": 2, "systems": []},
    }
    ctx = Context(Plan("t", {}, {}, {}, {C.NAME: params}), {}, {}, {}, RunStore(root / "runs"), root)
    add_cases(ctx, [C.NAME])
    table = run_sweep(C.tasks(ctx), ctx.cases, ctx.store, scheduler="serial", progress=False)
    yield C.analyse(ctx, table), root
    methods.unregister("open-loop-only")


def test_study_tables(tables):
    t, _ = tables
    runs = t[C.NAME].set_index(["method", "moment_gain"])
    refused = runs.loc[("open-loop-only", 0.5)]
    assert refused.status == C.NOT_SUPPORTED and "closed-loop drive law 'pd'" in refused.reason
    assert runs.loc[("pinocchio-rigid", 0.5)].status == C.NOT_SUPPORTED  # no moment to feed back
    rigid, chain = runs.loc[("pinocchio-rigid", 0.0)], runs.loc[("mujoco-chain", 0.5)]
    assert rigid.status == chain.status == "ok"
    assert 0 < chain.track_final < chain.track_move_max < 0.5
    assert chain.peak_w1 > 1e-3 and rigid.peak_w1 < 1e-9 and math.isnan(rigid.decay_rate1)
    assert 0 < chain.ee_diff_max < 0.05  # against the chain at k = 4: the second candidate
    assert math.isnan(rigid.ee_diff_max)  # another case: nothing to compare with
    assert t[f"{C.NAME}_info"].reference.iloc[0] == "mujoco-chain k=4 h=0.0005"
    g = t[f"{C.NAME}_gains"]
    assert len(g) == 4 and set(g[g.method == "open-loop-only"].status) == {C.NOT_SUPPORTED}
    ok = g[g.status == "ok"].set_index("moment_gain")
    assert ok.loc[1.0].peak_tau1 < ok.loc[0.0].peak_tau1  # the feedback lowers the torque
    s = t[f"{C.NAME}_series"]
    assert set(s.method) == {"mujoco-chain", "pinocchio-rigid", "reference"}


def test_section_builds_with_not_supported_rows(tables):
    from reports import control as RC
    from reports.build import Inputs, build

    t, root = tables
    (root / "fig").mkdir(exist_ok=True)
    inp = Inputs(dict(t), {}, root / "fig", root / "no_bench")
    sec = RC.section(inp)
    assert sec.title == "Closed loop"
    assert all((root / "fig" / f.removeprefix("figures/")).exists() for f, _ in sec.figures)
    assert len(sec.figures) == 2
    tab = dict((n, d) for n, d, *_ in sec.tables)["control_methods"]
    assert (tab.status == C.NOT_SUPPORTED).sum() == 2
    assert tab.note[tab.status == C.NOT_SUPPORTED].str.contains("not supported").all()
    text = " ".join(sec.text)
    assert "it does not damp" in text or "it damps" in text or "little effect" in text
    assert "Natural frequencies" in text and "MuJoCo hinge chain" in text
    modes = t[f"{C.NAME}_modes"]
    if np.isfinite(modes.dttmm_hz).any():  # dttmm.modes exists: the table is shown
        freq = dict((n, d) for n, d, *_ in sec.tables)["control_frequencies"]
        assert len(freq) == 2 and (modes.dttmm_hz > 0).all()
        assert (modes.rel_diff.dropna() < 1e-6).all()  # Exudyn's eigenvalues at the same k
    else:
        assert "Natural frequencies: skipped" in text
    _, md = build(dict(t), {}, root / "full", bench_dir=root / "no_bench")
    body = md.read_text()
    assert "## Closed loop" in body and "control_methods.csv" in body
    assert (root / "full" / "data" / "control_gain_sweep.csv").exists()


def test_section_rebuilds_from_stored_tables(tables, tmp_path):
    from experiments.study import load_tables, save_tables
    from reports import control as RC
    from reports.build import Inputs

    t, _ = tables
    stored = load_tables(save_tables(t, tmp_path / "data"))
    (tmp_path / "fig").mkdir()
    sec = RC.section(Inputs(stored, {}, tmp_path / "fig", tmp_path))
    again = RC.section(Inputs(dict(t), {}, tmp_path / "fig", tmp_path))
    assert sec.text == again.text and len(sec.figures) == 2


def test_gain_finding_is_computed_from_the_numbers():
    import pandas as pd

    from reports import control as RC

    def sweep(rates):
        return pd.DataFrame(
            {
                "method": "m",
                "moment_gain": [0.0, 1.0, 2.0],
                "status": "ok",
                "decay_rate1": rates,
                "peak_w1": [3e-3, 2e-3, 1e-3],
                "peak_tau1": [3.0, 2.0, 1.0],
                "track_final": [1e-3, 2e-3, 3e-3],
            }
        )

    assert "does not damp" in RC.gain_text(sweep([1.5, 1.0, 0.7]), "m")[0]
    assert "it damps" in RC.gain_text(sweep([0.7, 1.0, 1.5]), "m")[0]
    assert "little effect" in RC.gain_text(sweep([1.0, 1.01, 1.02]), "m")[0]
    assert "3× less" in RC.gain_text(sweep([1.5, 1.0, 0.7]), "m")[0]


def test_section_absent_without_the_study():
    from reports import control as RC
    from reports.build import Inputs

    assert RC.section(Inputs({}, {}, None, None)) is None


def test_pairs_sentence():
    import pandas as pd

    from reports import control as RC

    pairs = pd.DataFrame(
        {"a": ["dttmm"] * 2, "b": ["global"] * 2, "ee_max": [1e-12, 3e-11], "angle_max": [2e-12, 1e-12]}
    )
    (text,) = RC.pairs_text(pairs)
    assert "3e-11 m and 2e-12 rad over 2 run(s)" in text
    assert RC.pairs_text(pairs.iloc[:0]) == []
