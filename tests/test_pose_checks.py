"""The pose-check helper the smoothing tests rely on: closed forms."""

from __future__ import annotations

import numpy as np
import pytest
from pose_checks import pose_error
from scipy.spatial.transform import Rotation


def test_pose_error_closed_form() -> None:
    rng = np.random.default_rng(0)
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-20, 20, 3)
    assert pose_error(T, T) == pytest.approx((0.0, 0.0), abs=1e-7)
    # A body-frame step of 0.01 rad about z and 0.3 m along x.
    dT = np.eye(4)
    dT[:2, :2] = [[np.cos(0.01), -np.sin(0.01)], [np.sin(0.01), np.cos(0.01)]]
    dT[0, 3] = 0.3
    rot, trans = pose_error(T @ dT, T)
    assert rot == pytest.approx(0.01) and trans == pytest.approx(0.3)
    # Near pi the angle stays exact (no arccos of a trace).
    flip = np.diag([1.0, -1.0, -1.0, 1.0])
    assert pose_error(T @ flip, T)[0] == pytest.approx(np.pi)
