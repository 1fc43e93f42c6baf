"""One call for the CLI: simulate a built-in scene with a built-in rig by name."""

from __future__ import annotations

from planodom.errors import ConfigError
from planodom.simulation.rigs import SensorRig, rig_from_name
from planodom.simulation.scene import Scene
from planodom.simulation.simulate import SimulatedRun, simulate
from planodom.simulation.trajectory import (
    Trajectory,
    paper_loop_trajectory,
    urban_canyon_trajectory,
)
from planodom.simulation.worlds import scene_from_name

#: The trajectory that goes with each built-in scene, given the speed in m/s.
TRAJECTORIES = {"paper-loop": paper_loop_trajectory, "urban-canyon": urban_canyon_trajectory}


def simulate_named(
    scene: str | Scene = "paper-loop",
    rig: str | SensorRig = "isoclinal",
    noise: float | str = 0.0,
    seed: int = 0,
    n_epochs: int | None = None,
    duration: float | None = None,
    motion: str = "continuous",
    epoch_rate: float = 10.0,
    speed: float = 2.0,
    trajectory: Trajectory | None = None,
) -> SimulatedRun:
    """Simulate ``scene`` (``"paper-loop"`` | ``"urban-canyon"`` or a :class:`Scene`) with
    ``rig`` (``"isoclinal"`` | ``"lidar16"`` | ``"lidar32"`` | ``"lidar64"`` or a
    :class:`SensorRig`).

    Args:
        noise: range noise sigma in metres, or a ``NOISE_PRESETS`` name ("none",
            "lms221", "low-cost", "worst"). seed: noise seed.
        n_epochs / duration (s): length; default one lap / the whole street.
        motion: "continuous" or "snapshot". epoch_rate: Hz. speed: m/s of the built-in
            trajectory. trajectory: overrides it (required for a custom :class:`Scene`).
    """
    if trajectory is None:
        if not isinstance(scene, str):
            raise ConfigError("simulate_named: a custom scene needs a trajectory")
        if scene not in TRAJECTORIES:
            raise ConfigError(f"unknown scene '{scene}' (choose from {', '.join(TRAJECTORIES)})")
        trajectory = TRAJECTORIES[scene](speed=speed)
    scene_obj = scene_from_name(scene) if isinstance(scene, str) else scene
    rig_obj = rig_from_name(rig) if isinstance(rig, str) else rig
    return simulate(scene_obj, trajectory, rig_obj, n_epochs=n_epochs, duration=duration,
                    epoch_rate=epoch_rate, noise_sigma=noise, seed=seed, motion=motion)  # fmt: skip
