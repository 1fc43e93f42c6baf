"""RANSAC planes that cut across other surfaces: refused by the pixel normals of their points.

When the range image of a ringed scan is too noisy to grow regions on (a 64-beam lidar's
rows 0.4 deg apart at 2 cm: :func:`.normals.pixel_normals` declines), the RANSAC loop
finds the planes. Among dozens of facades seen at 20-80 m, it also finds "planes" that no
surface holds: a plane cutting a few centimetres deep through the scan lines of several
facades at different depths (near facades' lower lines, far facades' upper ones) gathers
20-160 points within the member tolerance, flat to the noise (measured on a procedural
64-beam world at 2 cm: about 25 of 45 planes an epoch, near level, each on vertical
facades; they froze the odometry's roll and pitch, 0.16 deg rms per epoch against the
oracle's 0.0007). Each point of such a set lies on a facade, and the pixel normal there
(its scan line's tangent crossed with the tangent across rows, however noisy) is the
facade's, tens of degrees from the cut's normal; on a true plane the pixel normals agree
with the plane's within their noise. :func:`cutting_planes` flags a fit when most of its
inliers that have a pixel normal disagree with it by more than
``ransac_normal_agreement_deg``.
"""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.lidar.grid import grid_indices, point_grid
from planodom.extraction.lidar.normals import first_row_step
from planodom.extraction.memo import float64_c
from planodom.extraction.noise import member_tolerance

#: Fewest inliers with a pixel normal that judge a plane (a cut through other surfaces'
#: scan lines keeps few: measured 0-17 of its 20-160 inliers on a 64-beam world at 2 cm).
MIN_JUDGED = 3


def point_normals(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sigma: float,
    config: ExtractionConfig,
) -> tuple[np.ndarray, np.ndarray] | None:
    """(N, 3) the pixel normal of every point (its pixel's, rows ``r +- 1``, window
    ``region_window``) and (N,) bool whether it has one; None without a grid (no usable
    times). ``points`` (N, 3) m, ``ring`` (N,), ``t`` (N,) s, ``sigma`` m."""
    row, col, H, W = grid_indices(ring, t)
    if col is None or H < 3:
        return None
    flat = row * W + col
    P = point_grid(float64_c(points), row, col, H, W)
    tol = member_tolerance(config, sigma)
    K = max(1, int(config.region_window))
    n, _, ok = first_row_step(P, K, float(sigma), float(tol), float(config.region_normal_sigmas))
    return n.reshape(-1, 3)[flat], ok.reshape(-1)[flat]


def cutting_planes(
    normals: np.ndarray,
    members: list[np.ndarray],
    point_normal: np.ndarray,
    has_normal: np.ndarray,
    config: ExtractionConfig,
) -> np.ndarray:
    """(G,) bool: whether each plane (unit ``normals`` (G, 3), inlier indices ``members``)
    is refused: more than half of its inliers that have a pixel normal (``point_normal``
    (N, 3), ``has_normal`` (N,)) differ from it by more than
    ``config.ransac_normal_agreement_deg`` (sign-free; None: none is). A plane with
    fewer than :data:`MIN_JUDGED` such inliers is kept: there is nothing to judge it by
    (refused with ``config.ransac_unjudged: refused``)."""
    angle = config.ransac_normal_agreement_deg
    if angle is None:
        return np.zeros(len(members), dtype=bool)
    limit = np.cos(np.radians(angle))
    unjudged = config.ransac_unjudged == "refused"
    out = np.zeros(len(members), dtype=bool)
    for g, idx in enumerate(members):
        own = idx[has_normal[idx]]
        if len(own) < MIN_JUDGED:
            out[g] = unjudged
            continue
        agree = np.abs(point_normal[own] @ normals[g]) >= limit
        out[g] = np.count_nonzero(agree) * 2 < len(own)
    return out
