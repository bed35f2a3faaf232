"""The global-equation solver of the spatial discretisation (docs/spatial.md): the reference.

Same model and same discretisation as the spatial DT-TMM (:mod:`dttmm.spatial`), but the
equations of motion are assembled into one dense system in the minimal coordinates

    q = [α_1, e_{1,1}, …, e_{1,k}, α_2, …],   e = (u, v, w, φx, φy, φz)

(no α for a locked joint, no u for an inextensible link) and solved as

    M(q) q̈ + h(q, q̇) + f_int(q) + f_d(q, q̇) = Q(t).

**Bodies.** Every element contributes the material points and sections at its 4 Gauss–Legendre
points ξ_g (weights w_g on [0, 1]): a point mass ρA l w_g at r(ξ_g) = r_I + R_I s(ξ_g) and a
rotary inertia l w_g R_s diag(ρJ, ρIy, ρIz) R_sᵀ with R_s = R_I exp([ψ(ξ_g)]×). A hub is a
mass at its link's root point with the inertia R_link J_h R_linkᵀ; a payload a mass at its
centre p_tip + R_tip c with the inertia R_tip J_p R_tipᵀ. The Jacobians of the bodies'
velocities (ṙ = J_v q̇, ω = J_ω q̇) follow the chain: a joint adds R_J a α̇ to the angular
velocity, an element's outboard node moves by ṙ_O = ṙ_I + ω_I × R_I d + R_I ḋ with
d = (l + u, v, w), and turns by ω_O = ω_I + R_I J_L(φ) φ̇ (J_L the left Jacobian of SO(3)).

**Equations.** M = Σ m J_vᵀJ_v + Σ J_ωᵀ I J_ω; the velocity terms
h = Σ m J_vᵀ (J̇_v q̇) + Σ J_ωᵀ (I J̇_ω q̇ + ω × I ω), with J̇q̇ the exact directional derivative
of J(q)q̇ along q̇, taken by the complex step Im[J(q + iε q̇)] q̇ / ε (ε = 1e-30; every map is
analytic); gravity Q_g = Σ m J_vᵀ g. External loads (``SpatialScenario.loads``: a force F and a
moment M at a link's tip point, world components or, for a follower load, tip-frame components
turned by R_tip) enter by their virtual work, Q = J_r,tipᵀ F + J_ω,tipᵀ M at the configuration
(re-evaluated at every iterate), and the cut loads of the cuts they are outboard of. The
elastic force is the gradient of the element strain energy (linear strain, or the second-order
axial strain of extensible links); the Kelvin–Voigt damping acts on the rate of the same strain measures (D = μK for linear strain).

**Time integration.** ``"newmark"`` (β = ¼, γ = ½) and ``"generalized-alpha"`` step the shared
schedule (:func:`dttmm.timegrid.step_schedule`) and iterate each step's accelerations with the
elastic and damping forces linearised at the iterate,
[M + c_v D_t + c_q K_T] q̈⁽ⁱ⁺¹⁾ = Q − h − f_int − f_d + (c_q K_T + c_v D_t) q̈⁽ⁱ⁾, stopped by
:func:`dttmm.iteration.stop_rule`; ``"rk4"`` integrates the forward dynamics. Motion drives
prescribe their joint (their torque is the equation's residual on α); open-loop torque
drives give Q.

**Closed-loop drives** (``pd``, ``pid``, user laws; docs/control.md), Newmark family only, as
the planar global solver (:mod:`reference_models._global_control`): joint i adds its law's
torque to the generalized force of α_i, evaluated implicitly at the step end with the state
there and the integral state of ``pid`` by the trapezoidal rule. The root bending moment of
the law is M_root = τ − H, H = a·(J_h ω̇ + ω × J_h ω) (the hub's moment balance about the root
point along the world joint axis a = R_link·axis; J_h in world components, ω̇ = J_ω q̈ + J̇_ω q̇
of the link frame: an exact row h of q̈ plus h₀), so τ = clip((L0 + g_M H)/(1 + g_M), ±limit).
The step iteration adds the law's linearisation in q̈ to the iteration matrix — its slope in
α̈_i (through α, α̇ and z) on the diagonal and ∂τ/∂H · h along the row — and solves the
unsymmetric system by LU. A user law sees a :class:`dttmm.drives.ControlState` at the latest
iterate (M_root = τ_used − H, τ_used the torque its last solve applied; ``angles``, ``rates``
of every unlocked joint; ``tip_deflections`` the component of every link's tip deflection along
the link frame's y axis). The forward dynamics at t = 0 and at restarts solve the laws with the
state's integral states by the same iteration.

**Outputs** (docs/spatial.md §4), on the scenario's output grid (cubic Hermite between step
ends): a :class:`dttmm.spatial.SpatialResult` whose ``joint_*`` arrays have one column per
unlocked joint, ``link_root`` and ``link_tip`` (nt, n, 3), ``end_effector`` (nt, 3),
``tip_deflection`` (nt, n, 2) (the components of tip − root along the root link frame's y and
z axes), ``twist`` (nt, n) (the x component of log(R_linkᵀ R_tip)), ``link_rotation`` R_link
and ``tip_rotation`` R_tip (nt, n, 3, 3); ``meta["q"]``, ``meta["qd"]`` hold the coordinates;
with ``cut_loads=True`` the loads at every element root and link tip, by Newton–Euler of the
bodies outboard of the cut (:func:`cut_loads`).

**Trees and closed loops** (docs/spatial.md "Global solver: trees and loops"): every link's
frames start from its parent's tip frame (the base for a link on the base); a cut's load sums
its own link's bodies beyond it and every body in the subtree of its link. A closure adds
g(q) = 0 (points equal; a revolute two axis equations, a weld three) with its analytic Jacobian
J; the Newmark family solves the step's equations with Jᵀλ_{n+1} and g(q_{n+1}) = 0 by Newton on
(q̈, λ) (index 3); RK4 with a closure is refused. ``closure_loads`` (nt, n_closures, 6),
``closure_residual`` and ``closure_angle_residual`` (nt, n_closures) are returned.

Readings of docs/spatial.md fixed here: the hub is rigid with the link frame R_link (it sits
before the roll of the element frames); tip deflections and twist use R_link as the root
frame; the second-order strain only concerns extensible links (inextensible links keep
their linear bending and torsion energy).

This module shares with :mod:`dttmm` only the model, scenario and result classes, the step
schedule, the Newmark-family coefficients, the stop rule of the iteration and the errors.
"""

from __future__ import annotations

from dttmm import plumbing
from dttmm.shapes import shape_points as shape_points_of
from dttmm.spatial import SpatialResult

from . import _spatial_driver
from ._spatial_driver import ENGINES, INTEGRATORS
from ._spatial_numpy import (
    STRAINS,
    _check_case,
    _layout,
    accelerations,
    coordinate_names,
    cut_loads,
    damping_forces,
    elastic_forces,
    energy,
    generalized_forces,
    kinematics,
    link_shapes,
    load_forces,
    mass_matrix,
)

__all__ = [
    "ENGINES",
    "INTEGRATORS",
    "STRAINS",
    "accelerations",
    "coordinate_names",
    "cut_loads",
    "damping_forces",
    "elastic_forces",
    "energy",
    "generalized_forces",
    "kinematics",
    "link_shapes",
    "load_forces",
    "mass_matrix",
    "simulate",
]


def simulate(
    case,
    *,
    elements_per_link,
    h,
    integrator="newmark",
    strain="linear",
    tol=1e-10,
    max_iterations=50,
    cut_loads=False,
    shape_points=0,
    engine=None,
    **options,
) -> SpatialResult:
    """Simulate a spatial case with the global equations of the spatial discretisation.

    Parameters
    ----------
    case : dttmm.spatial.SpatialCase, or a planar dttmm.Case (run as its embedding,
        :meth:`dttmm.spatial.SpatialCase.from_planar`)
    elements_per_link : int
        k ≥ 1 elements per link.
    h : float
        Step size (s), 0 < h ≤ duration.
    integrator : {"newmark", "generalized-alpha", "rk4"}
        Newmark (options ``beta`` = ¼, ``gamma`` = ½) and generalised-α (``rho_inf`` = 0.9)
        iterate every step to ``tol`` (relative, :func:`dttmm.iteration.stop_rule`) within
        ``max_iterations`` solves; RK4 evaluates the forward dynamics four times a step.
    strain : {"linear", "second-order"}
    cut_loads : bool
        Record the cut loads (see :func:`cut_loads`) on the output grid (nt, n(k + 1), 6), from
        the forward dynamics at every output state (left limits of the drives at t > 0).
    shape_points : int
        p ≥ 2 records ``link_shapes`` (nt, n, p, 3): the deflected centre line of every link from
        this module's element frames and shape matrices (:func:`link_shapes`); 0 (default): none.
    engine : {"numba", "numpy"} or None
        The mechanics at each state: "numba" (the default where numba is installed) assembles
        M and the forces by composite inertias in compiled code (O(N²)); "numpy" by the dense
        Jacobians of this module (O(N³), the readable form and the check of the compiled one).
        They agree to round-off.

    Returns
    -------
    dttmm.spatial.SpatialResult
        On ``case.scenario.output_times``; see the module notes for the spatial shapes.
        ``status`` "unconverged" when some step exhausted ``max_iterations``.

    Raises
    ------
    dttmm.InputError
        Bad case, k, h, integrator, strain or option; a closed-loop drive law with RK4.
    dttmm.SimulationError
        Non-finite state (``partial`` holds the outputs so far).
    """
    case = _check_case(case)
    h = plumbing.step_size(h, case.scenario.duration)
    opt = _spatial_driver.check_options(integrator, tol, max_iterations, options)
    engine = _spatial_driver.check_engine(engine)
    _spatial_driver.check_closed_loop(case, integrator)
    lay = _layout(case, elements_per_link, strain)
    return _spatial_driver.run(
        case, lay, h, integrator, opt, engine, bool(cut_loads), shape_points_of(shape_points)
    )
