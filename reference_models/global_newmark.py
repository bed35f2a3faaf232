"""The "traditional" global-equation solver of the DT-TMM discretisation.

Same model, same element kinematics and same time integration as :func:`dttmm.simulate`, but
the equations of motion are assembled into one dense system in the minimal coordinates

    q = [α_1, e_{1,1}, …, e_{1,k}, α_2, e_{2,1}, …],

with α_i the joint angles and e = (u, v, φ) (or (v, φ) for an inextensible link) the elastic
coordinates of every element, and solved as

    M(q) q̈ + h(q, q̇) + f_int(q) + D q̇ = Q(t, q),

f_int = K q for the linear element (``strain="linear"``, the default) or the gradient of the
second-order strain energy (``strain="second-order"``, extensible links; see
:func:`elastic_forces`). The Kelvin-Voigt damping acts on the rate of the same strain
measure (:func:`damping_forces`): D q̇ with D = μK for the linear element.

The readable mechanics — M = Σ J_elᵀ M_el J_el from dense recursive Jacobians, the forces,
energy and kinematics, and :func:`accelerations` (forward dynamics at one state, solved by
LU) — are in :mod:`reference_models._global_numpy`; it has no time loop. The time loop is
one source, :mod:`reference_models._global_numba`: it accumulates M column by column from
composite body inertias (O(N²), no Jacobian products) and solves by Cholesky. numba compiles
it (``engine="numba"``, the default when numba is installed); ``engine="python"`` (alias
``"numpy"``) runs the same file uncompiled (:mod:`reference_models._global_python`), as
:mod:`dttmm.kernel_python` does for DT-TMM. The two engines agree to round-off; the numpy
mechanics are the independent check of their one-step quantities. Either way the cost per
solve grows like N³ in the number N of coordinates.

Each step of Newmark / generalized-α iterates the accelerations with the elastic and
damping forces linearised at the iterate, and stops by the rule of :func:`dttmm.simulate`,
:func:`dttmm.iteration.stop_rule`: max|Δq̈| ≤ tol·max(1, max|q̈|), or, from the 4th solve on, a
change that stagnates at the round-off floor (Δ ≥ 0.9·Δ_prev and Δ ≤ 1e3·tol·max(1, max|q̈|)).
A step that exhausts ``max_iterations`` makes the Result's status "unconverged"; so does a
forward-dynamics solve with closed-loop laws (t = 0, restarts) that does
(``meta["unconverged_solves"]``).

Closed-loop drive laws (``pd``, ``pid``, user laws; docs/control.md, "Global solver") are
solved implicitly at every step end with the stepped integrators: the law's torque enters the
generalized force of its joint, its linearisation the iteration matrix, with the root bending
moment M_root = τ − J_hub ω̇ (ω̇ a fixed row of q̈). See :mod:`reference_models._global_control`
and ``_laws`` in :mod:`reference_models._global_numba`.

This module is an independent implementation: it shares with :mod:`dttmm` only the model,
scenario and result classes, the step schedule, the option checks, the stop rule of the
iteration and the errors.

Element kinematics (floating frame at the inboard node I, angle θ of the cross-section at I):
material point ξ ∈ [0, 1], x = ξl, local position s(ξ) = (x + ξu, N3 v + N4 φ),
N3 = 3ξ² − 2ξ³, N4 = l(ξ³ − ξ²); global r = r_I + A(θ) s. Outboard node
r_O = r_I + A(θ)(l + u, v), θ_O = θ + φ; a joint adds α to the angle.
"""

from __future__ import annotations

import dataclasses

from dttmm import plumbing
from dttmm.shapes import shape_points as _shape_points

from . import _global_control, _global_driver
from ._global_driver import ENGINES, INTEGRATORS
from ._global_numpy import (
    STRAINS,
    _layout,
    accelerations,
    coordinate_names,
    damping_forces,
    elastic_forces,
    element_mass,
    energy,
    kinematics,
    mass_matrix,
    stiffness_matrix,
)

__all__ = [
    "simulate",
    "accelerations",
    "mass_matrix",
    "stiffness_matrix",
    "elastic_forces",
    "energy",
    "kinematics",
    "coordinate_names",
    "element_mass",
    "damping_forces",
    "INTEGRATORS",
    "STRAINS",
    "ENGINES",
]


def simulate(case, *, elements_per_link, h, integrator="newmark", strain="linear", engine=None, **options):
    """Simulate ``case`` with the global equations of the DT-TMM discretisation.

    Parameters
    ----------
    case : dttmm.Case
        Model and scenario.
    elements_per_link : int
        Number k ≥ 1 of beam elements per link.
    h : float
        Step size (s), 0 < h ≤ duration.
    integrator : {"newmark", "generalized-alpha"}
        ``"newmark"`` (options ``beta`` = 0.25, ``gamma`` = 0.5) and ``"generalized-alpha"``
        (option ``rho_inf`` = 0.9) step the schedule of :func:`dttmm.timegrid.step_schedule`
        with the frozen-coefficient iteration (options ``iterations`` = None for
        tolerance-driven with ``tol`` = 1e-10 and at most ``max_iterations`` = 50 solves, or
        m for exactly m + 1 solves per step).
    strain : {"linear", "second-order"}
        Element strain measure (see :func:`elastic_forces`). With ``"second-order"`` the
        stepped integrators linearise the elastic forces at every iterate (Newton), exactly
        as :func:`dttmm.simulate` does, and the Kelvin-Voigt damping acts on the rate of the
        same strain (see :func:`damping_forces`).
    shape_points : int, option
        p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2) m from the element shape functions;
        0 (default) records none.
    engine : {"numba", "python", "numpy", None}
        ``"numba"``: the compiled time loop (the default when numba is installed);
        ``"python"``: the same source uncompiled (≈ 100× slower; same results to round-off);
        ``"numpy"`` is an alias of ``"python"``. Closed-loop user laws (Python callables) need
        ``"python"``. ``Result.meta["engine"]`` says which ran.

    Returns
    -------
    dttmm.Result
        Sampled on ``case.scenario.output_times``; ``wall_time`` covers the stepping only.
        ``status`` is "unconverged" (with a warning naming the first such time) when some
        step exhausted ``max_iterations``.

    Raises
    ------
    dttmm.InputError
        Bad k, h, integrator, engine or option (the message names the field), or a user law
        with the compiled engine.
    dttmm.SimulationError
        Non-finite state; ``partial`` holds the outputs so far.
    """
    p = _shape_points(options.pop("shape_points", 0))
    k, h = plumbing.discretisation(case, elements_per_link, h)
    opt = _global_driver.check_options(integrator, options)
    engine = _global_driver.check_engine(engine)
    if engine == "numba":
        _global_control.require_python_engine(case)
    lay = _layout(case, k, strain)
    if p:
        lay = dataclasses.replace(lay, shape_points=p)
    return _global_driver.run(case, lay, k, h, integrator, opt, engine)
