"""One epoch as the extraction paths see it: its points, after the input checks and the
deskewing, with what orients its planes (sensor origins, twist)."""

from __future__ import annotations

from dataclasses import dataclass

import numba
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

    def viewpoints(
        self, inliers: np.ndarray, bounds: np.ndarray, planes: np.ndarray, height_m: float
    ) -> np.ndarray:
        """(P, 3) :meth:`viewpoint` of each plane g in ``planes`` (P,) at once, its points
        ``inliers[bounds[g]:bounds[g + 1]]`` ((K,) int64 scan indices, (G + 1,) bounds)."""
        P = len(planes)
        if self.origins is None:
            return np.broadcast_to(np.array([0.0, 0.0, height_m]), (P, 3)).copy()
        org = self.origins
        ring, t = self.scan.ring, self.scan.t
        twisted = self.twist is not None and t is not None
        per_ring = len(org) > 1 and ring is not None
        if P == 0 or not (per_ring or twisted):
            return np.broadcast_to(org[0], (P, 3)).copy()
        # one compiled pass over the inliers (a Python loop of numpy calls per plane cost
        # a tenth of a 2D-rig extraction)
        view, mean_t = _mean_origins_times(
            org, np.zeros(0, np.int32) if not per_ring else ring,
            np.zeros(0) if not twisted else t, inliers, bounds, planes.astype(np.int64),
        )  # fmt: skip
        if twisted:
            assert self.twist is not None
            _carry_kernel(view, mean_t, np.asarray(self.twist, dtype=np.float64))
        return view


@numba.njit(cache=True)
def _carry_kernel(view, mean_t, xi):  # pragma: no cover - compiled
    """``view[p] = exp(mean_t[p] xi) view[p]`` in place for (P, 3) points, (P,) s and the
    (6,) twist: :func:`planodom.geometry.se3_exp`'s closed form and series, written out
    per plane (numpy's batched form cost ~50 us a call on a few planes; its BLAS products
    round differently, by ~1e-16 m here)."""
    K = np.empty((3, 3))
    K2 = np.empty((3, 3))
    R = np.empty((3, 3))
    for p in range(view.shape[0]):
        w0, w1, w2 = mean_t[p] * xi[0], mean_t[p] * xi[1], mean_t[p] * xi[2]
        v = (mean_t[p] * xi[3], mean_t[p] * xi[4], mean_t[p] * xi[5])
        th = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
        t2 = th * th
        if th < 1e-3:
            a = 1.0 - t2 / 6.0 + t2 * t2 / 120.0
            b = 0.5 - t2 / 24.0 + t2 * t2 / 720.0
            c = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0
        else:
            a = np.sin(th) / th
            b = (1.0 - np.cos(th)) / t2
            c = (th - np.sin(th)) / (t2 * th)
        K[0, 0], K[0, 1], K[0, 2] = 0.0, -w2, w1
        K[1, 0], K[1, 1], K[1, 2] = w2, 0.0, -w0
        K[2, 0], K[2, 1], K[2, 2] = -w1, w0, 0.0
        for i in range(3):
            for j in range(3):
                K2[i, j] = K[i, 0] * K[0, j] + K[i, 1] * K[1, j] + K[i, 2] * K[2, j]
        shift = np.zeros(3)
        for i in range(3):
            for j in range(3):
                e = 1.0 if i == j else 0.0
                R[i, j] = e + a * K[i, j] + b * K2[i, j]
                shift[i] += (e + b * K[i, j] + c * K2[i, j]) * v[j]
        x0, x1, x2 = view[p, 0], view[p, 1], view[p, 2]
        for i in range(3):
            view[p, i] = R[i, 0] * x0 + R[i, 1] * x1 + R[i, 2] * x2 + shift[i]


@numba.njit(cache=True)
def _mean_origins_times(org, ring, t, inliers, bounds, planes):  # pragma: no cover - compiled
    """Per plane g in ``planes``: the mean of ``org[ring[i]]`` (``org[0]`` when ``ring`` is
    empty) and of ``t[i]`` (0 when ``t`` is empty) over its inliers i."""
    P = len(planes)
    view = np.empty((P, 3))
    mean_t = np.zeros(P)
    for p in range(P):
        g = planes[p]
        a, b = bounds[g], bounds[g + 1]
        n = b - a
        if len(ring) == 0:
            view[p, 0], view[p, 1], view[p, 2] = org[0, 0], org[0, 1], org[0, 2]
        else:
            s0 = s1 = s2 = 0.0
            for k in range(a, b):
                r = ring[inliers[k]]
                s0 += org[r, 0]
                s1 += org[r, 1]
                s2 += org[r, 2]
            view[p, 0], view[p, 1], view[p, 2] = s0 / n, s1 / n, s2 / n
        if len(t) > 0:
            st = 0.0
            for k in range(a, b):
                st += t[inliers[k]]
            mean_t[p] = st / n
    return view, mean_t


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
