"""Pose checks shared by the tests: how far an estimated pose is from the truth."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation


def pose_error(T_est: np.ndarray, T_true: np.ndarray) -> tuple[float, float]:
    """Rotation error (rad) and translation error (m) of ``inv(T_true) @ T_est`` (4, 4)."""
    E = np.linalg.inv(T_true) @ T_est
    return float(Rotation.from_matrix(E[:3, :3]).magnitude()), float(np.linalg.norm(E[:3, 3]))
