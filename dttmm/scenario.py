"""What happens to the arm: duration, output grid and one drive per joint."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .drives import Drive
from .errors import InputError
from .schema import Checked, Positive

__all__ = ["Scenario"]


@dataclass(frozen=True)
class Scenario(Checked):
    """duration (s), output_step (s) of the common output grid, drives (one per joint, base first)."""

    duration: Positive
    output_step: Positive
    drives: tuple[Drive, ...]
    _where = "scenario"

    def _rules(self):
        if self.output_step > self.duration:
            raise InputError(
                "scenario.output_step", self.output_step, f"must not exceed the duration {self.duration}"
            )
        if not isinstance(self.drives, (tuple, list)):
            raise InputError("scenario.drives", self.drives, "must be a tuple of dttmm.Drive")
        drives = tuple(self.drives)
        for i, d in enumerate(drives):
            if not isinstance(d, Drive):
                raise InputError(f"scenario.drives[{i}]", d, "must be a dttmm.Drive")
        object.__setattr__(self, "drives", drives)

    @property
    def output_times(self) -> np.ndarray:
        """The common output grid 0, Δ, 2Δ, … up to the duration (inclusive within round-off)."""
        n = int(np.floor(self.duration / self.output_step * (1 + 1e-12) + 1e-9))
        return np.arange(n + 1) * self.output_step

    @property
    def breakpoints(self) -> tuple[float, ...]:
        """Sorted instants in (0, duration) where some drive jumps."""
        ts = {t for d in self.drives for t in d.breakpoints if 0.0 < t < self.duration}
        return tuple(sorted(ts))
