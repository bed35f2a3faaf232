"""A spatial case = a spatial manipulator + the planar suite's scenario (one drive per unlocked
joint, base first)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..errors import InputError
from ..scenario import Scenario
from .model import SpatialManipulator

__all__ = ["SpatialCase"]


@dataclass(frozen=True)
class SpatialCase:
    """The physical problem of a spatial arm: ``model`` and ``scenario``; ``provenance`` is
    free-form metadata (no part in equality)."""

    model: SpatialManipulator
    scenario: Scenario
    name: str = ""
    provenance: dict | None = field(default=None, compare=False)

    def __post_init__(self):
        if not isinstance(self.model, SpatialManipulator):
            raise InputError("case.model", self.model, "must be a dttmm.spatial.SpatialManipulator")
        if not isinstance(self.scenario, Scenario):
            raise InputError("case.scenario", self.scenario, "must be a dttmm.Scenario")
        if not isinstance(self.name, str):
            raise InputError("case.name", self.name, "must be a string")
        if self.provenance is not None:
            if not isinstance(self.provenance, dict) or not all(isinstance(k, str) for k in self.provenance):
                raise InputError(
                    "case.provenance", self.provenance, "must be a dict with string keys or None"
                )
            object.__setattr__(self, "provenance", dict(self.provenance))
        n, m = self.model.n_joints, len(self.scenario.drives)
        if n != m:
            raise InputError(
                "scenario.drives", f"{m} drives", f"needs exactly one drive per unlocked joint ({n} joints)"
            )

    @property
    def n_joints(self) -> int:
        return self.model.n_joints
