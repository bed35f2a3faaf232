"""The rigid arm of :mod:`reference_models.pinocchio_rigid` stepped by Newmark (β = ¼, γ = ½,
Newton on the joint-space equations τ(q, q̇, q̈) = τ_applied with RNEA and its derivatives),
for the rigid-limit tests: the same step as DT-TMM's Newmark on the same rigid dynamics, so
the time-discretisation errors cancel and stiffened beams must agree to 1e-6 rad.
"""

from __future__ import annotations

from reference_models import pinocchio_rigid as pr


def simulate(case, h, **options):
    """The rigid arm of ``case`` by Newmark with step h (s); a :class:`dttmm.Result`.
    Options: tol (relative Newton correction), max_iter."""
    res = pr.simulate(case, h=h, integrator="newmark", **options)
    assert res.status == "ok", f"Newton iteration of a Newmark step did not converge ({res.meta})"
    return res
