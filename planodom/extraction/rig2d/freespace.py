"""Free space: rays that pass through a plane's support (2D rig, sensor origins per ring).

A surface is opaque: no ray of any scanner crosses it where it was seen and hits something
behind it. A plane the grouping joined from lines of two scanners on two different walls
(two near-level lines at one height on two walls, coplanar by chance: world 20 at 6 mm,
``docs/RESULTS.md``) spans the free space between those walls, and the rays of every
scanner to the floor, the walls and the ceiling beyond cross it inside its support.
"""

from __future__ import annotations

import numpy as np


def pierce_counts(
    normal: np.ndarray,
    offset: float,
    polygon: np.ndarray,
    points: np.ndarray,
    origins: np.ndarray,
    tol_m: float,
) -> int:
    """How many rays ``origins[i] -> points[i]`` cross the plane ``normal . p + offset = 0``
    inside its support ``polygon`` (M, 3) m (convex, vertices in order, on the plane)
    shrunk by ``tol_m``, with both the origin and the point farther than ``tol_m`` from
    the plane on either side. ``points``, ``origins`` (N, 3) m, one frame."""
    if len(polygon) < 3 or len(points) == 0:
        return 0
    s_o = origins @ normal + offset
    s_p = points @ normal + offset
    cross = (s_o * s_p < 0) & (np.abs(s_p) > tol_m) & (np.abs(s_o) > tol_m)
    if not cross.any():
        return 0
    o, p = origins[cross], points[cross]
    f = s_o[cross] / (s_o[cross] - s_p[cross])
    q = o + f[:, None] * (p - o)
    return int(np.count_nonzero(_inside(q, polygon, normal, tol_m)))


def _inside(q: np.ndarray, polygon: np.ndarray, normal: np.ndarray, margin: float) -> np.ndarray:
    """(K,) bool: points ``q`` (K, 3) on the plane inside the convex ``polygon`` (M, 3) by
    at least ``margin`` m from every edge."""
    keep = np.linalg.norm(np.roll(polygon, -1, axis=0) - polygon, axis=1) > 1e-9
    polygon = polygon[keep]  # a repeated vertex (a closed ring) has no edge
    if len(polygon) < 3:
        return np.zeros(len(q), dtype=bool)
    edge = np.roll(polygon, -1, axis=0) - polygon
    inward = np.cross(normal, edge)
    c = polygon.mean(axis=0)
    sign = np.sign(np.einsum("mi,mi->m", inward, c - polygon))
    inward = inward * sign[:, None] / np.maximum(np.linalg.norm(inward, axis=1), 1e-12)[:, None]
    dist = np.einsum("mi,kmi->km", inward, q[:, None, :] - polygon[None, :, :])
    return np.all(dist >= margin, axis=1)
