"""Simulate a rig driving through a scene: per-epoch scans, raw ranges and ground truth.

Epoch ``k`` covers ``[t_k, t_k + 1/epoch_rate)`` with ``t_k = start_time + k / epoch_rate``
and gathers every sweep that *starts* in that window (the last one may end after it).
With ``motion="continuous"`` each firing is cast from the vehicle pose at its own time
and a point's ``t`` is its time relative to ``t_k``; with ``motion="snapshot"`` all sweeps
of the epoch are cast from the pose at ``t_k`` and every ``t`` is 0 (the paper's
simulator, or stop-and-go). Range noise is Gaussian, added along the ray, drawn from
``numpy.random.default_rng([seed, k])`` so that epoch k is reproducible on its own.
All rays of an epoch go to Embree in one call.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from planodom.errors import ConfigError
from planodom.rig import Rig
from planodom.scan import Scan
from planodom.simulation.raycast import RayCaster
from planodom.simulation.rayplan import TimingGroup, plan_rays
from planodom.simulation.rigs import SensorRig
from planodom.simulation.scene import Scene
from planodom.simulation.trajectory import Trajectory

#: Range noise sigma (m) of the paper's four data sets.
NOISE_PRESETS = {"none": 0.0, "lms221": 0.006, "low-cost": 0.02, "worst": 0.10}
MOTIONS = ("continuous", "snapshot")


@dataclass(frozen=True, eq=False)
class SimulatedRun:
    """A simulated run; also a sequence of :class:`Scan` (``len``, indexing).

    Attributes:
        scans: E scans, points (N, 3) in the base frame at each point's own acquisition
            time; ring = global ring id (scanner / lidar beam); t (s) relative to t_k
            (0 in snapshot mode); label = surface id (-1 none). No-return beams dropped.
        ranges: per epoch, per sensor, (sweeps, rays per sweep) float64 raw ranges in
            metres with noise, inf for no return (a lidar's rays ordered column-major:
            ``column * n_beams + beam``).
        sweep_starts: per epoch, per sensor, (sweeps,) absolute sweep start times, s.
        times: (E,) epoch reference times t_k, s. poses: (E, 4, 4) ``T_world_base(t_k)``.
        scene, sensor_rig (its sensors' ``noise_sigma`` = the noise used), trajectory,
        epoch_rate (Hz), motion, seed.
        rig: what a dataset of this run states (:class:`planodom.rig.Rig`, the same as a
            recorded dataset's ``Dataset.rig``), its platform the trajectory's.
    """

    scans: tuple[Scan, ...]
    ranges: tuple[tuple[np.ndarray, ...], ...]
    sweep_starts: tuple[tuple[np.ndarray, ...], ...]
    times: np.ndarray
    poses: np.ndarray
    scene: Scene
    sensor_rig: SensorRig
    trajectory: Trajectory
    epoch_rate: float
    motion: str
    seed: int

    @property
    def rig(self) -> Rig:
        """The typed rig of the run: sensor origins per ring, extrinsics, epoch rate and
        the platform (``trajectory.platform``: "vehicle" for a driven route)."""
        return self.sensor_rig.dataset_rig(self.epoch_rate, platform=self.trajectory.platform)

    def __len__(self) -> int:
        return len(self.scans)

    def __getitem__(self, k: int) -> Scan:
        return self.scans[k]

    def __iter__(self) -> Iterator[Scan]:
        return iter(self.scans)

    @property
    def gt_poses(self) -> np.ndarray:
        """(E, 4, 4) ground-truth ``T_world_base`` at the epochs' reference times."""
        return self.poses


@dataclass(frozen=True, eq=False)
class _Rays:
    """The rays of one timing group in one epoch: S sweeps x F firings x G rays."""

    starts: np.ndarray  # (S,) sweep start times, s
    times: np.ndarray  # (S, F) firing times, s
    shape: tuple[int, int, int]  # (S, F, G)
    rays: np.ndarray  # (S * F * G, 6) world origins (m) and unit directions, float64


def _group_rays(g: TimingGroup, traj: Trajectory, t_k: float, t_end: float, snapshot: bool):
    """World rays of timing group ``g`` for the sweeps starting in ``[t_k, t_end)``."""
    starts = g.sweep_starts(t_k, t_end)
    times = starts[:, None] + g.firing_times[None, :]
    (S, F), G = times.shape, len(g.origins)
    if snapshot:
        R, p = traj.rotations_translations(np.array([t_k]))
        A = np.concatenate([R[0].T, p])  # (4, 3)
        rays = np.broadcast_to(g.homogeneous @ A, (S, F, 2 * G, 3))
    else:
        R, p = traj.rotations_translations(times.ravel())
        A = np.empty((S, F, 4, 3))  # [R^T; p^T] per firing, C-contiguous for matmul
        A[:, :, :3], A[:, :, 3] = R.reshape(S, F, 3, 3).transpose(0, 1, 3, 2), p.reshape(S, F, 3)
        rays = np.matmul(g.homogeneous, A)  # (S, F, 2G, 3)
    return _Rays(starts, times, (S, F, G), rays.reshape(S * F * G, 6))


def _returns(g: TimingGroup, rays: _Rays, ranges: np.ndarray, labels: np.ndarray, dt: np.ndarray):
    """Points (base frame at their own time), rings, times and labels of the finite
    returns of one group, in acquisition order (sweep, firing, ray)."""
    S, F, G = rays.shape
    idx = np.flatnonzero(np.isfinite(ranges))
    fg, g_i = idx % (F * G), idx % G
    dirs = g.directions.reshape(-1, 3).take(fg, axis=0)
    pts = g.origins.take(g_i, axis=0) + ranges.take(idx)[:, None] * dirs
    return pts, g.rings.take(g_i), dt.ravel().take(idx // G), labels.take(idx)


@dataclass(frozen=True, eq=False)
class SimulatedEpoch:
    """One epoch: its :class:`Scan`, per-sensor raw ranges (sweeps, rays per sweep) and
    sweep start times (sweeps,) (see :class:`SimulatedRun`)."""

    scan: Scan
    ranges: tuple[np.ndarray, ...]
    sweep_starts: tuple[np.ndarray, ...]


class Simulator:
    """Ray caster and ray plan built once; :meth:`epoch` simulates one epoch at ``t_k``.

    Args: as :func:`simulate` (the rig's sensors' ``noise_sigma`` is the noise used).
    """

    def __init__(
        self,
        scene: Scene,
        trajectory: Trajectory,
        rig: SensorRig,
        epoch_rate: float = 10.0,
        seed: int = 0,
        motion: str = "continuous",
    ) -> None:
        if motion not in MOTIONS:
            raise ConfigError(f"motion must be one of {MOTIONS}, got '{motion}'")
        if not epoch_rate > 0:
            raise ConfigError(f"epoch_rate must be > 0, got {epoch_rate}")
        self.scene, self.trajectory, self.rig = scene, trajectory, rig
        self.epoch_rate, self.seed, self.motion = float(epoch_rate), int(seed), motion
        self.caster, self.groups = RayCaster(scene), plan_rays(rig)
        ranges = {float(s.max_range) for s in rig.sensors}
        sigmas = {float(s.noise_sigma) for s in rig.sensors}
        # scalars when all sensors agree, else None: per-ray arrays are built per epoch
        self._max_range = ranges.pop() if len(ranges) == 1 else None
        self._sigma = sigmas.pop() if len(sigmas) == 1 else None

    def _per_ray(self, name: str, rays: list[_Rays]) -> np.ndarray:
        """(N,) per-ray values of a per-sensor attribute of the timing groups."""
        return _concat(
            [
                np.broadcast_to(getattr(g, name), r.shape).ravel()
                for g, r in zip(self.groups, rays, strict=True)
            ]
        )

    def rays(self, t_k: float) -> np.ndarray:
        """All world rays (N, 6) ``[origin (m), unit direction]`` of the epoch at ``t_k`` (s)."""
        t_end, snapshot = t_k + 1.0 / self.epoch_rate, self.motion == "snapshot"
        return _concat(
            [_group_rays(g, self.trajectory, t_k, t_end, snapshot).rays for g in self.groups]
        )

    def epoch(self, k: int, t_k: float) -> SimulatedEpoch:
        """Epoch number ``k`` (seeds its noise) with reference time ``t_k`` (s)."""
        snapshot = self.motion == "snapshot"
        t_end = t_k + 1.0 / self.epoch_rate
        rays = [_group_rays(g, self.trajectory, t_k, t_end, snapshot) for g in self.groups]
        counts = [int(np.prod(r.shape)) for r in rays]
        hits = self.caster.cast_rays(
            _concat([r.rays for r in rays]),
            self._max_range if self._max_range is not None else self._per_ray("max_range", rays),
        )
        ranges = hits.ranges
        if self._sigma is None or self._sigma > 0:
            sigma = self._sigma if self._sigma is not None else self._per_ray("sigma", rays)
            noise = np.random.default_rng([self.seed, k]).standard_normal(len(ranges))
            ranges = ranges + sigma * noise
        blocks, out_ranges, out_starts, n0 = [], {}, {}, 0
        for g, r, n in zip(self.groups, rays, counts, strict=True):
            rg, lab = ranges[n0 : n0 + n], hits.labels[n0 : n0 + n]
            n0 += n
            dt = np.zeros(r.shape[:2]) if snapshot else r.times - t_k
            blocks.append(_returns(g, r, rg, lab, dt))
            rg = rg.reshape(r.shape)
            for i, sl in zip(g.sensors, g.slices, strict=True):
                out_ranges[i], out_starts[i] = (
                    rg[:, :, sl].reshape(r.shape[0], r.shape[1] * (sl.stop - sl.start)),
                    r.starts,
                )
        scan = Scan(*(_concat([b[j] for b in blocks]) for j in range(4)))
        order = range(len(self.rig.sensors))
        return SimulatedEpoch(
            scan, tuple(out_ranges[i] for i in order), tuple(out_starts[i] for i in order)
        )


def _concat(arrays: list[np.ndarray]) -> np.ndarray:
    return arrays[0] if len(arrays) == 1 else np.concatenate(arrays)


def resolve_noise(noise: float | str | None, rig: SensorRig) -> SensorRig:
    """The rig with range noise ``noise`` (m, or a :data:`NOISE_PRESETS` name; None keeps
    the rig's own per-sensor values)."""
    if noise is None:
        return rig
    if isinstance(noise, str):
        if noise not in NOISE_PRESETS:
            raise ConfigError(f"unknown noise preset '{noise}' ({', '.join(NOISE_PRESETS)})")
        noise = NOISE_PRESETS[noise]
    if not 0 <= float(noise) < math.inf:  # inf made every range NaN, without a word
        raise ConfigError(f"noise sigma must be finite and >= 0 (m), got {noise}")
    return rig.with_noise(float(noise))


def check_seed(seed: object) -> int:
    """``seed`` if it is an integer >= 0 (what numpy's generators take), else ConfigError."""
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ConfigError(f"seed: expected an integer >= 0, got {seed!r} (--seed)")
    return int(seed)


def simulate(
    scene: Scene,
    trajectory: Trajectory,
    rig: SensorRig,
    n_epochs: int | None = None,
    duration: float | None = None,
    epoch_rate: float = 10.0,
    noise_sigma: float | str | None = None,
    seed: int = 0,
    motion: str = "continuous",
    start_time: float = 0.0,
) -> SimulatedRun:
    """Simulate ``n_epochs`` epochs (or ``duration`` s; default: ``trajectory.duration``).

    Args:
        scene: surfaces to hit. trajectory: ground truth ``T_world_base(t)``. rig: sensors.
        epoch_rate: epochs per second (Hz). noise_sigma: range noise std in metres or a
            :data:`NOISE_PRESETS` name; None uses each sensor's ``noise_sigma``.
        seed: noise seed. motion: ``"continuous"`` or ``"snapshot"`` (module docstring).
        start_time: t_0, seconds.
    """
    rig = resolve_noise(noise_sigma, rig)
    check_seed(seed)
    if n_epochs is None:
        span = duration if duration is not None else trajectory.duration
        n_epochs = int(np.floor(span * epoch_rate + 1e-9))
    if n_epochs < 0:
        raise ConfigError(f"n_epochs must be >= 0, got {n_epochs}")
    sim = Simulator(scene, trajectory, rig, epoch_rate, seed, motion)
    times = start_time + np.arange(n_epochs) / epoch_rate
    epochs = [sim.epoch(k, t) for k, t in enumerate(times)]
    return SimulatedRun(
        scans=tuple(e.scan for e in epochs),
        ranges=tuple(e.ranges for e in epochs),
        sweep_starts=tuple(e.sweep_starts for e in epochs),
        times=times,
        poses=trajectory.poses(times) if n_epochs else np.zeros((0, 4, 4)),
        scene=scene,
        sensor_rig=rig,
        trajectory=trajectory,
        epoch_rate=float(epoch_rate),
        motion=motion,
        seed=int(seed),
    )
