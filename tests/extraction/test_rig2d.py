"""The 2D-rig path: exact planes, noise bounds, rejection of single and parallel traces,
normal orientation (also with the base origin on the ground), support and labels; a
scanner's own scan plane (dropped, or its ring trimmed off a group)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction import extract, extract_planes
from planodom.extraction.rig2d.grouping import GroupingParams
from planodom.extraction.rig2d.path import (
    lost_cross,
    spans_own_scan_plane,
    without_own_scan_plane,
)
from planodom.extraction.rig2d.segments import Segments
from planodom.geometry import transform_from_rpy_xyz

from .synth_scans import default_rig, default_scene, planes_in_base, rect, scan_rig

SCENE = default_scene()
TRUTH = planes_in_base(SCENE)
# Walls 1 and 3 are seen by one scanner each (a single trace): they must not be planes.
DETERMINED = {0, 2, 4}


def errors(plane):
    n, d = TRUTH[plane.truth_id]
    return np.degrees(np.arccos(np.clip(plane.normal @ n, -1, 1))), abs(plane.offset - d)


def test_noise_free_planes_are_exact_and_oriented():
    res = extract(scan_rig(SCENE))
    assert res.mode == "rig2d"
    assert {p.truth_id for p in res.planes} == DETERMINED
    for p in res.planes:
        ang, off = errors(p)  # truth normals point towards the vehicle, ground up
        assert ang < 1e-6 and off < 1e-6
        assert 0 < p.confidence <= 1
        assert p.covariance.shape == (4, 4)
        assert p.support.n_points >= 20 and len(p.support.polygon) >= 3
        assert np.all(np.abs(p.distance(p.support.polygon)) < 1e-6)


def test_noisy_planes_within_their_predicted_uncertainty():
    sigma = 0.006
    for seed in range(3):
        planes = extract_planes(
            scan_rig(SCENE, sigma=sigma, seed=seed), ExtractionConfig(range_noise_m=sigma)
        )
        assert {p.truth_id for p in planes} == DETERMINED
        for p in planes:
            n, d = TRUTH[p.truth_id]
            std_n = np.sqrt(np.trace(p.covariance[:3, :3]))  # rad
            std_d = np.sqrt(p.covariance[3, 3])
            assert np.linalg.norm(np.cross(p.normal, n)) < 5 * std_n
            assert abs(p.offset - d) < 5 * std_d


def test_single_trace_is_rejected():
    rig = default_rig()[:1]  # one scanner: every wall is a single trace per sweep
    assert extract_planes(scan_rig(SCENE, rig=rig)) == []


def test_parallel_traces_are_rejected():
    # Two scanners with the same orientation, 0.5 m apart: their traces on every wall are
    # parallel (also across sweeps), so nothing determines a plane.
    T = default_rig()[0]
    T2 = T.copy()
    T2[2, 3] += 0.5
    assert extract_planes(scan_rig(SCENE, rig=[T, T2])) == []


def test_walls_seen_by_one_scanner_are_not_guessed():
    planes = extract_planes(scan_rig(SCENE))
    assert not {p.truth_id for p in planes} & {1, 3}


def test_ground_normal_up_with_origin_on_ground():
    # The base origin lies on the ground plane z = 0 here: "towards the origin" is
    # undefined for it; the rule must still give +z, in every epoch.
    for seed in range(3):
        planes = extract_planes(scan_rig(SCENE, sigma=0.006, seed=seed))
        ground = [p for p in planes if p.truth_id == 0]
        assert len(ground) == 1 and ground[0].normal[2] > 0.999


def test_orientation_with_sensor_origins():
    rig = default_rig()
    origins = np.array([T[:3, 3] for T in rig])
    planes = extract_planes(scan_rig(SCENE), sensor_origins=origins)
    for p in planes:
        view = origins.mean(axis=0)
        assert p.distance(view[None])[0] > 0
    assert [p for p in planes if p.truth_id == 0][0].normal[2] > 0.999


def test_orientation_viewpoint_above_origin():
    # A wall whose plane passes 0.3 m from the base origin still faces the vehicle.
    scene = [rect([0.3, 0.0, 2.0], [-1, 0, 0], half_u=8), SCENE[0]]
    rig = [transform_from_rpy_xyz(r, 0.25, 0.0, -1.0, 0.0, 1.5) for r in (0.5, -0.5)]
    planes = extract_planes(scan_rig(scene, rig=rig))
    wall = [p for p in planes if p.truth_id == 0]
    assert wall and wall[0].normal[0] < -0.999


def test_majority_label_and_no_labels():
    scan = scan_rig(SCENE)
    unlabeled = type(scan)(scan.points, scan.ring, scan.t, None)
    assert all(p.truth_id == -1 for p in extract_planes(unlabeled))


@pytest.mark.parametrize("mode", ["auto", "rig2d"])
def test_modes(mode):
    assert extract(scan_rig(SCENE), ExtractionConfig(mode=mode)).mode == "rig2d"


def _segments(ring, centroid, direction, count=100, length=2.0):
    """Segments of ``count`` points spread evenly over ``length`` m (each a scalar or one
    per segment) along ``direction`` about ``centroid``: what :func:`spans_own_scan_plane`
    and :mod:`planodom.extraction.rig2d.sweeptilt` read (points and ends empty)."""
    s = len(ring)
    u = np.asarray(direction, dtype=np.float64)
    u = u / np.linalg.norm(u, axis=1)[:, None]
    n = np.broadcast_to(np.asarray(count, dtype=np.int64), (s,)).copy()
    ln = np.broadcast_to(np.asarray(length, dtype=np.float64), (s,)).copy()
    scatter = (n * ln**2 / 12.0)[:, None, None] * np.einsum("ki,kj->kij", u, u)
    z3, zi = np.zeros((s, 3)), np.zeros(s, dtype=np.int64)
    return Segments(
        points=np.zeros((0, 3)), order=np.zeros(0, dtype=np.int64), starts=zi, ends=zi,
        ring=np.asarray(ring, dtype=np.int64), sweep=zi, count=n,
        centroid=np.asarray(centroid, dtype=np.float64), scatter=scatter, direction=u,
        length=ln, rms=np.zeros(s), end0=z3, end1=z3,
    )  # fmt: skip


SIN2 = np.sin(np.radians(2.0))  # trace_parallel_deg
EVERY = np.arange(3)
# ring 2's lines on two walls (x = 4, y = 3) in its scan plane z = 0.8, and a short
# trace of ring 1 in that plane
SCAN_PLANE = _segments(
    [2, 2, 1], [[4.0, 0.0, 0.8], [1.0, 3.0, 0.8], [3.0, 2.0, 0.8]],
    [[0, 1, 0], [1, 0, 0], [1, 1, 0]], [200, 200, 20], [2.0, 2.0, 0.3],
)  # fmt: skip


def test_a_scanners_own_plane_is_not_a_wall():
    on_plane = np.array([[1.0, 0.5, 0.8], [1.0, -0.5, 0.8], [0.0, 0.0, 0.8]])
    assert spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, on_plane)
    # the same lines seen from 2.2 m above their plane: the rays cross it, a real floor;
    # 0.1 m above: rays at 1.6 deg (0.1 m over a mean range of 3.6 m), within 2 deg of
    # parallel; 0.3 m above: 4.8 deg, not
    assert not spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, on_plane + [0, 0, 2.2])
    assert spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, on_plane + [0, 0, 0.1])
    assert not spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, on_plane + [0, 0, 0.3])
    # no origins per ring: never
    assert not spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, None)
    assert not spans_own_scan_plane(SCAN_PLANE, EVERY, SIN2, on_plane[:1])
    # ring 1 alone with one segment in the plane of its sensor: not enough to tell
    assert not spans_own_scan_plane(SCAN_PLANE, np.array([2]), SIN2, on_plane)


def test_a_corridors_two_walls_in_one_scan_plane():
    # ring 0's parallel lines on the two walls of a corridor (y = -1.5, y = 1.5) lie in its
    # scan plane z = 0.8 (coplanar, any two parallel lines are) with its sensor: dropped;
    # ring 0's lines of two sweeps on the wall x = 4, seen from 4 m: kept
    corridor = _segments(
        [0, 0, 1], [[3.0, -1.5, 0.8], [3.0, 1.5, 0.8], [2.0, 0.0, 0.8]],
        [[1, 0, 0], [1, 0, 0], [1, 1, 0]], [200] * 3, [2.0] * 3,
    )  # fmt: skip
    origins = np.array([[0.0, 0.0, 0.8], [0.0, 1.0, 0.8]])
    assert spans_own_scan_plane(corridor, EVERY, SIN2, origins)
    wall = _segments(
        [0, 0, 1], [[4.0, 0.0, 0.8], [4.0, 0.0, 1.0], [4.0, 0.5, 0.9]],
        [[0, 1, 0.3], [0, 1, 0.3], [0, 1, -0.3]], [200] * 3, [2.0] * 3,
    )  # fmt: skip
    assert not spans_own_scan_plane(wall, EVERY, SIN2, origins)


# the grouping's rules for what is left of a trimmed group: crossing at 10 deg, 20 points,
# RMS within 3 cm (the other fields are not read)
RULES = GroupingParams(
    tol_m=0.06, sigma_m=0.02, sin_min_cross=float(np.sin(np.radians(10.0))),
    max_seed_err_rad=0.05, min_points=20.0, max_rms_m=0.03, min_trace_points=5,
    seed_floor_m=0.02, gap_m=10.0, gap_ratio=0.0, max_span_s=np.inf,
    parallel_rad=float(np.radians(2.0)),
)  # fmt: skip


def test_a_ghost_loses_its_ring_and_dies():
    # ring 2's lines on two walls in its own scan plane z = 0.8 and the short ring-1 trace
    # that seeded it: without ring 2 one ring is left, not a plane
    on_plane = np.array([[1.0, 0.5, 0.8], [1.0, -0.5, 0.8], [0.0, 0.0, 0.8]])
    assert without_own_scan_plane(SCAN_PLANE, EVERY, RULES, on_plane) is None
    # seen from 2.2 m above (a floor, the rays crossing it): kept whole, the same array
    assert without_own_scan_plane(SCAN_PLANE, EVERY, RULES, on_plane + [0, 0, 2.2]) is EVERY


# the floor z = 0 seen by rings 0 and 1 from 0.8 m above (crossing lines 2-4 m away) and by
# ring 2, at 5 cm above it, in two sweeps 12 m away: its rays 0.24 deg off the floor
FLOOR = _segments(
    [0, 0, 1, 1, 2, 2],
    [[3.0, 0.0, 0.0], [3.5, 0.2, 0.0], [2.0, 1.0, 0.0], [2.5, 1.2, 0.0],
     [12.0, 0.0, 0.0], [12.0, 0.5, 0.0]],
    [[0, 1, 0], [0, 1, 0], [1, 0, 0], [1, 0, 0], [0.2, 1, 0], [0.2, 1, 0]],
    [100, 100, 100, 100, 60, 60], [2.0, 2.0, 2.0, 2.0, 3.0, 3.0],
)  # fmt: skip
FLOOR_ORIGINS = np.array([[0.0, 0.0, 0.8], [0.0, 0.5, 0.8], [0.0, 0.0, 0.05]])


def test_a_floor_keeps_its_steep_rings_and_loses_the_grazing_one():
    group = np.arange(6)
    rest = without_own_scan_plane(FLOOR, group, RULES, FLOOR_ORIGINS)
    assert rest is not None
    assert rest.tolist() == [0, 1, 2, 3]
    # the refit on what is left: the floor, exactly (least squares over the moments)
    pts = FLOOR.centroid[rest]
    assert np.allclose(pts[:, 2], 0.0)
    # with ring 2's sensor 3 m up it is a steep view too: all kept
    high = FLOOR_ORIGINS + [[0, 0, 0], [0, 0, 0], [0, 0, 2.95]]
    assert without_own_scan_plane(FLOOR, group, RULES, high) is group


def test_what_is_left_must_still_be_a_plane():
    # rings 0 and 2 only: ring 0's two parallel lines are left, one ring
    group = np.array([0, 1, 4, 5])
    assert without_own_scan_plane(FLOOR, group, RULES, FLOOR_ORIGINS) is None
    # ring 1's lines turned parallel to ring 0's: two rings, but no crossing
    parallel = _segments(
        [0, 0, 1, 1, 2, 2], FLOOR.centroid, [[0, 1, 0]] * 4 + [[0.2, 1, 0]] * 2,
        [100, 100, 100, 100, 60, 60], [2.0] * 6,
    )  # fmt: skip
    assert without_own_scan_plane(parallel, np.arange(6), RULES, FLOOR_ORIGINS) is None
    # too few points left (10 of 20)
    few = _segments(
        [0, 1, 2, 2], FLOOR.centroid[[0, 2, 4, 5]], FLOOR.direction[[0, 2, 4, 5]],
        [5, 5, 60, 60], [2.0, 2.0, 3.0, 3.0],
    )  # fmt: skip
    assert without_own_scan_plane(few, np.arange(4), RULES, FLOOR_ORIGINS) is None
    # what is left is not flat: ring 0's lines 5 cm above the floor, ring 1's 5 cm below
    # (placed so that the group's plane stays z = 0), RMS 5 cm
    bent = _segments(
        [0, 0, 1, 1, 2, 2],
        [[2.9, 0.1, 0.05], [3.1, 0.1, 0.05], [3.0, 0.0, -0.05], [3.0, 0.2, -0.05],
         [12.0, 0.0, 0.0], [12.0, 0.5, 0.0]],
        FLOOR.direction, [100, 100, 100, 100, 60, 60], [2.0, 2.0, 2.0, 2.0, 3.0, 3.0],
    )  # fmt: skip
    assert without_own_scan_plane(bent, np.arange(6), RULES, FLOOR_ORIGINS) is None
    rest = without_own_scan_plane(bent, np.arange(6), RULES._replace(max_rms_m=0.06), FLOOR_ORIGINS)
    assert rest is not None and rest.tolist() == [0, 1, 2, 3]


def test_a_wall_seen_from_4_m_is_kept_whole():
    wall = _segments(
        [0, 0, 1], [[4.0, 0.0, 0.8], [4.0, 0.0, 1.0], [4.0, 0.5, 0.9]],
        [[0, 1, 0.3], [0, 1, 0.3], [0, 1, -0.3]], [200] * 3, [2.0] * 3,
    )  # fmt: skip
    origins = np.array([[0.0, 0.0, 0.8], [0.0, 1.0, 0.8]])
    assert without_own_scan_plane(wall, EVERY, RULES, origins) is EVERY


@pytest.mark.parametrize("mode", ["dropped", "trimmed"])
def test_real_walls_with_sensor_origins_are_kept(mode):
    # the synthetic scene's walls seen by the rig, with each ring's sensor origin: no ring
    # lies on a wall's plane, so both tests keep every plane of the test-free path exactly
    origins = np.array([t[:3, 3] for t in default_rig()])
    ref = extract(scan_rig(SCENE), ExtractionConfig(own_scan_plane="kept"), sensor_origins=origins)
    res = extract(scan_rig(SCENE), ExtractionConfig(own_scan_plane=mode), sensor_origins=origins)
    assert {p.truth_id for p in ref.planes} >= DETERMINED
    assert [p.truth_id for p in res.planes] == [p.truth_id for p in ref.planes]
    assert all(
        np.array_equal(a.normal, b.normal) for a, b in zip(res.planes, ref.planes, strict=True)
    )


def test_a_refit_that_loses_the_crossing_line():
    # ring 3's line in two pieces (9 and 22 points) crossed by ring 2's two segments (10
    # and 5 points): world 32 at 6 mm, epoch 71, where the refit kept 1 point of ring 2
    segs = _segments(
        [3, 3, 2, 2], [[0, 0, 0], [6, 0, 0], [3, 3, 0], [3, 4, 0]],
        [[1, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0]], [9, 22, 10, 5], [4.6, 2.9, 0.9, 0.2],
    )  # fmt: skip
    group = np.arange(4)
    rings = lambda n3, n2: np.array([3] * n3 + [2] * n2)  # noqa: E731
    assert lost_cross(segs, group, rings(31, 1), 3)
    assert lost_cross(segs, group, rings(31, 2), 3)
    assert lost_cross(segs, group, rings(31, 0), 3)
    assert not lost_cross(segs, group, rings(31, 3), 3)
    assert not lost_cross(segs, group, rings(20, 15), 3)
    # one scanner's lines of several sweeps: no crossing to lose
    assert not lost_cross(segs, group[:2], rings(31, 0), 3)
