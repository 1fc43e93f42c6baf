"""Few inlier planes that fix every direction (``planemap.few_inliers: observed``).

The plane map resolves an epoch with ``min_inliers`` (6) inlier planes, one per degree
of freedom; but a plane fixes up to three (its offset and two tilts), and a corridor seen
by a lidar gives five (floor, ceiling, two walls, an end wall) that fix the step. Where
such an epoch was left unresolved, the odometry took any other extraction of it that
reached six planes (most often the one without the deskewing twist, its walls in
fragments), or, when none did, bridged it and rebuilt the map from one scan (lidar world
335, LIDAR335 in docs/RESULTS.md). With ``observed`` an epoch with at least
``few_inliers_floor`` inliers is resolved when their information fixes every direction:
the covariance the status is judged by (:func:`.pose.relative_pose`: the information
plus the weak prior of the motion bounds) has no rotation axis with a 1-sigma above
``unobserved_rotation_deg`` and no translation direction (the vertical included) above
``unobserved_translation_m``. Stricter than the status rule for six planes, which keeps
a partly observed epoch (degenerate, or its rotation about an axis predicted): few planes
are trusted only when they observe everything.
"""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig


def observed_few(H: np.ndarray, n_inliers: int, config: PlanodomConfig) -> bool:
    """Whether ``n_inliers`` inlier planes with information ``H`` (6, 6; rotation then
    translation, rad and m) resolve an epoch under ``planemap.few_inliers: observed``
    (module docstring); False when the option is off or below ``few_inliers_floor``."""
    pm = config.planemap
    if pm.few_inliers != "observed" or n_inliers < pm.few_inliers_floor:
        return False
    rot_b = np.radians(config.association.max_rotation_deg)
    prior = np.diag([rot_b**-2] * 3 + [config.association.max_translation_m**-2] * 3)
    try:
        cov = np.linalg.inv(H + prior)
    except np.linalg.LinAlgError:
        return False
    rotation = np.linalg.eigvalsh(cov[:3, :3]).max() <= np.radians(pm.unobserved_rotation_deg) ** 2
    translation = np.linalg.eigvalsh(cov[3:, 3:]).max() <= pm.unobserved_translation_m**2
    return bool(rotation and translation)
