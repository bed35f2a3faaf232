"""User laws compiled by numba: the state type they see and the tables the kernel passes them.

A user law ``fn(t, state) -> (τ, ∂τ/∂α, ∂τ/∂α̇)`` that is a numba-jitted function runs inside
the compiled kernel. ``state`` is a :class:`JitState` (the fields of
:class:`dttmm.drives.ControlState`, the tuples as 1-d float64 arrays). The kernel calls the
law through a numba first-class function type of the one signature :func:`signature`, so the
kernel is compiled once for all laws (per number of distinct user-law joints, and cached on
disk like the rest of the kernel); each law is compiled once for that signature.

The kernel loop sees the laws in ``Drives.user`` as a :class:`UserTables` (the open-loop and
pd/pid runs keep an empty float array there, and with it their own compiled kernel).
"""

from __future__ import annotations

from functools import cache
from typing import NamedTuple

import numpy as np

from ..errors import InputError


class JitState(NamedTuple):
    """What a numba-jitted user law sees of the arm at time t (SI units, angles CCW).

    Same fields as :class:`dttmm.drives.ControlState`: ``joint`` (0-based), ``angle``,
    ``rate``, ``moment`` (root bending moment of the driven link, N·m, of the last sweep),
    ``integral`` (always 0.0 for a user law), ``angles``, ``rates``, ``tip_deflections``
    ((n,) float64 arrays, C-contiguous; the kernel reuses them: read them, do not keep or
    write them) and ``computed_torque`` (nan: not computed for a user law).
    """

    joint: int
    angle: float
    rate: float
    moment: float
    integral: float
    angles: np.ndarray
    rates: np.ndarray
    tip_deflections: np.ndarray
    computed_torque: float


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


@cache
def signature():
    """numba signature of a compiled user law: UniTuple(float64, 3)(float64, JitState type)."""
    from numba import types

    arr = types.Array(types.float64, 1, "C")
    state = types.NamedTuple(
        [types.int64] + [types.float64] * 4 + [arr] * 3 + [types.float64],
        JitState,
    )
    return types.UniTuple(types.float64, 3)(types.float64, state)


def is_jitted(fn) -> bool:
    """Whether ``fn`` is a numba-jitted function (a CPU dispatcher)."""
    try:
        from numba.core.registry import CPUDispatcher
    except ImportError:  # pragma: no cover - without numba
        return False
    return isinstance(fn, CPUDispatcher)


def compiled(fn, where: str):
    """``fn`` (numba-jitted) compiled for :func:`signature`, as a first-class function value
    the kernel can take; an InputError naming ``where`` if it does not compile for it."""
    from numba.core.types.function_type import CompileResultWAP

    try:
        cres = fn.get_compile_result(signature())
    except Exception as exc:  # numba TypingError and friends: the law does not fit the signature
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise InputError(
            where,
            getattr(fn, "__name__", fn),
            f"a numba-jitted user law must compile as fn(t: float, state: JitState) -> "
            f"(tau, dtau_dalpha, dtau_dalphadot) floats; numba says: {first}",
        ) from None
    return CompileResultWAP(cres)


class UserTables(NamedTuple):
    """``Drives.user`` of the compiled kernel with user laws: the laws (one per distinct
    function, a tuple of first-class functions), ``slot`` (n,) the law of each joint (-1:
    none), the state arrays (n,) the laws see, and the scratch rows that
    :func:`dttmm.kernel.recorder.sample` writes (``root``, ``tip`` (1, n, 2), ``root_angle``
    (1, n), ``energy`` (0,))."""

    fns: tuple
    slot: np.ndarray
    angles: np.ndarray
    rates: np.ndarray
    tips: np.ndarray
    root: np.ndarray
    tip: np.ndarray
    root_angle: np.ndarray
    energy: np.ndarray


def tables(laws, n: int) -> UserTables:
    """:class:`UserTables` of ``laws`` ((n,) tuple: a UserLaw with a jitted ``fn`` or None)."""
    fns, slot, seen = [], np.full(n, -1, np.int64), {}
    for i, law in enumerate(laws):
        if law is None:
            continue
        key = id(law.fn)
        if key not in seen:
            seen[key] = len(fns)
            fns.append(compiled(law.fn, f"scenario.drives[{i}].law"))
        slot[i] = seen[key]
    return UserTables(
        fns=tuple(fns),
        slot=slot,
        angles=np.zeros(n),
        rates=np.zeros(n),
        tips=np.zeros(n),
        root=np.zeros((1, n, 2)),
        tip=np.zeros((1, n, 2)),
        root_angle=np.zeros((1, n)),
        energy=np.zeros(0),
    )
