"""The lidar (3D) path: candidate inlier sets, robust fits and planes.

1. candidate inlier sets: region growing on the range image, or the seeded RANSAC loop
   (:func:`.candidates.lidar_candidates`);
2. a robust TLS fit of each candidate (:func:`planodom.extraction.planes.fit.robust_plane_fit`,
   iterated 1.4826 MAD inlier selection);
3. the planes (:func:`planodom.extraction.planes.builder.build_planes`).
"""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.epoch import Epoch, PathResult
from planodom.extraction.lidar.candidates import lidar_candidates
from planodom.extraction.planes.builder import PlaneFits, build_planes
from planodom.extraction.planes.fit import robust_plane_fit


def lidar_planes(epoch: Epoch, config: ExtractionConfig) -> PathResult:
    """The planes of a 3D scan (module docstring)."""
    scan = epoch.scan
    view = epoch.scan_viewpoint(config.viewpoint_height_m)
    candidates, sigma = lidar_candidates(epoch.points, config, scan.ring, view, scan.t)
    fits, n_small = fit_candidates(candidates, epoch.points, config)
    planes, inliers, n_rejected = build_planes(fits, epoch, sigma, config)
    return PathResult(planes, inliers, sigma, 0, len(candidates), n_small + n_rejected)


def fit_candidates(
    candidates: list[np.ndarray], points: np.ndarray, config: ExtractionConfig
) -> tuple[PlaneFits, int]:
    """Robust TLS fits of the candidate inlier sets (indices into ``points`` (N, 3), m)
    that keep ``min_plane_points`` inliers, and the number of the others."""
    fits = []
    for cand in candidates:
        if len(cand) < config.min_plane_points:
            continue
        fit = robust_plane_fit(points[cand], config.inlier_sigma_factor)
        if fit is not None and len(fit.inliers) >= config.min_plane_points:
            fits.append((cand[fit.inliers], fit))
    inliers = [idx for idx, _ in fits]
    bounds = np.zeros(len(fits) + 1, dtype=np.int64)
    np.cumsum(np.array([len(i) for i in inliers], dtype=np.int64), out=bounds[1:])
    flat = np.concatenate(inliers) if inliers else np.zeros(0, dtype=np.int64)
    out = PlaneFits(
        count=np.diff(bounds),
        centroid=np.array([f.centroid for _, f in fits]).reshape(-1, 3),
        offset=np.array([f.offset for _, f in fits]),
        evals=np.array([f.evals for _, f in fits]).reshape(-1, 3),
        evecs=np.array([f.evecs for _, f in fits]).reshape(-1, 3, 3),
        inliers=flat,
        bounds=bounds,
        outline=np.ones(len(flat), dtype=bool),
    )
    return out, len(candidates) - len(fits)
