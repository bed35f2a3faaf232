"""Rigid-link baseline of a planar case by Pinocchio: the limit of infinitely stiff links.

The planar arm runs as its spatial embedding (:func:`dttmm.spatial.embed_planar`: joint axes z,
gravity (g_x, g_y, 0)) on the spatial rigid baseline :mod:`reference_models.pinocchio_spatial`,
and its result comes back as a planar :class:`dttmm.Result`: joint angles, rates and torques,
link roots and tips (x, y), tip deflections (0 up to round-off: the links are rigid), the
end-effector, straight link shapes, the energy (kinetic + gravitational potential, zero at
y = 0).

Every flexible link is a uniform rigid rod (mass ρA·L, inertia mL²/12 about its centre; its
rotary inertia about the link axis does not enter planar motion), a rigid link its own body
(mass, centre of mass (x, y) in the link frame, inertia J about it); a hub is a rigid body at
the link root, a payload one at the link tip (its centre of mass at its offset in the tip
frame). Joint i turns about z at the tip of link i−1 (joint 1 at the origin).

Torque-driven joints follow forward dynamics with τ = drive.torque(t); motion-driven joints
follow their law and their torque comes from inverse dynamics (RNEA). Closed-loop drives
(``pd``, ``pid``, user laws; docs/control.md) are evaluated at every RK4 stage with the stage's
state, a ``pid`` law's integral of the angle error integrated by the same RK4 (0 at t = 0); a
rigid link has no bending moment to feed back, so ``moment_gain != 0`` is refused and user laws
see ``moment = nan``. The ``computed_torque`` feedforward is the RNEA of this rigid model along
every joint's reference.

Integrators (:data:`INTEGRATORS`): ``"rk4"`` on the shared step schedule (a step ends exactly at
each drive jump; the step ending there sees the left limit), ``"newmark"`` (β = ¼, γ = ½, Newton
on the RNEA residual: the same step as DT-TMM's Newmark, the rigid-limit tests' reference) and
``"dop853"`` (scipy's adaptive solver, restarted at every jump; the rigid reference of ``dttmm
validate``). Closed-loop drives run with ``"rk4"`` only.

Pinocchio is imported here only; ``dttmm`` itself never needs it.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from dttmm import plumbing
from dttmm.errors import SimulationError
from dttmm.result import make_result
from dttmm.shapes import shape_points as check_shape_points
from dttmm.shapes import straight_shapes
from dttmm.spatial import SpatialCase, embed_planar

from . import pinocchio_spatial

__all__ = ["INTEGRATORS", "build_model", "simulate"]

#: integrator name -> its options and their defaults
INTEGRATORS = pinocchio_spatial.INTEGRATORS


def build_model(manipulator) -> pin.Model:
    """The rigid planar arm as a Pinocchio model with gravity set (joint ids 1..n, revolute about
    z): the model of its spatial embedding. Frames ``link{i}`` and ``link{i}_tip`` (i = 1..n)
    mark the link roots and tips, ``tip`` the end-effector."""
    return pinocchio_spatial.build_model(embed_planar(manipulator))


def simulate(case, *, h, integrator="rk4", elements_per_link=None, shape_points=0, **options):
    """Simulate a planar case with rigid links.

    Parameters
    ----------
    case : dttmm.Case
    h : float
        Step size (s). For ``"dop853"`` the first trial step of each restart (the step size
        is adaptive; limit it with the option ``max_step``).
    integrator : ``"rk4"`` | ``"newmark"`` | ``"dop853"``
    elements_per_link : ignored (rigid links); accepted for the common call.
    shape_points : p ≥ 2 records ``Result.link_shapes`` (nt, n, p, 2) m, straight links.
    **options
        newmark: tol (1e-12), max_iter (25); dop853: rtol (1e-12), atol (1e-12), max_step (inf).

    Returns
    -------
    dttmm.Result on ``case.scenario.output_times``; ``wall_time`` covers the time stepping only.

    Raises
    ------
    dttmm.InputError
        h ≤ 0 or h > duration, unknown integrator or option, a closed-loop drive with moment
        feedback or with another integrator than rk4.
    dttmm.SimulationError
        non-finite state; ``partial`` holds the output samples up to the last good step.
    """
    plumbing.discretisation(case, elements_per_link, h, uses_k=False)
    p = check_shape_points(shape_points)
    spatial = SpatialCase(embed_planar(case.model), case.scenario, name=case.name)
    try:
        res = pinocchio_spatial.run(spatial, h, integrator, options, method="pinocchio-rigid")
    except SimulationError as e:
        e.partial = _planar(e.partial, p)
        raise
    return _planar(res, p)


def _planar(res, p):
    """The planar Result of a spatial one of the embedded arm (p: shape points or 0)."""
    root, tip = res.link_root[..., :2], res.link_tip[..., :2]
    meta = {k: x for k, x in res.meta.items() if k != "time_per_step"}
    meta["success"] = res.status != "failed"
    meta["n_steps"] = res.n_steps
    return make_result(
        t=res.t,
        joint_angle=res.joint_angle,
        joint_rate=res.joint_rate,
        joint_torque=res.joint_torque,
        link_root=root,
        link_root_angle=np.cumsum(res.joint_angle, axis=1),
        link_tip=tip,
        wall_time=res.wall_time,
        n_steps=res.n_steps,
        meta=meta,
        energy=res.energy,
        status=res.status,
        link_shapes=straight_shapes(root, tip, p) if p else None,
    )
