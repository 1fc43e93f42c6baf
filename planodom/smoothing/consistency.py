"""Consistency of smoothed poses with their covariances: the NEES.

The normalised estimation error squared of a pose estimate ``T`` with covariance ``P``
(gtsam's Pose3 tangent ``[rotation (rad), translation (m)]`` at the estimate, right
perturbation, as :func:`planodom.smoothing.batch.pose_covariances` gives it) against the
truth ``G`` is ``xi^T P^-1 xi`` with ``xi = Logmap(T^-1 G)``; for a consistent estimator
it follows chi2 with as many degrees of freedom as components are used.
"""

from __future__ import annotations

import gtsam
import numpy as np


def pose_nees(
    poses: np.ndarray, covariances: np.ndarray, gt_poses: np.ndarray, dof: int = 6
) -> np.ndarray:
    """(E,) NEES of each pose over its first ``dof`` tangent components.

    Args:
        poses: (E, 4, 4) estimates. covariances: (E, 6, 6) their covariances (see the
            module docstring). gt_poses: (E, 4, 4) the truth, in the same frame.
        dof: 6 for the full pose; 5 drops the body z (unobserved by the 5-DoF factors, the
            other components' NEES is then that of z marginalised out).

    Returns:
        (E,) NEES values; NaN where the covariance block is singular.
    """
    out = np.full(len(poses), np.nan)
    for k, (T, P, G) in enumerate(zip(poses, covariances, gt_poses, strict=True)):
        xi = np.asarray(gtsam.Pose3(T).localCoordinates(gtsam.Pose3(G)))[:dof]
        try:
            out[k] = xi @ np.linalg.solve(P[:dof, :dof], xi)
        except np.linalg.LinAlgError:
            continue
    return out
