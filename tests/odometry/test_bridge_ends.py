"""A bridged stretch interpolated between its measured ends (``odometry.bridge_ends``,
:mod:`planodom.odometry.bridge_ends`), against a closed-form trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform, se3_exp
from planodom.odometry.bridge_ends import bridged_stretches, interpolated_bridges
from planodom.odometry.relative import RelativePose, Status

DT, E = 0.1, 20


def twist_at(t: float) -> np.ndarray:
    """(6,) a twist linear in time: a turn tightening from 0.1 rad/s by 0.05 rad/s^2, a
    speed growing from 3 m/s, a little roll, pitch, lateral and vertical rate."""
    return np.array([0.01, -0.02, 0.1, 3.0, 0.05, 0.01]) + t * np.array(
        [0.002, 0.001, 0.05, 0.2, -0.01, 0.0]
    )


def truth() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (E,), steps (E, 4, 4) (``steps[k] = T_{k-1}_k``, each the exponential of the
    twist at its middle time: the closed form the interpolation reproduces) and poses."""
    times = np.arange(E) * DT
    steps = np.array([np.eye(4)] + [se3_exp(twist_at((k - 0.5) * DT) * DT) for k in range(1, E)])
    poses = np.array(steps)
    for k in range(1, E):
        poses[k] = poses[k - 1] @ steps[k]
    return times, steps, poses


def bridged_run(unresolved: range, prev_of: dict[int, int] | None = None):  # noqa: ANN201
    """The truth with ``unresolved`` epochs bridged by the last measured step held (their
    results against ``prev_of[k]``, default ``k - 1``), every other step measured."""
    times, steps, _ = truth()
    prev_of = prev_of or {}
    held = steps.copy()
    for k in unresolved:
        held[k] = held[k - 1] if k - 1 in unresolved else steps[k - 1]
    poses = np.array(held)
    for k in range(1, E):
        poses[k] = poses[k - 1] @ held[k]
    results: list[RelativePose | None] = [None]
    for k in range(1, E):
        p = prev_of.get(k, k - 1)
        status = Status.UNRESOLVED if k in unresolved else Status.OK
        T = invert_transform(poses[p]) @ poses[k]
        results.append(RelativePose(T, None, status, prev=p, curr=k))
    return times, poses, results


def test_a_stretch_in_a_tightening_turn_comes_back_to_the_truth():
    """Epochs 8-12 bridged with step 7's twist held are off the truth; interpolated
    between steps 7 and 13 they are the truth's (twists linear in time: exact), as are
    the poses after them, and each bridged result's ``T_prev_curr`` (against epoch 7,
    as the odometry's reference is held over a stretch without pairs)."""
    _, _, gt = truth()
    times, poses, results = bridged_run(range(8, 13), {k: 7 for k in range(9, 13)})
    assert np.abs(poses[-1] - gt[-1]).max() > 1e-3  # the held rate lags
    assert bridged_stretches(results) == [(8, 12)]
    out, new = interpolated_bridges(poses, times, results)
    np.testing.assert_allclose(out, gt, atol=1e-12)
    for k in range(8, 13):
        r = new[k]
        assert r is not None and r.prev == 7 and r.status is Status.UNRESOLVED
        np.testing.assert_allclose(r.T_prev_curr, invert_transform(gt[r.prev]) @ gt[k], atol=1e-12)
    assert new[13] is results[13]  # measured steps are not touched


def test_a_stretch_without_a_measured_end_keeps_its_bridge():
    """A stretch at the run's end, or one whose next epoch was measured against an
    earlier reference (not the stretch's last epoch), is left as bridged."""
    times, poses, results = bridged_run(range(15, 20))
    assert bridged_stretches(results) == []
    out, new = interpolated_bridges(poses, times, results)
    assert out is poses and all(a is b for a, b in zip(new, results, strict=True))
    times, poses, results = bridged_run(range(8, 13), {13: 7})
    assert bridged_stretches(results) == []


def test_two_stretches_each_from_its_own_ends():
    """Two stretches (3-4 and 10) both come back to the truth."""
    _, _, gt = truth()
    times, poses, results = bridged_run(range(3, 5))
    _, poses2, results2 = bridged_run(range(10, 11))
    results = results[:10] + results2[10:]
    steps = invert_transform(poses[:-1]) @ poses[1:]
    steps[9] = (invert_transform(poses2[:-1]) @ poses2[1:])[9]
    for k in range(1, E):
        poses[k] = poses[k - 1] @ steps[k - 1]
    assert bridged_stretches(results) == [(3, 4), (10, 10)]
    out, _ = interpolated_bridges(poses, times, results)
    np.testing.assert_allclose(out, gt, atol=1e-12)


def test_held_by_default_and_a_bad_mode_is_named():
    assert OdometryConfig().bridge_ends == "held"
    with pytest.raises(ConfigError, match="bridge_ends"):
        PlanodomConfig().updated({"odometry.bridge_ends": "spline"}, source="test")
