"""The plane builder's array work in two compiled calls (:func:`.builder.build_planes`).

Before the plane tests' outcome is known to the caller, :func:`fits_views_signs` runs the
per-fit arrays (:func:`.fit.fit_arrays`), the kept fits' viewpoints
(:meth:`planodom.extraction.epoch.Epoch.viewpoints`) and incidences
(:func:`.confidence.mean_incidences`) and the orientation (the builder's
``_orientation_kernel``) with the oriented normals and offsets; once the kept fits are
final, :func:`rows_labels_polygons` counts their rows, takes their majority labels
(:func:`.support.distinct_and_majority`) and builds their support polygons
(:func:`.support.support_polygons`). Both call the same compiled kernels in the same order
as the Python-level sequence did, so the outputs are the same bits; what goes is a
Python wrapper, its argument conversions and a dispatch per stage (about 30 us of the
270 us of Python in a 2D-rig extraction, SPEED2D7 in docs/RESULTS.md).
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.epoch import Epoch, _carry_kernel, _mean_origins_times
from planodom.extraction.planes.confidence import _incidence_kernel
from planodom.extraction.planes.fit import fit_arrays
from planodom.extraction.planes.support import (
    _POLY_DIRS,
    _distinct_majority_kernel,
    _polygons_kernel,
)

#: How the kept fits' viewpoints are found (:func:`view_mode`): above the base origin,
#: the one sensor origin, the mean origin of the inliers' rings carried with the twist.
VIEW_HEIGHT, VIEW_FIRST_ORIGIN, VIEW_MEAN_ORIGIN = 0, 1, 2
_NO_TWIST = np.zeros(6)
_NO_TIMES = np.zeros(0)
_NO_RINGS = np.zeros(0, dtype=np.int32)
_NO_ORIGIN = np.zeros((1, 3))


def view_mode(epoch: Epoch) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:meth:`Epoch.viewpoints`'s case for ``epoch`` and the arrays it reads: the mode
    (``VIEW_*``), the origins (R, 3) m, the rings (N,) (empty: one origin for all), the
    times (N,) s and the twist (6,) (empty times: not carried)."""
    org = epoch.origins
    if org is None:
        return VIEW_HEIGHT, _NO_ORIGIN, _NO_RINGS, _NO_TIMES, _NO_TWIST
    ring, t = epoch.scan.ring, epoch.scan.t
    twisted = epoch.twist is not None and t is not None
    per_ring = len(org) > 1 and ring is not None
    if not (per_ring or twisted):
        return VIEW_FIRST_ORIGIN, org, _NO_RINGS, _NO_TIMES, _NO_TWIST
    rings = ring if per_ring and ring is not None else _NO_RINGS
    times = t if twisted and t is not None else _NO_TIMES
    xi = np.asarray(epoch.twist, dtype=np.float64) if twisted else _NO_TWIST
    return VIEW_MEAN_ORIGIN, org, rings, times, xi


@numba.njit(cache=True)
def fits_views_signs(
    evals, evecs, centroid, count, offset, floor2, min_points, min_width, max_var_n,
    points, inliers, bounds, incidence_in, viewed, mode, height, org, ring, t, xi, cos45,
):  # fmt: skip  # pragma: no cover - compiled
    """The builder's arrays of G fits up to the CPEF weights: :func:`.fit.fit_arrays`
    (covariances (G, 4, 4), widths, RMS (G,), the plane tests, scatters (G, 3, 3)), the
    kept fits (P,) int64, the viewpoints (G, 3) (``(0, 0, height)`` unless ``viewed``:
    then the kept fits' by ``mode``, with ``org`` (R, 3), ``ring`` (N,) or empty, ``t``
    (N,) s or empty and the twist ``xi`` (6,)), the incidences (G,) (``incidence_in``,
    the kept fits' computed when ``viewed``), and the normals (G, 3) and offsets (G,)
    oriented towards the viewpoints (``cos45``: ``cos(radians(45))`` as numpy gives it).
    ``inliers`` (K,) int64 scan indices of ``points`` (N, 3), ``bounds`` (G + 1,)."""
    covs, width, rms, keep, scatter = fit_arrays(
        evals, evecs, centroid, count, floor2, min_points, min_width, max_var_n
    )
    G = evals.shape[0]
    kept = np.flatnonzero(keep)
    P = kept.shape[0]
    views = np.zeros((G, 3))
    views[:, 2] = height
    incidence = incidence_in.copy()
    if viewed:
        if mode == VIEW_MEAN_ORIGIN and P > 0:
            view_k, mean_t = _mean_origins_times(org, ring, t, inliers, bounds, kept)
            if t.shape[0] > 0:
                _carry_kernel(view_k, mean_t, xi)
        else:
            view_k = np.empty((P, 3))
            for p in range(P):
                for i in range(3):
                    view_k[p, i] = org[0, i] if mode == VIEW_FIRST_ORIGIN else views[0, i]
        normal_k = np.empty((P, 3))
        for p in range(P):
            for i in range(3):
                views[kept[p], i] = view_k[p, i]
                normal_k[p, i] = evecs[kept[p], i, 2]
        inc_k = _incidence_kernel(points, inliers, bounds, kept, view_k, normal_k)
        for p in range(P):
            incidence[kept[p]] = inc_k[p]
    normals = evecs[:, :, 2]
    signs = _orientation_kernel(normals, offset, centroid, views, cos45)
    n_or = np.empty((G, 3))
    d_or = np.empty(G)
    for g in range(G):
        for i in range(3):
            n_or[g, i] = signs[g] * normals[g, i]
        d_or[g] = signs[g] * offset[g]
    return covs, width, rms, kept, scatter, views, incidence, n_or, d_or


@numba.njit(cache=True)
def _orientation_kernel(normals, offsets, centroids, views, cos45):  # pragma: no cover
    """The orientation signs (G,): +1 or -1 (:func:`.builder.orientation_sign`), its sums
    of products in numpy's order: the same signs."""
    G = normals.shape[0]
    signs = np.empty(G)
    for g in range(G):
        n0, n1, n2 = normals[g, 0], normals[g, 1], normals[g, 2]
        dist = 0.0
        dist += n0 * views[g, 0]
        dist += n1 * views[g, 1]
        dist += n2 * views[g, 2]
        dist += offsets[g]
        if abs(dist) >= 1e-3:
            signs[g] = 1.0 if dist > 0 else -1.0
        elif abs(n2) >= cos45:
            signs[g] = 1.0 if n2 > 0 else -1.0
        else:
            towards = 0.0
            towards += n0 * centroids[g, 0]
            towards += n1 * centroids[g, 1]
            signs[g] = -1.0 if -towards < 0 else 1.0
    return signs


def rows_labels_polygons(
    epoch: Epoch, points: np.ndarray, inliers: np.ndarray, bounds: np.ndarray,
    outline: np.ndarray, kept: np.ndarray, centroid: np.ndarray, evecs: np.ndarray,
    count_rows: bool,
) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:  # fmt: skip
    """Per kept fit (``kept`` (P,) int64): the distinct rings among its inliers (0 unless
    ``count_rows`` and the scan has rings), its majority true label (-1 without labels)
    and its support polygon (M, 3) m, from the outline inliers about ``centroid`` (G, 3)
    in the plane of the first two columns of ``evecs`` (G, 3, 3); ``inliers`` (K,) int64
    indices of ``points`` (N, 3), ``bounds`` (G + 1,) int64, ``outline`` (K,) bool."""
    ring, labels = epoch.scan.ring if count_rows else None, epoch.scan.label
    empty = np.zeros(0, dtype=np.int64)
    rows, truth, flat, vb = _rows_labels_polygons(
        empty if ring is None else ring, empty if labels is None else labels,
        ring is not None, labels is not None, points, inliers, bounds, outline, kept,
        centroid, evecs, _POLY_DIRS,
    )  # fmt: skip
    return rows, truth, [flat[vb[p] : vb[p + 1]].copy() for p in range(len(kept))]


@numba.njit(cache=True)
def _rows_labels_polygons(
    ring, labels, has_ring, has_labels, points, inliers, bounds, outline, kept, centroid,
    evecs, dirs,
):  # fmt: skip  # pragma: no cover - compiled
    """:func:`.support._distinct_majority_kernel` and :func:`.support._polygons_kernel` in
    one call: rows, labels (P,) int64, the polygons stacked and their bounds (P + 1,)."""
    rows, truth = _distinct_majority_kernel(
        ring, labels, inliers, bounds, kept, has_ring, has_labels
    )
    axes = np.ascontiguousarray(evecs[:, :, :2])
    flat, vb = _polygons_kernel(points, inliers, bounds, outline, kept, centroid, axes, dirs)
    return rows, truth, flat, vb
