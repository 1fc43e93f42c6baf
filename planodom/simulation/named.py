"""One call for the CLI: simulate a built-in scene with a built-in rig by name."""

from __future__ import annotations

from dataclasses import replace

from planodom.errors import ConfigError
from planodom.simulation.random_world import random_world, simulate_world
from planodom.simulation.rigs import RIGS, SensorRig, rig_from_name
from planodom.simulation.scene import Scene
from planodom.simulation.simulate import SimulatedRun, check_seed, simulate
from planodom.simulation.trajectory import (
    Trajectory,
    paper_loop_trajectory,
    urban_canyon_trajectory,
)
from planodom.simulation.worlds import scene_from_name

#: Procedural scenes: ``random`` (outdoor or indoor, drawn), ``random-outdoor``, ``random-indoor``.
RANDOM_SCENES = {"random": None, "random-outdoor": "outdoor", "random-indoor": "indoor"}
#: Rig families of a random world (:func:`planodom.simulation.random_world.random_rig`).
RANDOM_RIG_FAMILIES = ("rig2d", "lidar16", "lidar32", "lidar64")

#: The trajectory that goes with each built-in scene, given the speed in m/s.
TRAJECTORIES = {"paper-loop": paper_loop_trajectory, "urban-canyon": urban_canyon_trajectory}


def simulate_random(
    scene: str = "random",
    rig: str | SensorRig | None = None,
    noise: float | str = 0.0,
    seed: int = 0,
    n_epochs: int | None = None,
    motion: str = "continuous",
    handheld: bool = False,
    noise_seed: int | None = None,
) -> SimulatedRun:
    """Simulate the procedural world of ``seed`` (:func:`random_world`): ``scene`` one of
    :data:`RANDOM_SCENES`; ``rig`` None (the world's own, drawn), a family of
    :data:`RANDOM_RIG_FAMILIES` (drawn within it), or a built-in rig name / a
    :class:`SensorRig` replacing the world's. One lap by default; noise seed ``seed``, or
    ``noise_seed`` (another draw of the noise on the same world).
    ``handheld``: the route walked with a hand-held lidar (a lidar family only)."""
    if scene not in RANDOM_SCENES:
        names = ", ".join(RANDOM_SCENES)
        raise ConfigError(f"unknown random scene '{scene}' (choose from {names})")
    family = rig if isinstance(rig, str) and rig in RANDOM_RIG_FAMILIES else None
    world = random_world(seed, RANDOM_SCENES[scene], family, "handheld" if handheld else "vehicle")
    if isinstance(rig, SensorRig) or (isinstance(rig, str) and rig in RIGS):
        sensor_rig = rig if isinstance(rig, SensorRig) else rig_from_name(rig)
        world = replace(world, sensor_rig=sensor_rig, epoch_rate=10.0, ring_field=True,
                        time_field=True)  # fmt: skip
    elif rig is not None and family is None:
        choices = ", ".join((*RANDOM_RIG_FAMILIES, *RIGS))
        raise ConfigError(f"unknown rig '{rig}' for a random scene (choose from {choices})")
    return simulate_world(world, noise, n_epochs=n_epochs, motion=motion, seed=noise_seed)


def simulate_named(
    scene: str | Scene = "paper-loop",
    rig: str | SensorRig | None = "isoclinal",
    noise: float | str = 0.0,
    seed: int = 0,
    n_epochs: int | None = None,
    duration: float | None = None,
    motion: str = "continuous",
    epoch_rate: float = 10.0,
    speed: float = 2.0,
    trajectory: Trajectory | None = None,
    handheld: bool = False,
    noise_seed: int | None = None,
) -> SimulatedRun:
    """Simulate ``scene`` (``"paper-loop"`` | ``"urban-canyon"`` or a :class:`Scene`) with
    ``rig`` (``"isoclinal"`` | ``"lidar16"`` | ``"lidar32"`` | ``"lidar64"`` or a
    :class:`SensorRig`; None: isoclinal, or a random world's own); the procedural
    ``"random"`` / ``"random-outdoor"`` / ``"random-indoor"`` scenes go to
    :func:`simulate_random` (``seed`` fixes the world).

    Args:
        noise: range noise sigma in metres, or a ``NOISE_PRESETS`` name ("none",
            "lms221", "low-cost", "worst"). seed: noise seed.
        n_epochs / duration (s): length; default one lap / the whole street.
        motion: "continuous" or "snapshot". epoch_rate: Hz. speed: m/s of the built-in
            trajectory. trajectory: overrides it (required for a custom :class:`Scene`).
        handheld: a random scene's route walked with a hand-held lidar (random scenes only).
        noise_seed: another draw of the range noise on the same scene and route (a random
            scene's ``seed`` draws its world; a built-in scene's is the noise seed).
    """
    check_seed(seed)
    if isinstance(scene, str) and scene in RANDOM_SCENES and trajectory is None:
        return simulate_random(scene, rig, noise, seed, n_epochs, motion, handheld, noise_seed)
    if handheld:
        raise ConfigError("--handheld: only with a random scene (random, random-outdoor, ...)")
    if trajectory is None:
        if not isinstance(scene, str):
            raise ConfigError("simulate_named: a custom scene needs a trajectory")
        if scene not in TRAJECTORIES:
            raise ConfigError(f"unknown scene '{scene}' (choose from {', '.join(TRAJECTORIES)})")
        trajectory = TRAJECTORIES[scene](speed=speed)
    scene_obj = scene_from_name(scene) if isinstance(scene, str) else scene
    rig_obj = rig_from_name(rig or "isoclinal") if not isinstance(rig, SensorRig) else rig
    return simulate(scene_obj, trajectory, rig_obj, n_epochs=n_epochs, duration=duration,
                    epoch_rate=epoch_rate, noise_sigma=noise,
                    seed=seed if noise_seed is None else noise_seed, motion=motion)  # fmt: skip
