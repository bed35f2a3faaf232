"""Closed-loop drive laws: definitions, slopes, saturation, the case format and the guard."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

import pytest

import dttmm
from dttmm.drives import (
    PD,
    PID,
    ComputedTorque,
    Constant,
    ControlState,
    Drive,
    Sine,
    Table,
    UserLaw,
    require_no_computed_torque,
    require_open_loop,
)
from dttmm.errors import InputError

HEAD = """
[model]
[[model.links]]
length = 1.0
EI = 10.0
rhoA = 1.0

[scenario]
duration = 1.0
output_step = 0.01

[[scenario.drives]]
kind = "torque"
"""


def load(drive_toml: str):
    return dttmm.case_from_dict(tomllib.loads(HEAD + drive_toml))


def test_pd_value_and_slopes_by_hand():
    law = PD(20.0, 1.5, Sine(0.5, 0.5), Constant(0.25), moment_gain=0.1)
    t = 0.3
    s = ControlState(joint=0, angle=0.1, rate=-0.2, moment=2.0)
    w = 2 * math.pi * 0.5
    want = 0.25 + 20.0 * (0.5 * math.sin(w * t) - 0.1) + 1.5 * (0.5 * w * math.cos(w * t) + 0.2) - 0.1 * 2.0
    tau, da, dr, dm = law.evaluate(t, s)
    assert tau == pytest.approx(want, rel=1e-14)
    assert (da, dr, dm) == (-20.0, -1.5, -0.1)


def test_pid_adds_ki_times_the_integral_and_its_rate_is_the_error():
    law = PID(2.0, 0.5, Constant(1.0), ki=3.0)
    s = ControlState(joint=0, angle=0.25, rate=0.0, integral=0.4)
    assert law.evaluate(0.0, s)[0] == pytest.approx(2.0 * 0.75 + 3.0 * 0.4)
    assert law.error_rate(0.0, s) == 0.75
    assert law.gain_integral == 3.0 and PD(1.0, 1.0, Constant(0.0)).gain_integral == 0.0


@pytest.mark.parametrize("angle", [-5.0, 5.0])
def test_saturation_clips_and_has_zero_slope_beyond_the_limit(angle):
    law = PD(10.0, 1.0, Constant(0.0), limit=2.0)
    tau, *slopes = law.evaluate(0.0, ControlState(0, angle, 0.0))
    assert tau == -math.copysign(2.0, angle) and slopes == [0.0, 0.0, 0.0]
    tau, *slopes = law.evaluate(0.0, ControlState(0, 0.1, 0.0))  # inside: the plain law
    assert tau == pytest.approx(-1.0) and slopes[:2] == [-10.0, -1.0]


def test_breakpoints_are_the_reference_and_feedforward_ones():
    law = PD(
        1.0,
        1.0,
        Table((0.1, 0.5), (0.0, 1.0)),
        {"law": "bang_bang", "levels": [0.0, 1.0], "switch_times": [0.3]},
    )
    assert Drive("torque", law).breakpoints == (0.1, 0.3, 0.5)


def test_closed_loop_drive_refuses_open_loop_calls():
    d = Drive("torque", PD(1.0, 1.0, Constant(0.0)))
    assert d.closed_loop and not Drive("torque", Constant(1.0)).closed_loop
    with pytest.raises(InputError, match="closed-loop law.*evaluate"):
        d.torque(0.0)
    with pytest.raises(InputError, match="open-loop law"):
        Drive("torque", Constant(1.0)).evaluate(0.0, ControlState(0, 0.0, 0.0))
    with pytest.raises(InputError, match="cannot drive a 'motion' joint"):
        Drive("motion", PD(1.0, 1.0, Constant(0.0)))


def test_user_law_wraps_a_callable_and_checks_what_it_returns():
    d = Drive("torque", UserLaw(lambda t, s: (-2.0 * s.angle, -2.0, 0.0)))
    assert d.evaluate(0.0, ControlState(0, 0.5, 0.0)) == (-1.0, -2.0, 0.0, 0.0)
    with pytest.raises(InputError, match="three numbers"):
        UserLaw(lambda t, s: 1.0, label="bad").evaluate(0.5, ControlState(0, 0.0, 0.0))
    with pytest.raises(InputError, match="non-finite.*joint 2"):
        UserLaw(lambda t, s: (math.nan, 0, 0)).evaluate(0.5, ControlState(1, 0.0, 0.0))
    with pytest.raises(InputError, match="law.fn"):
        UserLaw(3.0)
    with pytest.raises(InputError, match="case file"):
        UserLaw(lambda t, s: (0, 0, 0)).params()


def test_computed_torque_needs_an_engine_value():
    law = PD(1.0, 1.0, Constant(0.0), {"law": "computed_torque"})
    assert isinstance(law.feedforward, ComputedTorque)
    assert law.evaluate(0.0, ControlState(0, 0.0, 0.0, computed_torque=4.0))[0] == 4.0
    with pytest.raises(InputError, match="computed_torque"):
        law.evaluate(0.0, ControlState(0, 0.0, 0.0))


@pytest.mark.parametrize(
    "make, field, reason",
    [
        (lambda: PID(1.0, 1.0, Constant(0.0)), "law.ki", "must be a number"),
        (lambda: PD(-1.0, 1.0, Constant(0.0)), "law.kp", "non-negative"),
        (lambda: PD(1.0, 1.0, Constant(0.0), limit=0.0), "law.limit", "positive"),
        (lambda: PD(1.0, 1.0, Constant(0.0), moment_gain="1"), "law.moment_gain", "number"),
        (
            lambda: PD(1.0, 1.0, {"law": "bang_bang", "levels": [1.0], "switch_times": []}),
            "law.reference.law",
            "motion",
        ),
        (
            lambda: PD(1.0, 1.0, {"law": "sine", "amplitude": 1.0, "frequency": 1.0, "until": 2.0}),
            "law.reference.until",
            "abruptly",
        ),
        (
            lambda: PD(1.0, 1.0, Constant(0.0), {"law": "spin_up", "rate": 1.0, "ramp_time": 1.0}),
            "law.feedforward.law",
            "torque",
        ),
        (lambda: PD(1.0, 1.0, PD(1.0, 1.0, Constant(0.0))), "law.reference", "open-loop"),
        (lambda: PD(1.0, 1.0, 3.0), "law.reference", "open-loop"),
    ],
)
def test_python_constructor_errors(make, field, reason):
    with pytest.raises(InputError, match=reason) as e:
        make()
    assert e.value.field == field


def test_case_file_pd_loads_and_round_trips(tmp_path):
    case = load("""law = "pd"
kp = 20.0
kd = 1.5
reference = { law = "sine", amplitude = 0.5, frequency = 0.5 }
feedforward = { law = "constant", value = 0.0 }
moment_gain = 0.2
limit = 10.0
""")
    law = case.scenario.drives[0].law
    assert law == PD(20.0, 1.5, Sine(0.5, 0.5), Constant(0.0), 0.2, 10.0)
    back = dttmm.load_case(dttmm.save_case(case, tmp_path / "c.toml"))
    assert back.scenario == case.scenario


def test_case_file_pid_with_computed_torque():
    law = (
        load(
            'law = "pid"\nkp = 1.0\nkd = 2.0\nki = 3.0\nreference = { law = "constant", value = 0.1 }\n'
            'feedforward = { law = "computed_torque" }\n'
        )
        .scenario.drives[0]
        .law
    )
    assert law == PID(1.0, 2.0, Constant(0.1), ComputedTorque(), ki=3.0)


@pytest.mark.parametrize(
    "body, field, reason",
    [
        ('law = "pd"\nkp = 1.0\nkd = 1.0\n', "scenario.drives[0].reference", "is required"),
        (
            'law = "pid"\nkp = 1.0\nkd = 1.0\nreference = { law = "constant" }\n',
            "scenario.drives[0].ki",
            "is required",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nki = 1.0\nreference = { law = "constant" }\n',
            "scenario.drives[0].ki",
            "unknown key",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = { law = "constant", vlaue = 1.0 }\n',
            "scenario.drives[0].reference.vlaue",
            "did you mean 'value'",
        ),
        (
            'law = "pd"\nkp = true\nkd = 1.0\nreference = { law = "constant" }\n',
            "scenario.drives[0].kp",
            "must be a number",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = { law = "bang_bang", levels = [1.0], switch_times = [] }\n',
            "scenario.drives[0].reference.law",
            "'constant', 'sine', 'spin_up', 'table'",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = { value = 1.0 }\n',
            "scenario.drives[0].reference.law",
            "is required (one of: constant, sine, spin_up, table)",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = 0.5\n',
            "scenario.drives[0].reference",
            "must be a table",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = { law = "constant" }\nfeedforward = { law = "pd" }\n',
            "scenario.drives[0].feedforward.law",
            "unknown drive law",
        ),
        (
            'law = "pd"\nkp = 1.0\nkd = 1.0\nreference = { law = "constant" }\nlimit = -1.0\n',
            "scenario.drives[0].limit",
            "must be positive",
        ),
    ],
)
def test_case_file_errors_name_the_key(body, field, reason):
    with pytest.raises(InputError) as e:
        load(body)
    assert e.value.field == field
    assert reason in e.value.reason


def test_case_file_pd_on_a_motion_drive_is_refused():
    with pytest.raises(InputError, match="cannot drive a 'motion' joint"):
        dttmm.case_from_dict(
            tomllib.loads(
                HEAD.replace('"torque"', '"motion"') + 'law = "pd"\nkp = 1.0\n'
                'kd = 1.0\nreference = { law = "constant" }\n'
            )
        )


def test_require_open_loop_names_law_joint_and_method():
    base = load('law = "constant"\nvalue = 1.0\n')
    require_open_loop(base, "my-engine")  # open loop: nothing to refuse
    link = base.model.links[0]
    drives = (Drive("torque", Constant(0.0)), Drive("torque", PD(1.0, 1.0, Constant(0.0))))
    case = dttmm.Case(dttmm.Manipulator((link, link)), dttmm.Scenario(1.0, 0.1, drives))
    with pytest.raises(InputError) as e:
        require_open_loop(case, "my-engine")
    assert str(e.value) == (
        "scenario.drives[1].law = 'pd': closed-loop drive law 'pd' on joint 2 is not "
        "supported by my-engine yet"
    )
    require_no_computed_torque(case, "mujoco-chain")
    ct = (drives[0], Drive("torque", PD(1.0, 1.0, Constant(0.0), ComputedTorque())))
    with pytest.raises(InputError, match=r"drives\[1\].feedforward.*joint 2.*mujoco-chain"):
        require_no_computed_torque(dttmm.Case(case.model, dttmm.Scenario(1.0, 0.1, ct)), "mujoco-chain")


def test_the_shipped_closed_loop_case_loads_and_an_engine_without_closed_loop_refuses_it():

    path = (
        Path(__file__).resolve().parents[1]
        / "experiments"
        / "cases"
        / "control"
        / "closed_loop_three_link.toml"
    )
    case = dttmm.load_case(path)
    assert [d.law.name for d in case.scenario.drives] == ["pd"] * 3
    assert all(d.closed_loop and d.law.moment_gain == 0.5 for d in case.scenario.drives)
    assert [d.law.reference.motion(1.0)[0] for d in case.scenario.drives] == [0.8, -0.6, 0.4]
    with pytest.raises(InputError, match="joint 1 is not supported by my-engine yet"):
        require_open_loop(case, "my-engine")
