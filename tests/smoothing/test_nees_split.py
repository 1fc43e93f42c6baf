"""experiments/nees_split.py: the one world-frame rotation it takes out of a lap's errors,
against the closed form."""

from __future__ import annotations

import gtsam
import numpy as np
from experiment_scripts import load_script

from planodom.metrics import pose_errors


def _script():
    return load_script("nees_split")


def _lap(n: int = 24, radius: float = 10.0) -> np.ndarray:
    """(n, 4, 4) true poses on a circle, heading along it, the first at the origin."""
    out = []
    for k in range(n):
        a = 2 * np.pi * k / n
        T = np.eye(4)
        T[:3, :3] = gtsam.Rot3.Yaw(a).matrix()
        T[:3, 3] = [radius * np.sin(a), radius * (1 - np.cos(a)), 0.0]
        out.append(T)
    return np.stack(out)


def test_one_world_rotation_about_the_first_pose_is_taken_out_whole():
    script = _script()
    truth = _lap()
    theta = np.array([2e-3, -1e-3, 5e-4])  # rad, world frame
    R = gtsam.Rot3.Expmap(theta).matrix()
    est = truth.copy()
    est[:, :3, :3] = R[None] @ truth[:, :3, :3]
    est[:, :3, 3] = truth[:, :3, 3] @ R.T  # the whole lap turned about the first pose
    errors = pose_errors(est, truth)
    # xi = Local(est, truth): the truth is the estimate turned back by theta in the world
    world = np.einsum("kij,kj->ki", est[:, :3, :3], errors[:, :3])
    np.testing.assert_allclose(world, -np.tile(theta, (len(truth), 1)), atol=1e-8)
    left = script.without_rotation(est, errors, world.mean(axis=0))
    # what stays is second order in theta (|theta| 2.3 mrad, lap radius 10 m)
    assert np.abs(left[:, :3]).max() < 1e-8
    assert np.abs(left[:, 3:]).max() < 10.0 * 2.3e-3**2 * 2
