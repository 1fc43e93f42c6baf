"""The deskewing passes' streaming extraction kept where the twists agree
(``odometry.deskew_pass_skip``, planodom.odometry.pass_skip), against closed forms."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, invert_transform, se3_exp
from planodom.odometry import RelativePose, run_odometry
from planodom.odometry.deskewed_epochs import Curve
from planodom.odometry.pass_skip import (
    consistent_epochs,
    curve_twist,
    moved_planes,
    plane_test,
    twist_test,
)
from planodom.odometry.run import OdometryRun
from planodom.simulation import simulate_named

XI = np.array([0.02, -0.01, 0.3, 2.0, 0.3, 0.05])  # rad/s, m/s
DT = 0.1


def _curve(n: int = 12) -> Curve:
    """Nodes every DT s on the constant-twist motion ``exp(t XI)`` (its exact tangent
    coordinates are linear in t: the cubic through them is exact)."""
    times = DT * np.arange(n)
    return Curve(times, se3_exp(times[:, None] * XI), None, 3, None)


def test_the_curves_secant_twist_of_a_constant_twist_motion_is_the_twist():
    assert np.allclose(curve_twist(_curve(), 0.23, 0.31), XI, atol=1e-9)


def test_planes_moved_along_the_curve_are_the_planes_seen_from_the_true_pose():
    """A world plane seen from the base frame at t_k, moved to the frame at ``reference``,
    is the world plane seen from there (``T_base_world = exp(t XI)^-1``)."""
    world = Plane(np.array([0.6, 0.8, 0.0]), -4.0, covariance=np.diag([1e-4, 1e-4, 1e-4, 1e-6]))
    t_k, reference = 0.4, 0.45

    def seen(t: float) -> Plane:
        return world.transformed(invert_transform(se3_exp(t * XI)))

    (moved,) = moved_planes([seen(t_k)], _curve(), t_k, reference)
    truth = seen(reference)
    assert np.allclose(moved.normal, truth.normal, atol=1e-12)
    assert moved.offset == pytest.approx(truth.offset, abs=1e-12)
    assert np.allclose(moved.covariance, truth.covariance, atol=1e-15)
    same = [seen(t_k)]
    assert moved_planes(same, _curve(), t_k, t_k)[0] is same[0]  # equal times: kept


def test_the_twist_test_is_the_chi_square_quantile():
    q = 0.99
    limit = chi2.ppf(q, 6)
    var = np.full(6, 4.0)
    unit = np.ones(6) / np.sqrt(6)
    assert twist_test(unit * np.sqrt(0.999 * limit * 4.0), var, q)
    assert not twist_test(unit * np.sqrt(1.001 * limit * 4.0), var, q)
    # an unmeasured component (infinite variance) is not tested: five DoF
    var[3] = np.inf
    d = np.zeros(6)
    d[3] = 1e6
    d[0] = np.sqrt(0.999 * chi2.ppf(q, 5) * 4.0)
    assert twist_test(d, var, q)
    assert not twist_test(np.zeros(6), np.full(6, np.inf), q)  # nothing to test by


def test_the_plane_test_is_the_chi_square_of_the_planes_moves():
    """A plane z = 2 with sigmas 1 mm in its normal's x, y and 2 mm in its offset (none
    along the normal): a twist error that moves it by ``span J dxi`` = (a, 0, 0, b) has
    the squared distance (a / 1 mm)^2 + (b / 2 mm)^2, tested against chi2(q, 3)."""
    q, span = 0.99, 0.1
    J = np.zeros((4, 6))
    J[0, 2] = 1.0  # the yaw rate tilts the normal's x
    J[3, 3] = 1.0  # the x speed moves the offset
    plane = Plane(np.array([0.0, 0.0, 1.0]), -2.0,
                  covariance=np.diag([1e-6, 1e-6, 0.0, 4e-6]), deskew_jacobian=J)  # fmt: skip
    limit = chi2.ppf(q, 3)
    a = np.sqrt(0.5 * limit) * 1e-3  # half the budget each
    b = np.sqrt(0.5 * limit) * 2e-3
    dxi = np.array([0.0, 0.0, a, b, 0.0, 0.0]) / span
    assert plane_test([plane], 0.999 * dxi, span, q)
    assert not plane_test([plane], 1.001 * dxi, span, q)
    # two such planes: six DoF, the sum of both
    assert plane_test([plane, plane], 0.999 * dxi * np.sqrt(chi2.ppf(q, 6) / (2 * limit)), span, q)
    assert not plane_test([plane, replace(plane, deskew_jacobian=None)], 0 * dxi, span, q)
    assert not plane_test([], dxi, span, q)


def test_epochs_whose_streaming_twist_is_off_by_more_than_the_curves_noise_are_extracted():
    """Ten epochs on the constant-twist motion, step variances (1e-4 rad, 1 mm)^2 (a twist
    sigma of 1e-3 rad/s and 1 cm/s): the epochs deskewed with the true twist, or one off
    by 2 sigma in yaw rate, keep their planes; one 10 sigma off, the first (no twist), one
    without a twist and a superseded one are extracted again."""
    n = 10
    sigma = np.array([1e-4] * 3 + [1e-3] * 3)
    twists: list[np.ndarray | None] = [XI.copy() for _ in range(n)]
    off = np.zeros(6)
    off[2] = sigma[2] / DT
    twists[3] = XI + 2 * off
    twists[5] = XI + 10 * off
    twists[7] = None
    results: list[RelativePose | None] = [None]
    for k in range(1, n):
        results.append(RelativePose(np.eye(4), None, prev=k - 1, curr=k,
                                    deskew_twist=twists[k], deskew_times=(0.0, 0.09)))  # fmt: skip
    times = DT * np.arange(n)
    run = OdometryRun(se3_exp(times[:, None] * XI), times, results, np.zeros(n, int),
                      superseded=[8])  # fmt: skip
    variances = np.tile(sigma**2, (n - 1, 1))
    keep = consistent_epochs(run, _curve(n + 2), times, variances, 0.99)
    expected = np.ones(n, bool)
    expected[[0, 5, 7, 8]] = False
    assert keep.tolist() == expected.tolist()


@pytest.fixture(scope="module")
def loop():
    return simulate_named("paper-loop", "isoclinal", noise=0.006, seed=0, n_epochs=8,
                          motion="continuous")  # fmt: skip


def _config(**odometry: object) -> PlanodomConfig:
    return PlanodomConfig().updated({f"odometry.{k}": v for k, v in odometry.items()}, source="t")


def test_a_run_that_reextracts_every_epoch_is_the_passes_run(loop):
    """With a quantile no difference passes, the skip keeps nothing and the run is the
    passes' run to the bit; at 0.99 it keeps some epochs' planes and extracts fewer."""
    passes = run_odometry(loop, _config(deskew_passes=1), loop.rig)
    none = run_odometry(loop, _config(deskew_passes=1, deskew_pass_skip="twist",
                                      deskew_pass_skip_quantile=1e-12), loop.rig)  # fmt: skip
    assert np.array_equal(none.poses, passes.poses)
    assert none.reused == 0 and none.extractions == passes.extractions
    skip = run_odometry(loop, _config(deskew_passes=1, deskew_pass_skip="twist"), loop.rig)
    assert skip.reused > 0 and skip.extractions - skip.reused < passes.extractions
    assert passes.reused == 0


def test_the_options_are_validated():
    with pytest.raises(ConfigError, match="odometry.deskew_pass_skip"):
        _config(deskew_pass_skip="all")
    assert _config(deskew_pass_skip="planes").extraction.deskew_jacobian  # what it reads
    with pytest.raises(ConfigError, match="deskew_pass_skip_quantile"):
        _config(deskew_pass_skip_quantile=1.0)
