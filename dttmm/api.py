"""One public API for every arm: :func:`simulate`, :func:`accelerations` and :func:`statics` take a
planar :class:`dttmm.Case` or a spatial :class:`dttmm.spatial.SpatialCase` (as
:func:`dttmm.load_case` reads either) and pick the kernel (:func:`kernel_of`): a planar arm runs
on the planar kernel (:mod:`dttmm.solver`, the fast path; its results are those of a direct call,
bit for bit), a spatial arm on the spatial kernel (:mod:`dttmm.spatial`). ``kernel="spatial"``
runs a planar arm on the spatial kernel too, embedded by
:meth:`dttmm.spatial.SpatialCase.from_planar` (for comparison; the Result is then a
:class:`dttmm.spatial.SpatialResult`). These are ``dttmm.simulate``, ``dttmm.accelerations``
and ``dttmm.statics``.
"""

from __future__ import annotations

import numpy as np

from . import plumbing
from . import solver as planar
from .case import Case
from .errors import InputError

__all__ = ["KERNELS", "accelerations", "kernel_of", "simulate", "statics"]

#: the kernels that run an arm: "planar" (planar arms only) and "spatial" (any arm)
KERNELS = ("planar", "spatial")


def kernel_of(case, kernel: str | None = None) -> str:
    """The kernel that runs ``case``: "planar" for a :class:`dttmm.Case`, "spatial" for a
    :class:`dttmm.spatial.SpatialCase` (or a (SpatialManipulator, Scenario) pair); ``kernel``
    overrides the choice ("spatial" runs a planar arm on the spatial kernel; a spatial arm runs
    on the spatial kernel only). InputError (one line, naming the type) for anything else."""
    if kernel is not None:
        plumbing.choice("kernel", kernel, KERNELS)
    if isinstance(case, Case):
        return kernel or "planar"
    from .spatial.case import SpatialCase
    from .spatial.model import SpatialManipulator

    if isinstance(case, SpatialCase) or (
        isinstance(case, tuple) and len(case) == 2 and isinstance(case[0], SpatialManipulator)
    ):
        if kernel == "planar":
            raise InputError("kernel", kernel, "runs planar arms only; this case is spatial")
        return "spatial"
    raise InputError(
        "case",
        type(case).__name__,
        "must be a dttmm.Case or a dttmm.spatial.SpatialCase (see dttmm.load_case)",
    )


def _spatial_case(case):
    """``case`` for the spatial kernel: a planar case embedded (:meth:`SpatialCase.from_planar`,
    docs/spatial.md §1)."""
    from .spatial import SpatialCase

    return SpatialCase.from_planar(case) if isinstance(case, Case) else case


def _riccati_only(sweep: str) -> None:
    if sweep != "riccati":
        raise InputError("sweep", sweep, "the spatial kernel has the Riccati sweep only")


def simulate(
    case,
    *,
    elements_per_link: int,
    h: float,
    kernel: str | None = None,
    sweep: str = "riccati",
    cut_loads: bool | None = None,
    progress: bool | None = None,
    shape_points: int = 0,
    **options,
):
    """Simulate any arm by DT-TMM with k = ``elements_per_link`` elements per link and step ``h``.

    Parameters
    ----------
    case : dttmm.Case (planar kernel) or dttmm.spatial.SpatialCase (spatial kernel)
    kernel : None (default: chosen by the case, :func:`kernel_of`), "planar" or "spatial"
        ("spatial" runs a planar arm on the spatial kernel, for comparison).
    sweep : "riccati" (both kernels) or "plain" (the planar kernel only).
    cut_loads : record the cut loads; None: the kernel's default (planar on, spatial off).
    progress : a progress bar (tqdm, on stderr); None: on when the run, estimated after its
        first chunk of steps, takes over 2 s.
    shape_points : p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2), spatial (nt, n, p, 3).
    **options : the kernel's settings (``integrator``, ``iterations``, ``tol``,
        ``max_iterations``, ``beta``, ``gamma``, ``rho_inf``, ``energy``, ``engine``,
        ``auto_fraction``, ``strain``): :func:`dttmm.solver.simulate` (planar),
        :func:`dttmm.spatial.simulate` (spatial).

    Returns
    -------
    dttmm.Result (planar kernel) or dttmm.spatial.SpatialResult (spatial kernel), on
    ``case.scenario.output_times``. Both kernels refuse a run whose arrays would not fit in
    memory (:func:`dttmm.check_run_size`) before allocating it.

    Raises
    ------
    InputError for a bad case (one line naming its type) or setting; SimulationError (with
    ``.partial``) when the run diverges.
    """
    if kernel_of(case, kernel) == "planar":
        return planar.simulate(
            case,
            elements_per_link=elements_per_link,
            h=h,
            sweep=sweep,
            cut_loads=True if cut_loads is None else cut_loads,
            progress=progress,
            shape_points=shape_points,
            **options,
        )
    from .spatial.solver import simulate as spatial_simulate

    _riccati_only(sweep)
    return spatial_simulate(
        _spatial_case(case),
        elements_per_link=elements_per_link,
        h=h,
        cut_loads=bool(cut_loads),
        progress=progress,
        shape_points=shape_points,
        **options,
    )


def accelerations(
    case,
    elements_per_link: int,
    q,
    qd,
    t: float = 0.0,
    *,
    kernel: str | None = None,
    sweep: str = "riccati",
    engine: str | None = None,
    strain: str = "linear",
) -> np.ndarray:
    """Forward dynamics of any discretised arm: q̈ (n_dof,) from (q, q̇) (n_dof,) at time t (s).

    Coordinates as in :mod:`dttmm.structure` (``[α_1, e_11, …, α_2, …]``) on the planar kernel
    (:func:`dttmm.solver.accelerations`), as in docs/spatial.md §3 (e = (u, v, w, φx, φy, φz)) on
    the spatial one (a spatial case, or a planar one with ``kernel="spatial"``;
    :func:`dttmm.spatial.accelerations`).
    """
    if kernel_of(case, kernel) == "planar":
        return planar.accelerations(
            case, elements_per_link, q, qd, t, sweep=sweep, engine=engine, strain=strain
        )
    from .spatial.solver import accelerations as spatial_accelerations

    _riccati_only(sweep)
    return spatial_accelerations(
        _spatial_case(case), elements_per_link, q, qd, t, strain=strain, engine=engine
    )


def statics(case, *, elements_per_link: int, **options):
    """Static equilibrium of any arm with its joints held (at ``angles``, default 0) under its
    gravity and loads: :func:`dttmm.spatial.statics` (its options: ``loads``, ``t``, ``strain``,
    ``tol``, ``max_iterations``, ``steps``, ``angles``, ``engine``). A planar case is solved on
    the spatial kernel, embedded by :meth:`dttmm.spatial.SpatialCase.from_planar` (its plane is
    the world's x–y plane); returns a :class:`dttmm.spatial.StaticResult` (3-component positions)."""
    kernel_of(case, "spatial")
    from .spatial.statics import statics as spatial_statics

    return spatial_statics(_spatial_case(case), elements_per_link=elements_per_link, **options)
