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

from typing import NamedTuple

import numba
import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction.lidar.grid import grid_indices, point_grid
from planodom.extraction.lidar.normals import first_row_step
from planodom.extraction.memo import float64_c
from planodom.extraction.noise import member_tolerance

#: Fewest inliers with a pixel normal that judge a plane (a cut through other surfaces'
#: scan lines keeps few: measured 0-17 of its 20-160 inliers on a 64-beam world at 2 cm).
MIN_JUDGED = 3


class PointNormals(NamedTuple):
    """The pixel normals of a scan's grid and each point's pixel: a point's normal is
    looked up only when a plane's inliers are judged (not for all N points)."""

    #: (M, 3) unit pixel normals of the grid's M pixels (rows of the grid, flattened)
    normals: np.ndarray
    #: (M,) bool: whether the pixel has a normal
    has: np.ndarray
    #: (N,) int: each point's pixel (index into ``normals``)
    pixel: np.ndarray

    def judged(self, idx: np.ndarray) -> np.ndarray:
        """(k, 3) the pixel normals of those points ``idx`` (int array) that have one,
        in the order of ``idx``."""
        pix = self.pixel[idx]
        return self.normals[pix[self.has[pix]]]


def point_normals(
    points: np.ndarray,
    ring: np.ndarray,
    t: np.ndarray | None,
    sigma: float,
    config: ExtractionConfig,
) -> PointNormals | None:
    """The pixel normals of the points' grid (rows ``r +- 1``, window ``region_window``)
    and each point's pixel; None without a grid (no usable times). ``points`` (N, 3) m,
    ``ring`` (N,), ``t`` (N,) s, ``sigma`` m."""
    row, col, H, W = grid_indices(ring, t)
    if col is None or H < 3:
        return None
    P = point_grid(float64_c(points), row, col, H, W)
    tol = member_tolerance(config, sigma)
    K = max(1, int(config.region_window))
    n, _, ok = first_row_step(P, K, float(sigma), float(tol), float(config.region_normal_sigmas))
    return PointNormals(n.reshape(-1, 3), ok.reshape(-1), row * W + col)


def cutting_planes(
    normals: np.ndarray,
    members: list[np.ndarray],
    found: PointNormals,
    config: ExtractionConfig,
) -> np.ndarray:
    """(G,) bool: whether each plane (unit ``normals`` (G, 3), inlier indices ``members``)
    is refused: more than half of its inliers that have a pixel normal (``found``)
    differ from it by more than
    ``config.ransac_normal_agreement_deg`` (sign-free; None: none is). A plane with
    fewer than :data:`MIN_JUDGED` such inliers is kept: there is nothing to judge it by
    (refused with ``config.ransac_unjudged: refused``)."""
    angle = config.ransac_normal_agreement_deg
    if angle is None or not members:
        return np.zeros(len(members), dtype=bool)
    limit = np.cos(np.radians(angle))
    unjudged = config.ransac_unjudged == "refused"
    bounds = np.zeros(len(members) + 1, dtype=np.int64)
    np.cumsum([len(m) for m in members], out=bounds[1:])
    out, unsure = _verdicts(
        np.ascontiguousarray(found.normals, dtype=np.float64), found.has, found.pixel,
        np.concatenate(members).astype(np.int64), bounds,
        np.ascontiguousarray(normals, dtype=np.float64), float(limit), unjudged,
    )  # fmt: skip
    for g in np.flatnonzero(unsure):  # a product within rounding of the limit
        own = found.judged(members[g])
        agree = np.abs(own @ normals[g]) >= limit
        out[g] = np.count_nonzero(agree) * 2 < len(own)
    return out


#: Relative margin of :func:`_verdicts`' sure verdicts: a 3-term dot product of unit
#: vectors is within ``3 u sum |a_i b_i|`` (u = 2^-53) of the exact one, however it is
#: summed (numpy's BLAS ``gemv`` with FMA, or in order), so two ways of computing it agree
#: on ``|a . b| >= limit`` wherever it is farther than this from the limit.
_SURE = 1e-12


@numba.njit(cache=True)
def _verdicts(pix_n, has, pixel, flat, bounds, normals, limit, unjudged):  # pragma: no cover
    """(G,) refused and (G,) unsure of :func:`cutting_planes`, plane g's inliers
    ``flat[bounds[g]:bounds[g + 1]]`` judged by the pixel normals ``pix_n`` (M, 3) of
    their pixels ``pixel`` that have one (``has``), in one compiled pass: the per-plane
    numpy gathers and product cost ~1 ms an extraction of a 64-beam room. A plane is
    unsure when a judged product lies within :data:`_SURE` (relative) of the limit:
    its verdict is then the numpy product's (the caller), so that every verdict is the
    per-plane numpy one (tests/extraction/test_agreement.py)."""
    G = bounds.shape[0] - 1
    out = np.zeros(G, dtype=np.bool_)
    unsure = np.zeros(G, dtype=np.bool_)
    for g in range(G):
        n0, n1, n2 = normals[g, 0], normals[g, 1], normals[g, 2]
        judged = 0
        agree = 0
        for k in range(bounds[g], bounds[g + 1]):
            q = pixel[flat[k]]
            if not has[q]:
                continue
            judged += 1
            a0, a1, a2 = pix_n[q, 0] * n0, pix_n[q, 1] * n1, pix_n[q, 2] * n2
            d = abs(a0 + a1 + a2)
            scale = max(abs(a0) + abs(a1) + abs(a2), 1.0)
            if not abs(d - limit) > _SURE * scale:  # NaN too
                unsure[g] = True
            if d >= limit:
                agree += 1
        if judged < MIN_JUDGED:
            out[g] = unjudged
            unsure[g] = False  # no product decides it
        else:
            out[g] = agree * 2 < judged
    return out, unsure
