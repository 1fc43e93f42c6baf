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
