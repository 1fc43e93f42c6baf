"""The deskewing significance gate (``odometry.deskew_significance_gate``): a parked
lidar's step is noise, and is not deskewed with."""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig
from planodom.geometry import Plane, se3_exp
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.twist_refine import significant_twist
from planodom.planes import PlaneSet

DT = 0.1
#: a parked lidar's step covariance (roll, pitch, yaw, x, y): 0.05 deg and 3 cm sigmas,
#: x and y correlated (one weak direction), as nebula's parked Hesai scans gave
SIGMAS = np.array([np.radians(0.05)] * 3 + [0.03, 0.06])
COV = np.diag(SIGMAS**2)
COV[3, 4] = COV[4, 3] = -0.8 * 0.03 * 0.06
ON = OdometryConfig(deskew_significance_gate=True)


def _relative(step: np.ndarray, status: Status = Status.OK) -> RelativePose:
    return RelativePose(se3_exp(step), COV, status)


def _chi2(step5: np.ndarray, dims: slice) -> float:
    return float(step5[dims] @ np.linalg.inv(COV[dims, dims]) @ step5[dims])


def test_a_noise_sized_step_is_zero_and_a_measured_motion_is_kept():
    rng = np.random.default_rng(3)
    noise = rng.multivariate_normal(np.zeros(5), COV, size=200)
    for step5 in noise:  # independent check: the chi-square of each block
        twist = np.r_[step5, 0.001] / DT
        out = significant_twist(twist, _relative(twist * DT), DT, ON)
        assert np.array_equal(out[:3] == 0, np.full(3, _chi2(step5, slice(0, 3)) <= 7.8147))
        assert np.array_equal(out[3:] == 0, np.full(3, _chi2(step5, slice(3, 5)) <= 5.9915))
    moving = np.array([0.0, 0.0, np.radians(10.0), 5.0, 0.1, 0.0])  # 10 deg/s, 5 m/s
    assert np.array_equal(significant_twist(moving, _relative(moving * DT), DT, ON), moving)
    # off (the default): the twist as it is
    parked = np.r_[noise[0], 0.0] / DT
    assert np.array_equal(
        significant_twist(parked, _relative(parked * DT), DT, OdometryConfig()), parked
    )


def _estimate(twist: np.ndarray | None, step: np.ndarray) -> EpochEstimate:
    planes = [Plane(np.array([0.0, 0.0, 1.0]), float(i)) for i in range(5)]
    rel = _relative(step)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, rel.T_prev_curr, [])


def test_a_parked_epoch_is_not_extracted_again_with_its_noise():
    # the first step of a parked QT64 with times: 3.5 cm and 8.4 cm along the weak
    # direction, within its covariance; taken as a 0.9 m/s twist, the re-extraction
    # (and the reference's) registered 1.28 m
    step = np.array([0.0, 0.0, 0.0, -0.035, 0.084, 0.0])
    for config, expected in ((OdometryConfig(), 2), (ON, 1)):
        calls: list[np.ndarray | None] = []
        refreshed: list[np.ndarray] = []

        def estimate(twist, source=None, calls=calls):
            calls.append(twist)
            return _estimate(twist, step)

        best = register_deskewed(
            None, DT, estimate, lambda t, r=refreshed: bool(r.append(t)), config
        )
        assert len(calls) == expected
        if expected == 1:
            assert best.twist is None and not any(np.any(t) for t in refreshed)
