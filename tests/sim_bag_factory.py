"""A ROS 2 bag of the paper's rig: a simulated run written as four LaserScan topics with
/tf_static extrinsics and an /odom reference (the truth), for the CLI tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from bag_factory import T0_NS, BagWriter

from planodom.simulation import simulate_named
from planodom.simulation.sensors import Scanner2D
from planodom.simulation.simulate import SimulatedRun


def simulated_run(epochs: int = 12, noise: float | str = "lms221") -> SimulatedRun:
    """The paper loop with the isoclinal rig (four tilted 2D scanners), continuous motion."""
    return simulate_named("paper-loop", "isoclinal", noise=noise, seed=1, n_epochs=epochs)


def write_simulated_bag(path: Path, run: SimulatedRun, storage: str = "sqlite3") -> list[str]:
    """Write ``run`` as a ROS 2 bag; the simulation's time 0 is the bag's ``T0_NS``.

    Returns:
        the scan topics, in the rig's ring order.
    """
    sensors = run.sensor_rig.sensors
    assert all(isinstance(s, Scanner2D) for s in sensors)
    topics = [f"/scan_{k}" for k in range(len(sensors))]
    with BagWriter(path, 2, storage) as bw:
        static = [
            bw.transform_stamped(T0_NS, "base_link", f"laser_{k}", s.T_base_sensor)
            for k, s in enumerate(sensors)
        ]
        bw.write("/tf_static", bw.tf(static), T0_NS)
        events = []
        for e in range(len(run)):
            for k, s in enumerate(sensors):
                for sweep, start in enumerate(run.sweep_starts[e][k]):
                    stamp = T0_NS + round(start * 1e9)
                    events.append((stamp, topics[k], (k, s, run.ranges[e][k][sweep])))
        t_end = run.times[-1] + 1.0 / run.epoch_rate
        for t in np.arange(run.times[0] - 0.05, t_end + 0.05, 0.005):
            stamp = T0_NS + round(t * 1e9)
            events.append((stamp, "/odom", bw.odometry(stamp, run.trajectory.pose(t))))
        for stamp, topic, item in sorted(events, key=lambda x: (x[0], x[1])):
            if topic != "/odom":
                k, s, ranges = item
                item = _laser_scan(bw, stamp, f"laser_{k}", s, ranges)
            bw.write(topic, item, stamp)
    return topics


def _laser_scan(bw: BagWriter, stamp: int, frame: str, s: Scanner2D, ranges: np.ndarray):
    a = s.beam_angles
    dt = float(s.firing_times[1] - s.firing_times[0])
    return bw.T["sensor_msgs/msg/LaserScan"](
        header=bw.header(stamp, frame),
        angle_min=float(a[0]),
        angle_max=float(a[-1]),
        angle_increment=float(a[1] - a[0]),
        time_increment=dt,
        scan_time=1.0 / s.rate_hz,
        range_min=0.05,
        range_max=float(s.max_range),
        ranges=np.where(np.isfinite(ranges), ranges, np.inf).astype(np.float32),
        intensities=np.zeros(len(ranges), dtype=np.float32),
    )
