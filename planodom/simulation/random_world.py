"""Random worlds: a procedural scene, a closed route through it and a random rig, all
fixed by one seed.

    world = random_world(3)                  # outdoor or indoor, rig drawn too
    run = simulate_world(world, noise=0.02)  # a SimulatedRun (one lap by default)

A :class:`World` also says which point fields its data set has: 2D rigs always give
``ring`` and ``t``; a spinning lidar may come without ``ring`` and / or without ``t``
(the extraction then takes its 3D path without a range image, and cannot deskew).
:func:`issue_world` is the setting of issue 11 (non-Manhattan block, 116 m loop, the
paper-like rig of a pitched front pair and a rolled rear pair, five sweeps per epoch).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from planodom.errors import ConfigError
from planodom.scan import Scan
from planodom.simulation.handheld import random_handheld
from planodom.simulation.procedural import (
    Slope,
    clearance,
    indoor_layout,
    indoor_route,
    indoor_scene,
    outdoor_scene,
    random_route,
)
from planodom.simulation.rigs import SensorRig, isoclinal_rig, lidar_rig, scanner_pose
from planodom.simulation.scene import Scene
from planodom.simulation.sensors import Scanner2D
from planodom.simulation.simulate import SimulatedRun, simulate
from planodom.simulation.trajectory import RouteTrajectory, SpeedProfile, Sway

KINDS = ("outdoor", "indoor")
#: How the route is travelled (:func:`random_world`).
MOTIONS = ("vehicle", "handheld")
#: Smallest distance (m) of an indoor route to a wall (the rig reaches 1.1 m from the base).
MIN_INDOOR_CLEARANCE_M = 1.2
#: Typical vertical fields of view (lowest, highest elevation, deg) per beam count.
LIDAR_VFOV = {16: (-15.0, 15.0), 32: (-25.0, 15.0), 64: (-24.8, 2.0)}


@dataclass(frozen=True, eq=False)
class World:
    """A scene, a closed route, a rig and the data set's fields, drawn from ``seed``.

    Attributes:
        seed: what fixes everything. kind: "outdoor" | "indoor".
        scene, trajectory (one lap = ``trajectory.duration`` s), sensor_rig.
        epoch_rate: Hz. ring_field, time_field: whether the scans carry ``ring`` / ``t``.
        description: what was drawn (rig family, tilts, rates, speed, slope...).
    """

    seed: int
    kind: str
    scene: Scene
    trajectory: RouteTrajectory  # a HandheldTrajectory (a subclass) for a hand-held world
    sensor_rig: SensorRig
    epoch_rate: float
    ring_field: bool = True
    time_field: bool = True
    description: dict[str, Any] = field(default_factory=dict)

    @property
    def lap_epochs(self) -> int:
        """Epochs in one lap of the route."""
        return int(np.floor(self.trajectory.duration * self.epoch_rate + 1e-9))

    @property
    def is_rig2d(self) -> bool:
        return all(isinstance(s, Scanner2D) for s in self.sensor_rig.sensors)


def tilted_pairs_rig(
    front_pitch_deg: float = 20.0,
    rear_roll_deg: float = 30.0,
    fov_deg: float = 180.0,
    step_deg: float = 0.5,
    rate_hz: float = 50.0,
    mount_height: float = 0.8,
) -> SensorRig:
    """Four :class:`Scanner2D` like the paper's: a front pair pitched by +-``front_pitch_deg``
    (scan planes meet along the lateral axis; one looks down ahead, one up ahead) at
    (1.0, +-0.5, h) m and a rear pair rolled by +-``rear_roll_deg`` (meeting along the
    forward axis), looking backwards, at (-1.0, +-0.5, h) m. Rings 0, 1 front, 2, 3 rear."""
    p, r = np.deg2rad(front_pitch_deg), np.deg2rad(rear_roll_deg)
    sensors = []
    for k, sign in enumerate((1.0, -1.0)):
        normal = [sign * np.sin(p), 0.0, np.cos(p)]
        T = scanner_pose([1.0, 0.5 - k, mount_height], normal, [1.0, 0.0, 0.0])
        sensors.append(Scanner2D(T, name=f"front-{k}", fov_deg=fov_deg, step_deg=step_deg,
                                 rate_hz=rate_hz))  # fmt: skip
    for k, sign in enumerate((1.0, -1.0)):
        normal = [0.0, sign * np.sin(r), np.cos(r)]
        T = scanner_pose([-1.0, 0.5 - k, mount_height], normal, [-1.0, 0.0, 0.0])
        sensors.append(Scanner2D(T, name=f"rear-{k}", fov_deg=fov_deg, step_deg=step_deg,
                                 rate_hz=rate_hz))  # fmt: skip
    return SensorRig(tuple(sensors), "tilted-pairs")


def random_rig(rng: np.random.Generator, family: str | None = None):
    """A random rig: ``(SensorRig, epoch_rate Hz, ring_field, time_field, description)``.

    ``family``: "rig2d" (four tilted 2D scanners: the isoclinal layout with random
    inclination and meeting directions, or pitched / rolled pairs; field of view 180 or
    270 deg; step 0.25 / 0.5 / 1 deg; epochs at 5, 10 or 15 Hz of 1-5 sweeps, at most
    75 Hz) or "lidar16" /
    "lidar32" / "lidar64" (10 or 20 Hz, 512 or 1024 columns, ``ring`` and ``t`` each
    present with probability 0.7); None draws one (2D rig half of the time).
    """
    if family is None:
        family = "rig2d" if rng.random() < 0.5 else f"lidar{rng.choice([16, 32, 64])}"
    if family == "rig2d":
        sweeps, epoch_rate = int(rng.integers(1, 6)), float(rng.choice([5.0, 10.0, 15.0]))
        rate = min(sweeps * epoch_rate, 75.0)
        scanner = {"fov_deg": float(rng.choice([180.0, 270.0])),
                   "step_deg": float(rng.choice([0.25, 0.5, 1.0])), "rate_hz": rate}  # fmt: skip
        if rng.random() < 0.5:
            incl, meet = rng.uniform(18.0, 32.0), rng.uniform(30.0, 60.0)
            rig = isoclinal_rig(incl, (meet, -meet), **scanner)
            layout = {"layout": "isoclinal", "inclination_deg": incl, "meet_deg": meet}
        else:
            pitch, roll = rng.uniform(15.0, 30.0), rng.uniform(20.0, 35.0)
            rig = tilted_pairs_rig(pitch, roll, **scanner)
            layout = {"layout": "tilted-pairs", "pitch_deg": pitch, "roll_deg": roll}
        desc = {"family": "rig2d", "sweeps_per_epoch": rate / epoch_rate, **layout, **scanner}
        return rig, epoch_rate, True, True, desc
    if family not in ("lidar16", "lidar32", "lidar64"):
        raise ConfigError(f"unknown rig family '{family}' (rig2d, lidar16, lidar32, lidar64)")
    beams = int(family[5:])
    rate, columns = float(rng.choice([10.0, 20.0])), int(rng.choice([512, 1024]))
    ring, time = bool(rng.random() < 0.7), bool(rng.random() < 0.7)
    rig = lidar_rig(beams, LIDAR_VFOV[beams], n_columns=columns, rate_hz=rate)
    desc = {"family": family, "rate_hz": rate, "columns": columns, "ring": ring, "time": time}
    return rig, rate, ring, time, desc


def _sway(rng: np.random.Generator, lap_s: float, amplitude_deg: float = 1.5) -> Sway:
    """Roll and pitch up to +-``amplitude_deg`` and heave of 1-5 cm, each at a whole number
    of cycles per lap (so that the route closes in all six DoF)."""

    def hz(lo: float, hi: float) -> float:
        return max(1, round(rng.uniform(lo, hi) * lap_s)) / lap_s

    return Sway(
        roll=np.deg2rad(rng.uniform(0.5, 1.0) * amplitude_deg),
        roll_hz=hz(0.15, 0.6),
        pitch=np.deg2rad(rng.uniform(0.5, 1.0) * amplitude_deg),
        pitch_hz=hz(0.1, 0.5),
        heave=rng.uniform(0.01, 0.05),
        heave_hz=hz(0.2, 0.8),
    )


def _profile(rng: np.random.Generator, speed: float, lap_s: float, change: float) -> SpeedProfile:
    """Two harmonics (2 and 3 per lap) that change the speed by up to +-``change`` of it."""
    harmonics = []
    for m in (2, 3):
        a = rng.uniform(0.3, 0.5) * change * speed * lap_s / (2 * np.pi * m)
        harmonics.append((m, float(a), float(rng.uniform(0, 2 * np.pi))))
    return SpeedProfile(tuple(harmonics))


def _route_trajectory(rng, waypoints, speed, slope: Slope, change=0.35) -> RouteTrajectory:
    """The closed route at ``speed`` m/s on average, with speed changes and sway."""
    lap = RouteTrajectory(waypoints, speed=speed).duration
    sway = _sway(rng, lap)
    return RouteTrajectory(waypoints, speed=speed, sway=sway, gradient=(slope.gx, slope.gy),
                           profile=_profile(rng, speed, lap, change))  # fmt: skip


def _path_xy(traj: RouteTrajectory, step_m: float = 1.0) -> np.ndarray:
    """(M, 2) positions along one lap, about ``step_m`` apart (at the mean speed)."""
    t = np.linspace(0.0, traj.duration, max(50, int(traj.length / step_m)), endpoint=False)
    return traj.rotations_translations(t)[1][:, :2]


def random_world(
    seed: int, kind: str | None = None, rig: str | None = None, motion: str = "vehicle"
) -> World:
    """The world of ``seed``: ``kind`` "outdoor" / "indoor" (None: indoor one time in four)
    and ``rig`` family (see :func:`random_rig`; None: drawn).

    ``motion``: "vehicle" (the route driven, speed changes, +-1.5 deg sway) or "handheld"
    (:func:`planodom.simulation.handheld.random_handheld`: the same route walked with a
    hand-held lidar, its yaw swinging about the heading; drawn from an rng stream of its
    own, so the scene is the vehicle world's with the same rig; lidar families only, None
    drawing one of the three from that stream)."""
    if motion not in MOTIONS:
        raise ConfigError(f"unknown world motion '{motion}' (choose from {', '.join(MOTIONS)})")
    walk = np.random.default_rng([int(seed), 11, 2]) if motion == "handheld" else None
    if walk is not None:
        rig = rig or f"lidar{walk.choice([16, 32, 64])}"
        if rig == "rig2d":
            raise ConfigError("a hand-held world carries a lidar (lidar16, lidar32, lidar64)")
    rng = np.random.default_rng([int(seed), 11])
    if kind is None:
        kind = "indoor" if rng.random() < 0.25 else "outdoor"
    if kind not in KINDS:
        raise ConfigError(f"unknown world kind '{kind}' (choose from {', '.join(KINDS)})")
    sensor_rig, epoch_rate, ring, time, rig_desc = random_rig(rng, rig)
    if kind == "outdoor":
        grade = rng.uniform(0.0, 0.04)
        heading = rng.uniform(0, 2 * np.pi)
        slope = Slope(grade * np.cos(heading), grade * np.sin(heading))
        route = random_route(rng)
        traj = _route_trajectory(rng, route, rng.uniform(1.5, 4.0), slope)
        scene = outdoor_scene(rng, _path_xy(traj), slope)
        world_desc = {"grade": grade, "speed_mps": traj.speed, "lap_m": traj.length}
    else:
        for _ in range(20):  # redraw the rare layout whose rooms come too near the route
            layout = indoor_layout(rng)
            route = indoor_route(layout)
            traj = _route_trajectory(rng, route, rng.uniform(0.8, 1.8), Slope(), 0.3)
            scene = indoor_scene(rng, layout)
            if clearance(_path_xy(traj, 0.2), scene) >= MIN_INDOOR_CLEARANCE_M:
                break
        slope = Slope()
        world_desc = {"width_m": layout.width, "ceiling_m": layout.ceiling,
                      "speed_mps": traj.speed, "lap_m": traj.length}  # fmt: skip
    if walk is not None:  # same path (same clearance), walked by hand
        traj, walk_desc = random_handheld(walk, route, (slope.gx, slope.gy))
        world_desc |= walk_desc
    desc = {"kind": kind, **world_desc, **rig_desc}
    name = f"random-{kind}-{seed}" + ("-handheld" if walk is not None else "")
    return World(int(seed), kind, replace(scene, name=name), traj,
                 sensor_rig, epoch_rate, ring, time, desc)  # fmt: skip


def issue_world(seed: int = 0) -> World:
    """Issue 11's setting: an outdoor block (walls at arbitrary yaw, heights 6-15 m, low
    fences) around a 116 m loop driven in 60 s (600 epochs at 10 Hz, speed changes), roll
    and pitch +-1.5 deg and small height changes, on flat ground; the rig of
    :func:`tilted_pairs_rig` (front pair pitched +-20 deg, rear pair rolled +-30 deg, 180
    deg, 0.5 deg steps, 50 Hz: five sweeps per epoch); ring and time fields."""
    rng = np.random.default_rng([int(seed), 116])
    route = random_route(rng, (116.0, 116.0))
    lap_m = RouteTrajectory(route).length
    traj = _route_trajectory(rng, route, lap_m / 60.0, Slope(), change=0.3)
    scene = outdoor_scene(rng, _path_xy(traj), Slope())
    rig = tilted_pairs_rig(20.0, 30.0, 180.0, 0.5, 50.0)
    desc = {"kind": "outdoor", "family": "rig2d", "layout": "tilted-pairs", "lap_m": traj.length}
    return World(int(seed), "outdoor", replace(scene, name=f"issue-11-{seed}"), traj, rig,
                 10.0, True, True, desc)  # fmt: skip


def with_fields(scan: Scan, ring: bool, time: bool) -> Scan:
    """``scan`` without its ``ring`` and / or ``t`` field (labels kept)."""
    return Scan(scan.points, scan.ring if ring else None, scan.t if time else None, scan.label)


def simulate_world(
    world: World,
    noise: float | str = 0.0,
    n_epochs: int | None = None,
    seed: int | None = None,
    motion: str = "continuous",
    all_fields: bool = False,
) -> SimulatedRun:
    """Simulate ``n_epochs`` (default one lap) of ``world`` with range noise ``noise`` (m or
    a preset name); noise seed ``seed`` (default the world's). The scans carry the world's
    fields (all of them with ``all_fields``: what the oracle needs; :func:`world_fields`
    drops the others later); the run's ``sensor_rig`` and ``trajectory`` are the world's."""
    run = simulate(world.scene, world.trajectory, world.sensor_rig,
                   n_epochs=world.lap_epochs if n_epochs is None else n_epochs,
                   epoch_rate=world.epoch_rate, noise_sigma=noise,
                   seed=world.seed if seed is None else seed, motion=motion)  # fmt: skip
    return run if all_fields else world_fields(world, run)


def world_fields(world: World, run: SimulatedRun) -> SimulatedRun:
    """``run`` with only the point fields the world's data set has."""
    if world.ring_field and world.time_field:
        return run
    scans = tuple(with_fields(s, world.ring_field, world.time_field) for s in run.scans)
    return replace(run, scans=scans)
