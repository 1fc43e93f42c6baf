"""One scanner's lines of several sweeps against a group's plane (``extraction.sweep_tilt``):
lines that climb a wall as the vehicle moves are no evidence of a level plane through them."""

from __future__ import annotations

import numpy as np

from planodom.extraction.rig2d.grouping import GroupingParams
from planodom.extraction.rig2d.path import without_sweep_tilt
from planodom.extraction.rig2d.segments import Segments
from planodom.extraction.rig2d.sweeptilt import tilted_rings
from tests.extraction.test_rig2d import _segments

SIGMA = 0.006
TIMES = np.array([0.0, 0.0133, 0.0267])  # three sweeps of a 75 Hz scanner
RULES = GroupingParams(
    tol_m=0.01, sigma_m=SIGMA, sin_min_cross=float(np.sin(np.radians(10.0))),
    max_seed_err_rad=0.05, min_points=20.0, max_rms_m=0.03, min_trace_points=5,
    seed_floor_m=0.02, gap_m=10.0, gap_ratio=0.0, max_span_s=np.inf,
    parallel_rad=float(np.radians(2.0)),
)  # fmt: skip


def _two_walls(climb_m_s: float) -> Segments:
    """Ring 0's level lines on the wall x = 4 and ring 1's on the wall y = 3, both at
    z = 1 at time 0, each sweep's line ``climb_m_s`` * t higher on its wall: coplanar with
    the level plane z = 1 (they meet at the walls' edge x = 4, y = 3) when not climbing."""
    z = 1.0 + climb_m_s * TIMES
    cen = [[4.0, 0.0, h] for h in z] + [[2.0, 3.0, h] for h in z]
    return _segments([0] * 3 + [1] * 3, cen, [[0, 1, 0]] * 3 + [[1, 0, 0]] * 3)


def _floor(step_m_s: float) -> Segments:
    """The same two rings' lines on the floor z = 1 (a real level plane), each sweep's
    line moved ``step_m_s`` * t across itself on the floor (the vehicle's motion)."""
    d = step_m_s * TIMES
    cen = [[4.0 - s, 0.0, 1.0] for s in d] + [[2.0, 3.0 - s, 1.0] for s in d]
    return _segments([0] * 3 + [1] * 3, cen, [[0, 1, 0]] * 3 + [[1, 0, 0]] * 3)


UP = np.array([0.0, 0.0, 1.0])
EVERY = np.arange(6)


def test_lines_climbing_their_walls_are_not_a_level_plane():
    # 1.5 m/s over a 25-deg scan plane: the line climbs ~0.45 m/s; the spread of two
    # sweeps' means of 100 points at 6 mm is 0.85 mm, the test's noise 3 times that over
    # the times' spread (~0.15 m/s): both rings name themselves
    climbing = _two_walls(0.45)
    assert tilted_rings(climbing, EVERY, UP, np.tile(TIMES, 2), SIGMA, 3.0, 0.01) == [0, 1]
    # the climb over the epoch's 27 ms is 12 mm: within a member tolerance of 2 cm
    assert tilted_rings(climbing, EVERY, UP, np.tile(TIMES, 2), SIGMA, 3.0, 0.02) == []
    assert without_sweep_tilt(_two_walls(0.45), EVERY, RULES, np.tile(TIMES, 2), 3.0) is None


def test_a_floor_the_lines_move_over_is_kept():
    segs = _floor(1.5)
    assert tilted_rings(segs, EVERY, UP, np.tile(TIMES, 2), SIGMA, 3.0, 0.01) == []
    assert without_sweep_tilt(segs, EVERY, RULES, np.tile(TIMES, 2), 3.0) is EVERY


def test_a_climb_within_the_noise_is_kept():
    # 0.05 m/s: 1.3 mm over the epoch's three sweeps, within the noise of the means
    segs = _two_walls(0.05)
    assert tilted_rings(segs, EVERY, UP, np.tile(TIMES, 2), SIGMA, 3.0, 0.01) == []
    # one sweep per ring (a time window): nothing to tell
    one = np.zeros(6)
    assert tilted_rings(_two_walls(0.45), EVERY, UP, one, SIGMA, 3.0, 0.01) == []


def test_only_the_climbing_ring_leaves():
    # ring 0 climbs its wall, rings 1 and 2 lie on the floor the plane is: ring 0 goes,
    # rings 1 and 2 (crossing at 90 deg) are still a plane
    z = 1.0 + 0.45 * TIMES
    cen = (
        [[4.0, 0.0, h] for h in z]
        + [[2.0, 3.0 - s, 1.0] for s in 1.5 * TIMES]
        + [[1.0 - s, 2.0, 1.0] for s in 1.5 * TIMES]
    )
    u = [[0, 1, 0]] * 3 + [[1, 0, 0]] * 3 + [[0, 1, 0]] * 3
    segs = _segments([0] * 3 + [1] * 3 + [2] * 3, cen, u)
    rest = without_sweep_tilt(segs, np.arange(9), RULES, np.tile(TIMES, 3), 3.0)
    assert rest is not None
    assert sorted(set(segs.ring[rest].tolist())) == [1, 2]
