"""Extraction without a twist on a moving rig (the odometry's first epochs): points are
only combined within one time window, and the planes still match the true walls."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.geometry import invert_transform, se3_log, transform_planes
from planodom.simulation import simulate_named

SIGMA = 0.006
# Motion during one sweep (2 m/s x 1 / 75 s) plus 3 sigma; the same displacement over
# 1 m of wall as an angle.
TOL_M = 2.0 / 75.0 + 3 * SIGMA
TOL_DEG = float(np.degrees(2.0 / 75.0))


def _good(run, k, planes) -> int:
    n_true, d_true = transform_planes(
        invert_transform(run.poses[k]), run.scene.normals, run.scene.offsets
    )
    index = {int(i): j for j, i in enumerate(run.scene.ids)}
    good = set()
    for p in planes:
        if p.truth_id < 0:
            continue
        n, d = n_true[index[p.truth_id]], d_true[index[p.truth_id]]
        s = 1.0 if p.normal @ n >= 0 else -1.0
        ang = np.degrees(np.arccos(min(abs(float(p.normal @ n)), 1.0)))
        if ang <= TOL_DEG and abs(p.offset - s * d) <= TOL_M:
            good.add(p.truth_id)
    return len(good)


def test_no_twist_moving_epochs_give_true_planes():
    run = simulate_named(
        "paper-loop", "isoclinal", noise=SIGMA, seed=3, n_epochs=12, motion="continuous"
    )
    cfg = ExtractionConfig(range_noise_m=SIGMA)
    dt = 1.0 / run.epoch_rate
    ok = n_planes = n_matched = 0
    for k, scan in enumerate(run.scans):
        planes = extract(scan, cfg).planes
        n_good = _good(run, k, planes)
        ok += n_good >= 3
        n_planes += len(planes)
        n_matched += n_good
        T0, T1 = run.trajectory.poses(np.array([run.times[k], run.times[k] + dt]))
        twist = se3_log(invert_transform(T0) @ T1) / dt
        assert _good(run, k, extract(scan, cfg, twist=twist).planes) >= min(n_good, 3)
    assert ok >= 0.8 * len(run)
    assert n_matched >= 0.85 * n_planes  # planes off the truth (or repeats) are few


def test_snapshot_and_deskewed_scans_are_not_windowed():
    run = simulate_named(
        "paper-loop", "isoclinal", noise=0.0, seed=1, n_epochs=2, motion="snapshot"
    )
    cfg = ExtractionConfig(range_noise_m=0.002)
    # All times are 0: one window; a huge span disables windows on moving scans too.
    wide = ExtractionConfig(range_noise_m=0.002, time_windows={"span_s": 1.0})
    for scan in run.scans:
        a, b = extract(scan, cfg), extract(scan, wide)
        assert [len(i) for i in a.inliers] == [len(i) for i in b.inliers]


def test_slow_scanners_give_planes_without_a_twist():
    """2D scanners at 10 Hz in 5 Hz epochs (two sweeps of 50 ms each): before the windows
    were fitted to the sweeps, every epoch gave no plane (a 15 ms window never holds a
    50 ms ground trace, and 3 windows were required of a wall seen twice)."""
    from planodom.simulation import isoclinal_rig, paper_loop, paper_loop_trajectory, simulate

    rig = isoclinal_rig(rate_hz=10.0)
    run = simulate(paper_loop(), paper_loop_trajectory(), rig, n_epochs=6, epoch_rate=5.0,
                   noise_sigma=SIGMA, seed=1)  # fmt: skip
    cfg = ExtractionConfig(range_noise_m=SIGMA)
    speed_tol = 2.0 * 0.05 + 3 * SIGMA  # 2 m/s over one 50 ms sweep
    index = {int(i): j for j, i in enumerate(run.scene.ids)}
    n_planes = n_good = 0
    for k, scan in enumerate(run.scans):
        planes = extract(scan, cfg, sensor_origins=run.rig.sensor_origins).planes
        n_true, d_true = transform_planes(
            invert_transform(run.poses[k]), run.scene.normals, run.scene.offsets
        )
        good = 0
        for p in planes:  # on its wall, within the motion of one sweep
            n, d = n_true[index[p.truth_id]], d_true[index[p.truth_id]]
            s = 1.0 if p.normal @ n >= 0 else -1.0
            good += abs(p.offset - s * d) <= speed_tol and abs(p.normal @ n) > np.cos(0.05)
        assert good >= 3
        n_planes, n_good = n_planes + len(planes), n_good + good
    # Two sweeps cannot rule out two traces coplanar by chance as well as seven: measured
    # 29 of 31 planes on their walls (the odometry's consensus rejects the others).
    assert n_good >= 0.85 * n_planes


def _world_scan(seed: int, k: int = 1):
    from planodom.simulation.random_world import random_world, simulate_world, world_fields

    world = random_world(seed, rig="rig2d")
    full = simulate_world(world, 0.0, n_epochs=k + 1, all_fields=True)
    return world, full, world_fields(world, full)[k]


def test_sweeps_of_wide_and_partly_seen_scanners_are_told_apart():
    """The sweep timing against the rig the world was drawn with: a scanner turning over
    270 deg restarts with a jump forward over its blind sector (worlds 8 and 14), a ring
    that sees part of its field of view restarts with a short jump back (world 0)."""
    from planodom.extraction.rig2d.segments import split_scan_lines
    from planodom.extraction.rig2d.windows import sweep_timing

    for seed in (0, 8, 14):
        world, _, scan = _world_scan(seed)
        rig = world.description
        assert scan.ring is not None
        segs, _ = split_scan_lines(scan.points, scan.ring, scan.t, ExtractionConfig())
        timing = sweep_timing(scan, segs)
        assert timing.count == rig["sweeps_per_epoch"]
        np.testing.assert_allclose(timing.period, 1.0 / rig["rate_hz"], rtol=1e-6)
        duration = rig["fov_deg"] / 360.0 / rig["rate_hz"]
        assert abs(timing.duration - duration) <= rig["step_deg"] / 360.0 / rig["rate_hz"]


def test_no_twist_planes_of_a_wide_scanner_rig_are_at_the_epoch_time():
    """World 8 (270 deg scanners, 3.6 m/s in a turn): without a twist, the planes are
    those of the true surfaces at the epoch time (the oracle's fits of the labelled points
    with the true motion removed), not where the points were seen mid-epoch (30 cm)."""
    from planodom.oracle import epoch_moments

    world, full, scan = _world_scan(8, k=26)
    truth = epoch_moments(full.scans[26], world.trajectory, full.times[26])
    ids = list(truth.ids)
    planes = extract(scan, ExtractionConfig()).planes
    errors = []
    for p in planes:
        if p.truth_id in ids:
            j = ids.index(p.truth_id)
            s = 1.0 if p.normal @ truth.normal[j] >= 0 else -1.0
            errors.append(abs(p.offset - s * truth.offset[j]))
    assert len(errors) >= 5
    assert np.median(errors) <= 0.01


def test_median_range_is_numpys_median_of_the_point_norms_bit_for_bit():
    """The compiled median range (:func:`.windows.median_range`, the twist smear's range)
    against ``np.median(np.linalg.norm(points, axis=1))`` on random clouds of odd and
    even sizes, with repeated values."""
    from planodom.extraction.rig2d.windows import median_range

    rng = np.random.default_rng(11)
    for n in [1, 2, 3, 4, 7, 10, 101, 1000, 5001]:
        pts = rng.normal(size=(n, 3)) * rng.uniform(0.5, 40.0, size=(n, 1))
        if n > 4:
            pts[: n // 4] = pts[0]  # ties
        assert median_range(pts) == np.median(np.linalg.norm(pts, axis=1))


def test_a_sparse_rigs_walls_count_their_points_over_their_windows():
    """World 140 (1 deg steps, five 25 Hz sweeps an epoch, 3.7 m/s): a wall has 4-18
    points in one sweep, so with ``min_plane_points`` (20) in each window only the ground
    is found. Counted over the windows a wall must be found in
    (``time_windows.min_points_over_windows``), the walls are found too, each on its true
    surface at the epoch time (the oracle's fit of its labelled points, true motion
    removed) within the motion of one sweep (3.7 m/s over 40 ms: 15 cm)."""
    from planodom.oracle import epoch_moments
    from planodom.simulation.random_world import random_world, simulate_world, world_fields

    world = random_world(140, rig="rig2d")
    full = simulate_world(world, 0.0, n_epochs=3, all_fields=True)
    scans = world_fields(world, full)
    on = ExtractionConfig(time_windows={"min_points_over_windows": True})
    found: dict[bool, list[tuple[int, float, float]]] = {False: [], True: []}
    for k in range(3):
        truth = epoch_moments(full.scans[k], world.trajectory, full.times[k])
        ids = list(truth.ids)
        for flag, cfg in ((False, ExtractionConfig()), (True, on)):
            for p in extract(scans[k], cfg).planes:
                j = ids.index(p.truth_id)
                cos = float(p.normal @ truth.normal[j])
                angle = float(np.degrees(np.arccos(min(1.0, abs(cos)))))
                found[flag].append(
                    (p.truth_id, angle, abs(p.offset - np.sign(cos) * truth.offset[j]))
                )
    assert [i for i, _, _ in found[False]] == [0, 0, 0]  # the ground alone
    walls = [(a, e) for i, a, e in found[True] if i != 0]
    assert len(walls) >= 6  # measured: 8 (walls 33, 48, 13 and surface 5000)
    assert all(a <= 3.0 and e <= 0.15 for a, e in walls)
    assert np.median([e for _, e in walls]) <= 0.05


def test_a_windows_share_of_the_plane_minimum_adds_up_to_it():
    """Each window's minimum times the windows a wall must be found in is at least
    ``min_plane_points`` (and no more than one window's worth above it); off, the
    config is left as it is."""
    from planodom.config.extraction import TimeWindowConfig
    from planodom.extraction.rig2d.windows import per_window

    cfg = ExtractionConfig()
    assert per_window(cfg, TimeWindowConfig()) is cfg
    for n_min in (3, 7, 20, 21, 50):
        for m in (1, 2, 3, 5):
            c = ExtractionConfig(min_plane_points=n_min)
            share = per_window(c, TimeWindowConfig(min_windows=m, min_points_over_windows=True))
            k = share.min_plane_points
            assert k >= 3 and k * m >= n_min and (k - 1) * m < max(n_min, 3 * m)
