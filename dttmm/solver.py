"""DT-TMM simulation of planar arms: :func:`simulate` (Newmark family or RK4) and
:func:`accelerations` (positions, velocities → accelerations) on the planar kernel.
``dttmm.simulate`` and ``dttmm.accelerations`` (:mod:`dttmm.api`) take any arm and call these
for a planar one.

Both validate their settings here and hand the discretised case to the kernel
(:mod:`dttmm.kernel`), compiled by numba or run uncompiled (engine "python").
"""

from __future__ import annotations

import warnings

import numpy as np

from . import plumbing, shapes
from .case import Case
from .control_state import is_jitted
from .drives import UserLaw, require_open_loop
from .errors import InputError
from .kernel import driver
from .resources import check_run_size
from .structure import STRAINS, build_structure
from .sweeps import SWEEPS

__all__ = ["INTEGRATORS", "accelerations", "simulate"]

INTEGRATORS = ("newmark", "generalized-alpha", "rk4")


def accelerations(
    case: Case,
    elements_per_link: int,
    q,
    qd,
    t: float = 0.0,
    *,
    sweep: str = "riccati",
    engine: str | None = None,
    strain: str = "linear",
) -> np.ndarray:
    """Forward dynamics of the discretised arm: q̈ (n_dof,) from (q, q̇) (n_dof,) at time t (s).

    Coordinates as in :mod:`dttmm.structure` (``[α_1, e_11, …, α_2, …]``). Motion-driven joints
    take their angle, rate and acceleration from the law (the given values are overridden).
    ``engine``: "numba" (compiled, the default when numba is installed) or "python" (the same
    kernel uncompiled). The readable one-step reference is :func:`dttmm.sweeps.accelerations`.
    """
    if not isinstance(case, Case):
        raise InputError("case", type(case).__name__, "must be a dttmm.Case")
    require_open_loop(case, "dttmm")
    engine = driver.resolve_engine(engine)
    plumbing.choice("sweep", sweep, tuple(SWEEPS))
    _check_plain(case, sweep)
    st = build_structure(case, elements_per_link, strain)
    q = np.asarray(q, float)
    qd = np.asarray(qd, float)
    if q.shape != (st.n_dof,) or qd.shape != (st.n_dof,):
        raise InputError("q/qd", (q.shape, qd.shape), f"must both have shape ({st.n_dof},)")
    return driver.accelerations_at(st, q, qd, t, sweep, engine)


def _check_plain(case: Case, sweep: str) -> None:
    """The plain sweep carries flexible links with bodies on the beam axis only."""
    if sweep == "plain" and not case.model.flexible_only:
        i = next(
            i for i, lk in enumerate(case.model.links) if lk.rigid or (lk.payload and lk.payload.offset_set)
        )
        what = "a rigid link" if case.model.links[i].rigid else "an offset payload"
        raise InputError(
            "sweep",
            "plain",
            f"the plain sweep takes no rigid links or offset payloads ({what} at link {i + 1}); "
            "use sweep='riccati'",
        )


def _check_closed_loop(case: Case, sweep: str, engine: str) -> None:
    """Refuse the closed-loop drives the kernel does not run: user laws that are plain Python
    functions with the compiled kernel (numba-jitted ones run), and any closed-loop law with
    the plain sweep."""
    for i, d in enumerate(case.scenario.drives):
        if not d.closed_loop:
            continue
        if isinstance(d.law, UserLaw) and engine != "python" and not is_jitted(d.law.fn):
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.label,
                f"user law on joint {i + 1} is a plain Python function: it runs with "
                "engine='python' only (the compiled kernel calls no Python function; write the law "
                "as a numba-jitted function of (t, JitState) to run it compiled)",
            )
        if sweep == "plain":
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.name,
                f"closed-loop drive law {d.law.name!r} on joint {i + 1} needs sweep='riccati' "
                "(the plain sweep runs open-loop drives only)",
            )


def simulate(
    case: Case,
    *,
    elements_per_link: int,
    h: float,
    integrator: str = "newmark",
    sweep: str = "riccati",
    iterations: int | str | None = None,
    tol: float = 1e-10,
    max_iterations: int = 50,
    beta: float | None = None,
    gamma: float | None = None,
    rho_inf: float | None = None,
    cut_loads: bool = True,
    energy: bool = True,
    progress: bool | None = None,
    engine: str | None = None,
    auto_fraction: float = 0.1,
    strain: str = "linear",
    shape_points: int = 0,
):
    """Simulate ``case`` by DT-TMM with k = ``elements_per_link`` elements per link and step ``h``.

    Parameters
    ----------
    integrator : "newmark" (β = ¼, γ = ½ unless given), "generalized-alpha" (``rho_inf``,
        default 0.9) or "rk4" (explicit, on the acceleration solver).
    sweep : "riccati" (stable, default) or "plain" (the paper's transfer form).
    iterations : None → iterate each step until max|Δq̈| ≤ tol·max(1, max|q̈|) (at most
        ``max_iterations`` sweeps); m ≥ 0 → exactly m + 1 sweeps per step (0 = the paper's
        one-shot linearisation); "auto" → at least 2 sweeps, then stop as soon as the iteration
        error predicted from the contraction ρ = |Δq̈_m|/|Δq̈_{m−1}|, |Δq̈_m|·ρ/(1 − ρ), is below
        ``auto_fraction`` × the local truncation error estimate |β − 1/6|/β · max|q̈_{n+1} − q̈_n|
        (both measured in q̈; multiplied by βh² they are displacement errors), or the
        ``tol`` rule is met.
    engine : "numba" (compiled kernel, default when numba is installed) or "python" (the same
        kernel uncompiled, ~1000× slower; the default without numba). "numpy" is a deprecated
        alias of "python".
    strain : the elements' axial strain, "linear" (default: u/l, unconditionally stable with
        the trapezoidal rule) or "second-order" (u/l + ½ wᵀGw: the chord shortens as the element
        bends; converges much faster in k for extensible links, but with the trapezoidal rule
        it needs h small enough to resolve the axial-bending coupling — measured on single_link:
        h = 4e-3 diverged at k = 2 and 8, h ≤ 2e-3 ran; use generalised-α for large steps).
        See docs/method.md. Inextensible links are unaffected.
    cut_loads, energy : record the loads at every cut and the total energy on the output grid.
    shape_points : p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2), the deflected centre
        line of every link from the element shape functions (:mod:`dttmm.shapes`); 0 (default)
        records none.
    progress : show a progress bar (tqdm, on stderr); default: on when the run time, estimated
        after its first 0.5 %, exceeds 2 s.

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``.

    Raises
    ------
    InputError for bad settings; SimulationError (with ``.partial``) when the run diverges.
    """
    elements_per_link, h = plumbing.discretisation(case, elements_per_link, h)
    plumbing.choice("integrator", integrator, INTEGRATORS)
    plumbing.choice("sweep", sweep, tuple(SWEEPS))
    plumbing.choice("strain", strain, STRAINS)
    _check_plain(case, sweep)
    _check_closed_loop(case, sweep, driver.resolve_engine(engine))
    shape_points = shapes.shape_points(shape_points)
    check_run_size(case, elements_per_link, h, cut_loads=cut_loads, energy=energy, shape_points=shape_points)
    s = driver.Settings(
        h=h,
        integrator=integrator,
        sweep=sweep,
        iterations=plumbing.iterations_setting(iterations),
        tol=plumbing.open_fraction("tol", tol),
        max_iterations=plumbing.positive_integer("max_iterations", max_iterations),
        family=None
        if integrator == "rk4"
        else plumbing.newmark_family(integrator, beta=beta, gamma=gamma, rho_inf=rho_inf),
        auto_fraction=plumbing.positive_number("auto_fraction", auto_fraction),
        cut_loads=bool(cut_loads),
        energy=bool(energy),
        progress=progress,
        engine=driver.resolve_engine(engine),
        strain=strain,
        shape_points=shapes.shape_points(shape_points),
    )
    with warnings.catch_warnings():
        # numba flags its first-class function type (the calls of jitted user laws) as
        # experimental each time it types one; this project's tests cover that use
        warnings.filterwarnings("ignore", message="First-class function type feature is experimental")
        return driver.simulate_structure(build_structure(case, elements_per_link, strain), s)
