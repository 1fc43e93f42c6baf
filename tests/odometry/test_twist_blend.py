"""The angular rate weighed against its prediction (``odometry.twist_blend``,
:mod:`planodom.odometry.twist_blend`), against the closed-form Kalman update."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, se3_exp
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.twist_blend import blended, scaled_pinv
from planodom.odometry.twist_sigma import TwistUncertainty
from planodom.planes import PlaneSet

DT = 0.2


def _scalar(p: float, P: float, m: float, M: float) -> tuple[float, float]:
    """The scalar Kalman update written out: the mean weighted by inverse variances."""
    return (p / P + m / M) / (1 / P + 1 / M), P * M / (P + M)


def test_a_scalar_update_is_the_inverse_variance_weighted_mean():
    for p, P, m, M in ((1.0, 4.0, 3.0, 1.0), (-0.2, 1e-6, 0.5, 2e-6), (7.0, 9.0, -1.0, 0.25)):
        mean, cov = blended(np.array([p]), np.array([[P]]), np.array([m]), np.array([[M]]))
        want_mean, want_var = _scalar(p, P, m, M)
        assert mean[0] == pytest.approx(want_mean, rel=1e-12)
        assert cov[0, 0] == pytest.approx(want_var, rel=1e-12)


def test_axes_of_variances_ten_decades_apart_are_each_their_scalar_update():
    """Diagonal covariances: each axis is its own scalar update, however small (a roll
    rate measured by the ground against a yaw rate by one far wall)."""
    p, P = np.array([0.1, -0.3, 0.4]), np.array([1e-12, 3e-4, 2e-2])
    m, M = np.array([0.2, 0.1, 0.35]), np.array([4e-12, 1e-8, 5e-3])
    mean, cov = blended(p, np.diag(P), m, np.diag(M))
    for i in range(3):
        want_mean, want_var = _scalar(p[i], P[i], m[i], M[i])
        assert mean[i] == pytest.approx(want_mean, rel=1e-10)
        assert cov[i, i] == pytest.approx(want_var, rel=1e-10)
    assert np.all(cov[~np.eye(3, dtype=bool)] == pytest.approx(0.0, abs=1e-24))


def test_an_axis_the_measurement_does_not_inform_keeps_the_prior_exactly():
    p, m = np.array([0.1, -0.3, 0.4]), np.array([5.0, 6.0, 0.35])
    P, M = np.diag([1e-4, 2e-4, 3e-4]), np.diag([np.inf, np.inf, 1e-4])
    mean, cov = blended(p, P, m, M)
    assert mean[0] == p[0] and mean[1] == p[1]
    assert cov[0, 0] == pytest.approx(1e-4, rel=1e-12)
    assert mean[2] == pytest.approx(_scalar(0.4, 3e-4, 0.35, 1e-4)[0], rel=1e-12)


def test_without_prior_information_the_update_is_the_measurement():
    m, M = np.array([0.2, -0.1, 0.35]), np.array([[2e-4, 5e-5, 0], [5e-5, 1e-4, 0], [0, 0, 3e-3]])
    mean, cov = blended(np.array([9.0, 9.0, 9.0]), np.diag(np.full(3, np.inf)), m, M)
    np.testing.assert_allclose(mean, m, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(cov, M, rtol=1e-10, atol=1e-18)


def test_a_correlated_update_is_the_covariance_form_kalman_update():
    """Full covariances against the textbook form ``K = P (P + R)^-1`` solved directly."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        A, B = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        P, R = A @ A.T + 0.1 * np.eye(3), B @ B.T + 0.1 * np.eye(3)
        p, m = rng.normal(size=3), rng.normal(size=3)
        K = np.linalg.solve((P + R).T, P.T).T
        mean, cov = blended(p, P, m, R)
        np.testing.assert_allclose(mean, p + K @ (m - p), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(cov, (np.eye(3) - K) @ P, rtol=1e-9, atol=1e-12)


def test_the_scaled_pseudo_inverse_keeps_the_small_axes():
    a = np.diag([1e-14, 1.0, 1e3])
    np.testing.assert_allclose(scaled_pinv(a), np.diag([1e14, 1.0, 1e-3]), rtol=1e-12)
    assert np.linalg.pinv(a)[0, 0] == 0.0  # numpy's cut: why it is scaled


def _relative(rate_deg: np.ndarray, sigma_deg: np.ndarray, status: Status) -> RelativePose:
    """A step turning at ``rate_deg`` (deg/s) over DT, its rotation sigmas ``sigma_deg``
    (deg, per axis) and a translation of 1 m forward."""
    step = se3_exp(np.r_[np.radians(rate_deg), 5.0, 0.0, 0.0] * DT)
    cov = np.diag(np.r_[np.radians(sigma_deg) ** 2, 1e-4, 1e-4])
    return RelativePose(step, cov, status)


def _own(rate_deg: np.ndarray) -> np.ndarray:
    return np.r_[np.radians(rate_deg), 5.0, 0.0, 0.0]


def test_a_degenerate_step_on_walls_keeps_the_predicted_roll_and_pitch():
    """The filter in :class:`TwistUncertainty`: after an OK step, a degenerate step
    whose roll and pitch are 15 deg/s off with a 3 deg sigma (walls alone) keeps the
    prediction's roll and pitch nearly, its well-measured yaw rate follows the step;
    each axis the scalar update of the prediction's and the step's variances."""
    config = OdometryConfig(twist_blend="rate")
    model = TwistUncertainty(config)
    first = np.array([-1.0, 1.0, 10.0])
    got = model.update(_own(first), _relative(first, np.full(3, 0.02), Status.OK), DT)
    np.testing.assert_array_equal(got, _own(first))  # no prediction yet: the step's own
    prior_var = (
        np.radians(0.02) ** 2 / DT**2 + np.radians(config.deskew_rate_tolerance_deg_s) ** 2 / 3
    )
    wrong = np.array([14.0, -16.0, 11.0])
    sigma = np.array([3.0, 3.0, 0.01])
    got = model.update(_own(wrong), _relative(wrong, sigma, Status.DEGENERATE), DT)
    for i in range(3):
        want = _scalar(np.radians(first[i]), prior_var, np.radians(wrong[i]),
                       np.radians(sigma[i]) ** 2 / DT**2)[0]  # fmt: skip
        assert got[i] == pytest.approx(want, rel=1e-9)
    assert np.all(np.abs(np.degrees(got[:2]) - first[:2]) < 0.05)  # roll, pitch kept
    assert abs(np.degrees(got[2]) - 11.0) < 0.05  # yaw follows the step (11 deg/s)
    np.testing.assert_array_equal(got[3:], _own(wrong)[3:])  # the velocity is untouched


def test_off_the_update_returns_the_own_twist_itself():
    model = TwistUncertainty(OdometryConfig())
    for rate in (np.array([0.0, 0.0, 10.0]), np.array([14.0, -16.0, 11.0])):
        own = _own(rate)
        assert model.update(own, _relative(rate, np.full(3, 3.0), Status.DEGENERATE), DT) is own


def _estimate(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
    """A degenerate epoch whose own rate is 20 deg/s of roll whatever it is deskewed with."""
    planes = [Plane(np.array([0.866, -0.5, 0.0]), -7.0), Plane(np.array([0.0, 1.0, 0.0]), -4.0)]
    rel = _relative(np.array([20.0, 0.0, 5.0]), np.array([3.0, 3.0, 0.05]), Status.DEGENERATE)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, rel.T_prev_curr,
                         planes)  # fmt: skip


def test_the_deskewing_refinement_extracts_again_with_the_blended_rate():
    """``register_deskewed`` refines with what ``blend`` makes of the own twist."""
    seen: list[np.ndarray] = []

    def estimate(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        if twist is not None:
            seen.append(twist.copy())
        return _estimate(twist, source)

    def blend(own: np.ndarray, relative: RelativePose, dt: float) -> np.ndarray:
        return np.r_[0.0, 0.0, own[2], own[3:]]  # roll and pitch kept at the prediction's

    config = OdometryConfig(deskew_iterations=1)
    start = _own(np.array([0.0, 0.0, 3.0]))  # the own yaw rate is 5 deg/s
    register_deskewed(start, DT, estimate, lambda t: False, config, 2, blend=blend)
    assert len(seen) == 2
    own = _estimate(start).own_twist(DT)
    np.testing.assert_allclose(seen[1][:3], [0.0, 0.0, own[2]], atol=1e-12)
    seen.clear()
    register_deskewed(start, DT, estimate, lambda t: False, config, 2)
    np.testing.assert_allclose(seen[1][:3], own[:3], atol=1e-12)  # without: the own rate


def test_config_refuses_an_unknown_blend_naming_the_key():
    with pytest.raises(ConfigError, match="^config: field 'odometry.twist_blend': "):
        PlanodomConfig.from_dict({"odometry": {"twist_blend": "twist"}})


def test_with_degenerate_only_an_ok_step_replaces_the_rate_and_a_degenerate_one_is_weighed():
    """``twist_blend: degenerate``: an OK step's own rate is returned as it is (the
    posterior is the step's, its covariance too); a degenerate step after it is weighed
    against it, each axis the scalar update."""
    config = OdometryConfig(twist_blend="degenerate")
    model = TwistUncertainty(config)
    first, second = np.array([-1.0, 1.0, 10.0]), np.array([0.5, -0.5, 12.0])
    model.update(_own(first), _relative(first, np.full(3, 0.02), Status.OK), DT)
    own = _own(second)
    got = model.update(own, _relative(second, np.full(3, 0.02), Status.OK), DT)
    np.testing.assert_array_equal(got, own)
    np.testing.assert_allclose(model.blend.cov, np.diag(np.full(3, np.radians(0.02) ** 2 / DT**2)))
    wrong, sigma = np.array([14.0, -16.0, 11.0]), np.array([3.0, 3.0, 0.01])
    prior_var = np.radians(0.02) ** 2 / DT**2 + model.change()[0] ** 2 / 3
    got = model.update(_own(wrong), _relative(wrong, sigma, Status.DEGENERATE), DT)
    for i in range(3):
        want = _scalar(np.radians(second[i]), prior_var, np.radians(wrong[i]),
                       np.radians(sigma[i]) ** 2 / DT**2)[0]  # fmt: skip
        assert got[i] == pytest.approx(want, rel=1e-9)
