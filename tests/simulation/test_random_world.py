"""Procedural worlds: deterministic per seed, closed routes, clear of walls, labels on
their surfaces, the rig variants and the issue's world."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.simulation.procedural import clearance
from planodom.simulation.random_world import (
    issue_world,
    random_rig,
    random_world,
    simulate_world,
    world_fields,
)
from planodom.simulation.sensors import Scanner2D

SEEDS = range(8)


def _lap(world, n=1500):
    t = np.linspace(0.0, world.trajectory.duration, n)
    return t, world.trajectory.poses(t)


@pytest.mark.parametrize("seed", [0, 1, 5])
def test_same_seed_same_world_other_seed_other_world(seed):
    a, b, c = random_world(seed), random_world(seed), random_world(seed + 100)
    assert a.description == b.description
    assert len(a.scene) == len(b.scene)
    for s, r in zip(a.scene.surfaces, b.scene.surfaces, strict=True):
        assert s.id == r.id and np.array_equal(s.vertices, r.vertices)
    t = np.linspace(0.0, 30.0, 50)
    assert np.array_equal(a.trajectory.poses(t), b.trajectory.poses(t))
    assert a.sensor_rig.to_dict() == b.sensor_rig.to_dict()
    assert not np.allclose(a.trajectory.poses(t)[:, :3, 3], c.trajectory.poses(t)[:, :3, 3])


@pytest.mark.parametrize("seed", SEEDS)
def test_routes_close_in_six_dof_and_keep_clear_of_walls(seed):
    world = random_world(seed)
    traj = world.trajectory
    assert np.allclose(traj.pose(0.0), traj.pose(traj.duration), atol=1e-9)
    assert np.allclose(traj.pose(3.0), traj.pose(3.0 + traj.duration), atol=1e-9)
    t, poses = _lap(world)
    min_gap = 1.2 if world.kind == "indoor" else 2.5
    assert clearance(poses[:, :2, 3], world.scene) >= min_gap
    speed = np.linalg.norm(np.diff(poses[:, :2, 3], axis=0), axis=1) / np.diff(t)
    assert speed.min() > 0.3 * traj.speed and speed.max() > 1.1 * traj.speed  # speed changes


@pytest.mark.parametrize("seed", SEEDS)
def test_sway_within_bounds_and_base_above_the_sloped_ground(seed):
    world = random_world(seed)
    _, poses = _lap(world)
    z_axis = poses[:, :3, 2]
    ground = world.scene.by_id(0)
    tilt = np.degrees(np.arccos(np.clip(z_axis @ ground.normal, -1, 1)))
    assert tilt.max() <= 1.5 * np.sqrt(2) + 1e-6  # roll and pitch each within +-1.5 deg
    height = ground.distance(poses[:, :3, 3])
    assert np.all(np.abs(height - 1.0) <= 0.05 + 1e-9)  # 1 m above ground, heave <= 5 cm


@pytest.mark.parametrize("seed", [0, 1, 3])
def test_labels_lie_on_their_surfaces(seed):
    world = random_world(seed)
    run = simulate_world(world, 0.0, n_epochs=4, all_fields=True)
    planes = {s.id: s for s in world.scene.surfaces}
    for k, scan in enumerate(run):
        T = world.trajectory.poses(run.times[k] + scan.t)
        p = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points) + T[:, :3, 3]
        assert len(scan) > 500 and np.all(scan.label >= 0)
        for sid in np.unique(scan.label):
            assert np.abs(planes[int(sid)].distance(p[scan.label == sid])).max() < 1e-6


def test_rig_variants():
    rng = np.random.default_rng(0)
    for _ in range(40):
        rig, rate, ring, time, desc = random_rig(rng)
        if desc["family"] == "rig2d":
            sweeps = desc["sweeps_per_epoch"]
            assert ring and time and len(rig.sensors) == 4 and 5 <= rate <= 15
            assert sweeps == int(sweeps) and 1 <= sweeps <= 5
            assert all(s.rate_hz == rate * sweeps for s in rig.sensors)
        else:
            assert rig.sensors[0].n_beams == int(desc["family"][5:]) and rate in (10.0, 20.0)
    families = {random_rig(np.random.default_rng(i))[4]["family"] for i in range(30)}
    assert families == {"rig2d", "lidar16", "lidar32", "lidar64"}


def test_fields_follow_the_world():
    world = random_world(5, rig="lidar16")
    world = type(world)(**{**world.__dict__, "ring_field": False, "time_field": False})
    full = simulate_world(world, 0.0, n_epochs=2, all_fields=True)
    run = world_fields(world, full)
    assert full[0].ring is not None and full[0].t is not None
    assert run[0].ring is None and run[0].t is None and run[0].label is not None


def test_issue_world_is_the_issues_setting():
    world = issue_world(0)
    assert world.lap_epochs == 600 and world.epoch_rate == 10.0
    assert abs(world.trajectory.length - 116.0) < 4.0
    normals = np.array([s.scan_plane_normal for s in world.sensor_rig.sensors])
    assert all(isinstance(s, Scanner2D) and s.rate_hz == 50.0 for s in world.sensor_rig.sensors)
    front, rear = normals[:2], normals[2:]
    assert np.allclose(np.degrees(np.arcsin(front[:, 0])), [20.0, -20.0])  # pitched
    assert np.allclose(np.degrees(np.arcsin(rear[:, 1])), [30.0, -30.0])  # rolled
    tops = [s.vertices[:, 2].max() for s in world.scene.surfaces if s.id < 5000 and s.id > 0]
    assert 6.0 <= min(tops) and max(tops) <= 15.0
