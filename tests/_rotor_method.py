"""Test-only method: decoupled rigid rotors with a made-up discretisation error.

Each joint turns as a rigid rotor of inertia J = hub + beam (about the joint) + payload under
its drive; the "tip deflection" is 1 mm·sin(2πt)·(1 + 1/k²) and the angles carry an error
h²·t, so errors fall as k⁻² and h² — enough to exercise the harness without the solver.
Importable by separately started Dask workers (tests/ on their PYTHONPATH).
"""

from __future__ import annotations

import time

import numpy as np

from dttmm import make_result

CALLS = {"n": 0}
FAIL_AFTER = {"n": None}  # raise KeyboardInterrupt on this call (simulates a killed sweep)


def _angle(drive, link_inertia, t):
    if drive.kind == "motion":
        return np.array([drive.law.motion(x)[0] for x in t])
    fine = np.linspace(0.0, t[-1], 20 * (t.size - 1) + 1)
    acc = np.array([drive.law(x) for x in fine]) / link_inertia
    rate = drive.initial_rate + np.concatenate([[0], np.cumsum((acc[1:] + acc[:-1]) / 2 * np.diff(fine))])
    ang = drive.initial_angle + np.concatenate([[0], np.cumsum((rate[1:] + rate[:-1]) / 2 * np.diff(fine))])
    return np.interp(t, fine, ang)


def simulate(case, *, elements_per_link, h, **options):
    """Rigid rotors on the case's output grid; see the module docstring."""
    CALLS["n"] += 1
    if FAIL_AFTER["n"] is not None and CALLS["n"] >= FAIL_AFTER["n"]:
        raise KeyboardInterrupt("test: sweep killed")
    if options.get("fail"):
        raise ValueError("test failure on request")
    t0 = time.perf_counter()
    k = elements_per_link or 10**6
    t = case.scenario.output_times
    n = case.n_joints
    q = np.empty((t.size, n))
    for i, (link, drive) in enumerate(zip(case.model.links, case.scenario.drives)):
        b = link.beam
        J = link.hub_inertia + b.rhoA * b.length**3 / 3 + link.payload_mass * b.length**2 + 1e-3
        q[:, i] = _angle(drive, J, t) + h**2 * t
    phi = np.cumsum(q, axis=1)  # absolute root angle of each link (rigid joints chain)
    d = 1e-3 * np.sin(2 * np.pi * t)[:, None] * (1 + 1 / k**2)
    root = np.zeros((t.size, n, 2))
    tip = np.zeros((t.size, n, 2))
    for i, link in enumerate(case.model.links):
        if i:
            root[:, i] = tip[:, i - 1]
        L = link.beam.length
        c, s = np.cos(phi[:, i]), np.sin(phi[:, i])
        tip[:, i, 0] = root[:, i, 0] + L * c - d[:, 0] * s
        tip[:, i, 1] = root[:, i, 1] + L * s + d[:, 0] * c
    if options.get("nan"):
        tip[-1] = np.nan
    return make_result(
        t=t,
        joint_angle=q,
        joint_rate=np.gradient(q, t, axis=0),
        joint_torque=np.zeros_like(q),
        link_root=root,
        link_root_angle=phi,
        link_tip=tip,
        wall_time=time.perf_counter() - t0,
        n_steps=int(round(case.scenario.duration / h)),
        meta={"method": "rotor", "elements_per_link": elements_per_link, "h": h, "success": True, "n_dof": n},
    )
