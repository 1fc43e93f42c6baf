"""A degenerate stretch's unmeasured direction made again from its ends' velocities
(``odometry.degenerate_ends``, :mod:`planodom.odometry.degenerate_ends`), against a
closed-form trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform
from planodom.odometry.degenerate_ends import (
    degenerate_stretches,
    interpolated_degenerate,
    unmeasured_direction,
)
from planodom.odometry.relative import RelativePose, Status

DT, E = 0.1, 30
HEADING = np.radians(30.0)  # the road's direction in the base frame (a crab, for the test)


def truth() -> tuple[np.ndarray, np.ndarray]:
    """Times (E,) and poses (E, 4, 4): no rotation, moving along ``HEADING`` with a
    speed growing linearly from 2 m/s by 1.5 m/s^2, so each step's displacement over its
    time is the velocity at its middle time (exact under constant acceleration)."""
    times = np.arange(E) * DT
    s = 2.0 * times + 0.75 * times**2
    poses = np.repeat(np.eye(4)[None], E, axis=0)
    poses[:, 0, 3] = s * np.cos(HEADING)
    poses[:, 1, 3] = s * np.sin(HEADING)
    return times, poses


def covariance(direction: float) -> np.ndarray:
    """5 x 5 (roll, pitch, yaw, x, y): 3 cm along ``direction`` (rad), 2 mm across it."""
    c, s = np.cos(direction), np.sin(direction)
    R = np.array([[c, -s], [s, c]])
    C = np.diag([1e-6, 1e-6, 1e-6, 0.0, 0.0])
    C[3:5, 3:5] = R @ np.diag([0.03**2, 0.002**2]) @ R.T
    return C


def held_run(degenerate: range, unresolved: range = range(0), error_across: float = 0.0):  # noqa: ANN201
    """The truth with the ``degenerate`` steps' along-road translation the velocity of
    the step before the stretch held (and ``error_across`` m added across the road),
    ``unresolved`` steps the truth; every other step OK and exact."""
    times, gt = truth()
    steps = np.array([np.eye(4)] + list(invert_transform(gt[:-1]) @ gt[1:]))
    along = np.array([np.cos(HEADING), np.sin(HEADING), 0.0])
    across = np.array([-np.sin(HEADING), np.cos(HEADING), 0.0])
    held = steps.copy()
    for k in degenerate:
        start = min(j for j in degenerate if all(i in degenerate for i in range(j, k + 1)))
        t = held[k][:3, 3]
        t += along * (along @ steps[start - 1][:3, 3] - along @ t) + error_across * across
    poses = np.array(held)
    for k in range(1, E):
        poses[k] = poses[k - 1] @ held[k]
    results: list[RelativePose | None] = [None]
    for k in range(1, E):
        status = (Status.DEGENERATE if k in degenerate
                  else Status.UNRESOLVED if k in unresolved else Status.OK)  # fmt: skip
        T = invert_transform(poses[k - 1]) @ poses[k]
        results.append(RelativePose(T, covariance(HEADING), status, prev=k - 1, curr=k))
    return times, poses, results, gt


def test_an_accelerating_stretch_comes_back_to_the_truth():
    """Steps 10-19 held at step 9's speed fall short of the truth; made again from the
    medians of the 3 OK steps at each end (a speed linear in time: exact), the poses are
    the truth's, every changed result is its new step, and the OK steps are untouched."""
    times, poses, results, gt = held_run(range(10, 20))
    assert np.linalg.norm(poses[-1][:3, 3] - gt[-1][:3, 3]) > 0.1  # the held speed lags
    assert degenerate_stretches(results) == [(10, 19)]
    out, new = interpolated_degenerate(poses, times, results, window=3)
    np.testing.assert_allclose(out, gt, atol=1e-12)
    for k in range(10, 20):
        r = new[k]
        assert r is not None and r.status is Status.DEGENERATE and r.prev == k - 1
        np.testing.assert_allclose(r.T_prev_curr, invert_transform(gt[k - 1]) @ gt[k], atol=1e-12)
    assert new[20] is results[20] and new[9] is results[9]


def test_only_the_unmeasured_direction_moves():
    """An error across the road (the measured direction) stays: the poses' along-road
    positions are the truth's, the across-road error is the steps' summed error."""
    times, poses, results, gt = held_run(range(10, 20), error_across=0.001)
    out, _ = interpolated_degenerate(poses, times, results, window=3)
    along = np.array([np.cos(HEADING), np.sin(HEADING)])
    across = np.array([-np.sin(HEADING), np.cos(HEADING)])
    d = out[:, :2, 3] - gt[:, :2, 3]
    np.testing.assert_allclose(d @ along, 0.0, atol=1e-12)
    np.testing.assert_allclose(d[-1] @ across, 0.010, atol=1e-12)


def test_a_stretch_without_ok_ends_keeps_its_steps():
    """A stretch reaching the run's end, or next to an unresolved step, is not changed."""
    times, poses, results, _ = held_run(range(22, 30))
    assert degenerate_stretches(results) == []
    out, new = interpolated_degenerate(poses, times, results, window=3)
    assert out is poses and all(a is b for a, b in zip(new, results, strict=True))
    times, poses, results, _ = held_run(range(10, 15), unresolved=range(15, 16))
    assert degenerate_stretches(results) == []


def test_the_unmeasured_direction_is_the_covariances_larger_axis():
    """The larger eigenvector of the x, y block, horizontal; None without a covariance."""
    u = unmeasured_direction(covariance(HEADING))
    assert u is not None and u[2] == 0.0
    assert abs(abs(u[:2] @ [np.cos(HEADING), np.sin(HEADING)]) - 1.0) < 1e-12
    assert unmeasured_direction(None) is None
    assert unmeasured_direction(np.full((5, 5), np.inf)) is None


def test_the_option_is_validated_at_load():
    cfg = PlanodomConfig().updated({"odometry.degenerate_ends": "interpolated"}, source="t")
    assert cfg.odometry.degenerate_ends == "interpolated"
    assert PlanodomConfig().odometry.degenerate_ends == "kept"
    with pytest.raises(ConfigError, match="degenerate_ends"):
        PlanodomConfig().updated({"odometry.degenerate_ends": "ramp"}, source="t")
