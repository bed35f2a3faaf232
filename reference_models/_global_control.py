"""Closed-loop drive laws in the global-equation solver (the loop is in
:mod:`reference_models._global_numba`, ``_laws``; this module holds its checks and ω̇ rows).

A closed-loop joint i adds its law's torque τ_i to the generalized force of α_i. The law is
evaluated implicitly at the step end t_{n+1} with the state there, through the law objects of
:mod:`dttmm.drives`:

* ``pd``/``pid``: τ = clip(L0 − g_M M_root, ±limit) with L0 = τ_ff + kp (α_ref − α)
  + kd (α̇_ref − α̇) + ki z and the root bending moment M_root = τ − J_hub ω̇_i (moment balance
  of the hub, a point mass with inertia J_hub rotating with the link root), ω̇_i the absolute
  angular acceleration of link i's root cross-section: a fixed 0/1 row of q̈ (the joint angles
  up to i and the element rotations φ of every inboard link). The algebraic loop in τ is
  solved in closed form, τ = clip((L0 + g_M J_hub ω̇_i)/(1 + g_M), ±limit).
* the integral state of ``pid`` by the trapezoidal rule,
  z_{n+1} = z_n + (h/2)(α_ref(t_n) − α_n + α_ref(t_{n+1}) − α_{n+1}), z(0) = 0;
* a user law at the latest iterate, seeing M_root = τ_used − J_hub ω̇_i of that iterate.

The step iteration adds the law's linearisation in q̈ to the iteration matrix: the slope in
α̈_i (through α, α̇ and z) on the diagonal and the slope in ω̇_i along its exact row, so the
matrix is not symmetric (those solves use LU). User laws (Python callables) run in the
uncompiled engine only (``engine="python"``).
"""

from __future__ import annotations

import numpy as np

from dttmm.drives import UserLaw
from dttmm.errors import InputError

STEPPED = ("newmark", "generalized-alpha")


def require_stepped(case, what: str) -> None:
    """Refuse a closed-loop case for ``what`` (an integrator or a function) that cannot solve
    the laws implicitly.

    Raises
    ------
    InputError
        Naming ``scenario.drives[i].law`` and the integrators that can.
    """
    for i, d in enumerate(case.scenario.drives):
        if d.closed_loop:
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.name,
                f"closed-loop drive on joint {i + 1}: {what} of the global solver cannot run it "
                f"(its integrators {' and '.join(map(repr, STEPPED))} can)",
            )


def require_python_engine(case) -> None:
    """Refuse a user law (a Python callable) for the compiled engine."""
    for i, d in enumerate(case.scenario.drives):
        if isinstance(d.law, UserLaw):
            raise InputError(
                f"scenario.drives[{i}].law",
                d.law.label,
                f"a Python user law on joint {i + 1} cannot run in the compiled engine; use engine='python'",
            )


def omega_rows(lay) -> np.ndarray:
    """(n, N) 0/1 rows W with ω̇_i = W[i] @ q̈: the absolute angular acceleration of link i's
    root cross-section is the sum of the joint accelerations α̈_j (j ≤ i) and of the element
    rotations φ̈ of every element inboard of link i."""
    W = np.zeros((lay.n_links, lay.n_dof))
    for i in range(lay.n_links):
        W[i, lay.alpha_idx[: i + 1]] = 1.0
        phi = lay.e_idx[: lay.first_el[i], 2]
        W[i, phi[phi >= 0]] = 1.0
    return W
