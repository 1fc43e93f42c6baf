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

With ``moment_translation: offsets`` only the solve's rotation is taken, and the
translation is fitted again under it to the associated planes' offsets
(:func:`planodom.odometry.refine.plane_translation`, the translation refinement's fit):
the moments' centroid residuals weigh one epoch's normal error by the other epoch's
centroids (metres of lever arm), so an epoch's plane errors enter the steps into and out
of it differently and do not cancel along the path; a plane's offset at its own epoch's
origin enters both with opposite signs (docs/RESULTS.md MOMENTS3).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planodom.angles import cos_of_degrees
from planodom.config.odometry import OdometryConfig
from planodom.geometry import (
    Plane,
    invert_transform,
    orthonormalised,
    se3_log,
)
from planodom.odometry.moment_solve import moment_solve
from planodom.odometry.refine import plane_translation
from planodom.odometry.relative import RelativePose, Status, replaced
from planodom.oracle import SurfaceMoments
from planodom.planes import PlaneSet

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
    plane_sets: tuple[PlaneSet, PlaneSet] | None = None,
) -> RelativePose:
    """``result`` (from ``prev_planes`` to ``curr_planes``, its ``associations`` indexing
    them) with ``T_prev_curr`` refined over its associated planes' points (module
    docstring); unchanged when not OK or not refinable. ``config``: its inlier bounds.
    ``plane_sets``: the same planes as plane sets, for ``moment_translation: offsets``."""
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
    if config.moment_translation == "offsets" and plane_sets is not None:
        T = offset_translated(T, T0, plane_sets, ij, config)
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
    when it is singular. The angles of ``R = Rz(yaw) Ry(pitch) Rx(roll)`` in closed form
    (:func:`_rpy`), not scipy's: its call was a quarter of the refinement's time (docs/
    RESULTS.md ROT2D17); they agree to rounding away from pitch +-90 deg."""
    d = np.array([*(_wrapped(a - b) for a, b in zip(_rpy(T), _rpy(T0), strict=True)),
                  T[0, 3] - T0[0, 3], T[1, 3] - T0[1, 3]])  # fmt: skip
    try:
        return float(d @ np.linalg.solve(covariance, d))
    except np.linalg.LinAlgError:
        return float("inf")


def _rpy(T: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw), rad, of ``T``'s rotation ``Rz(yaw) Ry(pitch) Rx(roll)``."""
    r21, r22, r20 = float(T[2, 1]), float(T[2, 2]), float(T[2, 0])
    return (
        math.atan2(r21, r22),
        math.atan2(-r20, math.hypot(r21, r22)),
        math.atan2(float(T[1, 0]), float(T[0, 0])),
    )


def _wrapped(angle: float) -> float:
    """``angle`` (rad) wrapped into [-pi, pi]."""
    return math.remainder(angle, 2.0 * math.pi)


def offset_translated(
    T: np.ndarray,
    T0: np.ndarray,
    plane_sets: tuple[PlaneSet, PlaneSet],
    ij: np.ndarray,
    config: OdometryConfig,
) -> np.ndarray:
    """``T`` (4, 4) with its translation fitted again under its rotation to the offsets of
    the associations ``ij`` (L, 2) of ``plane_sets`` (previous, current), from ``T0``'s
    (the consensus's) translation, as the translation refinement fits it; ``T`` unchanged
    when that fit does not measure the horizontal translation."""
    level = cos_of_degrees(config.z_plane_max_tilt_deg)
    fit = plane_translation(
        *plane_sets, T[:3, :3], ij, T0[:3, 3], level if config.estimate_z else None,
        config.refine_offset_floor_m, config.refine_max_sigma_m,
        config.translation_inlier_m**2, True, config.refine_unmeasured, level,
    )  # fmt: skip
    if not fit.measured or not fit.n_planes or not np.all(np.isfinite(fit.t)):
        return T
    out = T.copy()
    out[:3, 3] = fit.t
    return out
