"""The motion guesses of the smoothing (planodom.smoothing.motion) against the truth."""

from __future__ import annotations

import numpy as np

from planodom.geometry import invert_transform, transform_from_rpy_xyz
from planodom.smoothing.motion import measured_step_prior


def _turning_path(n: int, step: float, yaw_rate: float) -> np.ndarray:
    """(n, 4, 4) a path at constant speed and yaw rate (constant body-frame steps)."""
    T = transform_from_rpy_xyz(0.0, 0.0, yaw_rate, step, 0.0, 0.0)
    out = [np.eye(4)]
    for _ in range(n - 1):
        out.append(out[-1] @ T)
    return np.stack(out)


def test_unmeasured_translations_take_the_measured_steps() -> None:
    truth = _turning_path(30, 0.1, np.radians(0.5))
    steps = invert_transform(truth[:-1]) @ truth[1:]
    rng = np.random.default_rng(3)
    measured = [True] * 30
    odometry = [truth[0]]
    for k in range(1, 30):
        step = steps[k - 1].copy()
        if 12 <= k <= 16:  # rotation-only: the solver's translation is 0.3-0.5 m off
            measured[k] = False
            step[:3, 3] += [rng.uniform(0.3, 0.5), rng.uniform(-0.05, 0.05), 0.0]
        elif k == 11:  # one bad measured step just before: the medoid leaves it out
            step[:3, 3] += [0.2, 0.0, 0.0]
        odometry.append(odometry[-1] @ step)
    prior = measured_step_prior(np.stack(odometry), measured)
    got = invert_transform(prior[:-1]) @ prior[1:]
    # the replaced steps: the true one (every measured step but k = 11 is the truth)
    np.testing.assert_allclose(got[11:16], steps[11:16], atol=1e-9)
    # measured steps kept as they are, rotations everywhere
    want = invert_transform(np.stack(odometry)[:-1]) @ np.stack(odometry)[1:]
    keep = [k - 1 for k in range(1, 30) if measured[k]]
    np.testing.assert_allclose(got[keep], want[keep], atol=1e-9)
    np.testing.assert_allclose(got[:, :3, :3], steps[:, :3, :3], atol=1e-9)
    # so the prior across the stretch is the true relative pose, the odometry's 2 m off
    across = invert_transform(prior[11]) @ prior[17]
    np.testing.assert_allclose(across, invert_transform(truth[11]) @ truth[17], atol=1e-9)
    chained = invert_transform(odometry[11]) @ odometry[17]
    assert np.linalg.norm(chained[:2, 3] - across[:2, 3]) > 1.5


def test_before_any_measured_step_the_odometrys_own() -> None:
    truth = _turning_path(6, 0.1, 0.0)
    odometry = truth.copy()
    odometry[1:] = odometry[1:] @ transform_from_rpy_xyz(0, 0, 0, 0.05, 0, 0)  # step 1 off
    measured = [True, False, True, False, True, True]
    prior = measured_step_prior(odometry, measured)
    np.testing.assert_allclose(prior[1], odometry[1], atol=1e-12)  # nothing measured yet
    # epoch 3: the last measured step (fewer than three known), the true one
    np.testing.assert_allclose(
        invert_transform(prior[2]) @ prior[3], invert_transform(odometry[1]) @ odometry[2]
    )
