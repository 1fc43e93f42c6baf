"""Step 1 of the range-image path (:mod:`.rangeimage`): pixel normals of the grid.

``n = t_h x t_v`` with the row tangent ``t_h = sum_k k (p[c+k] - p[c-k])``, ``k = 1..K``
(columns wrap) and the column tangent ``t_v = p[r+S] - p[r-S]``; predicted angular error
``e = sigma sqrt(2 sum k^2 / |t_h|^2 + 2 / |t_v|^2)``. :func:`pixel_normals` picks the row
step ``S``; the compiled kernel :func:`_pixel_normals` computes them (a short loop over
~3 * 10^4 pixels with a few branches, where numpy needed the grid shifted by every window
offset).
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.memo import identity_memo, read_only
from planodom.median import median_at_most


def pixel_normals(
    P: np.ndarray, sigma: float, tol: float, config: ExtractionConfig, viewpoint: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """Step 1: the pixel normals (H, W, 3), their predicted errors (H, W) rad and ``ok``
    (H, W) of the grid ``P`` (H, W, 3) m, with the column tangent between the rows
    ``r +- S`` for the smallest row step ``S`` = 1, 2, ... (at most a quarter of the
    rows) whose median predicted error is within ``region_max_normal_error_deg``; None
    when none is. A dense lidar's rows are close (a 64-beam unit's 0.4 deg apart), so at
    high noise the normals across neighbouring rows are too noisy to grow regions on,
    while across rows two or three apart they are not (the error falls as ``1 / S``);
    a wider stencil only loses the pixels within ``S`` rows of an edge. Only the column
    tangent's part of the error falls with ``S``: None at once when the row tangent's
    part alone is over the limit. The medians are compared with their limits by counting
    (:func:`planodom.median.median_at_most`, the same verdicts): on a 64-beam room at 6 mm,
    declined at row steps 1 and 2, the five partitions of ~6 * 10^4 values were a fifth
    of this function's time."""
    ks = float(config.region_normal_sigmas)
    K = int(config.region_window)
    limit = np.radians(config.region_max_normal_error_deg)
    # The row tangent's part of the error does not depend on S: when it alone is over the
    # limit (short column spacing, a sparse lidar close to its walls), no S helps (and a
    # wide S would only pass the test on the pixels far from every edge).
    masked = config.region_noisy_pixels == "masked"
    if not masked:
        e_row = _row_errors(P, K, float(sigma))
        if len(e_row) and not median_at_most(e_row, limit):
            return None
    ray = unit_rays(P, np.ascontiguousarray(viewpoint, dtype=np.float64))
    width = _chord_widths(ray, K)
    tallest = None
    for S in range(1, max(1, P.shape[0] // 4) + 1):
        if S > 1 and not _stencil_within_width(ray, S, width):
            break
        if S == 1:
            n, e, ok = first_row_step(P, K, float(sigma), float(tol), ks)
        else:
            n, e, ok = _pixel_normals(P, K, S, float(sigma), float(tol), ks)
        if np.count_nonzero(ok) < config.min_plane_points or median_at_most(e[ok], limit):
            return n, e, ok
        tallest = (n, e, ok)
    if not masked or tallest is None:
        return None
    n, e, ok = tallest
    ok = ok & (e <= limit)
    if np.count_nonzero(ok) < config.min_plane_points:
        return None
    return n, np.where(ok, e, np.inf), ok


@identity_memo
def first_row_step(
    P: np.ndarray, K: int, sigma: float, tol: float, ks: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`_pixel_normals` of the grid ``P`` (H, W, 3) with the row step 1, read-only
    and memoised (:mod:`planodom.extraction.memo`): on a grid too noisy to grow regions on,
    the RANSAC agreement check (:mod:`.agreement`) asks for these very normals of the
    same grid (:func:`.grid.point_grid`) again."""
    n, e, ok = _pixel_normals(P, K, 1, sigma, tol, ks)
    return read_only(n), read_only(e), read_only(ok)


def _stencil_within_width(ray: np.ndarray, S: int, width: np.ndarray) -> bool:
    """Whether the column tangent between the rows ``r +- S`` spans at most the angle the
    row tangent does as seen from the sensor (``ray`` (H, W, 3): the pixels' unit
    directions; ``width`` (H, W): the chord ``|u[c+K] - u[c-K]|``), in the median over the
    pixels that have both (angles, not metres: on the ground the rows are far apart in
    metres at any angle): a taller stencil straddles the edges a square one does not (a
    16-beam lidar's rows are 2 deg apart: rows 4 apart span 8 deg where 2 x 3 columns of
    1024 span 2; measured on an indoor lidar16 world at 6 mm, such stencils gave 10
    planes instead of 15 and 0.9 deg errors)."""
    return median_at_most(_stencil_ratios(ray, S, width), 1.0)


@numba.njit(cache=True, error_model="numpy")
def _row_errors(P, K, sigma):  # pragma: no cover - compiled
    """(M,) the row tangent's part of the predicted error (rad), ``sigma sqrt(2 sum k^2 /
    |t_h|^2)``, at the pixels of ``P`` (H, W, 3) (NaN: no point; window half-width ``K``,
    columns wrap) where it is finite, row-major: the terms of :func:`_pixel_normals`'s
    ``t_h``, in its order (one pass instead of the grid rolled 2K times)."""
    H, W = P.shape[0], P.shape[1]
    s2 = 0.0
    for k in range(1, K + 1):
        s2 += k * k
    s2 *= 2.0
    out = np.empty(H * W)
    m = 0
    wrap = np.arange(-K, W + K) % W  # column c + k is wrap[c + k + K]
    for r in range(H):
        for c in range(W):
            h0 = h1 = h2 = 0.0
            for k in range(1, K + 1):
                a, b = wrap[c + k + K], wrap[c - k + K]
                h0 += k * (P[r, a, 0] - P[r, b, 0])
                h1 += k * (P[r, a, 1] - P[r, b, 1])
                h2 += k * (P[r, a, 2] - P[r, b, 2])
            e = sigma * np.sqrt(s2 / (h0 * h0 + h1 * h1 + h2 * h2))
            if np.isfinite(e):
                out[m] = e
                m += 1
    return out[:m]


@identity_memo
def unit_rays(P: np.ndarray, viewpoint: np.ndarray) -> np.ndarray:
    """(H, W, 3) the unit rays from ``viewpoint`` (3,) float64 to the pixels of ``P``
    (H, W, 3) (NaN: no point), as numpy's norms compute them (sums in axis order);
    read-only and memoised (:mod:`planodom.extraction.memo`): the pixel normals' stencil
    test and the range image's row spacing take them from one grid."""
    return read_only(_unit_rays(P, viewpoint))


@numba.njit(cache=True, error_model="numpy")
def _unit_rays(P, viewpoint):  # pragma: no cover - compiled
    """The rays of :func:`unit_rays`."""
    H, W = P.shape[0], P.shape[1]
    ray = np.empty((H, W, 3))
    for r in range(H):
        for c in range(W):
            x0 = P[r, c, 0] - viewpoint[0]
            x1 = P[r, c, 1] - viewpoint[1]
            x2 = P[r, c, 2] - viewpoint[2]
            nrm = np.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
            ray[r, c, 0], ray[r, c, 1], ray[r, c, 2] = x0 / nrm, x1 / nrm, x2 / nrm
    return ray


@numba.njit(cache=True, error_model="numpy")
def _chord_widths(ray, K):  # pragma: no cover - compiled
    """(H, W) the chords ``|u[c+K] - u[c-K]|`` of the unit rays ``ray`` (H, W, 3) over the
    row tangent's window (columns wrap), summed in axis order as numpy's norm."""
    H, W = ray.shape[0], ray.shape[1]
    width = np.empty((H, W))
    for r in range(H):
        for c in range(W):
            a, b = (c + K) % W, (c - K + W) % W
            d0 = ray[r, a, 0] - ray[r, b, 0]
            d1 = ray[r, a, 1] - ray[r, b, 1]
            d2 = ray[r, a, 2] - ray[r, b, 2]
            width[r, c] = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return width


@numba.njit(cache=True, error_model="numpy")
def row_chords(ray):  # pragma: no cover - compiled
    """(M,) the finite chords ``|u[r+1] - u[r]|`` (row-major) between the unit rays
    ``ray`` (H, W, 3) of vertically neighbouring pixels, as numpy's norm."""
    H, W = ray.shape[0], ray.shape[1]
    out = np.empty(max(H - 1, 0) * W)
    m = 0
    for r in range(H - 1):
        for c in range(W):
            d0 = ray[r + 1, c, 0] - ray[r, c, 0]
            d1 = ray[r + 1, c, 1] - ray[r, c, 1]
            d2 = ray[r + 1, c, 2] - ray[r, c, 2]
            chord = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            if np.isfinite(chord):
                out[m] = chord
                m += 1
    return out[:m]


@numba.njit(cache=True, error_model="numpy")
def _stencil_ratios(ray, S, width):  # pragma: no cover - compiled
    """(M,) ``|u[r+S] - u[r-S]| / max(width, 1e-12)`` at the pixels (row-major) where
    both are finite (:func:`_stencil_within_width`)."""
    H, W = ray.shape[0], ray.shape[1]
    out = np.empty(H * W)
    m = 0
    for r in range(S, H - S):
        for c in range(W):
            d0 = ray[r + S, c, 0] - ray[r - S, c, 0]
            d1 = ray[r + S, c, 1] - ray[r - S, c, 1]
            d2 = ray[r + S, c, 2] - ray[r - S, c, 2]
            tall = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            w = width[r, c]
            if np.isfinite(tall) and np.isfinite(w):
                out[m] = tall / max(w, 1e-12)
                m += 1
    return out[:m]


@numba.njit(cache=True, error_model="numpy")
def _pixel_normals(P, K, S, sigma, tol, ks):  # pragma: no cover - compiled
    """Step 1 on the grid ``P`` (H, W, 3) (NaN: no point), window half-width ``K``,
    column tangent between the rows ``r +- S``.

    Returns the unit normals (H, W, 3) (0 where not ``ok``), their predicted errors
    (H, W) (rad; inf where not ``ok``) and ``ok`` (H, W): the pixel has a normal, and the
    ends of its window (the columns c +- K, the rows r +- S) lie within
    ``tol + ks e |q - p|`` of its tangent plane (a window across an edge or a corner has
    a mixed normal). A pixel without a point between pixels that have one gets a normal
    too (counted in the median error); it joins no edge.
    """
    H, W = P.shape[0], P.shape[1]
    normal = np.zeros((H, W, 3))
    err = np.full((H, W), np.inf)
    ok = np.zeros((H, W), dtype=np.bool_)
    s2 = 0.0
    for k in range(1, K + 1):
        s2 += k * k
    s2 *= 2.0
    q = np.empty((4, 3))
    wrap = np.arange(-K, W + K) % W  # column c + k is wrap[c + k + K]
    for r in range(S, H - S):  # the first and last S rows have no column tangent
        for c in range(W):
            p0, p1, p2 = P[r, c, 0], P[r, c, 1], P[r, c, 2]
            h0 = h1 = h2 = 0.0
            for k in range(1, K + 1):
                a = wrap[c + k + K]
                b = wrap[c - k + K]
                h0 += k * (P[r, a, 0] - P[r, b, 0])
                h1 += k * (P[r, a, 1] - P[r, b, 1])
                h2 += k * (P[r, a, 2] - P[r, b, 2])
            v0 = P[r + S, c, 0] - P[r - S, c, 0]
            v1 = P[r + S, c, 1] - P[r - S, c, 1]
            v2 = P[r + S, c, 2] - P[r - S, c, 2]
            n0 = h1 * v2 - h2 * v1
            n1 = h2 * v0 - h0 * v2
            n2 = h0 * v1 - h1 * v0
            nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            lh2 = h0 * h0 + h1 * h1 + h2 * h2
            lv2 = v0 * v0 + v1 * v1 + v2 * v2
            e = sigma * np.sqrt(s2 / lh2 + 2.0 / lv2)
            if not (np.isfinite(nn) and nn > 0 and np.isfinite(e)):
                continue
            n0, n1, n2 = n0 / nn, n1 / nn, n2 / nn
            a = wrap[c + 2 * K]
            b = wrap[c]
            for j in range(3):
                q[0, j] = P[r, a, j]
                q[1, j] = P[r, b, j]
                q[2, j] = P[r + S, c, j]
                q[3, j] = P[r - S, c, j]
            good = True
            for m in range(4):
                d0, d1, d2 = q[m, 0] - p0, q[m, 1] - p1, q[m, 2] - p2
                res = abs(d0 * n0 + d1 * n1 + d2 * n2)
                if res > tol + ks * e * np.sqrt(d0 * d0 + d1 * d1 + d2 * d2):
                    good = False
                    break
            if good:
                ok[r, c] = True
                err[r, c] = e
                normal[r, c, 0] = n0
                normal[r, c, 1] = n1
                normal[r, c, 2] = n2
    return normal, err, ok
