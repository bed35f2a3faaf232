"""Model, scenario and case files: loading, saving, and refusal of bad input."""

import math

import numpy as np
import pytest
from conftest import CASES, case

import dttmm
from dttmm import (
    BangBang,
    Case,
    Constant,
    Drive,
    Hub,
    InputError,
    Link,
    Manipulator,
    Payload,
    Scenario,
    Section,
    Sine,
    SpinUp,
    Table,
)


@pytest.mark.parametrize("name", ["single_link", "three_link", "spin_up"])
def test_case_files_round_trip(name, tmp_path):
    c = case(name)
    path = dttmm.save_case(c, tmp_path / f"{name}.toml")
    assert dttmm.load_case(path) == c


def test_single_link_material_form_gives_section_values():
    b = case("single_link").model.links[0].beam
    # 70 GPa, 2700 kg/m³, 50 mm × 2 mm
    assert b.EI == pytest.approx(70e9 * 0.05 * 0.002**3 / 12, rel=1e-14)
    assert b.rhoA == pytest.approx(2700 * 0.05 * 0.002, rel=1e-14)
    assert b.EA == pytest.approx(70e9 * 0.05 * 0.002, rel=1e-14)


def test_design_example_format_loads(tmp_path):
    # the user-facing example of docs/cases.md
    text = (CASES / "three_link.toml").read_text()
    p = tmp_path / "x.toml"
    p.write_text(text)
    c = dttmm.load_case(p)
    assert c.n_joints == 3 and c.model.gravity == (0.0, -9.81)
    assert c.model.links[2].payload == Payload(0.1, 0.0)
    assert c.scenario.drives[1].torque(0.25) == pytest.approx(0.4)
    assert c.scenario.drives[1].torque(1.5) == 0.0


def test_drive_laws():
    bb = BangBang((1.0, -1.0, 0.0), (0.5, 1.0))
    assert bb(0.49) == 1 and bb(0.5) == -1 and bb(0.5, left=True) == 1 and bb(1.2) == 0
    s = SpinUp(4.0, 15.0)
    a, r, _acc = s.motion(7.5)
    assert r == pytest.approx((4 / 15) * (7.5 - 15 / (2 * math.pi) * math.sin(math.pi)))
    # the angle is the integral of the rate: check by quadrature
    ts = np.linspace(0, 7.5, 20001)
    rates = np.array([s.motion(t)[1] for t in ts])
    assert a == pytest.approx(np.trapezoid(rates, ts), rel=1e-7)
    assert s.motion(20.0) == (pytest.approx(4 * (20 - 7.5)), 4.0, 0.0)
    tb = Table((0.0, 1.0, 2.0), (0.0, 2.0, 0.0))
    assert tb(0.5) == 1.0 and tb(3.0) == 0.0
    sn = Sine(2.0, 1.0, until=1.0)
    assert sn(0.25) == pytest.approx(2.0) and sn(1.25) == 0.0


def _valid_parts():
    sec = Section(1.0, 2.0, 0.3)
    man = Manipulator((Link(sec, Hub(0.1, 0.01)),), (0.0, -9.81))
    scen = Scenario(1.0, 0.01, (Drive("torque", Constant(1.0)),))
    return sec, man, scen


@pytest.mark.parametrize(
    "make, field, value",
    [
        (lambda: Section(-1.0, 2.0, 0.3), "section.length", -1.0),
        (lambda: Section(1.0, 0.0, 0.3), "section.EI", 0.0),
        (lambda: Section(1.0, 2.0, float("nan")), "section.rhoA", float("nan")),
        (lambda: Section(1.0, 2.0, 0.3, EA=float("inf")), "section.EA", float("inf")),
        (lambda: Section(1.0, 2.0, 0.3, damping=-0.1), "section.damping", -0.1),
        (lambda: Hub(-1.0), "hub.mass", -1.0),
        (lambda: Manipulator((), (0.0, 0.0)), "model.links", ()),
        (
            lambda: Manipulator((Link(Section(1, 1, 1)),), (0.0, float("nan"))),
            "model.gravity[1]",
            float("nan"),
        ),
        (lambda: Scenario(0.0, 0.01, ()), "scenario.duration", 0.0),
        (lambda: Scenario(1.0, 2.0, ()), "scenario.output_step", 2.0),
        (lambda: Drive("force", Constant(1.0)), "drive.kind", "force"),
        (lambda: Drive("motion", BangBang((0.0, 1.0), (0.5,))), "drive.law", "bang_bang"),
        (lambda: BangBang((1.0,), (0.5,)), "law.levels", [1.0]),
        (lambda: Table((0.0, 0.0), (1.0, 2.0)), "law.times", [0.0, 0.0]),
    ],
)
def test_bad_fields_are_named(make, field, value):
    with pytest.raises(InputError) as exc:
        make()
    assert exc.value.field == field
    assert field in str(exc.value)
    if isinstance(value, float) and math.isnan(value):
        assert math.isnan(exc.value.value)
    else:
        assert exc.value.value == value


def test_wrong_number_of_drives():
    _sec, man, scen = _valid_parts()
    scen2 = Scenario(1.0, 0.01, scen.drives * 2)
    with pytest.raises(InputError, match="scenario.drives"):
        Case(man, scen2)


def test_unknown_law_in_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text((CASES / "single_link.toml").read_text().replace('law = "bang_bang"', 'law = "square"'))
    with pytest.raises(InputError, match=r"scenario.drives\[0\].law = 'square'"):
        dttmm.load_case(p)


def test_negative_stiffness_in_file(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text((CASES / "three_link.toml").read_text().replace("EI = 2.3333333333333335", "EI = -2.0", 1))
    with pytest.raises(InputError, match=r"model.links\[0\].EI = -2.0"):
        dttmm.load_case(p)


@pytest.mark.parametrize(
    "kw, field",
    [
        ({"elements_per_link": 0, "h": 1e-3}, "elements_per_link"),
        ({"elements_per_link": 2.5, "h": 1e-3}, "elements_per_link"),
        ({"elements_per_link": 2, "h": 0.0}, "h"),
        ({"elements_per_link": 2, "h": -1e-3}, "h"),
        ({"elements_per_link": 2, "h": 5.0}, "h"),
        ({"elements_per_link": 2, "h": 1e-3, "integrator": "euler"}, "integrator"),
        ({"elements_per_link": 2, "h": 1e-3, "sweep": "lu"}, "sweep"),
        ({"elements_per_link": 2, "h": 1e-3, "iterations": -1}, "iterations"),
    ],
)
def test_bad_solver_settings(single_link, kw, field):
    with pytest.raises(InputError) as exc:
        dttmm.simulate(single_link, **kw)
    assert exc.value.field == field


def test_motion_initial_angle_must_match_law():
    with pytest.raises(InputError, match="initial_angle"):
        Drive("motion", Constant(0.5), initial_angle=0.1)
