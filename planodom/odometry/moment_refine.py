"""The relative pose refined by the oracle's solve over the associated planes' points
(``odometry.refinement: moments``; beyond the paper).

The consensus takes the rotation from one pair of plane associations (the winner), and
the translation refinement (:mod:`planodom.odometry.refine`) solves the translation
under it. Then an error in one epoch's planes (its deskewing) enters the step into it
through one pair and the step out of it through another: the two do not cancel, and the
trajectory integrates them. Split against the oracle on the 2D rig (experiments/
rig2d_ingredients.py, docs/RESULTS.md RIG2DACC), the oracle's solve on planodom's own
planes and associations took world 160's ATE at 6 mm from 18x the oracle's to 1.25x.

This step does the same: for an OK estimate, the 6-DoF pose minimising the squared
distances of each epoch's inlier points to the other epoch's planes over all its strict
associations, both ways, each plane's points summarised by their moments
(:class:`planodom.geometry.PlaneSupport`: count, centroid, scatter), is solved by
:func:`planodom.odometry.moment_solve.moment_solve` (the oracle's solve,
:func:`planodom.oracle.relative_pose`, with an analytic Jacobian) from the estimate:
Gauss-Newton restricted to the directions the planes measure strongly (judged on the
fitted normals). The estimate is kept when a plane lacks its moments, fewer than three are
associated, the solve does not measure all five of roll, pitch, yaw, x and y, or it moves
the estimate by more than the association's inlier bounds (``rotation_inlier_deg``,
``translation_inlier_m``), or, with ``moment_gate_chi2``, farther than that squared
Mahalanobis distance under the estimate's own covariance. The covariance stays the
solver's.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.config.odometry import OdometryConfig
from planodom.geometry import (
    Plane,
    invert_transform,
    orthonormalised,
    pose5_from_transform,
    se3_log,
)
from planodom.odometry.moment_solve import moment_solve
from planodom.odometry.relative import RelativePose, Status, replaced
from planodom.oracle import SurfaceMoments

#: Fewest associations refined (three planes of independent normals fix a pose).
MIN_ASSOCIATIONS = 3


def plane_moments(planes: Sequence[Plane]) -> SurfaceMoments | None:
    """The planes' inlier moments (ids 0 .. K-1, normal and offset the planes' own), or
    None when one lacks them (no support, no scatter, no points)."""
    rows = []
    for p in planes:
        s = p.support
        if s is None or s.scatter is None or s.n_points <= 0:
            return None
        rows.append((s.n_points, s.centroid, s.scatter, p.normal, p.offset))
    count, centroid, scatter, normal, offset = (np.array(c) for c in zip(*rows, strict=True))
    ids = np.arange(len(planes))
    return SurfaceMoments(ids, count.astype(np.float64), centroid, scatter, normal, offset)


def moment_refined(
    result: RelativePose,
    prev_planes: Sequence[Plane],
    curr_planes: Sequence[Plane],
    config: OdometryConfig,
) -> RelativePose:
    """``result`` (from ``prev_planes`` to ``curr_planes``, its ``associations`` indexing
    them) with ``T_prev_curr`` refined over its associated planes' points (module
    docstring); unchanged when not OK or not refinable. ``config``: its inlier bounds."""
    ij = np.asarray(result.associations, dtype=np.int64).reshape(-1, 2)
    if result.status is not Status.OK or len(ij) < MIN_ASSOCIATIONS:
        return result
    prev = plane_moments([prev_planes[i] for i in ij[:, 0]])
    curr = plane_moments([curr_planes[j] for j in ij[:, 1]])
    if prev is None or curr is None:
        return result
    T0 = result.T_prev_curr
    with np.errstate(all="ignore"):
        try:
            est = moment_solve(prev, curr, T0)
        except np.linalg.LinAlgError:
            return result
    T = est.T_prev_curr
    if est.status != "ok" or not np.all(np.isfinite(T)):
        return result
    T = orthonormalised(T)
    change = se3_log(invert_transform(T0) @ T)
    max_rotation = np.radians(config.rotation_inlier_deg)
    if (
        np.linalg.norm(change[:3]) > max_rotation
        or np.linalg.norm(change[3:]) > config.translation_inlier_m
    ):
        return result
    if config.moment_gate_chi2 is not None and result.covariance is not None:
        if mahalanobis2(T0, T, result.covariance) > config.moment_gate_chi2:
            return result
    return replaced(result, T_prev_curr=T)


def mahalanobis2(T0: np.ndarray, T: np.ndarray, covariance: np.ndarray) -> float:
    """The squared Mahalanobis distance of ``T`` (4, 4) from ``T0`` (4, 4) in (roll, pitch,
    yaw, x, y) of ``T_prev_curr``, the parameters of ``covariance`` (5, 5; rad^2, m^2); inf
    when it is singular."""
    d = pose5_from_transform(T) - pose5_from_transform(T0)
    d[:3] = np.angle(np.exp(1j * d[:3]))
    try:
        return float(d @ np.linalg.solve(covariance, d))
    except np.linalg.LinAlgError:
        return float("inf")
