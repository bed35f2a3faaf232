"""External loads on a spatial arm and the spatial scenario that carries them (docs/spatial.md
§1, "External loads"; file format in docs/cases.md, "Spatial cases").

A :class:`SpatialLoad` is a force F (N) and a moment M (N·m) at the tip point of one link
(the origin of its tip frame), times a scalar factor law of time f(t) (any open-loop torque
law of :mod:`dttmm.drives`: ``constant``, ``bang_bang``, ``sine``, ``table``). In the frame
``"world"`` F and M are world components (a fixed direction, as the benchmark problems load);
in the frame ``"tip"`` they are components in the link's deformed tip frame (a follower load,
turning with the tip). A :class:`SpatialScenario` is the suite's :class:`dttmm.Scenario` plus a
tuple of loads; its breakpoints include the instants where a load's value or slope jumps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Annotated, Literal

import numpy as np
from pydantic import BeforeValidator, Strict

from ..drives import OPEN_LAWS, Constant, law_from_dict
from ..errors import InputError
from ..scenario import Scenario
from ..schema import _short, _Strict, check_fields
from .model import Vector3

__all__ = ["LOAD_FRAMES", "LOAD_LAWS", "SpatialLoad", "SpatialScenario", "load_inputs", "require_no_loads"]

LOAD_FRAMES = ("world", "tip")
#: the laws a load's factor can follow (open-loop torque laws: a value of time)
LOAD_LAWS = tuple(n for n, c in OPEN_LAWS.items() if "torque" in c.kinds)
#: columns of :func:`load_inputs`: world force, world moment, tip-frame force, tip-frame moment
LOAD_COLUMNS = 12


def _integer(value):
    if isinstance(value, bool) or not isinstance(value, int):
        raise InputError("", _short(value), "must be an integer (an index into model.links)")
    return value


LinkIndex = Annotated[int, BeforeValidator(_integer), Strict()]


class SpatialLoadFields(_Strict):
    force: Vector3 = [0.0, 0.0, 0.0]
    moment: Vector3 = [0.0, 0.0, 0.0]
    link: LinkIndex | None = None
    frame: Literal["world", "tip"] = "world"


def _factor_law(value, where: str):
    """An open-loop torque law (or its table ``{law = "sine", …}``) as a load's factor."""
    if isinstance(value, dict):
        if "law" in value and value.get("law") == "constant" and "value" not in value:
            raise InputError(f"{where}.value", None, "is required (a constant factor without a value is 0)")
        value = law_from_dict(value, where)
    name = getattr(value, "name", None)
    if getattr(value, "closed_loop", False) or name not in LOAD_LAWS or OPEN_LAWS[name] is not type(value):
        raise InputError(
            where, _short(value), f"must be an open-loop law of time (one of: {', '.join(LOAD_LAWS)})"
        )
    return value


@dataclass(frozen=True)
class SpatialLoad:
    """An external load at the tip point of link ``link`` (index in ``model.links``; None: the
    last link): ``force`` (N) and ``moment`` (N·m), both times ``factor(t)``; ``frame`` "world"
    (world components: a fixed direction) or "tip" (components in the link's deformed tip
    frame: a follower load). ``factor``: an open-loop torque law (``Constant``, ``BangBang``,
    ``Sine``, ``Table``; default constant 1) or its table."""

    force: tuple = (0.0, 0.0, 0.0)
    moment: tuple = (0.0, 0.0, 0.0)
    link: int | None = None
    frame: str = "world"
    factor: object = field(default_factory=lambda: Constant(1.0))
    _where: str = field(default="load", repr=False, compare=False)

    def __post_init__(self):
        w = self._where
        ok = check_fields(
            SpatialLoadFields, w, force=self.force, moment=self.moment, link=self.link, frame=self.frame
        )
        if ok["link"] is not None and ok["link"] < 0:
            raise InputError(f"{w}.link", ok["link"], "must be a link index >= 0 (or None: the last link)")
        for k, v in ok.items():
            object.__setattr__(self, k, v)
        object.__setattr__(self, "factor", _factor_law(self.factor, f"{w}.factor"))

    @property
    def follower(self) -> bool:
        return self.frame == "tip"

    def value(self, t: float, left: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """(F (3,), M (3,)) at t in the load's frame (left limit when ``left``)."""
        f = float(self.factor(t, left))
        return f * np.array(self.force, float), f * np.array(self.moment, float)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Instants where the load's value or its slope jumps (a table's every point)."""
        law = self.factor
        bp = set(law.breakpoints)
        if law.name == "table":
            bp |= set(law.times)
        return tuple(sorted(b for b in bp if math.isfinite(b)))

    def link_index(self, n_links: int) -> int:
        return n_links - 1 if self.link is None else self.link


@dataclass(frozen=True)
class SpatialScenario(Scenario):
    """The suite's scenario (duration, output grid, one drive per unlocked joint) plus external
    ``loads`` (a tuple of :class:`SpatialLoad`)."""

    loads: tuple = ()

    def _rules(self):
        super()._rules()
        if not isinstance(self.loads, (tuple, list)):
            raise InputError(
                "scenario.loads", _short(self.loads), "must be a tuple of dttmm.spatial.SpatialLoad"
            )
        loads = tuple(self.loads)
        for j, ld in enumerate(loads):
            if not isinstance(ld, SpatialLoad):
                raise InputError(f"scenario.loads[{j}]", _short(ld), "must be a dttmm.spatial.SpatialLoad")
        object.__setattr__(self, "loads", loads)

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Sorted instants in (0, duration) where a drive jumps or a load's value or slope does."""
        ts = set(super().breakpoints)
        ts |= {t for ld in self.loads for t in ld.breakpoints if 0.0 < t < self.duration}
        return tuple(sorted(ts))


def case_loads(case) -> tuple:
    """The loads of a case's scenario (none for a plain :class:`dttmm.Scenario`)."""
    return tuple(getattr(case.scenario, "loads", ()))


def check_load_links(case) -> None:
    """Every load names a link of the case's model."""
    n = case.model.n_links
    for j, ld in enumerate(case_loads(case)):
        if ld.link is not None and not ld.link < n:
            raise InputError(f"scenario.loads[{j}].link", ld.link, f"must be a link index in 0..{n - 1}")


def require_no_loads(case, method: str) -> None:
    """Refuse a case with external loads for an engine that does not apply them."""
    loads = case_loads(case)
    if loads:
        raise InputError(
            "scenario.loads", f"{len(loads)} load(s)", f"external loads are not supported by {method} yet"
        )


def load_inputs(case, t: float, left: bool = False, out=None) -> np.ndarray:
    """The loads of ``case`` at t, summed per link: (n_links, 12) rows (world force, world moment,
    tip-frame force, tip-frame moment); into ``out`` when given."""
    n = case.model.n_links
    out = np.zeros((n, LOAD_COLUMNS)) if out is None else out
    for ld in case_loads(case):
        F, M = ld.value(t, left)
        i = ld.link_index(n)
        c = 6 if ld.follower else 0
        out[i, c : c + 3] += F
        out[i, c + 3 : c + 6] += M
    return out
