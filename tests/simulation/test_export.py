"""A simulated run written as a dataset reads back identically, its platform too."""

from __future__ import annotations

import numpy as np
import yaml

from planodom.config import PlanodomConfig
from planodom.datasets import load_dataset
from planodom.odometry import with_platform
from planodom.simulation import SensorRig, simulate_named
from planodom.simulation.export import dataset_rig, write_simulated_dataset
from planodom.simulation.trajectory import TwistTrajectory


def test_simulated_dataset_round_trip(tmp_path) -> None:
    run = simulate_named("paper-loop", "isoclinal", noise=0.006, seed=3, n_epochs=3)
    ds = write_simulated_dataset(run, tmp_path / "ds", scene_name="paper-loop")
    assert len(ds) == 3
    np.testing.assert_array_equal(ds.times, run.times)
    np.testing.assert_allclose(ds.gt_poses, run.poses, atol=1e-14)
    for k in range(3):
        a, b = ds[k], run[k]
        np.testing.assert_array_equal(a.points, b.points)
        np.testing.assert_array_equal(a.ring, b.ring)
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.label, b.label)
    rig = load_dataset(tmp_path / "ds").rig
    assert rig.epoch_rate_hz == run.epoch_rate == run.rig.epoch_rate_hz
    assert rig.extra["simulation"]["seed"] == 3
    sensors = run.sensor_rig
    assert rig.sensor_origins.shape == (sensors.n_rings, 3)
    np.testing.assert_array_equal(rig.sensor_origins, run.rig.sensor_origins)
    for ring in np.unique(run[0].ring):  # each ring's origin is its scanner's position
        sensor = sensors.sensors[int(np.searchsorted(sensors.ring_offsets, ring, "right")) - 1]
        np.testing.assert_array_equal(rig.sensor_origins[ring], sensor.T_base_sensor[:3, 3])
    for T, sensor in zip(rig.extrinsics, sensors.sensors, strict=True):
        np.testing.assert_array_equal(T, sensor.T_base_sensor)
    # the sensor models travel in rig.yaml too, and read back as the same rig
    back = SensorRig.from_dict(rig.extra["sensor_rig"])
    assert back.to_dict() == sensors.to_dict()


def test_a_simulated_dataset_declares_its_platform_and_an_old_one_reads_as_unknown(
    tmp_path,
) -> None:
    run = simulate_named("paper-loop", "isoclinal", noise=0.006, seed=3, n_epochs=1)
    write_simulated_dataset(run, tmp_path / "ds", scene_name="paper-loop")
    text = (tmp_path / "ds" / "rig.yaml").read_text()
    assert yaml.safe_load(text)["platform"] == "vehicle" == run.rig.platform
    ds = load_dataset(tmp_path / "ds")
    assert ds.rig.platform == "vehicle" and "platform" not in ds.rig.extra
    assert with_platform(PlanodomConfig(), ds.rig).odometry.start_vehicle_twist
    # a dataset written before the field: its rig.yaml without the key
    old = {k: v for k, v in yaml.safe_load(text).items() if k != "platform"}
    (tmp_path / "ds" / "rig.yaml").write_text(yaml.safe_dump(old))
    ds = load_dataset(tmp_path / "ds")
    assert ds.rig.platform is None and ds.notes == load_dataset(tmp_path / "ds").notes
    assert not any("platform" in note for note in ds.notes)
    resolved = with_platform(PlanodomConfig(), ds.rig).odometry
    assert (resolved.platform, resolved.start_vehicle_twist) == ("unknown", False)


def test_a_walk_declares_handheld_and_a_bare_trajectory_nothing(tmp_path) -> None:
    walk = simulate_named("random", "lidar16", seed=2, n_epochs=1, handheld=True)
    assert walk.rig.platform == "handheld"
    ds = write_simulated_dataset(walk, tmp_path / "walk")
    assert load_dataset(ds.path).rig.platform == "handheld"
    assert not with_platform(PlanodomConfig(), ds.rig).odometry.start_vehicle_twist
    T0 = np.eye(4)
    T0[2, 3] = 1.0
    bare = simulate_named(
        "paper-loop", "isoclinal", n_epochs=1, trajectory=TwistTrajectory(T0, np.zeros(6))
    )
    assert bare.rig.platform is None
    assert "platform" not in dataset_rig(bare).to_dict()
