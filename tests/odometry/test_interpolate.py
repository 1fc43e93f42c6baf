"""Deskewing through neighbouring poses (planodom.odometry.interpolate) against closed forms."""

import numpy as np
import pytest

from planodom.errors import GeometryError
from planodom.extraction.deskew import deskew_points
from planodom.geometry import invert_transform, se3_exp
from planodom.odometry.interpolate import (
    curve_poses,
    deskew_with_poses,
    fit_weights,
    increment_fit_weights,
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


def test_fit_weights_reproduce_a_cubic_whatever_the_weights():
    """The weighted least-squares cubic over 9 nodes is exact for a cubic (any weights),
    and over 4 nodes it is the interpolating polynomial."""
    nodes = np.linspace(-0.4, 0.4, 9)
    t = np.linspace(-0.05, 0.1, 5)
    f = lambda x: 1.0 - 2.0 * x + 3.0 * x**2 - 4.0 * x**3  # noqa: E731
    w = np.random.default_rng(1).uniform(0.1, 10.0, 9)
    np.testing.assert_allclose(fit_weights(nodes, t, 3, w) @ f(nodes), f(t), atol=1e-12)
    np.testing.assert_allclose(fit_weights(nodes[:4], t, 3, w[:4]), lagrange_weights(nodes[:4], t),
                               atol=1e-10)  # fmt: skip


def test_fit_weights_are_least_squares():
    """Against numpy's polyfit with weights sqrt(w) (an independent computation)."""
    rng = np.random.default_rng(2)
    nodes, y, w = np.linspace(0, 1, 8), rng.normal(size=8), rng.uniform(0.5, 2.0, 8)
    coef = np.polyfit(nodes, y, 3, w=np.sqrt(w))
    np.testing.assert_allclose(fit_weights(nodes, np.array([0.3]), 3, w) @ y,
                               np.polyval(coef, 0.3), atol=1e-12)  # fmt: skip
    with pytest.raises(GeometryError):
        fit_weights(nodes, np.zeros(1), 3, np.r_[np.ones(3), np.zeros(5)])


def _noisy(poses: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    noise = rng.normal(0.0, sigma, (len(poses), 6))
    return poses @ se3_exp(noise)


def test_weighted_curve_is_exact_for_constant_twist_and_averages_noise():
    """Through 13 nodes of a constant twist the fit is exact; through the same nodes with
    independent noise its motion within an epoch is closer to the truth than the
    interpolation's (rms over 200 draws, compared with the true motion)."""
    times = np.arange(13) * 0.1
    var = np.ones((13, 6))
    t = np.array([0.6, 0.65, 0.7])
    poses = _constant_twist_poses(times)
    np.testing.assert_allclose(curve_poses(times, poses, 0.65, t, 3, var, 13),
                               _constant_twist_poses(t), atol=1e-12)  # fmt: skip
    rng = np.random.default_rng(3)
    truth = invert_transform(_constant_twist_poses(t[:1])) @ _constant_twist_poses(t)
    err = {"interpolate": [], "fit": []}
    for _ in range(200):
        noisy = _noisy(poses, 1e-3, rng)
        for name, n_fit in (("interpolate", None), ("fit", 13)):
            c = curve_poses(times, noisy, 0.65, t, 3, var, n_fit)
            motion = invert_transform(c[:1]) @ c
            err[name].append(np.abs(motion - truth).max())
    rms = {k: np.sqrt(np.mean(np.square(v))) for k, v in err.items()}
    assert rms["fit"] < 0.5 * rms["interpolate"], rms


def test_weighted_curve_ignores_a_node_of_infinite_variance():
    """A node with infinite variances does not move the fitted curve; with finite ones the
    component weights follow the inverse variances (a wrong node of tiny weight moves it
    less than the same node at equal weight)."""
    times = np.arange(10) * 0.1
    poses = _constant_twist_poses(times)
    bad = poses.copy()
    bad[6] = bad[6] @ se3_exp(np.array([0.01, 0, 0, 0.05, 0, 0]))
    var = np.ones((10, 6))
    t = np.array([0.45, 0.5])
    var_inf = var.copy()
    var_inf[6] = np.inf
    np.testing.assert_allclose(curve_poses(times, bad, 0.45, t, 3, var_inf, 10),
                               _constant_twist_poses(t), atol=1e-12)  # fmt: skip
    var_big = var.copy()
    var_big[6] = 100.0

    def off(v: np.ndarray) -> float:
        return float(
            np.abs(curve_poses(times, bad, 0.45, t, 3, v, 10) - _constant_twist_poses(t)).max()
        )

    assert off(var_big) < 0.2 * off(var)


def test_increment_fit_reproduces_a_cubic_and_interpolates_four_nodes():
    nodes = np.linspace(-0.4, 0.4, 9)
    t = np.linspace(-0.05, 0.1, 5)
    f = lambda x: 1.0 - 2.0 * x + 3.0 * x**2 - 4.0 * x**3  # noqa: E731
    w = np.random.default_rng(4).uniform(0.1, 10.0, 9)
    np.testing.assert_allclose(increment_fit_weights(nodes, t, 3, w) @ f(nodes), f(t), atol=1e-12)
    np.testing.assert_allclose(increment_fit_weights(nodes[:4], t, 3, w[:4]),
                               lagrange_weights(nodes[:4], t), atol=1e-10)  # fmt: skip


def test_increment_fit_is_least_squares_on_the_increments():
    """Against an independent least squares: the polynomial's shape by numpy's lstsq on the
    increments (weights 1 here), its constant from the nodes' mean."""
    rng = np.random.default_rng(5)
    nodes, y = np.linspace(0.0, 1.0, 8), rng.normal(size=8)
    V = np.vander(nodes, 4, increasing=True)[:, 1:]
    shape = np.linalg.lstsq(np.diff(V, axis=0), np.diff(y), rcond=None)[0]
    const = np.mean(y - V @ shape)
    expected = const + np.array([0.3, 0.3**2, 0.3**3]) @ shape
    got = increment_fit_weights(nodes, np.array([0.3]), 3) @ y
    np.testing.assert_allclose(got, expected, atol=1e-12)


def test_increment_fit_leaves_one_wrong_step_out_of_the_shape():
    """A single wrong step (every later node shifted by the same amount) with a tiny weight
    on the nodes beside it: the fit to the increments keeps the curve's motion over an
    epoch within 4e-4 of the truth (the weights' 1 % floor and the chart's curvature), the
    fit to the values bends by 1e-2."""
    times = np.arange(10) * 0.1
    poses = _constant_twist_poses(times)
    jump = se3_exp(np.array([0.02, 0, 0, 0.05, 0, 0]))
    bad = np.array([T @ jump if k >= 6 else T for k, T in enumerate(poses)])
    var = np.ones((10, 6))
    var[5:7] = 1e6  # the step between nodes 5 and 6 is not trusted
    t = np.array([0.3, 0.4])
    truth = invert_transform(_constant_twist_poses(t[:1])) @ _constant_twist_poses(t)

    def motion_error(increments: bool) -> float:
        c = curve_poses(times, bad, 0.3, t, 3, var, 10, increments)
        return float(np.abs(invert_transform(c[:1]) @ c - truth).max())

    assert motion_error(True) < 0.2 * motion_error(False)
