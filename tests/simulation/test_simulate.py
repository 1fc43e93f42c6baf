"""simulate(): exact geometry at sigma 0, noise statistics, seeds, timing, snapshot mode."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.errors import ConfigError
from planodom.geometry import make_transform, transform_from_rpy_xyz
from planodom.scan import Scan
from planodom.simulation import (
    NOISE_PRESETS,
    Scene,
    SensorRig,
    Simulator,
    StaticTrajectory,
    TwistTrajectory,
    isoclinal_rig,
    lidar_rig,
    paper_loop,
    paper_loop_trajectory,
    simulate,
    simulate_named,
    wall,
)

SCENE = paper_loop()
LOOP = paper_loop_trajectory()


def _world_points(scan: Scan, traj, t_k: float, own_time: bool = True) -> np.ndarray:
    """Points of ``scan`` in the world with the pose at each point's time (or at t_k)."""
    T = traj.poses(t_k + scan.t) if own_time else np.broadcast_to(traj.pose(t_k), (len(scan), 4, 4))
    return np.einsum("nij,nj->ni", T[:, :3, :3], scan.points) + T[:, :3, 3]


def _plane_errors(scan: Scan, scene: Scene, world: np.ndarray) -> np.ndarray:
    index = {s.id: k for k, s in enumerate(scene.surfaces)}
    k = np.array([index[i] for i in scan.label])
    return np.abs(np.sum(world * scene.normals[k], axis=1) + scene.offsets[k])


@pytest.fixture(scope="module")
def run():
    """A few epochs on a curve of the loop (fast turn: motion matters)."""
    return simulate(SCENE, LOOP, isoclinal_rig(), n_epochs=6, start_time=20.0)


def test_noise_free_points_lie_on_their_labelled_wall(run):
    for k, scan in enumerate(run.scans):
        assert len(scan) > 1000 and np.all(scan.label >= 0)
        err = _plane_errors(scan, SCENE, _world_points(scan, LOOP, run.times[k]))
        assert err.max() < 1e-9
    # the pose at each point's own time matters: with the epoch pose the error is large
    scan = run.scans[0]
    err = _plane_errors(scan, SCENE, _world_points(scan, LOOP, run.times[0], own_time=False))
    assert err.max() > 0.05


def test_lidar_points_lie_on_their_labelled_wall():
    run = simulate(SCENE, LOOP, lidar_rig(32, n_columns=512), n_epochs=2, start_time=5.0)
    for k, scan in enumerate(run.scans):
        assert set(np.unique(scan.ring)) == set(range(32))
        assert (
            np.abs(_plane_errors(scan, SCENE, _world_points(scan, LOOP, run.times[k]))).max() < 1e-9
        )


def test_run_layout(run):
    assert len(run) == 6 and run[2] is run.scans[2]
    np.testing.assert_allclose(run.times, 20.0 + np.arange(6) / 10.0)
    np.testing.assert_array_equal(run.poses, LOOP.poses(run.times))
    np.testing.assert_array_equal(run.gt_poses, run.poses)
    for k in range(6):
        assert len(run.ranges[k]) == 4
        starts = run.sweep_starts[k][0]
        assert len(starts) in (7, 8)  # 75 Hz sweeps in a 0.1 s epoch
        assert np.all((starts >= run.times[k] - 1e-12) & (starts < run.times[k] + 0.1))
        for r in run.ranges[k]:
            assert r.shape == (len(starts), 361)
        n_finite = sum(int(np.isfinite(r).sum()) for r in run.ranges[k])
        scan = run.scans[k]
        assert len(scan) == n_finite
        assert scan.t.min() >= 0.0 and scan.t.max() < 0.1 + 0.5 / 75.0
        for ring in range(4):  # each ring in scan (time) order
            assert np.all(np.diff(scan.t[scan.ring == ring]) >= 0)
    # sweeps tile the time line: each epoch's first sweep follows the previous epoch's last
    starts = np.concatenate([run.sweep_starts[k][0] for k in range(6)])
    np.testing.assert_allclose(np.diff(starts), 1.0 / 75.0)


def test_inf_ranges_where_there_is_no_wall():
    scene = Scene((wall(1, (10, -5), (10, 5), -3.0, 5.0),))
    rig = lidar_rig(16, (-10.0, 10.0), n_columns=360, max_range=50.0)
    run = simulate(scene, StaticTrajectory(np.eye(4)), rig, n_epochs=1)
    r = run.ranges[0][0].reshape(360, 16)  # columns x beams
    az = np.rad2deg(rig.sensors[0].azimuths)
    assert np.all(np.isinf(r[np.abs(az) > 30]))  # the wall spans +-26.6 deg
    assert np.all(np.isfinite(r[np.abs(az) < 20]))
    assert len(run.scans[0]) == np.isfinite(r).sum() and np.all(run.scans[0].label == 1)


def test_noise_std_matches_sigma():
    sigma = NOISE_PRESETS["low-cost"]
    clean = simulate(SCENE, LOOP, isoclinal_rig(), n_epochs=3, noise_sigma=0.0)
    noisy = simulate(SCENE, LOOP, isoclinal_rig(), n_epochs=3, noise_sigma=sigma, seed=5)
    a = np.concatenate([r.ravel() for e in clean.ranges for r in e])
    b = np.concatenate([r.ravel() for e in noisy.ranges for r in e])
    ok = np.isfinite(a) & np.isfinite(b)
    assert np.array_equal(np.isfinite(a), np.isfinite(b)) or ok.sum() > 0.999 * np.isfinite(a).sum()
    res = b[ok] - a[ok]
    n = len(res)
    assert n > 10000
    assert abs(res.mean()) < 5 * sigma / np.sqrt(n)
    assert abs(res.std() / sigma - 1.0) < 5 / np.sqrt(2 * n)
    assert noisy.sensor_rig.sensors[0].noise_sigma == sigma


def test_noise_is_deterministic_per_seed():
    kw = dict(n_epochs=2, noise_sigma="lms221")
    a = simulate(SCENE, LOOP, isoclinal_rig(), seed=1, **kw)
    b = simulate(SCENE, LOOP, isoclinal_rig(), seed=1, **kw)
    c = simulate(SCENE, LOOP, isoclinal_rig(), seed=2, **kw)
    for k in range(2):
        np.testing.assert_array_equal(a.scans[k].points, b.scans[k].points)
        for ra, rb in zip(a.ranges[k], b.ranges[k], strict=True):
            np.testing.assert_array_equal(ra, rb)
        assert not np.array_equal(a.scans[k].points, c.scans[k].points)
    # epoch k is reproducible on its own
    sim = Simulator(SCENE, LOOP, isoclinal_rig(noise_sigma=0.006), seed=1)
    np.testing.assert_array_equal(sim.epoch(1, 0.1).scan.points, a.scans[1].points)


def test_snapshot_points_lie_in_their_scan_planes():
    rig = isoclinal_rig()
    run = simulate(SCENE, LOOP, rig, n_epochs=3, start_time=40.0, motion="snapshot")
    for k, scan in enumerate(run.scans):
        np.testing.assert_array_equal(scan.t, 0.0)
        for ring, sensor in enumerate(rig.sensors):
            p = scan.points[scan.ring == ring] - sensor.T_base_sensor[:3, 3]
            assert len(p) > 100
            assert np.abs(p @ sensor.scan_plane_normal).max() < 1e-9
        # and all of the epoch was seen from the pose at t_k
        err = _plane_errors(scan, SCENE, _world_points(scan, LOOP, run.times[k], own_time=False))
        assert err.max() < 1e-9


def test_continuous_motion_under_a_constant_twist():
    """With a twist trajectory, points taken back with the twist land on their walls."""
    T0 = transform_from_rpy_xyz(0.0, 0.0, 0.3, 0.0, 0.0, 1.0)
    traj = TwistTrajectory(T0, [0.05, -0.03, 0.4, 3.0, 0.0, 0.0])
    run = simulate(SCENE, traj, isoclinal_rig(), n_epochs=2)
    for k, scan in enumerate(run.scans):
        assert _plane_errors(scan, SCENE, _world_points(scan, traj, run.times[k])).max() < 1e-9


def test_epoch_rate_and_duration():
    run = simulate(
        SCENE,
        StaticTrajectory(make_transform(np.eye(3), [0, 0, 1.0])),
        lidar_rig(16, n_columns=64),
        duration=0.5,
        epoch_rate=20.0,
    )
    assert len(run) == 10
    # 10 Hz lidar, 20 Hz epochs: every other epoch starts a sweep
    assert [len(s[0]) for s in run.sweep_starts] == [1, 0] * 5
    assert len(run.scans[1]) == 0


def test_bad_arguments():
    with pytest.raises(ConfigError, match="motion"):
        simulate(SCENE, LOOP, isoclinal_rig(), n_epochs=1, motion="teleport")
    with pytest.raises(ConfigError, match="noise"):
        simulate(SCENE, LOOP, isoclinal_rig(), n_epochs=1, noise_sigma="loud")
    with pytest.raises(ConfigError, match="scene"):
        simulate_named("moon")


@pytest.mark.parametrize(
    ("scene", "rig"), [("paper-loop", "lidar16"), ("urban-canyon", "isoclinal")]
)
def test_simulate_named(scene, rig):
    run = simulate_named(scene, rig, noise="worst", seed=3, n_epochs=2, motion="snapshot")
    assert len(run) == 2 and run.motion == "snapshot" and run.seed == 3
    assert run.sensor_rig.sensors[0].noise_sigma == NOISE_PRESETS["worst"]
    assert run.scene.name == scene and all(len(s) > 100 for s in run.scans)


def test_mixed_rig_with_per_sensor_noise_and_ranges():
    """Two timing groups (2D scanners and a lidar), per-sensor sigma and max range."""
    iso = isoclinal_rig()
    quiet, loud = (
        replace(iso.sensors[0], noise_sigma=0.0),
        replace(iso.sensors[1], noise_sigma=0.05),
    )
    short = replace(iso.sensors[2], max_range=10.0)
    lidar = lidar_rig(16, n_columns=128).sensors[0]
    rig = SensorRig((quiet, loud, short, iso.sensors[3], lidar))
    np.testing.assert_array_equal(rig.ring_offsets, [0, 1, 2, 3, 4])
    assert rig.n_rings == 20
    clean = simulate(SCENE, LOOP, rig.with_noise(0.0), n_epochs=2)
    noisy = simulate(SCENE, LOOP, rig, n_epochs=2, seed=4)
    for k in range(2):
        np.testing.assert_array_equal(noisy.ranges[k][0], clean.ranges[k][0])
        a, b = noisy.ranges[k][1], clean.ranges[k][1]
        both = np.isfinite(a) & np.isfinite(b)
        assert 0.03 < np.std(a[both] - b[both]) < 0.07
        short_ranges = noisy.ranges[k][2]
        assert np.all(short_ranges[np.isfinite(short_ranges)] <= 10.0)
        assert np.isinf(short_ranges).any()
        assert noisy.ranges[k][4].shape == (1, 128 * 16)
        scan = clean.scans[k]
        assert set(np.unique(scan.ring)) == set(range(20))
        assert _plane_errors(scan, SCENE, _world_points(scan, LOOP, clean.times[k])).max() < 1e-9
