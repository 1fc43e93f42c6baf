"""Planes of an unorganised spinning-lidar cloud (no ring, no time) on a recovered range
image of square angular pixels.

1. Rows: :func:`.rows.scan_rows` (ring-major runs of the azimuth, else modes of the
   elevation), seen from the sensor origin. H rows.
2. Columns: azimuth bins of the same angular size as the mean row spacing
   ``dv = (elevation span of the row means) / (H - 1)``, ``W = round(2 pi / dv)`` (at
   most the point count of the fullest row): square pixels in angle, so that the pixel
   normals' two tangents have similar lengths. A pixel is the mean of its points; its
   noise is ``sigma / sqrt(m)`` (m: median points per filled pixel), sigma measured along
   the rows (:func:`.candidates.ring_noise`). At native resolution (one point per pixel)
   pixel normals of real lidars are too noisy: at 0.18 deg azimuth steps and 1 cm noise a
   7-point window's normal is off by ~7 deg at 10 m.
3. Region growing: the kernels of :mod:`.rangeimage` (pixel normals, edges, union-find)
   on this grid; the pixel normals' window is ``region_window`` pixels wide but at most
   ``organised_window_deg`` of azimuth (:func:`organised_window`: a 16-beam lidar's 2 deg
   pixels would otherwise make it 6 deg on each side). The gap rule (:mod:`.rangeimage`)
   with ``organised_gap: range`` is unscaled: a 16-beam lidar's 2 deg pixels then cut
   every plane seen at under 20 deg, the floor and ceiling of a room beyond 5 m
   (measured on an indoor 16-beam world at 6 mm without times: 4 planes, no floor or
   ceiling). With
   ``incidence`` its step is the native column step (``2 pi / n``, n: the point count of
   the fullest row): pixels ``dv`` apart on a plane get the incidence limit the rule
   gives consecutive points of a scan line (there: 7 planes, floor and ceiling found),
   but KITTI's HDL-64E cloud (pixels ~2.3 native columns wide) measured worse with it
   (:class:`planodom.config.ExtractionConfig`).
4. Pieces that region growing chained over a curved or bent surface (a cambered road, a
   bent facade) are cut by their two in-plane principal axes, recursively (a quadtree in
   the piece's own frame: no tile size to choose), until every part is flat to
   ``max(max_rms_sigma_factor * sigma, rms_floor_m)`` (:func:`split_curved`).
5. Coplanar pieces are merged: grid neighbours (as :mod:`.rangeimage` step 3) and, anywhere
   in the scan, pieces whose bounding circles come within ``plane_gap_m`` (one facade cut
   by a tree, a car or a pole becomes one plane with one covariance): normals within
   ``region_merge_deg + 3 (e_a + e_b)``, each centroid within the member tolerance of the
   other's plane.
6. Every point joins its pixel's plane (or a 3 x 3 neighbour's) within the member
   tolerance (:func:`.grid.assign_points`). These sets are the candidates; the caller
   fits them (plain TLS: membership already applied the tolerance) and the plane builder
   applies the plane tests.

Deterministic: no sampling; pieces and planes are numbered in grid order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.lidar.candidates import ring_noise, ring_noise_in_order
from planodom.extraction.lidar.grid import (
    assign_points,
    near_pairs,
    plane_members,
    ring_order,
)
from planodom.extraction.lidar.normals import _pixel_normals
from planodom.extraction.lidar.rangeimage import (
    _NEIGHBOURS,
    _grow_pieces,
    _piece_moments,
    merge_coplanar,
    moment_sums,
    within_reach,
)
from planodom.extraction.lidar.rows import azimuth
from planodom.extraction.noise import effective_noise, member_tolerance, rms_limit
from planodom.geometry import row_norms


@dataclass(frozen=True, eq=False)
class OrganisedCandidates:
    """What :func:`organised_candidates` found.

    Attributes:
        candidates: per candidate plane, (K,) int64 indices into the points.
        sigma_m: the point noise sigma (m) the tolerances were scaled with.
        grid: (H, W) rows and columns of the recovered range image.
    """

    candidates: list[np.ndarray]
    sigma_m: float
    grid: tuple[int, int]


@numba.njit(cache=True)
def _mean_grid(points, flat, n_pix):  # pragma: no cover - compiled
    """(n_pix, 3) mean point of every pixel (NaN: none) and (n_pix,) point counts."""
    S = np.zeros((n_pix, 3))
    cnt = np.zeros(n_pix)
    for i in range(flat.shape[0]):
        f = flat[i]
        cnt[f] += 1.0
        for k in range(3):
            S[f, k] += points[i, k]
    for f in range(n_pix):
        for k in range(3):
            S[f, k] = S[f, k] / cnt[f] if cnt[f] > 0 else np.nan
    return S, cnt


def grid_of(points: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, int, int]:
    """Column (N,) int64 and grid size (H, W) of square angular pixels (step 2) for
    sensor-centred ``points`` (N, 3) and their ``rows`` (N,) int64."""
    H = int(rows.max()) + 1
    r = row_norms(points)
    el = np.arcsin(np.clip(points[:, 2] / np.maximum(r, 1e-9), -1.0, 1.0))
    counts = np.bincount(rows, minlength=H)
    filled = counts > 0
    mean = np.bincount(rows, el, minlength=H)[filled] / counts[filled]
    dv = (mean.max() - mean.min()) / max(len(mean) - 1, 1)
    W = int(min(max(np.rint(2 * np.pi / max(dv, 1e-6)), 16), counts.max()))
    col = np.floor((azimuth(points) + np.pi) / (2 * np.pi) * W).astype(np.int64) % W
    return col, H, W


def split_curved(
    P: np.ndarray, piece: np.ndarray, C: int, max_rms: float, min_width: float, min_px: int
) -> tuple[np.ndarray, int]:
    """Step 4 on pixel points ``P`` (H * W, 3) labelled ``piece`` (H * W,) (C pieces):
    the new labels (-1: none) and their count. Parts under ``min_px`` pixels or thinner
    than ``min_width`` (m, ``2 sqrt(l2 / n)``: lines) are dropped. Level by level: all
    parts of a level are tested at once (one compiled moment pass, batched eigen-solver);
    flat parts are numbered in the order of their level and their index in it."""
    label = piece.copy()
    out = np.full(piece.shape[0], -1, dtype=np.int64)
    n, n_out = C, 0
    while n > 0:
        cnt, cen, sc = _piece_moments(P, label, n)
        ev, V = np.linalg.eigh(sc)
        safe = np.maximum(cnt, 1.0)
        alive = (cnt >= min_px) & (2.0 * np.sqrt(np.maximum(ev[:, 1], 0.0) / safe) >= min_width)
        flat = alive & (np.sqrt(np.maximum(ev[:, 0], 0.0) / safe) <= max_rms)
        split = alive & ~flat
        number = np.full(n + 1, -1, dtype=np.int64)  # index n: pixels without a part
        number[:n][flat] = n_out + np.arange(np.count_nonzero(flat))
        n_out += int(np.count_nonzero(flat))
        part = np.where(label >= 0, label, n)
        taken = number[part] >= 0
        out[taken] = number[part[taken]]
        idx = np.flatnonzero(np.r_[split, False][part])
        g = label[idx]
        d = P[idx] - cen[g]
        quadrant = 2 * (np.einsum("ij,ij->i", d, V[g, :, 2]) >= 0) + (
            np.einsum("ij,ij->i", d, V[g, :, 1]) >= 0
        )
        rank = np.cumsum(split) - 1
        label = np.full(piece.shape[0], -1, dtype=np.int64)
        label[idx] = 4 * rank[g] + quadrant
        n = 4 * int(np.count_nonzero(split))
    return out, n_out


def organised_candidates(
    points: np.ndarray, rows: np.ndarray, origin: np.ndarray, config: ExtractionConfig
) -> OrganisedCandidates:
    """Candidate inlier sets of the cloud ``points`` (N, 3), m, with recovered ``rows``
    (N,) int64, seen from ``origin`` (3,) m (module docstring)."""
    rel = np.ascontiguousarray(points - origin, dtype=np.float64)
    rows = np.asarray(rows, dtype=np.int64)
    if np.all(rows[1:] >= rows[:-1]):  # ring-major: rows in file order, each in azimuth order
        sigma = effective_noise(config, ring_noise(rel, rows, config))
    else:  # within a row in azimuth order, whatever the file order
        order = _row_azimuth_order(rel, rows)
        sigma = effective_noise(config, ring_noise_in_order(rel, order, rows, config))
    col, H, W = grid_of(rel, rows)
    P, cnt_pix = _mean_grid(rel, rows * W + col, H * W)
    m = float(np.median(cnt_pix[cnt_pix > 0]))
    sigma_pix = sigma / np.sqrt(max(m, 1.0))
    P = P.reshape(H, W, 3)
    ks = float(config.region_normal_sigmas)
    tol_pix = member_tolerance(config, sigma_pix)
    n, e, ok = _pixel_normals(P, organised_window(config, W), 1, sigma_pix, tol_pix, ks)
    min_px = max(3, config.min_plane_points // 2 // max(int(m), 1))
    native_step = 2.0 * np.pi / float(np.bincount(rows).max())  # rad, a native column
    piece, C = _grow_pieces(
        P, n, e, ok, float(tol_pix), ks, float(np.radians(config.region_normal_floor_deg)),
        float(config.min_gap_m), float(config.gap_range_ratio), np.zeros(3), min_px,
        _gap_step(config, native_step),
    )  # fmt: skip
    empty = OrganisedCandidates([], sigma, (H, W))
    if C == 0:
        return empty
    Pf = P.reshape(-1, 3)
    # Flat to the point noise (not the pixel noise: pixel means of a real wall keep the
    # lasers' range biases, which averaging over a pixel does not remove).
    piece, C = split_curved(
        Pf, piece, C, rms_limit(config, sigma), config.min_plane_width_m, min_px
    )
    if C == 0:
        return empty
    tol = member_tolerance(config, sigma)
    label, normal, offset, C = _merge_coplanar(Pf, piece.reshape(H, W), C, sigma_pix, tol, config)
    owner = assign_points(
        rel, rows, col, np.ascontiguousarray(label), np.ascontiguousarray(normal),
        offset, float(tol), _NEIGHBOURS,
    )  # fmt: skip
    idx, bounds = plane_members(owner, C)
    sets = [idx[bounds[k] : bounds[k + 1]] for k in range(C)]
    return OrganisedCandidates([s for s in sets if len(s) >= 3], sigma, (H, W))


def _row_azimuth_order(rel: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(N,) int64 ``np.lexsort((azimuth(rel), rows))`` of ``rel`` (N, 3) and ``rows`` (N,)
    int64, the same permutation: for rows from 0 and finite azimuths, a stable counting
    sort by row (:func:`.grid.ring_order`), then a stable sort of each row's azimuths
    (numpy's timsort: a ring in firing order is two sorted runs; lexsort sorts all the
    azimuths at once, 9x slower on the 6 * 10^4 points of an HDL-32E sweep)."""
    az = azimuth(rel)
    if rows.min() < 0 or np.isnan(az).any():
        return np.lexsort((az, rows))
    H = int(rows.max()) + 1
    by_row = ring_order(rows, H)
    bounds = np.r_[0, np.cumsum(np.bincount(rows, minlength=H))]
    order = np.empty_like(by_row)
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        idx = by_row[a:b]
        order[a:b] = idx[np.argsort(az[idx], kind="stable")]
    return order


def organised_window(config: ExtractionConfig, W: int) -> int:
    """Half-width (pixels, at least 1) of the row tangent on a grid of ``W`` columns:
    ``region_window``, capped at ``organised_window_deg`` of azimuth."""
    K = max(1, int(config.region_window))
    if config.organised_window_deg is None:
        return K
    pixel_deg = 360.0 / W
    return max(1, min(K, int(np.floor(config.organised_window_deg / pixel_deg + 1e-9))))


def _gap_step(config: ExtractionConfig, native_step: float) -> float:
    """The angular step (rad) the gap ratio refers to (``organised_gap``; 0: unscaled).
    grazing: pixels ``a`` apart get the ratio ``max(1, a / step)`` times, which keeps
    whole a plane seen at more than ``organised_min_incidence_deg`` (pixel neighbours
    on it are ``range * a / sin(incidence)`` apart, :mod:`.rangeimage`)."""
    if config.organised_gap == "incidence":
        return native_step
    if config.organised_gap == "grazing":
        incidence = np.radians(config.organised_min_incidence_deg)
        return config.gap_range_ratio * float(np.sin(incidence))
    return 0.0


def _merge_coplanar(
    Pf: np.ndarray,
    label: np.ndarray,
    C: int,
    sigma_pix: float,
    tol: float,
    config: ExtractionConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Step 5: the merged pixel labels (H, W), plane normals (C', 3), offsets (C',) and
    their number C'."""
    cnt, cen, sc = _piece_moments(Pf, label.reshape(-1), C)
    vals, vecs = np.linalg.eigh(sc)
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    W = label.shape[1]
    gap_cols = max(1, int(np.ceil(np.radians(config.cluster_gap_deg) / (2 * np.pi / W))))
    near = np.unique(near_pairs(label, C, gap_cols))
    a, b = near // C, near % C
    a, b = within_reach(a, b, cnt, cen, vals, config.plane_gap_m)
    if len(a) == 0:
        return label, normal, offset, C
    err = sigma_pix / np.sqrt(np.maximum(vals[:, 1], 1e-300))
    M, merged = merge_coplanar(a, b, normal, offset, cen, err, tol, config.region_merge_deg)
    if M == C:
        return label, normal, offset, C
    cnt, cen, sc = moment_sums(merged, M, cnt, cen, sc)
    vecs = np.linalg.eigh(sc)[1]
    normal = vecs[:, :, 0]
    offset = -np.einsum("ij,ij->i", normal, cen)
    label = np.where(label >= 0, merged[np.maximum(label, 0)], -1)
    return label, normal, offset, M
