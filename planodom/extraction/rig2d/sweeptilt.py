"""One scanner's lines of several sweeps against the plane they were grouped into (2D rig).

The grouping (:mod:`.grouping`) makes a plane of two traces of two scanners that cross and
are coplanar. Two lines of two scanners on two different walls are coplanar too when they
meet at the walls' common edge, extended: two near-level lines at one height on two walls
make a level "plane" between them (world 20 at 6 mm: 22 such planes in 150 epochs, 84-90
deg from the walls whose points they hold, declared sigma 0.01-0.1 deg; ``docs/RESULTS.md``).
Each scanner's own lines tell them apart. A scanner sees a surface along one line per
sweep; the motion between sweeps moves that line over the surface, so its deskewed lines
of several sweeps are displaced *within* the true surface (they span it with the line's
direction), and on a plane that is not the surface they are displaced *across* it (on the
level plane between two walls, each scanner's lines climb its wall). :func:`tilted_rings`
names the rings whose lines, by their segments' centroids against time, move farther
across the plane than within it, beyond their noise: the surface the ring's lines span is
then more than 45 deg from the plane. No threshold of its own: 45 deg is "closer to another plane
than to this one", the noise is the extraction's sigma times ``member_sigma_factor``, and
the climb over the ring's time span must exceed the member tolerance (whose floor,
``tolerance_floor_m``, holds the deskewing's residue: without it the test took true walls,
whose lines a twist error moves across them).
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.rig2d.segments import Segments


def tilted_rings(
    segs: Segments,
    group: np.ndarray,
    normal: np.ndarray,
    seg_times: np.ndarray,
    sigma_m: float,
    factor: float,
    tol_m: float,
) -> list[int]:
    """The rings of ``group`` (K,) segment indices whose lines move with time farther
    along ``normal`` (3,) than across the ring's line within the plane: the slopes
    ``alpha`` (along the normal) and ``beta`` (within the plane, across the line) of the
    ring's segment centroids against their mean times ``seg_times`` (S,) s (least squares,
    weighted by point counts), with ``|alpha| - |beta|`` above ``factor`` times its noise
    ``sigma_m sqrt(2 / S_tt)`` (m/s; ``S_tt`` the count-weighted sum of squared time
    deviations) and, over the ring's time span, above ``tol_m`` (m, the member
    tolerance, whose floor holds the deskewing's residue): the lines leave the plane.
    Times, not the segments' sweep ids: a scanner without a dead angle has no time gap
    between its sweeps, so one id may hold several."""
    rings = segs.ring[group]
    bad = []
    for r in np.unique(rings):
        mine = group[rings == r]
        if len(mine) < 2:
            continue
        n_k = segs.count[mine].astype(np.float64)
        tau = seg_times[mine]
        dt = tau - (n_k @ tau) / n_k.sum()
        s_tt = float(n_k @ dt**2)
        if not s_tt > 0:
            continue
        u = segs.direction[mine]
        u = u * np.where(u @ u[0] < 0, -1.0, 1.0)[:, None]
        u = (n_k[:, None] * u).sum(axis=0)
        u -= (u @ normal) * normal
        if not np.linalg.norm(u) > 0:
            continue
        w = np.cross(normal, u / np.linalg.norm(u))
        c = segs.centroid[mine]
        alpha = float((n_k * dt) @ (c @ normal)) / s_tt
        beta = float((n_k * dt) @ (c @ w)) / s_tt
        excess = abs(alpha) - abs(beta)
        if excess > factor * sigma_m * np.sqrt(2.0 / s_tt) and excess * np.ptp(tau) > tol_m:
            bad.append(int(r))
    return bad
