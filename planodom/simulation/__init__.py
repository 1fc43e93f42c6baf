"""Simulation platform: scenes of planar polygons, trajectories, rigs, ray casting, noise.

Typical use::

    from planodom.simulation import simulate_named
    run = simulate_named("paper-loop", "isoclinal", noise=0.006, seed=0, n_epochs=100)
    scan = run[0]            # planodom.scan.Scan, base frame, labels = surface ids
    run.gt_poses             # (E, 4, 4) T_world_base at the epochs' reference times
"""

from planodom.simulation.named import simulate_named
from planodom.simulation.observability import (
    EpochObservability,
    ObservabilityStats,
    RingTraces,
    epoch_observability,
    observability,
    ring_traces,
)
from planodom.simulation.raycast import RayCaster, RayHits
from planodom.simulation.rigs import (
    SensorRig,
    isoclinal_normals,
    isoclinal_rig,
    lidar_rig,
    load_sensor_rig,
    rig_from_name,
    save_sensor_rig,
    scanner_pose,
)
from planodom.simulation.scene import (
    Scene,
    Surface,
    ground,
    load_scene,
    save_scene,
    scene_from_dict,
    scene_to_dict,
    wall,
)
from planodom.simulation.sensors import Scanner2D, Sensor, SpinningLidar
from planodom.simulation.simulate import (
    NOISE_PRESETS,
    SimulatedEpoch,
    SimulatedRun,
    Simulator,
    simulate,
)
from planodom.simulation.trajectory import (
    StaticTrajectory,
    Sway,
    Trajectory,
    TwistTrajectory,
    WaypointTrajectory,
    paper_loop_trajectory,
    urban_canyon_trajectory,
)
from planodom.simulation.worlds import (
    PAPER_LOOP_ROUTE,
    URBAN_CANYON_ROUTE,
    paper_loop,
    random_walls,
    scene_from_name,
    urban_canyon,
)

__all__ = [
    "NOISE_PRESETS",
    "PAPER_LOOP_ROUTE",
    "URBAN_CANYON_ROUTE",
    "EpochObservability",
    "ObservabilityStats",
    "RayCaster",
    "RayHits",
    "RingTraces",
    "Scanner2D",
    "Scene",
    "SensorRig",
    "Sensor",
    "SimulatedEpoch",
    "SimulatedRun",
    "Simulator",
    "SpinningLidar",
    "StaticTrajectory",
    "Surface",
    "Sway",
    "Trajectory",
    "TwistTrajectory",
    "WaypointTrajectory",
    "epoch_observability",
    "ground",
    "isoclinal_normals",
    "isoclinal_rig",
    "lidar_rig",
    "load_sensor_rig",
    "load_scene",
    "observability",
    "paper_loop",
    "paper_loop_trajectory",
    "random_walls",
    "rig_from_name",
    "ring_traces",
    "save_sensor_rig",
    "save_scene",
    "scanner_pose",
    "scene_from_dict",
    "scene_from_name",
    "scene_to_dict",
    "simulate",
    "simulate_named",
    "urban_canyon",
    "urban_canyon_trajectory",
    "wall",
]
