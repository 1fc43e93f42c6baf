"""The plane map's tie rule between gated landmarks (``planemap.tie_rule``), on
synthetic landmarks whose true surfaces are known."""

from __future__ import annotations

import numpy as np
from planemap_factory import plane_points

from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.register import ScanPlanes, associate, candidates

SIGMA = 0.006
BIAS = 0.02
UP = np.array([0.0, 0.0, 1.0])


def _map(sets: list[np.ndarray], rows: list[float]) -> PlaneMap:
    """Landmarks of the point sets (world frame), first seen in scan 0."""
    M = PlaneMap()
    M.add(Moments.of_points(sets, np.array(rows)), np.tile(UP, (len(sets), 1)), 0,
          np.arange(len(sets)))  # fmt: skip
    M.refit(SIGMA, BIAS)
    return M


def _scan(points: np.ndarray, rows: float) -> ScanPlanes:
    return ScanPlanes.of(Moments.of_points([points], np.array([rows])), UP[None], SIGMA, BIAS)


def test_a_stale_weak_duplicate_passes_the_gate_but_the_live_landmark_wins() -> None:
    """World 75's case: the ground's live landmark (45,000 points over 60 lines, its
    offset 3 mm below the surface, as a map a few scans old) and a stale one of the same
    ground (25 points on one line at the plane's edge) that happens to pass through the plane
    seen. Both pass the gates; the stale one is nearer by 3 mm, so the least mean
    squared distance takes it, while the likelihood takes the live one, whose offset
    sigma at the plane is a hundred times smaller."""
    rng = np.random.default_rng(7)
    live = plane_points(rng, UP, 1.803, [0, 0, 0], 40, 45000, SIGMA)
    stale = plane_points(rng, UP, 1.8, [14, 0, 0], 1.0, 25)  # exactly on it
    M = _map([live, stale], [60, 1])
    cur = _scan(plane_points(rng, UP, 1.8, [0, 0, 0], 20, 8310, SIGMA), 30)
    c = candidates(M, np.eye(4), cur, np.radians(0.05), 0.01, BIAS)
    assert c.ok[0].all()  # both gated: the tie decides
    assert c.e2[0, 1] < c.e2[0, 0]
    x = cur.m.c
    assert M.var_at(np.array([1]), x)[0] > 100 * M.var_at(np.array([0]), x)[0]
    assert associate(M, np.eye(4), cur, np.radians(0.05), 0.01, BIAS, "distance")[0] == 1
    for rule in ("likelihood", "informative"):
        assert associate(M, np.eye(4), cur, np.radians(0.05), 0.01, BIAS, rule)[0] == 0


def test_two_surfaces_alike_known_the_nearer_wins_either_way() -> None:
    """A kerb: two ground levels 5 cm apart, each a well-observed landmark; with gates
    wide enough for both (a poorly known motion), the plane seen on the lower level ties
    to it under either rule (equal uncertainties: the distance decides)."""
    rng = np.random.default_rng(8)
    road = plane_points(rng, UP, 1.8, [0, -4, 0], 8, 20000, SIGMA)
    walk = plane_points(rng, UP, 1.75, [0, 4, 0], 8, 20000, SIGMA)
    M = _map([road, walk], [40, 40])
    cur = _scan(plane_points(rng, UP, 1.8, [0, 0, 0], 8, 5000, SIGMA), 20)
    c = candidates(M, np.eye(4), cur, np.radians(0.5), 0.05, BIAS)
    assert c.ok[0].all()
    for rule in ("distance", "likelihood", "informative"):
        assert associate(M, np.eye(4), cur, np.radians(0.5), 0.05, BIAS, rule)[0] == 0
