"""The deskewing's rate refinement as a root search (``odometry.deskew_rate_solve``,
:mod:`planodom.odometry.deskew_secant`), on a linear model of a degenerate step whose
yaw rate the deskewing moves more than itself (one far wall)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, se3_exp
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.deskew_secant import secant_rate
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet

DT = 0.2
TRUE_RATE = 0.222  # rad/s (12.7 deg/s)
GAIN = 3.8  # own(r) - true = GAIN (r - true): the fixed point diverges (|GAIN| > 1)


def _own(rate: float) -> np.ndarray:
    return np.array([0.0, 0.0, TRUE_RATE + GAIN * (rate - TRUE_RATE), 2.8, 0.0, 0.0])


def _degenerate(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
    planes = [Plane(np.array([0.866, -0.5, 0.0]), -75.0), Plane(np.array([0, 0, 1.0]), 0.0)]
    if twist is None:  # not deskewed: the wall is lost (the ground alone)
        planes = planes[1:]
        rel = RelativePose(np.eye(4), None, Status.UNRESOLVED)
        return EpochEstimate(planes, PlaneSet.from_planes(planes), None, rel, np.eye(4), planes)
    step = se3_exp(_own(float(twist[2])) * DT)
    rel = RelativePose(step, None, Status.DEGENERATE)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, step, planes)


def test_the_secant_of_a_linear_own_rate_is_its_root():
    """Through two points of a linear ``own(r)``, the secant lands on ``own(r) = r``."""
    u0, u1 = np.r_[0, 0, 0.21, 2.0, 0, 0], np.r_[0, 0, 0.215, 2.0, 0, 0]
    o0, o1 = _own(0.21), _own(0.215)
    new = np.r_[o1[:3], u1[3:]]
    got = secant_rate(new, u1, o1, u0, o0)
    assert got[2] == pytest.approx(TRUE_RATE, abs=1e-12)
    np.testing.assert_array_equal(got[3:], new[3:])  # the velocity stays the refinement's
    np.testing.assert_array_equal(got[:2], new[:2])  # components it did not change


def test_the_secant_step_is_bounded_and_level_points_keep_the_plain_step():
    u0, u1 = np.r_[0, 0, 0.20, 0, 0, 0], np.r_[0, 0, 0.21, 0, 0, 0]
    o0, o1 = np.r_[0, 0, 0.2401, 0, 0, 0], np.r_[0, 0, 0.25, 0, 0, 0]  # nearly level g
    new = np.r_[o1[:3], 0, 0, 0]
    got = secant_rate(new, u1, o1, u0, o0)
    assert got[2] == pytest.approx(0.21 + 2.0 * 0.04, abs=1e-12)  # twice the plain step
    u0, u1 = np.r_[0, 0, 0.25, 0, 0, 0], np.r_[0, 0, 0.5, 0, 0, 0]
    o0, o1 = np.r_[0, 0, 0.375, 0, 0, 0], np.r_[0, 0, 0.625, 0, 0, 0]  # g exactly level
    new = np.r_[o1[:3], 0, 0, 0]
    np.testing.assert_array_equal(secant_rate(new, u1, o1, u0, o0), new)


@pytest.mark.parametrize("solve", ["fixed_point", "secant"])
def test_a_diverging_refinement_reaches_the_true_rate_only_by_secant(solve):
    """Deskewed first 0.3 deg/s off, the fixed point runs away from the true rate; the
    secant's second refinement is the true rate (the model is linear)."""
    config = OdometryConfig(deskew_rate_solve=solve, deskew_iterations=2)
    start = np.array([0.0, 0.0, TRUE_RATE - np.radians(0.3), 2.8, 0.0, 0.0])
    best = register_deskewed(start, DT, _degenerate, lambda t: False, config, 2)
    assert best.twist is not None
    err = abs(best.twist[2] - TRUE_RATE)
    if solve == "secant":
        assert err < 1e-9
    else:
        assert err > np.radians(1.0)


def test_config_refuses_an_unknown_solve_naming_the_key():
    with pytest.raises(ConfigError, match="^config: field 'odometry.deskew_rate_solve': "):
        PlanodomConfig.from_dict({"odometry": {"deskew_rate_solve": "newton"}})


def test_the_epoch_config_keeps_the_secant_to_pairwise_pipelines_and_a_gap_unrefined():
    from planodom.odometry.deskew_secant import epoch_deskew_config

    plain = OdometryConfig()
    assert epoch_deskew_config(plain, False, True) is plain  # nothing to change: itself
    assert epoch_deskew_config(plain, False, False) is plain
    assert epoch_deskew_config(plain, True, True).deskew_iterations == 0
    secant = OdometryConfig(deskew_rate_solve="secant")
    assert epoch_deskew_config(secant, False, True).deskew_rate_solve == "secant"
    mapped = epoch_deskew_config(secant, True, False)
    assert mapped.deskew_rate_solve == "fixed_point" and mapped.deskew_iterations == 0
