"""Drive laws and per-joint drives.

A law is a small named function of time. For a torque drive it gives the motor torque
τ(t) (N·m); for a motion drive the joint angle α(t) (rad) with its rate and acceleration.

Closed-loop laws (``pd``, ``pid``, :class:`UserLaw`) compute the torque from the state of the
arm instead: ``law.evaluate(t, state)`` with a :class:`ControlState`. A drive with such a law is
``closed_loop``; its ``torque(t)`` is refused (there is no torque without a state). Engines that
do not support them yet call :func:`require_open_loop`. Reference: docs/control.md.

Every law lists its ``breakpoints``: instants where its value (torque) or acceleration
(motion) may jump. Integrators end a step exactly there and restart, so a jump costs no order
of accuracy; at a breakpoint the step that ends there sees the left limit (``left=True``)
and the step that starts there the right limit.
"""

from __future__ import annotations

import bisect
import dataclasses
import itertools
import math
from dataclasses import dataclass, field
from typing import Annotated, Literal, Optional, Union

from pydantic import Field, Strict, ValidationError, create_model

from .control_state import ControlState, JitState, is_jitted, jit_state
from .errors import InputError
from .schema import (
    Checked,
    Finite,
    Limit,
    NonNegative,
    Positive,
    Until,
    _set,
    _short,
    build,
    field_types,
    fields_model,
    input_error,
    tuple_of,
)

__all__ = [
    "LAWS",
    "LAW_FIELDS",
    "PD",
    "PID",
    "BangBang",
    "ComputedTorque",
    "Constant",
    "ControlState",
    "Drive",
    "JitState",
    "Sine",
    "SpinUp",
    "Table",
    "UserLaw",
    "law_from_dict",
    "reference_of",
    "require_no_computed_torque",
    "require_open_loop",
]


def _check_kind(law, kind: str, where: str):
    if kind not in law.kinds:
        raise InputError(
            f"{where}.law", law.name, f"cannot drive a {kind!r} joint (allowed for: {', '.join(law.kinds)})"
        )


@dataclass(frozen=True)
class Constant(Checked):
    """τ = value, or α = value (held angle)."""

    value: Finite = 0.0
    name = "constant"
    kinds = ("torque", "motion")
    _where = "law"

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
class BangBang(Checked):
    """Piecewise constant: ``levels[i]`` holds on [t_i, t_{i+1}) with t_0 = -inf."""

    levels: tuple_of(Finite, min_length=1)
    switch_times: tuple_of(Finite)
    name = "bang_bang"
    kinds = ("torque",)
    _where = "law"

    def _rules(self):
        lv, st = self.levels, self.switch_times
        if len(lv) != len(st) + 1:
            raise InputError("law.levels", list(lv), f"needs len(switch_times) + 1 = {len(st) + 1} entries")
        if any(b <= a for a, b in itertools.pairwise(st)):
            raise InputError("law.switch_times", list(st), "must be strictly increasing")

    def __call__(self, t: float, left: bool = False) -> float:
        side = bisect.bisect_left if left else bisect.bisect_right
        return self.levels[side(self.switch_times, t)]

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return self.switch_times

    def params(self) -> dict:
        return {"levels": list(self.levels), "switch_times": list(self.switch_times)}


def _set_params(law, bound: str) -> dict:
    """The optional parameters of ``law`` that are set: its ``phase``, ``offset`` or
    ``moment_gain`` when nonzero, its ``bound`` (``until``, ``limit``) when finite."""
    d = {k: v for k in ("phase", "offset", "moment_gain") if (v := getattr(law, k, 0.0))}
    v = getattr(law, bound)
    return {**d, bound: v} if math.isfinite(v) else d


@dataclass(frozen=True)
class Sine(Checked):
    """amplitude·sin(2π·frequency·t + phase) + offset for t < until, offset afterwards."""

    amplitude: Finite
    frequency: Positive
    phase: Finite = 0.0
    offset: Finite = 0.0
    until: Until = math.inf
    name = "sine"
    kinds = ("torque", "motion")
    _where = "law"

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
        return {"amplitude": self.amplitude, "frequency": self.frequency, **_set_params(self, "until")}


@dataclass(frozen=True)
class SpinUp(Checked):
    """Smooth spin-up to the rate ω_s (rad/s) over ``ramp_time`` T (s) (motion only).

    rate (ω_s/T)(t − (T/2π) sin(2πt/T)) for t < T, then ω_s; the angle is its integral
    (ω_s/T)(t²/2 + (T/2π)²(cos(2πt/T) − 1)), then ω_s(t − T/2).
    """

    rate: Finite
    ramp_time: Positive
    name = "spin_up"
    kinds = ("motion",)
    _where = "law"

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
class Table(Checked):
    """Tabulated law through the points (times[i], values[i]), held at the end values outside.

    Torque: piecewise linear. Motion: the angle is the cubic spline through the points with
    zero rate at the first and last point ("clamped"), so the joint starts and ends at rest and
    angle and rate are continuous everywhere (no impulsive torque); the acceleration is
    continuous inside the table and jumps at its two ends, which are the law's breakpoints.
    """

    times: tuple_of(Finite, min_length=2)
    values: tuple_of(Finite, min_length=2)
    name = "table"
    kinds = ("torque", "motion")
    _where = "law"
    _spline: object = field(default=None, init=False, repr=False, compare=False)

    def _rules(self):
        ts, vs = self.times, self.values
        if len(vs) != len(ts):
            raise InputError("law.values", list(vs), f"needs one value per time ({len(ts)} entries)")
        if any(b <= a for a, b in itertools.pairwise(ts)):
            raise InputError("law.times", list(ts), "must be strictly increasing")

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


# --- closed-loop laws ---------------------------------------------------------------------------
@dataclass(frozen=True)
class ComputedTorque:
    """Feedforward of the rigid-model inverse dynamics of the reference motion of all joints.

    Only an engine with a rigid model computes it (it passes the value in
    ``ControlState.computed_torque``); elsewhere :func:`require_no_computed_torque` refuses it.
    """

    name = "computed_torque"
    kinds = ("torque",)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return ()  # the reference's breakpoints are the drive's already

    def params(self) -> dict:
        return {}


def _sub_law(value, where: str, kind: str):
    """A reference (``kind="motion"``) or feedforward (``"torque"``) law from a law object or a
    table (dict); open-loop laws only."""
    if isinstance(value, dict):
        if kind == "torque" and value.get("law") == "computed_torque":
            extra = sorted(k for k in value if k != "law")
            if extra:
                raise InputError(
                    f"{where}.{extra[0]}",
                    value[extra[0]],
                    "unknown key (computed_torque takes no parameters)",
                )
            return ComputedTorque()
        value = law_from_dict(value, where)
    if isinstance(value, ComputedTorque) and kind == "torque":
        return value
    if getattr(value, "closed_loop", False) or getattr(value, "name", None) not in LAWS:
        raise InputError(
            where,
            value,
            "must be an open-loop drive law (constant, bang_bang, sine, "
            "spin_up, table) or a table with a 'law' key",
        )
    _check_kind(value, kind, where)
    if kind == "motion" and value.name == "sine" and math.isfinite(value.until):
        raise InputError(
            f"{where}.until",
            value.until,
            "a reference motion cannot stop a sine abruptly (the rate would jump)",
        )
    return value


def _saturate(tau: float, limit: float, slopes: tuple) -> tuple:
    """(τ, slopes…) clipped to |τ| ≤ limit; beyond the limit every slope is zero."""
    if abs(tau) > limit:
        return (math.copysign(limit, tau),) + (0.0,) * len(slopes)
    return (tau, *slopes)


#: > −1: at −1 the torque loop through the root bending moment has no solution
MomentGain = Annotated[float, Strict(), Field(gt=-1.0, allow_inf_nan=False)]


@dataclass(frozen=True)
class PD(Checked):
    """τ = τ_ff(t) + kp (α_ref − α) + kd (α̇_ref − α̇) − moment_gain·M_root, then |τ| ≤ limit.

    kp : N·m/rad, kd : N·m·s/rad (both ≥ 0); reference : a motion law (or its table) giving
    α_ref(t); feedforward : None, a torque law or :class:`ComputedTorque`; moment_gain : 1;
    limit : N·m (inf: no saturation). Beyond the limit τ = ±limit and every slope is 0.
    """

    kp: NonNegative
    kd: NonNegative
    reference: object
    feedforward: object = None
    moment_gain: MomentGain = 0.0
    limit: Limit = math.inf
    name = "pd"
    kinds = ("torque",)
    closed_loop = True
    _where = "law"

    def _rules(self):
        _set(self, {"reference": _sub_law(self.reference, "law.reference", "motion")})
        if self.feedforward is not None:
            _set(self, {"feedforward": _sub_law(self.feedforward, "law.feedforward", "torque")})

    def _gains(self) -> dict:
        return {"kp": self.kp, "kd": self.kd, "moment_gain": self.moment_gain, "limit": self.limit}

    @property
    def gain_integral(self) -> float:
        """∂τ/∂(integral state) before saturation (N·m/(rad·s)); 0 for a PD law."""
        return 0.0

    def feedforward_torque(self, t: float, state: ControlState, left: bool = False) -> float:
        ff = self.feedforward
        if ff is None:
            return 0.0
        if isinstance(ff, ComputedTorque):
            if state.computed_torque is None:
                raise InputError(
                    "law.feedforward",
                    "computed_torque",
                    "needs an engine that computes the rigid inverse dynamics",
                )
            return float(state.computed_torque)
        return float(ff(t, left))

    def error_rate(self, t: float, state: ControlState, left: bool = False) -> float:
        """d(integral)/dt = α_ref(t) − α (rad): the right-hand side of the integrator state."""
        return self.reference.motion(t, left)[0] - state.angle

    def evaluate(self, t: float, state: ControlState, left: bool = False):
        """(τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂M_root) at t (``left``: left limit of the laws of time)."""
        a_ref, r_ref, _ = self.reference.motion(t, left)
        tau = (
            self.feedforward_torque(t, state, left)
            + self.kp * (a_ref - state.angle)
            + self.kd * (r_ref - state.rate)
            + self.gain_integral * state.integral
        )
        if self.moment_gain:  # an engine without bending moments passes nan
            tau -= self.moment_gain * state.moment
        return _saturate(tau, self.limit, (0.0 - self.kp, 0.0 - self.kd, 0.0 - self.moment_gain))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        ff = () if self.feedforward is None else tuple(self.feedforward.breakpoints)
        return tuple(sorted(set(self.reference.breakpoints) | set(ff)))

    def params(self) -> dict:
        d = {k: v for k, v in self._gains().items() if k in ("kp", "kd", "ki")}
        d["reference"] = {"law": self.reference.name, **self.reference.params()}
        if self.feedforward is not None:
            d["feedforward"] = {"law": self.feedforward.name, **self.feedforward.params()}
        return {**d, **_set_params(self, "limit")}


@dataclass(frozen=True)
class PID(PD):
    """PD plus ki·∫(α_ref − α)dt: ki in N·m/(rad·s), the integral state starts at 0.

    The integral is an extra state every engine integrates (no anti-windup: it keeps
    integrating while the torque is saturated).
    """

    ki: NonNegative = None  # required: None is refused with a clear message
    name = "pid"

    def _gains(self) -> dict:
        return {**super()._gains(), "ki": self.ki}

    @property
    def gain_integral(self) -> float:
        return self.ki


@dataclass(frozen=True)
class UserLaw:
    """A closed-loop law written in Python: ``fn(t, state) -> (τ, ∂τ/∂α, ∂τ/∂α̇)``.

    ``state`` is a :class:`ControlState`; if ``fn`` is numba-jitted, it runs inside the
    compiled kernel and ``state`` is a :class:`JitState` (the same fields, the tuples as
    float64 arrays). ``breakpoints`` (s): instants where τ may jump (the
    integrators end a step there). ``label`` names the law in messages. A user law cannot be
    written to a case file.
    """

    fn: object
    breakpoints: tuple = ()
    label: str = "user"
    name = "user"
    kinds = ("torque",)
    closed_loop = True
    feedforward = None
    moment_gain = 0.0
    gain_integral = 0.0

    def __post_init__(self):
        if not callable(self.fn):
            raise InputError(
                "law.fn", self.fn, "must be a callable fn(t, state) -> (tau, dtau_dalpha, dtau_dalphadot)"
            )
        bp = tuple(float(b) for b in self.breakpoints)
        if any(not (math.isfinite(b) and b > 0) for b in bp) or any(
            b <= a for a, b in itertools.pairwise(bp)
        ):
            raise InputError("law.breakpoints", self.breakpoints, "must be positive, finite and increasing")
        _set(self, {"breakpoints": bp})

    def error_rate(self, t, state, left=False) -> float:
        return 0.0

    def evaluate(self, t: float, state: ControlState, left: bool = False):
        """(τ, ∂τ/∂α, ∂τ/∂α̇, 0.0) from the user's function (a numba-jitted one is given the
        state as a :class:`JitState`, in every engine)."""
        if isinstance(state, ControlState) and is_jitted(self.fn):
            state = jit_state(state)
        out = self.fn(t, state)
        try:
            tau, da, dr = (float(x) for x in out)
        except (TypeError, ValueError):
            raise InputError(
                f"law {self.label!r}",
                _short(out),
                f"at t = {t:g} s must return three numbers (tau, dtau_dalpha, dtau_dalphadot)",
            ) from None
        if not all(map(math.isfinite, (tau, da, dr))):
            raise InputError(
                f"law {self.label!r}",
                out,
                f"returned a non-finite value at t = {t:g} s (joint {state.joint + 1})",
            )
        return tau, da, dr, 0.0

    def params(self) -> dict:
        raise InputError("law", self.label, "a user law (Python callable) cannot be written to a case file")


OPEN_LAWS = {cls.name: cls for cls in (Constant, BangBang, Sine, SpinUp, Table)}
LAWS = {**OPEN_LAWS, "pd": PD, "pid": PID}


# --- law tables: a law in a case file, ``law = "sine"`` and its parameters ----------------------
def _tagged(name: str, fields):
    """The model ``fields`` plus the tag ``law = name``: one member of a union of law tables."""
    return create_model(
        f"{fields.__name__[:-6]}Table", __base__=fields, __module__=__name__, law=(Literal[name], ...)
    )


def _union(tables):
    return Annotated[Union[tuple(tables)], Field(discriminator="law")]  # noqa: UP007


#: ``{ law = "computed_torque" }``: rigid-model inverse dynamics of the reference motion
ComputedTorqueTable = _tagged("computed_torque", fields_model(ComputedTorque))

#: the tables of a PD/PID law's sub-laws: reference (a motion law), feedforward (a torque law)
SUB_LAW_TABLES = {
    "reference": _union(_tagged(n, fields_model(c)) for n, c in OPEN_LAWS.items() if "motion" in c.kinds),
    "feedforward": _union(
        [
            *(_tagged(n, fields_model(c)) for n, c in OPEN_LAWS.items() if "torque" in c.kinds),
            ComputedTorqueTable,
        ]
    ),
}


def _law_fields(cls):
    """The model of the parameters of law ``cls`` in a table: its case fields, and its sub-laws
    as tables (required, or optional with the dataclass default None)."""
    subs = {
        f.name: (
            (SUB_LAW_TABLES[f.name], ...)
            if f.default is dataclasses.MISSING
            else (Optional[SUB_LAW_TABLES[f.name]], f.default)  # noqa: UP045
        )
        for f in dataclasses.fields(cls)
        if f.name in SUB_LAW_TABLES
    }
    if not subs:
        return fields_model(cls)
    return create_model(f"{cls.__name__}Fields", __base__=fields_model(cls), __module__=__name__, **subs)


#: law name -> the model of its parameters (every law a case file can name)
LAW_FIELDS = {name: _law_fields(cls) for name, cls in LAWS.items()}


def _prefixed(exc: InputError, where: str) -> InputError:
    """``exc`` with its leading ``law`` replaced by the path ``where``."""
    return InputError(exc.field.replace("law", where, 1), exc.value, exc.reason)


def law_from_table(name: str, spec):
    """The law ``name`` from a table its :data:`LAW_FIELDS` model (or a drive table) has
    validated: built from the validated values; only the cross-field rules run."""
    if name == "computed_torque":
        return ComputedTorque()
    cls = LAWS[name]
    values = {k: getattr(spec, k) for k in field_types(cls)}
    for k in [f.name for f in dataclasses.fields(cls) if f.name in SUB_LAW_TABLES]:
        sub = getattr(spec, k)
        try:
            values[k] = None if sub is None else law_from_table(sub.law, sub)
        except InputError as exc:
            raise _prefixed(exc, f"law.{k}") from None
    return build(cls, **values)


def law_from_dict(params: dict, where: str = "law"):
    """Build a law from its table (``law = "sine"`` plus its parameters, schema-checked:
    unknown or private keys are refused)."""
    if not isinstance(params, dict):
        raise InputError(where, params, "must be a table with a 'law' key")
    params = dict(params)
    name = params.pop("law", None)
    if not isinstance(name, str) or name not in LAWS:
        raise InputError(f"{where}.law", name, f"unknown drive law (one of: {', '.join(LAWS)})")
    try:
        ok = LAW_FIELDS[name].model_validate(params)
    except ValidationError as exc:
        raise input_error(exc, LAW_FIELDS[name], where) from None
    try:
        return law_from_table(name, ok)
    except InputError as exc:
        raise _prefixed(exc, where) from None


@dataclass(frozen=True)
class Drive(Checked):
    """How one joint is driven.

    kind : ``"torque"`` (the law gives τ; the joint angle is free) or ``"motion"`` (the law
    gives the joint angle α(t); the torque is an output). A torque drive with a closed-loop
    law (``PD``, ``PID``, ``UserLaw``) is ``closed_loop``: its torque comes from
    :meth:`evaluate` with the state, and :meth:`torque` refuses.
    initial_angle, initial_rate : joint state at t = 0 for torque drives. For motion drives
    they follow from the law; if given they must agree with it.
    """

    kind: Literal["torque", "motion"]
    law: object
    initial_angle: Finite = 0.0
    initial_rate: Finite = 0.0
    _where: str = field(default="drive", repr=False, compare=False)

    def _rules(self):
        w = self._where
        if getattr(self.law, "name", None) not in LAWS and not isinstance(self.law, UserLaw):
            raise InputError(
                f"{w}.law",
                self.law,
                "must be a drive law (constant, bang_bang, sine, spin_up, "
                "table, pd, pid or a dttmm.drives.UserLaw)",
            )
        _check_kind(self.law, self.kind, w)
        if self.kind == "motion" and self.law.name == "sine" and math.isfinite(self.law.until):
            raise InputError(
                f"{w}.until",
                self.law.until,
                "a motion drive cannot stop a sine abruptly (the angle or rate would jump)",
            )
        if self.kind == "motion":
            a0, r0, _ = self.law.motion(0.0)
            for nm, given, lawv in (
                ("initial_angle", self.initial_angle, a0),
                ("initial_rate", self.initial_rate, r0),
            ):
                if given != 0.0 and abs(given - lawv) > 1e-12 * max(1.0, abs(lawv)):
                    raise InputError(
                        f"{w}.{nm}", given, f"contradicts the motion law, which gives {lawv!r} at t = 0"
                    )
            object.__setattr__(self, "initial_angle", float(a0))
            object.__setattr__(self, "initial_rate", float(r0))

    @property
    def breakpoints(self) -> tuple[float, ...]:
        return tuple(self.law.breakpoints)

    @property
    def closed_loop(self) -> bool:
        """True when the torque is a function of the state (``pd``, ``pid``, a user law)."""
        return bool(getattr(self.law, "closed_loop", False))

    def torque(self, t: float, left: bool = False) -> float:
        """Motor torque of an open-loop torque drive at t (left limit when ``left``)."""
        if self.closed_loop:
            raise InputError(
                f"{self._where}.law",
                self.law.name,
                "is a closed-loop law: its torque depends on the state; use drive.evaluate(t, state)",
            )
        return self.law(t, left)

    def evaluate(self, t: float, state: ControlState, left: bool = False):
        """(τ, ∂τ/∂α, ∂τ/∂α̇, ∂τ/∂M_root) of a closed-loop drive at t (see :class:`PD`)."""
        if not self.closed_loop:
            raise InputError(
                f"{self._where}.law",
                self.law.name,
                "is an open-loop law: use drive.torque(t) or drive.motion(t)",
            )
        return self.law.evaluate(t, state, left)

    def motion(self, t: float, left: bool = False) -> tuple[float, float, float]:
        """(α, α̇, α̈) of a motion drive at t."""
        return self.law.motion(t, left)


def reference_of(drive: Drive):
    """The motion law a joint follows or tracks (a motion drive's law, a closed-loop law's
    reference), or None for an open-loop torque drive or a user law."""
    if drive.kind == "motion":
        return drive.law
    return getattr(drive.law, "reference", None)


def require_open_loop(case, method: str) -> None:
    """Refuse a case with a closed-loop drive for an engine that does not support them yet.

    Raises
    ------
    InputError
        ``scenario.drives[1].law = 'pd': closed-loop drive law 'pd' on joint 2 is not supported
        by <method> yet``.
    """
    for i, d in enumerate(case.scenario.drives):
        if d.closed_loop:
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.name,
                f"closed-loop drive law {d.law.name!r} on joint {i + 1} is not supported by {method} yet",
            )


def require_no_computed_torque(case, method: str) -> None:
    """Refuse a ``computed_torque`` feedforward for an engine without a rigid model."""
    for i, d in enumerate(case.scenario.drives):
        if isinstance(getattr(d.law, "feedforward", None), ComputedTorque):
            raise InputError(
                f"scenario.drives[{i}].feedforward",
                "computed_torque",
                f"the computed_torque feedforward on joint {i + 1} is not supported by "
                f"{method} (only pinocchio-rigid computes it)",
            )
