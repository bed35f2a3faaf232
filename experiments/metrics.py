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
    "comparable_loads",
    "has_spatial_cut_loads",
    "is_spatial_result",
    "load_differences",
    "load_errors",
    "load_series",
    "nan_errors",
    "quantities",
    "spatial_root_moment",
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
# ``moment1``: bending moment at the root of link 1 (N·m).
# * Planar arm: the hub of link 1 turns about the fixed base joint, so its moment balance gives
#   M = τ₁ − J₁ θ̈₁ for every method, from the stored joint torque and rate (θ̈₁ by central
#   differences on the output grid); without a hub (J₁ = 0) it is joint 1's torque and is left
#   out. The cut loads a DT-TMM Result carries give the same value (checked in
#   tests/test_report_loads.py); they are used when both results have them.
# * Spatial arm (a ``SpatialResult``): the moment at link 1's root cut (cut 0 of ``cut_loads``:
#   the moment about the link's root point that the inboard side — base, joint 1 and link 1's
#   hub — exerts on link 1's beam, docs/spatial.md §4) has a bending part and a torsion part; the
#   compared value is the magnitude of the bending part, √(M·y₁)² + (M·z₁)², y₁ and z₁ the y and
#   z axes of link 1's frame (``link_rotation``, before the section's roll), torsion M·x₁ left
#   out (:func:`spatial_root_moment`). A hub balance gives only the component along the joint
#   axis, so only results with the cut table of docs/spatial.md §4 (k + 1 cuts per link: the
#   spatial DT-TMM and global solver run with ``cut_loads=True``) give it.
# ``torque{i}``: torque of joint i where the joint is motion-driven (there it is an output; a
# torque-driven joint's torque is the input law). ``energy``: total energy (J) where the method
# records it.

LOAD_KINDS = ("l2", "linf")


def is_spatial_result(result) -> bool:
    """Whether ``result`` is a spatial arm's (3-component positions)."""
    return np.shape(result.end_effector)[-1] == 3


def has_spatial_cut_loads(result) -> bool:
    """Whether a spatial ``result`` carries the cut table of docs/spatial.md §4 (k + 1 cuts per
    link, k ≥ 1, with their times and the link frames). Exudyn's section loads
    (``section_loads``: one midpoint section per link) are not that table."""
    cl = getattr(result, "cut_loads", None)
    if cl is None or result.cut_load_t is None or getattr(result, "link_rotation", None) is None:
        return False
    n_links, n_cuts = np.shape(result.link_root)[1], np.shape(cl)[1]
    return n_cuts % n_links == 0 and n_cuts // n_links >= 2 and np.shape(cl)[-1] == 6


def spatial_root_moment(result) -> np.ndarray | None:
    """Root bending moment of link 1 of a spatial ``result`` on its output times (nt,), N·m:
    the magnitude of the components of cut 0's moment along link 1's frame y and z axes
    (torsion excluded); None without the cut table (:func:`has_spatial_cut_loads`)."""
    if not has_spatial_cut_loads(result):
        return None
    t, tc = np.asarray(result.t, float), np.asarray(result.cut_load_t, float)
    m = np.asarray(result.cut_loads, float)[:, 0, 3:]  # world components, about the root point
    if not np.array_equal(tc, t):
        m = np.column_stack([np.interp(t, tc, m[:, j]) for j in range(3)])
    axes = np.asarray(result.link_rotation, float)[:, 0]  # (nt, 3, 3): columns x, y, z in W
    bending = np.einsum("tij,ti->tj", axes[:, :, 1:], m)  # (M·y₁, M·z₁)
    return np.hypot(bending[:, 0], bending[:, 1])


def load_series(result, case) -> dict[str, np.ndarray]:
    """Load quantities of ``result`` on its output times: name -> (nt,) array (see above)."""
    t = np.asarray(result.t, float)
    out = {}
    planar = not is_spatial_result(result)
    if not planar:
        m = spatial_root_moment(result)
        if m is not None:
            out["moment1"] = m
    elif result.cut_loads is not None and result.cut_load_t is not None:
        out["moment1"] = np.interp(t, result.cut_load_t, result.cut_loads[:, 0, 0])
    elif t.size >= 3 and case.model.links[0].hub_inertia > 0:  # without a hub it is joint 1's torque
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


def comparable_loads(result):
    """``result`` as the report's load comparison takes it: a planar result without its cut
    loads (its root moment from the hub balance, like for like across engines), a spatial one
    as it is (its root bending moment needs the cut loads)."""
    return result if is_spatial_result(result) else without_cut_loads(result)


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
