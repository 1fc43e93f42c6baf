"""Group straight segments of different rings and sweeps into planes.

Two segments seed a plane only when they come from different rings (scanners) and cross
at ``min_cross_angle_deg`` or more: the segments of one ring lie in (nearly) one scan
plane, so two of them on different walls would "determine" the scan plane itself, and
two of them on one wall are parallel (successive sweeps). A seed pair must also be
coplanar within the tolerance. Every other segment (of any ring and sweep, parallel or
not) joins a seeded plane when both its end points lie within the tolerance of it.

Seeds are taken greedily, the one whose plane gathers the most points first; its plane is
refit from the members' moments (total least squares) and its members re-collected until
they no longer change. A seed whose own segments do not stay in its refit plane is
dropped. Members of an accepted plane are not used again. So a group always contains two
non-parallel traces of two different scanners: a set of parallel traces is never
accepted, and a plane is never guessed from one trace.
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.segments import Segments


def combined_fit(segs: Segments, members: np.ndarray) -> tuple[np.ndarray, float, float]:
    """Total-least-squares plane of the union of the segments ``members`` (bool (S,)).

    Uses the parallel-axis theorem on the segments' centred scatter matrices, so no point
    is touched. Returns the unit normal (3,), offset d (m) and RMS residual (m).
    """
    cnt = segs.count[members].astype(np.float64)
    cen = segs.centroid[members]
    total = cnt.sum()
    c = (cnt[:, None] * cen).sum(axis=0) / total
    dc = cen - c
    scatter = segs.scatter[members].sum(axis=0) + (
        cnt[:, None, None] * dc[:, :, None] * dc[:, None, :]
    ).sum(axis=0)
    vals, vecs = np.linalg.eigh(scatter)
    n = vecs[:, 0]
    return n, float(-n @ c), float(np.sqrt(max(vals[0], 0.0) / total))


def _within(segs: Segments, n: np.ndarray, d: float, tol: float) -> np.ndarray:
    """(S,) bool: both end points of each segment within ``tol`` of the plane (n, d)."""
    dist_c = np.abs(segs.centroid @ n + d)
    tilt = np.abs(segs.direction @ n) * 0.5 * segs.length
    return dist_c + tilt <= tol


def group_segments(
    segs: Segments,
    tol_m: float,
    sigma_m: float,
    min_cross_angle_deg: float,
    max_seed_direction_error_deg: float,
    min_points: int,
    max_rms_m: float,
    margin_m: float = 0.2,
) -> tuple[list[np.ndarray], int]:
    """Segments grouped into planes.

    Args:
        segs: the epoch's segments.
        tol_m: distance (m) within which a segment's ends must lie of a plane to join it.
        sigma_m: noise sigma (m); predicts each segment's direction error
            ``sigma sqrt(12 / N) / length`` (rad).
        min_cross_angle_deg: smallest angle between a seed pair's directions (deg).
        max_seed_direction_error_deg: largest predicted direction error of a seed (deg).
        min_points: fewest points of a group.
        max_rms_m: largest RMS residual (m) of a group's points to its plane.
        margin_m: an L-shaped seed pair has its crossing within this (m) of both ends.

    Returns:
        A list of (K,) int64 arrays of segment indices, one per plane, and the number of
        seeds rejected after refitting.
    """
    S = len(segs)
    if S < 2:
        return [], 0
    dir_err = sigma_m * np.sqrt(12.0 / segs.count) / np.maximum(segs.length, 1e-9)
    seeds = np.flatnonzero(dir_err <= np.radians(max_seed_direction_error_deg))
    a, b = np.triu_indices(len(seeds), 1)
    iu, ju = seeds[a], seeds[b]
    keep = segs.ring[iu] != segs.ring[ju]
    iu, ju = iu[keep], ju[keep]
    cross = np.cross(segs.direction[iu], segs.direction[ju])
    sin_a = np.linalg.norm(cross, axis=1)
    keep = sin_a >= np.sin(np.radians(min_cross_angle_deg))
    iu, ju, cross, sin_a = iu[keep], ju[keep], cross[keep], sin_a[keep]
    normals = cross / sin_a[:, None]
    mid = 0.5 * (segs.centroid[iu] + segs.centroid[ju])
    offs = -np.einsum("ij,ij->i", normals, mid)
    sep = segs.centroid[iu] - segs.centroid[ju]
    gap = np.abs(np.einsum("ij,ij->i", normals, sep))
    # The pair's normal is uncertain by about (err_i + err_j) / sin(angle) (rad).
    slack = np.linalg.norm(sep, axis=1) * 2.0 * (dir_err[iu] + dir_err[ju]) / sin_a
    keep = gap <= tol_m + slack
    # Two lines that meet are coplanar: the traces of two scanners on two walls that
    # meet at a corner, each ending at the corner, look like one plane when they reach
    # the corner at the same point. Such an L (the crossing point at an end of both
    # segments) is ambiguous and seeds nothing; X, T and V shapes do.
    ui, uj = segs.direction[iu], segs.direction[ju]
    a_ = np.einsum("ij,ij->i", ui, uj)
    wi, wj = np.einsum("ij,ij->i", ui, sep), np.einsum("ij,ij->i", uj, sep)
    den = np.maximum(1.0 - a_ * a_, 1e-12)
    s_i = (a_ * wj - wi) / den
    s_j = (wj - a_ * wi) / den
    hi, hj = 0.5 * segs.length[iu], 0.5 * segs.length[ju]
    at_end_i = np.abs(np.abs(s_i) - hi) <= np.maximum(margin_m, 0.05 * hi)
    at_end_j = np.abs(np.abs(s_j) - hj) <= np.maximum(margin_m, 0.05 * hj)
    keep &= ~(at_end_i & at_end_j)
    iu, ju, normals, offs = iu[keep], ju[keep], normals[keep], offs[keep]
    if len(iu) == 0:
        return [], 0
    # Many pairs (sweeps x sweeps of two scanners on one wall) seed the same plane: keep
    # one per cell of (normal, offset) space (cells of ~0.6 deg and of the tolerance).
    sgn = np.where(offs < 0, -1.0, 1.0)
    key = np.column_stack(
        [np.round(normals * sgn[:, None] / 0.01), np.round(offs * sgn / max(tol_m, 1e-3))]
    ).astype(np.int64)
    _, first = np.unique(key, axis=0, return_index=True)
    first.sort()
    iu, ju, normals, offs = iu[first], ju[first], normals[first], offs[first]
    # Membership of every segment in every candidate plane: (P, S).
    dist_c = np.abs(normals @ segs.centroid.T + offs[:, None])
    tilt = np.abs(normals @ segs.direction.T) * (0.5 * segs.length)[None, :]
    member = (dist_c + tilt) <= tol_m
    weight = segs.count.astype(np.float64)
    scores = member @ weight
    alive = np.ones(len(iu), dtype=bool)
    available = np.ones(S, dtype=bool)
    groups: list[np.ndarray] = []
    rejected = 0
    while True:
        masked = np.where(alive, scores, -1.0)
        p = int(np.argmax(masked))
        if masked[p] < min_points:
            break
        alive[p] = False
        members = member[p] & available
        for _ in range(5):
            n, d, rms = combined_fit(segs, members)
            new = _within(segs, n, d, tol_m) & available
            if np.array_equal(new, members) or np.count_nonzero(new) < 2:
                break
            members = new
        n, d, rms = combined_fit(segs, members)
        if (
            not (members[iu[p]] and members[ju[p]])
            or weight[members].sum() < min_points
            or rms > max_rms_m
        ):
            rejected += 1
            # Seeds that both fall in this rejected set would grow into it again.
            alive &= ~(members[iu] & members[ju])
            continue
        idx = np.flatnonzero(members)
        groups.append(idx)
        available[idx] = False
        alive &= available[iu] & available[ju]
        scores -= member[:, idx] @ weight[idx]
    return groups, rejected
