"""Link shapes: the deflected centre line of every link, for :attr:`dttmm.Result.link_shapes`.

Every method reports the positions of the same p material points per link, at the reference
arc lengths x_m = L·(m − 1)/(p − 1), m = 1..p (root and tip included), as an array
(nt, n_links, p, 2) in m — (nt, n_links, p, 3) for a spatial arm. How each method gets them
from its own state:

* DT-TMM (:func:`element_shapes`): the element shape functions of :mod:`dttmm.element`,
  r(x) = r_I + A(θ) (s0(ξ) + S(ξ) e) in the element holding x; spatial DT-TMM
  (:func:`frame_shapes`): r(x) = r_I + R_I (s0(ξ) + Σ(ξ) e) from its element frames
  (docs/spatial.md §2);
* the global solvers: the same interpolation from their own element frames
  (:mod:`reference_models._global_numpy`; the spatial one through :func:`frame_shapes` with its
  own shape matrices);
* Exudyn (:func:`hermite_shapes`): cubic Hermite between the beam nodes from their positions
  and slopes ∂r/∂x (ANCF cable: the element's own interpolation; geometrically exact beam:
  the cross-section direction as the slope);
* MuJoCo chain (:func:`polyline_shapes`): straight pieces between its hinges;
* rigid baseline (:func:`straight_shapes`): straight links from root to tip.

The option that asks for them is ``shape_points`` (:func:`shape_points`): 0 (the default)
records none.
"""

from __future__ import annotations

import numpy as np

from .element import shape
from .errors import InputError

__all__ = [
    "element_shapes",
    "frame_shapes",
    "hermite_shapes",
    "polyline_shapes",
    "shape_points",
    "stations",
    "straight_shapes",
]


def shape_points(value) -> int:
    """The ``shape_points`` option: 0 (no link shapes) or an integer p ≥ 2."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 0 or value == 1:
        raise InputError("shape_points", value, "must be 0 (no link shapes) or an integer ≥ 2")
    return int(value)


def stations(length: float, p: int) -> np.ndarray:
    """The reference arc lengths (p,) in m of the shape points of a link of ``length`` m."""
    return np.linspace(0.0, float(length), int(p))


def _locate(x: np.ndarray, length: float, k: int):
    """Element index (p,) and local coordinate ξ ∈ [0, 1] (p,) of the arc lengths x on a link
    of k equal elements (the tip belongs to the last element, at ξ = 1). A link of zero length
    (a robot's body on its joint, from a URDF) has every point at its root."""
    if length <= 0.0:
        n = np.asarray(x).shape[0]
        return np.zeros(n, dtype=int), np.zeros(n)
    s = np.asarray(x, float) / (length / k)
    j = np.minimum(np.floor(s).astype(int), k - 1)
    return j, s - j


def _rot_apply(theta: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A(θ) v for angles (...) and vectors (..., 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([c * v[..., 0] - s * v[..., 1], s * v[..., 0] + c * v[..., 1]], axis=-1)


def element_shapes(st, q: np.ndarray, p: int) -> np.ndarray:
    """Link shapes of the DT-TMM discretisation from its coordinates.

    Parameters
    ----------
    st : dttmm.structure.Structure
    q : (nt, n_dof) coordinates at the output times (layout of :mod:`dttmm.structure`)
    p : points per link (≥ 2)

    Returns
    -------
    (nt, n_links, p, 2) m
    """
    q = np.atleast_2d(np.asarray(q, float))
    nt = q.shape[0]
    out = np.empty((nt, st.n_links, p, 2))
    root = np.zeros((nt, 2))
    th0 = np.zeros(nt)
    for i, lk in enumerate(st.links):
        theta = th0 + q[:, lk.i_alpha]
        if lk.rigid:  # straight: the stations along the link's x axis
            x = stations(lk.length, p)
            out[:, i] = root[:, None, :] + _rot_apply(theta[:, None], np.stack([x, np.zeros_like(x)], -1))
            root = root + _rot_apply(theta, np.array([lk.length, 0.0]))  # the tip
            th0 = theta
            continue
        et, k = lk.et, lk.k
        e = q[:, lk.e_slice].reshape(nt, k, et.ne)
        phi = e[:, :, et.iphi]
        theta = (th0 + q[:, lk.i_alpha])[:, None] + np.concatenate(
            (np.zeros((nt, 1)), np.cumsum(phi[:, :-1], axis=1)), axis=1
        )
        s_out = et.sO0 + e @ et.SO.T  # (nt, k, 2) outboard node in each element frame
        chord = _rot_apply(theta, s_out)
        r = root[:, None, :] + np.concatenate(
            (np.zeros((nt, 1, 2)), np.cumsum(chord[:, :-1], axis=1)), axis=1
        )
        jj, xi = _locate(stations(lk.length, p), lk.length, k)
        s0, S = shape(xi, et.l, et.ne == 3)  # (p, 2), (p, 2, ne)
        local = s0 + np.einsum("pij,tpj->tpi", S, e[:, jj, :])
        out[:, i] = r[:, jj] + _rot_apply(theta[:, jj], local)
        root = r[:, -1] + chord[:, -1]
        th0 = theta[:, -1] + phi[:, -1]
    return out


def frame_shapes(
    RI: np.ndarray, rI: np.ndarray, e: np.ndarray, lengths, k: int, p: int, tables
) -> np.ndarray:
    """Link shapes of a spatial arm from its element frames: r(x) = r_I + R_I (s0(ξ) + Σ(ξ) e)
    in the element holding x (docs/spatial.md §2).

    Parameters
    ----------
    RI : (nt, n·k, 3, 3) element frames (world), base link first
    rI : (nt, n·k, 3) m, their origins (the elements' inboard nodes)
    e : (nt, n·k, 6) padded elastic coordinates (u, v, w, φx, φy, φz) of every element
    lengths : (n,) m, link lengths
    k : elements per link
    p : points per link (≥ 2)
    tables : ``tables(i, xi) -> (s0 (p, 3), Σ (p, 3, 6))``, the shape functions of link i at the
        local coordinates xi (each method passes its own)

    Returns
    -------
    (nt, n, p, 3) m
    """
    nt = RI.shape[0]
    out = np.empty((nt, len(lengths), p, 3))
    for i, length in enumerate(lengths):
        jj, xi = _locate(stations(length, p), length, k)
        s0, S = tables(i, xi)
        el = i * k + jj
        local = s0 + np.einsum("pij,tpj->tpi", S, e[:, el])
        out[:, i] = rI[:, el] + np.einsum("tpij,tpj->tpi", RI[:, el], local)
    return out


def hermite_shapes(x_nodes: np.ndarray, pos: np.ndarray, slope: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of a centre line through nodes.

    Parameters
    ----------
    x_nodes : (m,) m, reference arc lengths of the nodes (increasing)
    pos : (nt, m, d) m, node positions (d = 2 planar, 3 spatial)
    slope : (nt, m, d) ∂r/∂x at the nodes (dimensionless)
    x : (p,) m, reference arc lengths to evaluate

    Returns
    -------
    (nt, p, d) m
    """
    x_nodes = np.asarray(x_nodes, float)
    j = np.clip(np.searchsorted(x_nodes, x, side="right") - 1, 0, x_nodes.size - 2)
    le = x_nodes[j + 1] - x_nodes[j]
    u = (np.asarray(x, float) - x_nodes[j]) / le
    h00 = 2 * u**3 - 3 * u**2 + 1
    h10 = (u**3 - 2 * u**2 + u) * le
    h01 = -2 * u**3 + 3 * u**2
    h11 = (u**3 - u**2) * le
    w = lambda c: c[None, :, None]
    return w(h00) * pos[:, j] + w(h10) * slope[:, j] + w(h01) * pos[:, j + 1] + w(h11) * slope[:, j + 1]


def polyline_shapes(x_nodes: np.ndarray, pos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Piecewise-linear centre line through nodes (a chain of rigid pieces).

    x_nodes (m,) m reference arc lengths of the piece ends; pos (nt, m, d) m their positions
    (d = 2 or 3); x (p,) m. Returns (nt, p, d) m.
    """
    x_nodes = np.asarray(x_nodes, float)
    j = np.clip(np.searchsorted(x_nodes, x, side="right") - 1, 0, x_nodes.size - 2)
    u = ((np.asarray(x, float) - x_nodes[j]) / (x_nodes[j + 1] - x_nodes[j]))[None, :, None]
    return (1 - u) * pos[:, j] + u * pos[:, j + 1]


def straight_shapes(root: np.ndarray, tip: np.ndarray, p: int) -> np.ndarray:
    """Straight links: root (nt, n, d) and tip (nt, n, d) in m → (nt, n, p, d) m (d = 2 or 3)."""
    u = np.linspace(0.0, 1.0, int(p))[None, None, :, None]
    root = np.asarray(root, float)[:, :, None, :]
    return root + u * (np.asarray(tip, float)[:, :, None, :] - root)
