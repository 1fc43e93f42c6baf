"""Values the solver and the associations derive from the configuration every pass, remembered.

The streaming odometry solves four or five times an epoch, and each solve converted the
same configured angles to radians and built the same covariance floor anew (a numpy call
of a microsecond or more each, on Python floats): computed here once per distinct value,
by the same numpy calls, so the values are the same bits.
"""

from __future__ import annotations

import functools

import numpy as np


@functools.lru_cache(maxsize=256)
def radians(angle_deg: float) -> np.float64:
    """``np.radians(angle_deg)``, remembered."""
    return np.radians(angle_deg)


@functools.lru_cache(maxsize=256)
def cos_of_degrees(angle_deg: float) -> float:
    """``float(np.cos(np.radians(angle_deg)))``, remembered."""
    return float(np.cos(np.radians(angle_deg)))


@functools.lru_cache(maxsize=256)
def sin_of_degrees(angle_deg: float) -> float:
    """``float(np.sin(np.radians(angle_deg)))``, remembered."""
    return float(np.sin(np.radians(angle_deg)))


@functools.lru_cache(maxsize=64)
def pose_floor(rotation_deg: float, translation_m: float) -> np.ndarray:
    """(5, 5) read-only ``np.diag`` of the squared sigma floors of (roll, pitch, yaw, x, y):
    ``np.radians(rotation_deg)`` three times, ``translation_m`` twice."""
    r = np.radians(rotation_deg)
    out = np.diag([r**2] * 3 + [translation_m**2] * 2)
    out.flags.writeable = False
    return out
