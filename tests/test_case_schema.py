"""The strict case schema: every bad input found by a systematic run is a one-line InputError.

Each regression below was accepted silently or raised a traceback before the schema existed.
"""

from __future__ import annotations

import dataclasses as dc
import math
import tomllib

import numpy as np
import pydantic
import pytest
from conftest import CASES

import dttmm
from dttmm import Case, Drive, Hub, InputError, Link, Manipulator, Scenario, Section, Sine, Table
from dttmm.resources import check_run_size, estimate_run_bytes

THREE = (CASES / "three_link.toml").read_text()
SINGLE = (CASES / "single_link.toml").read_text()
TABLE_LAW = 'law = "table"\ntimes = [0.0, 1.0]\nvalues = [0.0, 1.0]\n'
SINGLE_TABLE = (
    SINGLE.replace('law = "bang_bang"', TABLE_LAW)
    .replace("levels = [1.0, -1.0, 0.0]     # N·m\n", "")
    .replace("switch_times = [0.5, 1.0]     # s\n", "")
)


def _load_text(tmp_path, text: str) -> Case:
    p = tmp_path / "case.toml"
    p.write_text(text)
    return dttmm.load_case(p)


def _refused(tmp_path, text: str) -> InputError:
    with pytest.raises(InputError) as exc:
        _load_text(tmp_path, text)
    msg = str(exc.value)
    assert "\n" not in msg
    return exc.value


# (name, edited file, field named in the error, fragment of the reason)
REGRESSIONS = [
    ("misspelt gravity", THREE.replace("gravity =", "gravty ="), "model.gravty", "did you mean 'gravity'"),
    ("misspelt name", THREE.replace("name =", "nmae ="), "nmae", "did you mean 'name'"),
    (
        "misspelt output_step",
        THREE.replace("output_step =", "output_stepp ="),
        "scenario.output_stepp",
        "did you mean 'output_step'",
    ),
    ("unknown table", THREE + "\n[solver]\nh = 1e-3\n", "solver", "unknown key"),
    (
        "misspelt law parameter",
        THREE.replace("amplitude = 1.0", "amplitud = 1.0", 1),
        "scenario.drives[0].amplitud",
        "did you mean 'amplitude'",
    ),
    (
        "misspelt hub key",
        THREE.replace("hub = { mass = 0.0,", "hub = { mas = 0.0,", 1),
        "model.links[0].hub.mas",
        "did you mean 'mass'",
    ),
    ("EA = true", THREE.replace("EA = 7.0e6", "EA = true", 1), "model.links[0].EA", "must be a number"),
    (
        "length string",
        THREE.replace("length = 0.5", 'length = "1.0"', 1),
        "model.links[0].length",
        "must be a number",
    ),
    (
        "duration string",
        THREE.replace("duration = 2.0", 'duration = "0.05"'),
        "scenario.duration",
        "must be a number",
    ),
    (
        "inextensible string",
        SINGLE.replace("hub =", 'inextensible = "no"\nhub ='),
        "model.links[0].inextensible",
        "true or false",
    ),
    (
        "gravity scalar",
        THREE.replace("gravity = [0.0, -9.81]", "gravity = -9.81"),
        "model.gravity",
        "must be a list",
    ),
    (
        "gravity 3 entries",
        THREE.replace("gravity = [0.0, -9.81]", "gravity = [0.0, -9.81, 0.0]"),
        "model.gravity",
        "at most 2",
    ),
    ("model = 3", "model = 3\n[scenario]\nduration = 1.0\noutput_step = 0.1\n", "model", "must be a table"),
    (
        "links = 5",
        THREE.split("[[model.links]]")[0].replace("[model]", "[model]\nlinks = 5")
        + "[scenario]\nduration = 1.0\noutput_step = 0.1\n",
        "model.links",
        "must be a list",
    ),
    (
        "drives = [1]",
        THREE.split("[[scenario.drives]]")[0] + "drives = [1]\n",
        "scenario.drives[0]",
        "must be a table",
    ),
    (
        "until string",
        THREE.replace("until = 1.0", 'until = "abc"', 1),
        "scenario.drives[0].until",
        "must be a number",
    ),
    (
        "private field",
        SINGLE_TABLE.replace(TABLE_LAW, TABLE_LAW + "_spline = 1\n"),
        "scenario.drives[0]._spline",
        "unknown key",
    ),
    (
        "unknown law",
        THREE.replace('law = "sine"', 'law = "sin"', 1),
        "scenario.drives[0].law",
        "unknown drive law",
    ),
    ("law missing", THREE.replace('law = "sine"', "", 1), "scenario.drives[0].law", "is required"),
    ("EI nan", THREE.replace("EI = 2.3333333333333335", "EI = nan", 1), "model.links[0].EI", "finite"),
    ("EI inf", THREE.replace("EI = 2.3333333333333335", "EI = inf", 1), "model.links[0].EI", "finite"),
    ("half a material", SINGLE.replace("rho = 2700.0", ""), "model.links[0].rho", "material form"),
    ("both forms", SINGLE.replace("E = 70.0e9", "E = 70.0e9\nEI = 1.0"), "model.links[0].EI", "either"),
    (
        "EA and inextensible",
        THREE.replace("EA = 7.0e6", "EA = 7.0e6\ninextensible = true", 1),
        "model.links[0].EA",
        "contradicts",
    ),
    ("name number", THREE.replace('name = "three_link"', "name = 3"), "name", "must be a string"),
    (
        "table lengths",
        SINGLE_TABLE.replace("values = [0.0, 1.0]", "values = [0.0, 1.0, 2.0]"),
        "scenario.drives[0].values",
        "one value per time",
    ),
    (
        "kind misspelt",
        THREE.replace('kind = "torque"', 'kind = "torqe"', 1),
        "scenario.drives[0].kind",
        "one of",
    ),
    ("missing scenario", THREE.split("[scenario]")[0], "scenario", "is required"),
    (
        "one drive too few",
        THREE.rsplit("[[scenario.drives]]", 1)[0],
        "scenario.drives",
        "one drive per joint",
    ),
]


@pytest.mark.parametrize("name, text, field, reason", REGRESSIONS, ids=[r[0] for r in REGRESSIONS])
def test_bad_case_file_is_one_line_input_error(tmp_path, name, text, field, reason):
    err = _refused(tmp_path, text)
    assert err.field == field, str(err)
    assert reason in err.reason, str(err)


def test_int_for_float_is_fine_and_stays_float(tmp_path):
    c = _load_text(
        tmp_path, THREE.replace("duration = 2.0", "duration = 2").replace("length = 0.5", "length = 1", 1)
    )
    assert c.scenario.duration == 2.0 and isinstance(c.scenario.duration, float)
    assert c.model.links[0].beam.length == 1.0


@pytest.mark.parametrize(
    "make, where",
    [
        (lambda p: p.joinpath("missing.toml"), "does not exist"),
        (lambda p: p, "is a directory"),
        (lambda p: _write_bytes(p / "bin.toml", b"\x7fELF\x02\x01\x00\x00binary"), "binary"),
        (lambda p: _write_bytes(p / "latin1.toml", "name = 'é'\n".encode("latin-1")), "not UTF-8"),
        (lambda p: _write_bytes(p / "bad.toml", b"[model\n"), "not valid TOML"),
    ],
)
def test_file_errors_name_the_path(tmp_path, make, where):
    path = make(tmp_path)
    with pytest.raises(InputError) as exc:
        dttmm.load_case(path)
    assert exc.value.field == str(path) and where in exc.value.reason
    assert "\n" not in exc.value.reason.strip()


def _write_bytes(path, data: bytes):
    path.write_bytes(data)
    return path


def test_provenance_is_kept_and_round_trips(tmp_path):
    text = THREE + (
        '\n[provenance]\nsource = "a paper, Table 2"\ntolerance = 0.02\n'
        "published = { tip_deflection_mm = [1.5, 2.0] }\n"
    )
    c = _load_text(tmp_path, text)
    assert c.provenance == {
        "source": "a paper, Table 2",
        "tolerance": 0.02,
        "published": {"tip_deflection_mm": [1.5, 2.0]},
    }
    back = dttmm.load_case(dttmm.save_case(c, tmp_path / "again.toml"))
    assert back.provenance == c.provenance and back == c


@pytest.mark.parametrize("name", ["three_link.toml", "control/closed_loop_three_link.toml"])
def test_a_case_file_is_validated_once(monkeypatch, name):
    # one validation of the whole document; the objects are built from it without a second check
    # (a material-form link checks the EI, rhoA and EA it derives: they are new numbers)
    seen = []
    validate = pydantic.BaseModel.model_validate.__func__

    def spy(cls, obj, *a, **k):
        seen.append((cls.__name__, sorted(obj)))
        return validate(cls, obj, *a, **k)

    monkeypatch.setattr(pydantic.BaseModel, "model_validate", classmethod(spy))
    case = dttmm.load_case(CASES / name)
    derived = sum("E" in link for link in tomllib.loads((CASES / name).read_text())["model"]["links"])
    assert seen[0][0] == "CaseFile" and seen[1:] == [("SectionFields", ["EA", "EI", "rhoA"])] * derived
    monkeypatch.undo()
    rebuilt = dc.replace(case, model=dc.replace(case.model), scenario=dc.replace(case.scenario))
    assert rebuilt == case  # the constructors, which validate, accept the same values


# --- the Python constructors follow the same rules ---------------------------------------------------
@pytest.mark.parametrize(
    "make, field",
    [
        (lambda: Section(True, 1.0, 1.0), "section.length"),
        (lambda: Section(1.0, "2.0", 1.0), "section.EI"),
        (lambda: Section(1.0, 1.0, 1.0, EA=True), "section.EA"),
        (lambda: Hub("1"), "hub.mass"),
        (lambda: Manipulator((Link(Section(1, 1, 1)),), -9.81), "model.gravity"),
        (lambda: Manipulator(5), "model.links"),
        (lambda: Scenario("1", 0.1, ()), "scenario.duration"),
        (lambda: Scenario(1.0, 0.1, 5), "scenario.drives"),
        (lambda: Sine(1.0, 1.0, until="abc"), "law.until"),
        (lambda: Sine(1.0, 1.0, until=float("nan")), "law.until"),
        (lambda: Drive("torque", Sine(1.0, 1.0), initial_rate=False), "drive.initial_rate"),
        (
            lambda: dttmm.drives.law_from_dict(
                {"law": "table", "times": [0, 1], "values": [0, 1], "_spline": 1}, "d"
            ),
            "d._spline",
        ),
    ],
)
def test_constructors_refuse_bools_strings_and_wrong_shapes(make, field):
    with pytest.raises(InputError) as exc:
        make()
    assert exc.value.field == field


def test_constructors_accept_numpy_scalars_and_arrays():
    sec = Section(np.float32(1.0), np.int64(2), np.float64(0.3))
    assert sec.length == 1.0 and isinstance(sec.EI, float)
    tb = Table(np.linspace(0, 1, 3), np.array([0.0, 1.0, 0.0]))
    assert tb.times == (0.0, 0.5, 1.0)


def test_private_spline_is_not_a_constructor_argument():
    with pytest.raises(TypeError):
        Table((0.0, 1.0), (0.0, 1.0), _spline=1)


# --- resource guard -----------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "h, output_step, field", [(1e-12, 1e-3, "h"), (1e-3, 1e-12, "scenario.output_step"), (1e-25, 1e-3, "h")]
)
def test_run_size_guard_names_the_knob(three_link, h, output_step, field):
    c = dc.replace(three_link, scenario=dc.replace(three_link.scenario, output_step=output_step))
    with pytest.raises(InputError) as exc:
        check_run_size(c, 4, h)
    assert exc.value.field == field and "GiB" in exc.value.reason and "duration" in exc.value.reason


def test_run_size_estimate_counts_steps_and_samples(three_link):
    total, n_steps, n_out = estimate_run_bytes(three_link, 4, 1e-3)
    assert (n_steps, n_out) == (2000 + 1, 2001)  # 2 s / 1 ms steps (+1 breakpoint at 1 s), 2001 samples
    assert 1e6 < total < 1e8
    assert check_run_size(three_link, 4, 1e-3) == total
    with pytest.raises(InputError, match="limit"):
        check_run_size(three_link, 4, 1e-3, limit_bytes=total / 2)


@pytest.mark.parametrize("h", ["1e-3", True, float("nan"), -1.0, 1e-300])
def test_step_size_validator(h):
    with pytest.raises(InputError) as exc:
        dttmm._validate.step_size(h)
    assert exc.value.field == "h"


# --- motion tables: the rate never jumps -----------------------------------------------------------
def test_two_point_motion_table_is_the_rest_to_rest_cubic():
    # closed form of the cubic with zero end rates: α = Δ(3s² − 2s³), s = t/T
    T, d = 0.3, 0.7
    law = Table((0.0, T), (0.0, d))
    for t in (0.0, 0.05, 0.15, 0.29):
        s = t / T
        a, r, acc = law.motion(t)
        assert a == pytest.approx(d * (3 * s**2 - 2 * s**3), abs=1e-15)
        assert r == pytest.approx(d * (6 * s - 6 * s**2) / T, abs=1e-13)
        assert acc == pytest.approx(d * (6 - 12 * s) / T**2, abs=1e-11)
    assert law.motion(T, left=True)[2] == pytest.approx(-6 * d / T**2)
    assert law.motion(T) == (d, 0.0, 0.0) and law.motion(2 * T) == (d, 0.0, 0.0)
    assert law.breakpoints == (0.0, T)


def test_motion_table_is_c1_everywhere_and_c2_inside():
    # the properties that define the clamped cubic spline, checked by finite differences
    ts, vs = (0.1, 0.3, 0.35, 0.8, 1.0), (0.0, 0.4, 0.5, -0.2, 0.1)
    law = Table(ts, vs)
    assert [law.motion(t)[0] for t in ts[1:-1]] == pytest.approx(vs[1:-1], abs=1e-14)
    e = 1e-6
    for t in ts:  # rate: central difference of the angle across every knot and both table ends
        fd = (law.motion(t + e)[0] - law.motion(t - e)[0]) / (2 * e)
        assert fd == pytest.approx(law.motion(t, left=True)[1], abs=1e-5)
        assert law.motion(t, left=True)[1] == pytest.approx(law.motion(t)[1], abs=1e-12)
    for t in ts[1:-1]:  # acceleration continuous at interior knots
        assert law.motion(t - 1e-9)[2] == pytest.approx(law.motion(t + 1e-9)[2], rel=1e-6, abs=1e-6)
    assert law.motion(ts[0])[1] == 0.0 and law.motion(ts[-1], left=True)[1] == pytest.approx(0.0, abs=1e-12)
    assert law.breakpoints == (ts[0], ts[-1])


def test_motion_table_joint_torque_is_the_rigid_body_one():
    # a stiff, damped link driven by a rest-to-rest table: away from the acceleration jumps at the
    # table ends the joint torque is J·α̈ with J = hub + ρA·L³/3 (rigid rod about its end)
    law = Table((0.0, 0.1, 0.25, 0.4), (0.0, 0.02, 0.08, 0.1))
    arm = Manipulator((Link(Section(1.0, 1e4, 0.27, damping=1.5e-3), Hub(0.0, 0.01)),), (0.0, 0.0))
    case = Case(arm, Scenario(0.5, 1e-3, (Drive("motion", law),)))
    assert case.scenario.breakpoints == (0.4,)
    res = dttmm.simulate(case, elements_per_link=2, h=5e-4)
    J = 0.01 + 0.27 * 1.0**3 / 3
    want = np.array([J * law.motion(t, left=True)[2] for t in res.t])
    calm = ((res.t > 0.03) & (res.t < 0.39)) | (res.t > 0.43)
    # 1 %: the jerk jumps at the knots and the link's ~110 Hz mode rings a little (measured 0.7 %)
    assert np.max(np.abs(res.joint_torque[calm, 0] - want[calm])) < 1e-2 * np.max(np.abs(want))
    assert np.max(np.abs(res.joint_angle[:, 0] - [law.motion(t)[0] for t in res.t])) < 1e-12


def test_motion_sine_with_until_still_refused():
    with pytest.raises(InputError, match="until"):
        Drive("motion", Sine(1.0, 1.0, until=0.5))


def test_nan_in_python_api_reported_as_nan():
    with pytest.raises(InputError) as exc:
        Section(1.0, 1.0, math.nan)
    assert math.isnan(exc.value.value)


@pytest.mark.parametrize(
    "old, new, field",
    [
        ("length = 0.5", "length = 1e300", "model.links[0].length"),
        ("EI = 2.3333333333333335", "EI = 1e-300", "model.links[0].EI"),
        ("gravity = [0.0, -9.81]", "gravity = [0.0, -1e31]", "model.gravity[1]"),
        ("frequency = 1.0", "frequency = 1e31", "scenario.drives[0].frequency"),
    ],
)
def test_magnitudes_outside_the_window_are_refused(tmp_path, old, new, field):
    # 1e300 m once overflowed inside the element matrices (OverflowError, found by the fuzz test)
    err = _refused(tmp_path, THREE.replace(old, new, 1))
    assert err.field == field


def test_long_values_are_cut_in_messages(tmp_path):
    big = "[" + ", ".join(["1.0"] * 500) + "]"
    err = _refused(tmp_path, THREE + f"\n[solver]\nsteps = {big}\n")
    assert err.field == "solver" and len(str(err)) < 250 and str(err).count("...") == 1
