"""Drive laws and per-joint drives.

A law is a small named function of time. For a torque drive it gives the motor torque
τ(t) (N·m); for a motion drive the joint angle α(t) (rad) with its rate and acceleration.

Every law lists its ``breakpoints``: instants where its value (torque) or acceleration
(motion) may jump. Integrators end a step exactly there and restart, so a jump costs no order
of accuracy; at a breakpoint the step that ends there sees the left limit (``left=True``)
and the step that starts there the right limit.
"""
from __future__ import annotations

import bisect
import itertools
import math
from dataclasses import dataclass, field

from pydantic import ValidationError

from .errors import InputError
from .schema import LAW_FIELDS, DriveFields, check_fields

__all__ = ["LAWS", "BangBang", "Constant", "Drive", "Sine", "SpinUp", "Table", "law_from_dict"]


def _set(obj, values: dict):
    for k, v in values.items():
        object.__setattr__(obj, k, v)


def _check_kind(law, kind: str, where: str):
    if kind not in law.kinds:
        raise InputError(f"{where}.law", law.name,
                         f"cannot drive a {kind!r} joint (allowed for: {', '.join(law.kinds)})")


@dataclass(frozen=True)
class Constant:
    """τ = value, or α = value (held angle)."""

    value: float = 0.0
    name = "constant"
    kinds = ("torque", "motion")

    def __post_init__(self):
        _set(self, check_fields(LAW_FIELDS["constant"], "law", value=self.value))

    def __call__(self, t: float, left: bool = False) -> float:
        return self.value

    def motion(self, t: float, left: bool = False):
        return self.value, 0.0, 0.0

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return ()

    def params(self) -> dict:
        return {"value": self.value}


@dataclass(frozen=True)
class BangBang:
    """Piecewise constant: ``levels[i]`` holds on [t_i, t_{i+1}) with t_0 = -inf."""

    levels: tuple[float, ...]
    switch_times: tuple[float, ...]
    name = "bang_bang"
    kinds = ("torque",)

    def __post_init__(self):
        ok = check_fields(LAW_FIELDS["bang_bang"], "law", levels=self.levels, switch_times=self.switch_times)
        lv, st = ok["levels"], ok["switch_times"]
        if len(lv) != len(st) + 1:
            raise InputError("law.levels", list(lv),
                             f"needs len(switch_times) + 1 = {len(st) + 1} entries")
        if any(b <= a for a, b in itertools.pairwise(st)):
            raise InputError("law.switch_times", list(st), "must be strictly increasing")
        object.__setattr__(self, "levels", lv)
        object.__setattr__(self, "switch_times", st)

    def __call__(self, t: float, left: bool = False) -> float:
        side = bisect.bisect_left if left else bisect.bisect_right
        return self.levels[side(self.switch_times, t)]

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return self.switch_times

    def params(self) -> dict:
        return {"levels": list(self.levels), "switch_times": list(self.switch_times)}


@dataclass(frozen=True)
class Sine:
    """amplitude·sin(2π·frequency·t + phase) + offset for t < until, offset afterwards."""

    amplitude: float
    frequency: float
    phase: float = 0.0
    offset: float = 0.0
    until: float = math.inf
    name = "sine"
    kinds = ("torque", "motion")

    def __post_init__(self):
        _set(self, check_fields(LAW_FIELDS["sine"], "law", amplitude=self.amplitude,
                                frequency=self.frequency, phase=self.phase, offset=self.offset,
                                until=self.until))

    def _on(self, t, left):
        return t < self.until or (left and t <= self.until)

    def __call__(self, t: float, left: bool = False) -> float:
        if not self._on(t, left):
            return self.offset
        return self.amplitude * math.sin(2 * math.pi * self.frequency * t + self.phase) + self.offset

    def motion(self, t: float, left: bool = False):
        if not self._on(t, left):
            return self.offset, 0.0, 0.0
        w = 2 * math.pi * self.frequency
        a = w * t + self.phase
        A = self.amplitude
        return A * math.sin(a) + self.offset, A * w * math.cos(a), -A * w * w * math.sin(a)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return (self.until,) if math.isfinite(self.until) else ()

    def params(self) -> dict:
        d = {"amplitude": self.amplitude, "frequency": self.frequency}
        if self.phase:
            d["phase"] = self.phase
        if self.offset:
            d["offset"] = self.offset
        if math.isfinite(self.until):
            d["until"] = self.until
        return d


@dataclass(frozen=True)
class SpinUp:
    """Smooth spin-up to the rate ω_s (rad/s) over ``ramp_time`` T (s) (motion only).

    rate (ω_s/T)(t − (T/2π) sin(2πt/T)) for t < T, then ω_s; the angle is its integral
    (ω_s/T)(t²/2 + (T/2π)²(cos(2πt/T) − 1)), then ω_s(t − T/2).
    """

    rate: float
    ramp_time: float
    name = "spin_up"
    kinds = ("motion",)

    def __post_init__(self):
        _set(self, check_fields(LAW_FIELDS["spin_up"], "law", rate=self.rate, ramp_time=self.ramp_time))

    def motion(self, t: float, left: bool = False):
        ws, T = self.rate, self.ramp_time
        if t < T:
            c = 2 * math.pi / T
            ang = (ws / T) * (t * t / 2 + (math.cos(c * t) - 1) / (c * c))
            rate = (ws / T) * (t - math.sin(c * t) / c)
            acc = (ws / T) * (1 - math.cos(c * t))
            return ang, rate, acc
        return ws * (t - T / 2), ws, 0.0

    def __call__(self, t: float, left: bool = False) -> float:
        return self.motion(t)[0]

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return ()

    def params(self) -> dict:
        return {"rate": self.rate, "ramp_time": self.ramp_time}


@dataclass(frozen=True)
class Table:
    """Tabulated law through the points (times[i], values[i]), held at the end values outside.

    Torque: piecewise linear. Motion: the angle is the cubic spline through the points with
    zero rate at the first and last point ("clamped"), so the joint starts and ends at rest and
    angle and rate are continuous everywhere (no impulsive torque); the acceleration is
    continuous inside the table and jumps at its two ends, which are the law's breakpoints.
    """

    times: tuple[float, ...]
    values: tuple[float, ...]
    name = "table"
    kinds = ("torque", "motion")
    _spline: object = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self):
        ok = check_fields(LAW_FIELDS["table"], "law", times=self.times, values=self.values)
        ts, vs = ok["times"], ok["values"]
        if len(vs) != len(ts):
            raise InputError("law.values", list(vs), f"needs one value per time ({len(ts)} entries)")
        if any(b <= a for a, b in itertools.pairwise(ts)):
            raise InputError("law.times", list(ts), "must be strictly increasing")
        object.__setattr__(self, "times", ts)
        object.__setattr__(self, "values", vs)

    def __call__(self, t: float, left: bool = False) -> float:
        ts, vs = self.times, self.values
        if t <= ts[0]:
            return vs[0]
        if t >= ts[-1]:
            return vs[-1]
        i = bisect.bisect_right(ts, t) - 1
        return vs[i] + (vs[i + 1] - vs[i]) * (t - ts[i]) / (ts[i + 1] - ts[i])

    def motion(self, t: float, left: bool = False):
        """(α, α̇, α̈) at t; at a table end, ``left`` picks the side of the acceleration jump."""
        t0, t1 = self.times[0], self.times[-1]
        if t < t0 or (t == t0 and left and t0 > 0.0):
            return self.values[0], 0.0, 0.0
        if t > t1 or (t == t1 and not left):
            return self.values[-1], 0.0, 0.0
        if self._spline is None:
            from scipy.interpolate import CubicSpline

            object.__setattr__(self, "_spline", CubicSpline(self.times, self.values, bc_type="clamped"))
        s = self._spline
        return float(s(t)), float(s(t, 1)), float(s(t, 2))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """The table ends: a motion table's acceleration jumps there (a torque table's slope)."""
        return (self.times[0], self.times[-1])

    def params(self) -> dict:
        return {"times": list(self.times), "values": list(self.values)}


LAWS = {cls.name: cls for cls in (Constant, BangBang, Sine, SpinUp, Table)}


def law_from_dict(params: dict, where: str = "law"):
    """Build a law from its table (``law = "sine"`` plus its parameters, schema-checked:
    unknown or private keys are refused)."""
    if not isinstance(params, dict):
        raise InputError(where, params, "must be a table with a 'law' key")
    params = dict(params)
    name = params.pop("law", None)
    if not isinstance(name, str) or name not in LAWS:
        raise InputError(f"{where}.law", name, f"unknown drive law (one of: {', '.join(LAWS)})")
    from .schema import input_error

    try:
        ok = LAW_FIELDS[name].model_validate(params)
    except ValidationError as exc:
        raise input_error(exc, LAW_FIELDS[name], where) from None
    try:
        return LAWS[name](**dict(ok))
    except InputError as exc:
        raise InputError(exc.field.replace("law.", f"{where}.", 1), exc.value, exc.reason) from None


@dataclass(frozen=True)
class Drive:
    """How one joint is driven.

    kind : ``"torque"`` (the law gives τ; the joint angle is free) or ``"motion"`` (the law
    gives the joint angle α(t); the torque is an output).
    initial_angle, initial_rate : joint state at t = 0 for torque drives. For motion drives
    they follow from the law; if given they must agree with it.
    """

    kind: str
    law: object
    initial_angle: float = 0.0
    initial_rate: float = 0.0
    _where: str = field(default="drive", repr=False, compare=False)

    def __post_init__(self):
        w = self._where
        _set(self, check_fields(DriveFields, w, kind=self.kind, initial_angle=self.initial_angle,
                                initial_rate=self.initial_rate))
        if getattr(self.law, "name", None) not in LAWS:
            raise InputError(f"{w}.law", self.law, "must be a drive law (constant, bang_bang, sine, spin_up, table)")
        _check_kind(self.law, self.kind, w)
        if self.kind == "motion" and self.law.name == "sine" and math.isfinite(self.law.until):
            raise InputError(f"{w}.until", self.law.until,
                             "a motion drive cannot stop a sine abruptly (the angle or rate would jump)")
        if self.kind == "motion":
            a0, r0, _ = self.law.motion(0.0)
            for nm, given, lawv in (("initial_angle", self.initial_angle, a0),
                                    ("initial_rate", self.initial_rate, r0)):
                if given != 0.0 and abs(given - lawv) > 1e-12 * max(1.0, abs(lawv)):
                    raise InputError(f"{w}.{nm}", given,
                                     f"contradicts the motion law, which gives {lawv!r} at t = 0")
            object.__setattr__(self, "initial_angle", float(a0))
            object.__setattr__(self, "initial_rate", float(r0))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return tuple(self.law.breakpoints)

    def torque(self, t: float, left: bool = False) -> float:
        """Motor torque of a torque drive at t (left limit when ``left``)."""
        return self.law(t, left)

    def motion(self, t: float, left: bool = False) -> tuple[float, float, float]:
        """(α, α̇, α̈) of a motion drive at t."""
        return self.law.motion(t, left)
