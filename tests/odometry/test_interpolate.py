"""Deskewing through neighbouring poses (planodom.odometry.interpolate) against closed forms."""

import numpy as np
import pytest

from planodom.errors import GeometryError
from planodom.extraction.deskew import deskew_points
from planodom.geometry import invert_transform, se3_exp
from planodom.odometry.interpolate import (
    curve_poses,
    deskew_with_poses,
    lagrange_weights,
    midpoint_nodes,
    window,
)
from planodom.scan import Scan

XI = np.array([0.05, -0.02, 0.3, 2.0, 0.1, 0.05])  # rad/s, m/s


def _constant_twist_poses(times: np.ndarray) -> np.ndarray:
    """T_world_base(t) = exp(t XI): a constant body twist (closed form)."""
    return se3_exp(np.asarray(times)[:, None] * XI)


def test_window_is_centred_and_clipped():
    assert window(5, 10, 3).tolist() == [4, 5, 6, 7]
    assert window(0, 10, 3).tolist() == [0, 1, 2, 3]
    assert window(9, 10, 3).tolist() == [6, 7, 8, 9]
    assert window(1, 2, 3).tolist() == [0, 1]


def test_lagrange_weights_reproduce_a_cubic():
    nodes = np.array([-0.1, 0.0, 0.12, 0.2])
    t = np.linspace(-0.05, 0.25, 7)
    f = lambda x: 1.0 - 2.0 * x + 3.0 * x**2 - 4.0 * x**3  # noqa: E731
    np.testing.assert_allclose(lagrange_weights(nodes, t) @ f(nodes), f(t), atol=1e-12)


def test_curve_through_constant_twist_poses_is_exact():
    times = np.arange(8) * 0.1
    poses = _constant_twist_poses(times)
    t = np.array([0.31, 0.35, 0.44])
    np.testing.assert_allclose(curve_poses(times, poses, 0.35, t), _constant_twist_poses(t),
                               atol=1e-12)  # fmt: skip


def test_curve_rejects_unordered_times():
    with pytest.raises(GeometryError):
        curve_poses(np.array([0.0, 0.2, 0.1]), np.tile(np.eye(4), (3, 1, 1)), 0.1, np.zeros(1))


def test_midpoint_nodes_cancel_a_sawtooth():
    """Epoch poses whose steps err alternately (+e, -e): the steps between mid-epoch nodes
    are the true ones (every node carries the same offset e / 2: the cubic's midpoint
    weights are -1/16, 9/16, 9/16, -1/16), so the motion they deskew with is right."""
    times = np.arange(10) * 0.1
    truth = _constant_twist_poses(times)
    bump = se3_exp(np.array([1e-4, 0, 0, 0, 0, 0]))  # 5.7 mdeg of roll on odd epochs
    sawtooth = np.array([T @ bump if k % 2 else T for k, T in enumerate(truth)])
    mid, nodes = midpoint_nodes(times, sawtooth)
    np.testing.assert_allclose(mid, times[:-1] + 0.05)
    expected = _constant_twist_poses(mid)
    # interior nodes (a full cubic window): the 5.7 mdeg sawtooth cancels up to its
    # product with the motion across the window (0.06 rad)
    for j in range(1, len(nodes) - 2):
        step = invert_transform(nodes[j]) @ nodes[j + 1]
        err = invert_transform(invert_transform(expected[j]) @ expected[j + 1]) @ step
        assert np.degrees(np.abs(err[:3, :3] - np.eye(3)).max()) < 5e-4
        assert np.abs(err[:3, 3]).max() < 1e-5


def test_deskew_with_poses_matches_the_constant_twist_map():
    """On a constant-twist motion the curve deskews like the closed-form twist map."""
    times = np.arange(8) * 0.1
    mid, nodes = midpoint_nodes(times, _constant_twist_poses(times))
    rng = np.random.default_rng(0)
    pts = rng.uniform(-20, 20, (200, 3))
    t = rng.uniform(0.0, 0.11, 200)
    out = deskew_with_poses(Scan(pts, t=t), mid, nodes, float(times[3]))
    np.testing.assert_allclose(out.points, deskew_points(pts, t, XI), atol=1e-9)
    assert np.all(out.t == 0.0)


def test_deskew_with_poses_leaves_a_scan_without_times():
    scan = Scan(np.ones((3, 3)))
    assert deskew_with_poses(scan, np.zeros(1), np.eye(4)[None], 0.0) is scan
