"""Link shapes of a spatial arm (:attr:`dttmm.spatial.SpatialResult.link_shapes`): the kernel's
element frames at a state and the element shape functions of docs/spatial.md §2, through the
shared :func:`dttmm.shapes.frame_shapes`."""

from __future__ import annotations

import numpy as np

from .. import plumbing
from ..shapes import frame_shapes, shape_points
from .build import STRAINS, build_model, make_work, shape_tables

__all__ = ["from_frames", "link_shapes"]


def from_frames(model, k: int, RI, rI, e, p: int) -> np.ndarray:
    """Link shapes (nt, n, p, 3) m of the spatial manipulator ``model`` from the kernel's element
    frames RI (nt, n·k, 3, 3), origins rI (nt, n·k, 3) and padded elastic coordinates
    e (nt, n·k, 6) (the kernel's ``Work.Rw``, ``pw``, ``e`` after ``kinematics``)."""
    lengths = [lk.beam.length for lk in model.links]
    ext = [lk.beam.EA is not None for lk in model.links]
    tables = lambda i, xi: shape_tables(lengths[i] / k, ext[i], xi)[:2]
    return frame_shapes(RI, rI, e, lengths, k, p, tables)


def link_shapes(case, elements_per_link: int, q, p: int, *, strain: str = "linear", engine=None):
    """Link shapes (nt, n, p, 3) m of the discretised spatial arm at coordinates q (nt, n_dof)
    or (n_dof,) (docs/spatial.md §3 layout): p ≥ 2 points per link from root to tip at equal
    reference arc lengths."""
    from .solver import _kernel, _motion_flags, as_spatial_case

    case = as_spatial_case(case)
    k = plumbing.elements_per_link(elements_per_link)
    plumbing.choice("strain", strain, STRAINS)
    p = shape_points(p)
    _, core, _ = _kernel(engine)
    md = build_model(case.model, k, strain, _motion_flags(case))
    ws = make_work(md)
    q = np.atleast_2d(np.asarray(q, float))
    nt = q.shape[0]
    RI, rI, e = np.zeros((nt, md.nel, 3, 3)), np.zeros((nt, md.nel, 3)), np.zeros((nt, md.nel, 6))
    zero = np.zeros(md.ndof)
    for j in range(nt):
        core.kinematics(md, ws, q[j], zero)
        RI[j], rI[j], e[j] = ws.Rw, ws.pw, ws.e
    return from_frames(case.model, k, RI, rI, e, p)
