"""Link shapes of a spatial arm (:attr:`dttmm.spatial.SpatialResult.link_shapes`): the kernel's
element frames at a state and the element shape functions of docs/spatial.md §2, through the
shared :func:`dttmm.shapes.frame_shapes` (at any coordinates: :func:`dttmm.spatial.link_shapes`)."""

from __future__ import annotations

import numpy as np

from ..shapes import frame_shapes
from .build import shape_tables

__all__ = ["from_frames"]


def from_frames(model, k: int, RI, rI, e, p: int) -> np.ndarray:
    """Link shapes (nt, n, p, 3) m of the spatial manipulator ``model`` from the kernel's element
    frames RI (nt, n·k, 3, 3), origins rI (nt, n·k, 3) and padded elastic coordinates
    e (nt, n·k, 6) (the kernel's ``Work.Rw``, ``pw``, ``e`` after ``kinematics``)."""
    lengths = [lk.beam.length for lk in model.links]
    ext = [not lk.rigid and lk.beam.EA is not None for lk in model.links]  # a rigid link: e = 0
    tables = lambda i, xi: shape_tables(lengths[i] / k, ext[i], xi)[:2]
    return frame_shapes(RI, rI, e, lengths, k, p, tables)
