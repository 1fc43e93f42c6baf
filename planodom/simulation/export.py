"""Write a simulated run as a dataset directory (the project's interchange format)."""

from __future__ import annotations

from pathlib import Path

from planodom.datasets import Dataset, write_dataset
from planodom.rig import Rig
from planodom.simulation.scene import scene_to_dict
from planodom.simulation.simulate import SimulatedRun


def dataset_rig(run: SimulatedRun, scene_name: str | None = None) -> Rig:
    """The typed ``rig.yaml`` of a simulated run: :attr:`SimulatedRun.rig` (epoch rate,
    sensor origins per ring, extrinsics) plus, as extra keys, ``sensor_rig`` (the sensor
    models: :meth:`SensorRig.to_dict`) and ``simulation`` (scene name and polygons, seed,
    motion, noise sigma in metres); ``platform`` the trajectory's ("vehicle" for the
    built-in scenes' and the random worlds' routes, "handheld" for a walk)."""
    sensors = run.sensor_rig.sensors
    simulation = {
        "scene_name": scene_name,
        "seed": int(run.seed),
        "motion": run.motion,
        "noise_sigma": float(max((s.noise_sigma for s in sensors), default=0.0)),
        "scene": scene_to_dict(run.scene),
    }
    extra = {"sensor_rig": run.sensor_rig.to_dict(), "simulation": simulation}
    return run.sensor_rig.dataset_rig(run.epoch_rate, extra, run.trajectory.platform)


def write_simulated_dataset(
    run: SimulatedRun, path: str | Path, scene_name: str | None = None, overwrite: bool = False
) -> Dataset:
    """Write ``run`` to ``path``: scans (with ring, t, label), ``poses.tum``, ``rig.yaml``."""
    return write_dataset(
        path,
        run.scans,
        run.times,
        gt_poses=run.poses,
        rig=dataset_rig(run, scene_name),
        overwrite=overwrite,
    )
