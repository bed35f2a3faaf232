"""Errors of a Result against a reference Result — the one place they are computed.

Quantities: ``ee`` (end-effector position, norm of the difference, m), ``tip{i}`` (tip
transverse deflection of link i, m; on a spatial arm the norm of the difference of both
planes' deflections) and ``angle{i}`` (joint angle i, rad). Kinds: ``l2`` (RMS
over the output times), ``linf`` (max abs) and ``final`` (at the last output time). Column
names are ``{quantity}_{kind}``, e.g. ``ee_l2``, ``tip3_linf``, ``angle1_final``.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "KINDS",
    "columns",
    "difference_series",
    "errors",
    "load_differences",
    "load_errors",
    "load_series",
    "nan_errors",
    "quantities",
    "without_cut_loads",
]

KINDS = ("l2", "linf", "final")


def quantities(n_joints: int) -> list[str]:
    """Quantity names for an arm of ``n_joints`` joints."""
    return (
        ["ee"] + [f"tip{i}" for i in range(1, n_joints + 1)] + [f"angle{i}" for i in range(1, n_joints + 1)]
    )


def columns(n_joints: int) -> list[str]:
    """Every error column for an arm of ``n_joints`` joints."""
    return [f"{q}_{k}" for q in quantities(n_joints) for k in KINDS]


def nan_errors(n_joints: int) -> dict[str, float]:
    """The error row of a run that failed: NaN everywhere (the reason is kept beside it)."""
    return dict.fromkeys(columns(n_joints), float("nan"))


def _on_grid(ref_t: np.ndarray, values: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Reference values (nt_ref, m) interpolated linearly to the times t (nt,)."""
    if ref_t.shape == t.shape and np.allclose(ref_t, t, rtol=0, atol=1e-12):
        return values
    return np.column_stack([np.interp(t, ref_t, values[:, j]) for j in range(values.shape[1])])


def difference_series(result, reference) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Pointwise differences of result minus reference on the result's times.

    Only times inside the reference's time span are kept. Returns (t (nt,), {quantity: (nt,)});
    ``ee`` is the norm of the end-effector difference (m), the others are signed.
    """
    t = np.asarray(result.t, float)
    rt = np.asarray(reference.t, float)
    keep = (t >= rt[0] - 1e-12) & (t <= rt[-1] + 1e-12)
    t = t[keep]
    if t.size == 0:
        raise ValueError("result and reference share no output times")
    n = result.n_joints
    if reference.n_joints != n:
        raise ValueError(f"result has {n} joints, reference {reference.n_joints}")
    d = {"ee": np.linalg.norm(result.end_effector[keep] - _on_grid(rt, reference.end_effector, t), axis=1)}
    tip, ref_tip = np.asarray(result.tip_deflection), np.asarray(reference.tip_deflection)
    if tip.ndim == 3:  # a spatial arm: the deflections in both planes, as one vector per link
        nt, n_links, _ = tip.shape
        diff = tip[keep] - _on_grid(rt, ref_tip.reshape(len(rt), -1), t).reshape(-1, n_links, 2)
        tips = np.linalg.norm(diff, axis=2)
    else:
        tips = tip[keep] - _on_grid(rt, ref_tip, t)
    angles = result.joint_angle[keep] - _on_grid(rt, reference.joint_angle, t)
    for i in range(tips.shape[1]):
        d[f"tip{i + 1}"] = tips[:, i]
    for i in range(n):
        d[f"angle{i + 1}"] = angles[:, i]
    return t, d


def errors(result, reference) -> dict[str, float]:
    """Error row of ``result`` against ``reference``: ``{quantity}_{kind}`` -> float.

    Non-finite results give NaN (the caller records why).
    """
    _, diffs = difference_series(result, reference)
    out = {}
    for q, e in diffs.items():
        a = np.abs(e)
        out[f"{q}_l2"] = float(np.sqrt(np.mean(a**2)))
        out[f"{q}_linf"] = float(np.max(a))
        out[f"{q}_final"] = float(a[-1])
    return {k: (v if np.isfinite(v) else float("nan")) for k, v in out.items()}


# --- Beyond the end-effector: loads and energy -------------------------------------------------
#
# ``moment1``: bending moment at the root of link 1 (N·m). The hub of link 1 turns about the
# fixed base joint, so its moment balance gives M = τ₁ − J₁ θ̈₁ for every method, from the stored
# joint torque and rate (θ̈₁ by central differences on the output grid); without a hub (J₁ = 0) it
# is joint 1's torque and is left out. The cut loads a DT-TMM
# Result carries give the same value (checked in tests/test_report_loads.py); they are used when
# both results have them. ``torque{i}``: torque of joint i where the joint is motion-driven (there
# it is an output; a torque-driven joint's torque is the input law). ``energy``: total energy (J)
# where the method records it.

LOAD_KINDS = ("l2", "linf")


def load_series(result, case) -> dict[str, np.ndarray]:
    """Load quantities of ``result`` on its output times: name -> (nt,) array (see above)."""
    t = np.asarray(result.t, float)
    out = {}
    planar = np.shape(result.end_effector)[-1] == 2  # a spatial arm's root moment is a vector: not compared
    if planar and result.cut_loads is not None and result.cut_load_t is not None:
        out["moment1"] = np.interp(t, result.cut_load_t, result.cut_loads[:, 0, 0])
    elif (
        planar and t.size >= 3 and case.model.links[0].hub_inertia > 0
    ):  # without a hub it is joint 1's torque
        J = case.model.links[0].hub_inertia
        out["moment1"] = result.joint_torque[:, 0] - J * np.gradient(result.joint_rate[:, 0], t, edge_order=2)
    for i, d in enumerate(case.scenario.drives):
        if d.kind == "motion":
            out[f"torque{i + 1}"] = np.asarray(result.joint_torque[:, i], float)
    if result.energy is not None:
        out["energy"] = np.asarray(result.energy, float)
    return out


def load_differences(result, reference, case, *, both_cut_loads=None):
    """(t, {quantity: result minus reference}) for the load quantities both have.

    Only the reference's time span is kept; the reference is interpolated to the result's times.
    The root moment is taken the same way for both (from cut loads only when both have them).
    """
    if both_cut_loads is None:
        both_cut_loads = result.cut_loads is not None and reference.cut_loads is not None
    a = load_series(result if both_cut_loads else without_cut_loads(result), case)
    b = load_series(reference if both_cut_loads else without_cut_loads(reference), case)
    t, rt = np.asarray(result.t, float), np.asarray(reference.t, float)
    keep = (t >= rt[0] - 1e-12) & (t <= rt[-1] + 1e-12)
    diffs = {q: a[q][keep] - np.interp(t[keep], rt, b[q]) for q in a if q in b}
    return t[keep], diffs


def without_cut_loads(result):
    """``result`` without its cut loads (the root moment then comes from the hub balance)."""
    from dataclasses import replace

    return replace(result, cut_loads=None, cut_load_t=None) if result.cut_loads is not None else result


def load_errors(result, reference, case) -> dict[str, float]:
    """``{quantity}_l2`` (RMS) and ``{quantity}_linf`` (max abs) of the load differences, plus
    ``{quantity}_scale``: the largest absolute value of the reference (for relative errors)."""
    both = result.cut_loads is not None and reference.cut_loads is not None
    _, diffs = load_differences(result, reference, case, both_cut_loads=both)
    ref = load_series(reference if both else without_cut_loads(reference), case)
    out = {}
    for q, e in diffs.items():
        a = np.abs(e)
        out[f"{q}_l2"] = float(np.sqrt(np.mean(a**2))) if a.size else float("nan")
        out[f"{q}_linf"] = float(np.max(a)) if a.size else float("nan")
        out[f"{q}_scale"] = float(np.max(np.abs(ref[q])))
    return {k: (v if np.isfinite(v) else float("nan")) for k, v in out.items()}
