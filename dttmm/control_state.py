"""What a closed-loop law sees of the arm: :class:`ControlState`, and its numba form
:class:`JitState` (declared from it, field by field) for laws compiled by numba.

The kernel builds a :class:`JitState` for a jitted user law (see :mod:`dttmm.kernel.userlaw`);
engines that call a law from Python give it a :class:`ControlState`, turned into a
:class:`JitState` for a jitted law (:func:`jit_state`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

__all__ = ["ControlState", "JitState", "is_jitted", "jit_state", "make_state"]


@dataclass(frozen=True)
class ControlState:
    """What a closed-loop law sees of the arm at time t (SI units, angles CCW).

    joint : 0-based index of the driven joint.
    angle, rate : α (rad) and α̇ (rad/s) of the driven joint.
    moment : root bending moment of the driven link (N·m): the moment the inboard side (joint and
        hub) exerts on the beam at its root cross-section, CCW positive — positive while the hub
        drags a lagging beam forward.
    integral : ∫₀ᵗ (α_ref − α) dt (rad·s), the integrator state of a ``pid`` law (0 at t = 0).
    angles, rates : (n,) every joint's angle and rate.
    tip_deflections : (n,) transverse tip deflection of every link in its clamped-root frame (m).
    computed_torque : rigid inverse-dynamics torque of the reference motion at this joint (N·m),
        filled only by engines that compute the ``computed_torque`` feedforward; else None.
    """

    joint: int
    angle: float
    rate: float
    moment: float = 0.0
    integral: float = 0.0
    angles: tuple = ()
    rates: tuple = ()
    tip_deflections: tuple = ()
    computed_torque: float | None = None


# the type of each ControlState field in the numba form: tuples become float64 arrays, an
# absent computed torque nan
_JIT_TYPES = {"int": int, "float": float, "tuple": np.ndarray, "float | None": float}

JitState = NamedTuple("JitState", [(f.name, _JIT_TYPES[f.type]) for f in fields(ControlState)])
JitState.__doc__ = """What a numba-jitted user law sees of the arm at time t: the fields of
:class:`ControlState`, in its order, with ``angles``, ``rates``, ``tip_deflections`` as (n,)
float64 arrays (C-contiguous; the kernel reuses them: read them, do not keep or write them),
``integral`` always 0.0 and ``computed_torque`` nan (not computed for a user law)."""


def make_state(joint, angle, rate, moment=0.0, integral=0.0, angles=None, rates=None, tips=None) -> JitState:
    """A :class:`JitState` from Python numbers and sequences (to call or test a law by hand);
    ``angles``, ``rates``, ``tips`` default to the single joint's values / 0."""
    arr = lambda v, d: np.ascontiguousarray(np.atleast_1d(d if v is None else v), np.float64)
    return JitState(
        int(joint),
        float(angle),
        float(rate),
        float(moment),
        float(integral),
        arr(angles, angle),
        arr(rates, rate),
        arr(tips, 0.0),
        float("nan"),
    )


def jit_state(state: ControlState) -> JitState:
    """The :class:`JitState` of a :class:`ControlState` (computed_torque None → nan)."""
    js = make_state(
        state.joint,
        state.angle,
        state.rate,
        state.moment,
        state.integral,
        state.angles or None,
        state.rates or None,
        state.tip_deflections or None,
    )
    ct = state.computed_torque
    return js._replace(computed_torque=math.nan if ct is None else float(ct))


def is_jitted(fn) -> bool:
    """Whether ``fn`` is a numba-jitted function (a CPU dispatcher)."""
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:  # pragma: no cover - without numba
        return False
    return isinstance(fn, CPUDispatcher)
