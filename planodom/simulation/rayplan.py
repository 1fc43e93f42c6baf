"""Which rays a rig fires in an epoch, when, and from where: precomputed once per rig.

Sensors with the same timing (rate, time offset, firing times) form a group that shares
the vehicle poses of its firings, so the trajectory is evaluated once per firing instant
and not once per ray: four synchronised 2D scanners need 361 poses a sweep, a lidar one
per column. Ray directions and origins are precomputed in the base frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planodom.simulation.rigs import SensorRig


@dataclass(frozen=True, eq=False)
class TimingGroup:
    """Sensors sharing one firing schedule.

    Attributes:
        sensors: indices into ``rig.sensors``. slices: each one's ray columns in ``G``.
        rate_hz, time_offset: sweeps per second; start of sweep 0, seconds.
        firing_times: (F,) seconds from a sweep start.
        directions: (F, G, 3) unit ray directions in the base frame (G: all the rays of
            one firing over the group's sensors).
        origins: (G, 3) ray origins in the base frame, metres.
        rings: (G,) int32 global ring id. max_range, sigma: (G,) metres.
    """

    sensors: tuple[int, ...]
    slices: tuple[slice, ...]
    rate_hz: float
    time_offset: float
    firing_times: np.ndarray
    directions: np.ndarray
    origins: np.ndarray
    rings: np.ndarray
    max_range: np.ndarray
    sigma: np.ndarray
    _homogeneous: np.ndarray = field(init=False, repr=False)

    @property
    def homogeneous(self) -> np.ndarray:
        """(F, 2G, 4) rows ``(o_g, 1)``, ``(d_fg, 0)`` per ray: ``homogeneous @ A`` with
        ``A = [R^T; p^T]`` (4, 3) gives each ray's world origin and direction, in the
        layout of a (F * G, 6) ray array."""
        return self._homogeneous

    def __post_init__(self) -> None:
        F, G = self.directions.shape[:2]
        h = np.zeros((F, G, 2, 4))
        h[:, :, 0, :3], h[:, :, 0, 3] = self.origins, 1.0
        h[:, :, 1, :3] = self.directions
        object.__setattr__(self, "_homogeneous", h.reshape(F, 2 * G, 4))

    def sweep_starts(self, t0: float, t1: float) -> np.ndarray:
        """(S,) start times (s) of the sweeps starting in ``[t0, t1)``."""
        eps = 1e-9
        i0 = int(np.ceil((t0 - self.time_offset) * self.rate_hz - eps))
        i1 = int(np.ceil((t1 - self.time_offset) * self.rate_hz - eps))
        return self.time_offset + np.arange(i0, i1) / self.rate_hz


def plan_rays(rig: SensorRig) -> list[TimingGroup]:
    """Group the rig's sensors by timing and precompute their rays in the base frame."""
    keys: dict[tuple, list[int]] = {}
    for i, s in enumerate(rig.sensors):
        key = (float(s.rate_hz), float(s.time_offset), s.firing_times.tobytes())
        keys.setdefault(key, []).append(i)
    offsets = rig.ring_offsets
    groups = []
    for members in keys.values():
        dirs, origins, rings, rmax, sigma, slices, g = [], [], [], [], [], [], 0
        for i in members:
            s = rig.sensors[i]
            R, t = s.T_base_sensor[:3, :3], s.T_base_sensor[:3, 3]
            G = s.directions.shape[1]
            dirs.append(s.directions @ R.T)
            origins.append(np.repeat(t[None], G, axis=0))
            rings.append(offsets[i] + np.arange(G))
            rmax.append(np.full(G, s.max_range))
            sigma.append(np.full(G, s.noise_sigma))
            slices.append(slice(g, g + G))
            g += G
        first = rig.sensors[members[0]]
        groups.append(
            TimingGroup(
                sensors=tuple(members),
                slices=tuple(slices),
                rate_hz=float(first.rate_hz),
                time_offset=float(first.time_offset),
                firing_times=first.firing_times,
                directions=np.ascontiguousarray(np.concatenate(dirs, axis=1)),
                origins=np.concatenate(origins),
                rings=np.concatenate(rings).astype(np.int32),
                max_range=np.concatenate(rmax),
                sigma=np.concatenate(sigma),
            )
        )
    return groups
