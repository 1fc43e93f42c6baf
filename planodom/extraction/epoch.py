"""One epoch as the extraction paths see it: its points, after the input checks and the
deskewing, with what orients its planes (sensor origins, twist)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.geometry import Plane, se3_exp
from planodom.scan import Scan


@dataclass(frozen=True, eq=False)
class Epoch:
    """The checked input of :func:`planodom.extraction.extract`.

    Attributes:
        scan: the epoch as given (``ring``, ``t``, ``label`` are read from it).
        points: (N, 3) float64 metres, the points the planes are fit to (deskewed to the
            reference time when a twist was given and the scan has times).
        origins: (S, 3) sensor positions in the base frame (m), S = 1 for one for all
            points, else indexed by ring id; None when unknown.
        twist: (6,) constant body twist (rad/s, m/s) the points were deskewed with, or None.
    """

    scan: Scan
    points: np.ndarray
    origins: np.ndarray | None
    twist: np.ndarray | None

    def scan_viewpoint(self, height_m: float) -> np.ndarray:
        """(3,) one viewpoint for the whole scan: the mean sensor origin, or without
        origins ``(0, 0, height_m)`` above the base origin."""
        if self.origins is None:
            return np.array([0.0, 0.0, height_m])
        return self.origins.mean(axis=0)

    def viewpoint(self, idx: np.ndarray, height_m: float) -> np.ndarray:
        """(3,) where the points ``idx`` (K,) were seen from, in the reference-time base
        frame: the mean origin of their scanners carried to the reference time with the
        twist at their mean time; ``(0, 0, height_m)`` without origins."""
        if self.origins is None:
            return np.array([0.0, 0.0, height_m])
        org = self.origins
        ring = self.scan.ring
        view = org[0] if len(org) == 1 or ring is None else org[ring[idx]].mean(axis=0)
        if self.twist is not None and self.scan.t is not None:
            T_ref_t = se3_exp(float(self.scan.t[idx].mean()) * self.twist)
            view = T_ref_t[:3, :3] @ view + T_ref_t[:3, 3]
        return view


@dataclass(frozen=True, eq=False)
class PathResult:
    """What one extraction path found in an epoch.

    Attributes:
        planes: the planes, in the path's order. inliers: per plane, (K,) int64 scan
            indices. sigma_m: the noise sigma (m) the tolerances were scaled with.
        n_segments: straight segments found (2D-rig path; 0 otherwise).
        n_candidates: candidate inlier sets before the plane tests.
        n_rejected: candidates rejected (too few points, too thin, seed lost, a repeat).
    """

    planes: list[Plane]
    inliers: list[np.ndarray]
    sigma_m: float
    n_segments: int
    n_candidates: int
    n_rejected: int
