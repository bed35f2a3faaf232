"""The Result of a spatial run: :class:`dttmm.Result` with 3-D fields."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..result import Result

__all__ = ["SpatialResult"]


@dataclass(frozen=True)
class SpatialResult(Result):
    """A :class:`dttmm.Result` of a spatial arm (docs/spatial.md §4), n links, m unlocked joints:

    joint_angle, joint_rate, joint_torque (nt, m); link_root, link_tip (nt, n, 3) m;
    end_effector (nt, 3); tip_deflection (nt, n, 2): components of tip − root along the link
    frame's y and z axes (m); twist (nt, n): the x component of log(R_rootᵀ R_tip) (rad);
    cut_loads (nc, n_cuts, 6): force and moment (N, N·m; world components, moment about the
    cut's point) that the inboard part exerts on the outboard part, at every element root and
    every link tip (k + 1 cuts per link, base link first); link_rotation, tip_rotation
    (nt, n, 3, 3): the link frame at the root and the tip frame.
    """

    twist: np.ndarray | None = None
    link_rotation: np.ndarray | None = None
    tip_rotation: np.ndarray | None = None

    def to_frame(self):  # pragma: no cover - the planar table has 2-D columns
        raise NotImplementedError("SpatialResult has no tidy table yet; read its arrays")
