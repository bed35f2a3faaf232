"""Rotations of the spatial model (numpy): URDF roll-pitch-yaw, axis-angle, the SO(3)
exponential and its left Jacobian (docs/spatial.md §1-2)."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["axis_angle_matrix", "exp_so3", "hat", "left_jacobian", "log_so3", "rpy_matrix"]


def hat(v) -> np.ndarray:
    """The skew matrix [v]× with [v]× w = v × w."""
    x, y, z = (float(c) for c in v)
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def rpy_matrix(rpy) -> np.ndarray:
    """URDF convention: R = Rz(yaw) · Ry(pitch) · Rx(roll)."""
    r, p, y = (float(c) for c in rpy)
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    return rz @ ry @ rx


def axis_angle_matrix(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit vector ``axis`` (Rodrigues)."""
    a = np.asarray(axis, dtype=float)
    k = hat(a)
    return np.eye(3) + math.sin(angle) * k + (1.0 - math.cos(angle)) * (k @ k)


def _coefficients(t2: float):
    """(sin θ/θ, (1−cos θ)/θ², (θ−sin θ)/θ³) at θ² = t2; Taylor series for small θ."""
    if t2 < 1e-8:
        return 1.0 - t2 / 6.0 + t2 * t2 / 120.0, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, 1.0 / 6.0 - t2 / 120.0
    t = math.sqrt(t2)
    s, c = math.sin(t), math.cos(t)
    return s / t, (1.0 - c) / t2, (t - s) / (t2 * t)


def exp_so3(phi) -> np.ndarray:
    """exp([φ]×): the rotation by the rotation vector φ."""
    k = hat(phi)
    a, b, _ = _coefficients(float(np.dot(phi, phi)))
    return np.eye(3) + a * k + b * (k @ k)


def left_jacobian(phi) -> np.ndarray:
    """J_L(φ) = I + (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×², θ = |φ|: the angular velocity of
    exp([φ]×) is J_L(φ) φ̇ (in the frame φ is measured in)."""
    k = hat(phi)
    _, b, c = _coefficients(float(np.dot(phi, phi)))
    return np.eye(3) + b * k + c * (k @ k)


def log_so3(r) -> np.ndarray:
    """The rotation vector φ with exp([φ]×) = R (|φ| ≤ π)."""
    r = np.asarray(r, dtype=float)
    w = 0.5 * np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    s = float(np.linalg.norm(w))
    c = 0.5 * (float(np.trace(r)) - 1.0)
    t = math.atan2(s, c)
    if s < 1e-7 and c > 0:
        return w * (1.0 + t * t / 6.0)
    if s < 1e-7:  # θ near π: from the symmetric part
        m = 0.5 * (r + r.T) - c * np.eye(3)
        i = int(np.argmax(np.diag(m)))
        v = m[:, i] / math.sqrt(max(m[i, i], 1e-300))
        v = v if np.dot(v, w) >= 0 else -v
        return t * v / np.linalg.norm(v)
    return w * (t / s)
