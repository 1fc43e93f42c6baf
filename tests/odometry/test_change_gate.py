"""The deskewing change gate (``odometry.deskew_change_gate``): an epoch is extracted again
with its own twist only where that differs from the twist used beyond the own twist's
error."""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig
from planodom.geometry import Plane, se3_exp
from planodom.odometry.change_gate import significant_change, step_sigma
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet

DT = 0.2
#: a step's covariance (roll, pitch, yaw, x, y): 0.1 deg per axis, 1 cm per axis
COV = np.diag([np.radians(0.1) ** 2] * 3 + [0.01**2] * 2)
#: the twist sigmas it gives by hand: root of the trace of each block over DT
RATE_SIGMA = np.sqrt(3) * np.radians(0.1) / DT
SPEED_SIGMA = np.sqrt(2) * 0.01 / DT
CHI2_95_3 = 7.814727903251178  # chi2.ppf(0.95, 3), from a table


def _relative(status: Status = Status.OK) -> RelativePose:
    return RelativePose(se3_exp(np.array([0, 0, 0.05, 1.0, 0, 0])), COV, status)


def test_step_sigma_is_the_root_of_each_blocks_trace_over_dt():
    assert np.allclose(step_sigma(_relative(), DT), [RATE_SIGMA, SPEED_SIGMA])
    degenerate = step_sigma(_relative(Status.DEGENERATE), DT)
    assert np.isclose(degenerate[0], RATE_SIGMA) and degenerate[1] == np.inf
    assert np.all(step_sigma(_relative(Status.UNRESOLVED), DT) == np.inf)


def test_a_change_within_the_own_twists_error_is_not_taken():
    used = np.array([0.0, 0.0, 0.2, 5.0, 0.0, 0.0])
    bound_rate = np.sqrt(CHI2_95_3 / 3) * RATE_SIGMA  # |d| at the 95 % bound
    bound_speed = np.sqrt(CHI2_95_3 / 3) * SPEED_SIGMA
    for scale, taken in ((0.9, False), (1.1, True)):
        new = used + np.r_[0, 0, scale * bound_rate, 0, scale * bound_speed, 0]
        out = significant_change(new, used, _relative(), DT)
        assert np.array_equal(out, new if taken else used)
    # each part on its own: the rate beyond, the velocity within
    new = used + np.r_[1.1 * bound_rate, 0, 0, 0.5 * bound_speed, 0, 0]
    out = significant_change(new, used, _relative(), DT)
    assert np.array_equal(out, np.r_[new[:3], used[3:]])
    # unknown error (no covariance): the refined twist as it is
    unknown = RelativePose(np.eye(4), None, Status.OK)
    new = used + np.r_[0, 0, 0.5 * bound_rate, 0, 0, 0]
    assert np.array_equal(significant_change(new, used, unknown, DT), new)


def _estimate(twist: np.ndarray | None, relative: RelativePose) -> EpochEstimate:
    planes = [Plane(np.array([0.0, 0.0, 1.0]), float(i)) for i in range(5)]
    return EpochEstimate(
        planes, PlaneSet.from_planes(planes), twist, relative, relative.T_prev_curr, []
    )


def test_the_policy_extracts_again_only_for_a_measured_change():
    # the prediction is 1 deg/s off the step's own yaw rate: beyond the 0.5 deg/s
    # tolerance, within the own twist's error when the step's rotation sigma is 1 deg
    own_step = np.array([0.0, 0.0, np.radians(11.0) * DT, 1.0, 0.0, 0.0])
    predicted = np.array([0.0, 0.0, np.radians(10.0), 1.0 / DT, 0.0, 0.0])
    for rot_sigma_deg, gate, expected in ((1.0, True, 1), (1.0, False, 2), (0.05, True, 2)):
        cov = np.diag([np.radians(rot_sigma_deg) ** 2] * 3 + [1e-6] * 2)
        relative = RelativePose(se3_exp(own_step), cov, Status.OK)
        calls: list[np.ndarray | None] = []

        def estimate(twist, source=None, relative=relative, calls=calls):
            calls.append(twist)
            return _estimate(twist, relative)

        config = OdometryConfig(deskew_change_gate=gate, deskew_iterations=1)
        register_deskewed(predicted, DT, estimate, lambda _: False, config)
        assert len(calls) == expected, (rot_sigma_deg, gate)
