"""Write a simulated run as a dataset directory (the project's interchange format)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from planodom.datasets import Dataset, write_dataset
from planodom.simulation.scene import scene_to_dict
from planodom.simulation.simulate import SimulatedRun


def rig_description(run: SimulatedRun, scene_name: str | None = None) -> dict[str, Any]:
    """The ``rig.yaml`` dict of a simulated run.

    Keys: ``epoch_rate`` (Hz); ``rig`` (sensors with ``T_base_sensor`` extrinsics, rates,
    ranges, noise: :meth:`Rig.to_dict`); ``sensor_origins`` ((R, 3): for each ring, the
    position of its sensor in the base frame, metres, for orienting normals);
    ``simulation`` (scene name and polygons, seed, motion, noise sigma in metres).
    """
    sensors = run.rig.sensors
    return {
        "epoch_rate": float(run.epoch_rate),
        "rig": run.rig.to_dict(),
        "sensor_origins": np.repeat(
            [s.T_base_sensor[:3, 3] for s in sensors], [s.n_rings for s in sensors], axis=0
        ).tolist(),
        "simulation": {
            "scene_name": scene_name,
            "seed": int(run.seed),
            "motion": run.motion,
            "noise_sigma": float(max((s.noise_sigma for s in sensors), default=0.0)),
            "scene": scene_to_dict(run.scene),
        },
    }


def write_simulated_dataset(
    run: SimulatedRun, path: str | Path, scene_name: str | None = None, overwrite: bool = False
) -> Dataset:
    """Write ``run`` to ``path``: scans (with ring, t, label), ``poses.tum``, ``rig.yaml``."""
    return write_dataset(
        path,
        run.scans,
        run.times,
        gt_poses=run.poses,
        rig=rig_description(run, scene_name),
        overwrite=overwrite,
    )
