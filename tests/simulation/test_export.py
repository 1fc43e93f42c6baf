"""A simulated run written as a dataset reads back identically."""

from __future__ import annotations

import numpy as np

from planodom.datasets import load_dataset
from planodom.simulation import SensorRig, simulate_named
from planodom.simulation.export import write_simulated_dataset


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
