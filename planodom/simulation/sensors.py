"""Laser sensors: a 2D line scanner (SICK LMS 221-like) and a spinning multi-beam lidar.

A sensor fires its rays in *firings*: a firing is one instant and ``G`` rays (one beam
of a 2D scanner; one column of ``n_beams`` rays of a lidar). A sweep is ``F`` firings;
sweep ``i`` starts at ``time_offset + i / rate_hz`` and firing ``f`` of it at that plus
``firing_times[f]``. Ray directions are fixed in the sensor frame: ``directions`` is
(F, G, 3) unit vectors. The simulator poses every firing with the vehicle pose at its
own time.

Sensor frames: a 2D scanner sweeps its x-y plane (its scan-plane normal is its z axis),
beam angles from ``-fov/2`` to ``+fov/2`` about z, 0 along x; its mirror turns once per
period, so a 180 deg sweep takes half of ``1 / rate_hz``. A lidar spins about its z axis
counter-clockwise, column 0 looking backwards (azimuth -180 deg) so that the seam is
behind; beams from the lowest to the highest elevation of ``vfov_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar

import numpy as np

from planodom.errors import ConfigError
from planodom.geometry import rotation_problem


def _check_transform(T: np.ndarray, name: str) -> np.ndarray:
    T = np.asarray(T, dtype=np.float64)
    if T.shape != (4, 4) or not np.all(np.isfinite(T)):
        raise ConfigError(f"sensor '{name}': T_base_sensor must be a finite 4x4 matrix")
    problem = rotation_problem(T[:3, :3])
    if problem is not None:
        raise ConfigError(f"sensor '{name}': T_base_sensor is not a rigid transform ({problem})")
    if not np.allclose(T[3], [0, 0, 0, 1]):
        raise ConfigError(f"sensor '{name}': T_base_sensor last row must be [0, 0, 0, 1]")
    return T


@dataclass(frozen=True, eq=False)
class _Sensor:
    """Fields common to every sensor (see the subclasses)."""

    T_base_sensor: np.ndarray = field(default_factory=lambda: np.eye(4))
    rate_hz: float = 10.0
    max_range: float = 80.0
    noise_sigma: float = 0.0
    time_offset: float = 0.0
    name: str = "sensor"
    type: ClassVar[str] = "sensor"

    def __post_init__(self) -> None:
        object.__setattr__(self, "T_base_sensor", _check_transform(self.T_base_sensor, self.name))
        for key in ("rate_hz", "max_range"):
            if not getattr(self, key) > 0:
                raise ConfigError(f"sensor '{self.name}': {key} must be > 0")
        if not self.noise_sigma >= 0:
            raise ConfigError(f"sensor '{self.name}': noise_sigma must be >= 0")
        self._check()

    def _check(self) -> None:
        """Checks of a subclass's own fields (raise :class:`ConfigError`)."""

    def _own_dict(self) -> dict[str, Any]:
        """A subclass's own fields for ``rig.yaml``."""
        return {}

    @property
    def n_rings(self) -> int:
        """Number of scan lines (rings) this sensor contributes."""
        return int(self.directions.shape[1])

    @property
    def sweep_duration(self) -> float:
        """Seconds from the first to just after the last firing of a sweep."""
        return float(self.firing_times[-1]) + 1e-9

    @property
    def directions(self) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    @property
    def firing_times(self) -> np.ndarray:  # pragma: no cover - overridden
        raise NotImplementedError

    def to_dict(self) -> dict[str, Any]:
        """Plain dict for a sensor rig file: the common fields, then the subclass's own."""
        return {
            "type": self.type,
            "name": self.name,
            "T_base_sensor": self.T_base_sensor.tolist(),
            "rate_hz": float(self.rate_hz),
            "max_range": float(self.max_range),
            "noise_sigma": float(self.noise_sigma),
            "time_offset": float(self.time_offset),
            **self._own_dict(),
        }


@dataclass(frozen=True, eq=False)
class Scanner2D(_Sensor):
    """A 2D line scanner like the SICK LMS 221: 180 deg, 0.5 deg steps, 75 Hz, 80 m.

    Attributes (besides the common ones: ``T_base_sensor`` (4, 4), ``rate_hz`` sweeps/s,
    ``max_range`` m, ``noise_sigma`` m, ``time_offset`` s, ``name``):
        fov_deg: field of view in the scan plane, degrees. step_deg: angular step, degrees.
    """

    type: ClassVar[str] = "scanner2d"
    name: str = "scanner"
    fov_deg: float = 180.0
    step_deg: float = 0.5
    rate_hz: float = 75.0

    def _check(self) -> None:
        if not (0 < self.fov_deg <= 360 and 0 < self.step_deg <= self.fov_deg):
            raise ConfigError(f"sensor '{self.name}': need 0 < step_deg <= fov_deg <= 360")

    @cached_property
    def beam_angles(self) -> np.ndarray:
        """(B,) beam angles in the scan plane, radians, from -fov/2 to +fov/2."""
        n = int(round(self.fov_deg / self.step_deg)) + 1
        return np.deg2rad(np.linspace(-self.fov_deg / 2, self.fov_deg / 2, n))

    @cached_property
    def directions(self) -> np.ndarray:
        """(B, 1, 3) unit beam directions in the sensor frame (in its x-y plane)."""
        a = self.beam_angles
        return np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], axis=1)[:, None, :]

    @cached_property
    def firing_times(self) -> np.ndarray:
        """(B,) seconds from the sweep start: the mirror turns 360 deg per period."""
        a = self.beam_angles - self.beam_angles[0]
        return a / (2.0 * np.pi * self.rate_hz)

    @property
    def scan_plane_normal(self) -> np.ndarray:
        """(3,) unit normal of the scan plane in the base frame (the sensor's z axis)."""
        return self.T_base_sensor[:3, 2].copy()

    def _own_dict(self) -> dict[str, Any]:
        return {"fov_deg": self.fov_deg, "step_deg": self.step_deg}


@dataclass(frozen=True, eq=False)
class SpinningLidar(_Sensor):
    """A spinning multi-beam lidar: ``n_beams`` rings over ``vfov_deg`` = (lowest, highest)
    elevation in degrees, ``n_columns`` firings per revolution, ``rate_hz`` revolutions/s."""

    type: ClassVar[str] = "lidar"
    name: str = "lidar"
    n_beams: int = 32
    vfov_deg: tuple[float, float] = (-25.0, 15.0)
    n_columns: int = 1024
    rate_hz: float = 10.0
    max_range: float = 100.0

    def _check(self) -> None:
        lo, hi = self.vfov_deg
        if self.n_beams < 1 or self.n_columns < 1 or not -90 <= lo <= hi <= 90:
            raise ConfigError(f"sensor '{self.name}': need n_beams, n_columns >= 1, lo <= hi")
        object.__setattr__(self, "vfov_deg", (float(lo), float(hi)))

    @cached_property
    def elevations(self) -> np.ndarray:
        """(G,) beam elevations, radians, lowest first."""
        return np.deg2rad(np.linspace(*self.vfov_deg, self.n_beams))

    @cached_property
    def azimuths(self) -> np.ndarray:
        """(F,) column azimuths, radians, from -pi, counter-clockwise."""
        return -np.pi + 2.0 * np.pi * np.arange(self.n_columns) / self.n_columns

    @cached_property
    def directions(self) -> np.ndarray:
        """(F, G, 3) unit ray directions in the sensor frame."""
        az, el = self.azimuths[:, None], self.elevations[None, :]
        return np.stack(
            np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)),
            axis=-1,
        )

    @cached_property
    def firing_times(self) -> np.ndarray:
        """(F,) seconds from the sweep start."""
        return np.arange(self.n_columns) / (self.n_columns * self.rate_hz)

    def _own_dict(self) -> dict[str, Any]:
        return {
            "n_beams": self.n_beams,
            "vfov_deg": list(self.vfov_deg),
            "n_columns": self.n_columns,
        }


Sensor = Scanner2D | SpinningLidar
