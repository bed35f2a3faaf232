"""User laws compiled by numba: the state type they see and the tables the kernel passes them.

A user law ``fn(t, state) -> (τ, ∂τ/∂α, ∂τ/∂α̇)`` that is a numba-jitted function runs inside
the compiled kernel. ``state`` is a :class:`dttmm.control_state.JitState` (declared from
:class:`dttmm.control_state.ControlState`, the tuples as 1-d float64 arrays). The kernel calls the
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

from ..control_state import JitState, is_jitted, make_state
from ..errors import InputError

__all__ = ["JitState", "UserTables", "compiled", "is_jitted", "make_state", "signature", "tables"]


@cache
def signature():
    """numba signature of a compiled user law: UniTuple(float64, 3)(float64, JitState type)."""
    from numba import types

    kinds = {int: types.int64, float: types.float64, np.ndarray: types.Array(types.float64, 1, "C")}
    state = types.NamedTuple([kinds[tp] for tp in JitState.__annotations__.values()], JitState)
    return types.UniTuple(types.float64, 3)(types.float64, state)


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
