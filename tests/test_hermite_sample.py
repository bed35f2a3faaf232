"""``dttmm.plumbing.hermite_sample``, the output sampler of the uncompiled solvers: exact for
cubics, one-sided derivatives at a restart node, snapping to the nodes."""

from __future__ import annotations

import numpy as np

from dttmm.plumbing import hermite_sample


def test_reproduces_a_cubic_and_its_derivative_on_uneven_nodes():
    nodes = np.array([0.0, 0.3, 0.45, 1.0, 1.7])
    f = lambda t: np.stack([t**3 - 2 * t, 0.5 * t**2 + 1], axis=-1)
    df = lambda t: np.stack([3 * t**2 - 2, t], axis=-1)
    t = np.linspace(0.0, 1.7, 41)
    y, yd = hermite_sample(t, nodes, f(nodes), df(nodes), derivative=True)
    np.testing.assert_allclose(y, f(t), rtol=0, atol=1e-14)
    np.testing.assert_allclose(yd, df(t), rtol=0, atol=1e-13)


def test_one_sided_derivatives_at_a_restart_node():
    """Two different cubics left and right of node 1: dy holds the right-side derivatives (start
    of each interval), dy_end the left-side ones (end of each interval)."""
    nodes = np.array([0.0, 1.0, 2.0])
    left, dleft = lambda t: t**3, lambda t: 3 * t**2
    right, dright = lambda t: 1.0 + 5 * (t - 1) - (t - 1) ** 2, lambda t: 5 - 2 * (t - 1)
    y = np.array([left(0.0), left(1.0), right(2.0)])
    dy = np.array([dleft(0.0), dright(1.0), dright(2.0)])
    dy_end = np.array([dleft(0.0), dleft(1.0), dright(2.0)])
    t = np.array([0.25, 0.5, 0.99, 1.0, 1.01, 1.5, 2.0])
    got = hermite_sample(t, nodes, y, dy, dy_end)
    want = np.where(t < 1.0, left(t), right(t))
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


def test_times_within_snap_of_a_node_get_the_node_value():
    nodes = np.array([0.0, 1.0, 2.0])
    y = np.array([0.0, 1.0, 0.0])
    dy = np.array([10.0, -10.0, 10.0])
    t = np.array([1.0 - 1e-12, 1.0 + 1e-12, 0.5])
    got = hermite_sample(t, nodes, y, dy, snap=1e-9)
    assert got[0] == 1.0 and got[1] == 1.0
    assert abs(got[2] - 3.0) < 1e-14  # 10·h10(½) + h01(½) − 10·h11(½), not snapped
