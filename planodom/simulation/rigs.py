"""Simulated sensor rigs: the isoclinal 2D-scanner rig (default) and spinning lidars.

A :class:`SensorRig` is a tuple of sensor models (:class:`Scanner2D`,
:class:`SpinningLidar`) with their extrinsics ``T_base_sensor``: what the simulator casts
rays with. Rings are numbered over the rig: a 2D scanner is one ring, a lidar ``n_beams``
rings, in sensor order (:attr:`SensorRig.ring_offsets`). What a dataset states about its
rig, recorded or simulated, is the typed :class:`planodom.rig.Rig`
(:meth:`SensorRig.dataset_rig`: sensor origins per ring, extrinsics, epoch rate).

Default isoclinal geometry (see the brief's RIG.md). A wall with horizontal normal n
gets non-parallel traces from two scan planes with normals m1, m2 iff ``n . h != 0``,
``h = m1 x m2`` being the direction in which the scan planes meet; for two planes rolled
by +-theta about a horizontal h the traces cross at ``2 atan(tan(theta) |n . h| / |h|)``
(:func:`isoclinal_normals`). A pair therefore
sees as planes all walls except those whose normal is perpendicular to h, and no single
pair covers every orientation. The default (:func:`isoclinal_rig`) uses two pairs of
scan planes inclined by 25 deg to the horizontal, each pair rolled by +-25 deg about its
horizontal meeting direction: the forward pair (looking forward, 10 deg down) meets
along azimuth +45 deg, the backward pair (looking backward) along -45 deg. Their blind
orientations (wall normals at -45 and +45 deg) are 90 deg apart, so a wall blind to one
pair is seen at the best angle by the other, and walls along or across the road (the
common case) get traces crossing at 36.5 deg from both pairs. Mixed pairs (a
forward and a backward scanner on the same wall) add crossings. The ground gets two
distinct parallel traces from each pair.

Checked numerically with ``experiments/observability.py --compare`` (one noise-free lap
of the paper loop, 730 epochs; "observable" = two traces more than 10 deg apart): walls
observable as planes per epoch min/median/max 3/6/10, non-parallel pairs of them 2/13/42,
at least one pair in 100 % of epochs (with a 20 deg threshold: 2/5/8, 0/8/25, 99.6 %).
Both pairs meeting forward (rolled scanners) give 2/3/5 observable walls, both meeting
laterally (nodding) leave 23 % of epochs without a pair; 15 deg inclination reaches more
walls but its traces on walls along or across the road cross at only 21.5 deg (its
observable count drops to 1/5/9 at 20 deg), 35 deg reaches fewer walls; meeting at
+-60 deg is about the same as +-45 deg.
"""

from __future__ import annotations

import typing
from collections.abc import Callable
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from planodom.config.section import holds_bool
from planodom.errors import ConfigError, DatasetError
from planodom.geometry import make_transform
from planodom.rig import Rig
from planodom.simulation.sensors import Scanner2D, Sensor, SpinningLidar
from planodom.yaml_files import read_yaml_file

__all__ = [
    "SensorRig",
    "Scanner2D",
    "SpinningLidar",
    "isoclinal_rig",
    "lidar_rig",
    "rig_from_name",
    "scanner_pose",
    "load_sensor_rig",
    "save_sensor_rig",
]


@dataclass(frozen=True, eq=False)
class SensorRig:
    """Sensor models mounted on the vehicle base; ``name`` is free text."""

    sensors: tuple[Sensor, ...]
    name: str = "rig"

    def __post_init__(self) -> None:
        if len(self.sensors) == 0:
            raise ConfigError(f"rig '{self.name}' has no sensors")
        object.__setattr__(self, "sensors", tuple(self.sensors))

    def __len__(self) -> int:
        return len(self.sensors)

    @property
    def ring_offsets(self) -> np.ndarray:
        """(S,) int, the first global ring id of each sensor."""
        return np.concatenate([[0], np.cumsum([s.n_rings for s in self.sensors])[:-1]]).astype(int)

    @property
    def n_rings(self) -> int:
        """Total number of rings."""
        return int(sum(s.n_rings for s in self.sensors))

    @property
    def sensor_origins(self) -> np.ndarray:
        """(R, 3) float64, metres: for each ring, its sensor's position in the base frame."""
        origins = [s.T_base_sensor[:3, 3] for s in self.sensors]
        return np.repeat(origins, [s.n_rings for s in self.sensors], axis=0)

    def dataset_rig(
        self,
        epoch_rate_hz: float,
        extra: dict[str, Any] | None = None,
        platform: str | None = None,
    ) -> Rig:
        """The typed :class:`planodom.rig.Rig` a dataset of this rig states: sensor origins
        per ring, extrinsics per sensor, ``epoch_rate_hz``, ``extra`` (kept as given) and
        the ``platform`` carrying it (None: not stated)."""
        return Rig(
            epoch_rate_hz=float(epoch_rate_hz),
            sensor_origins=self.sensor_origins,
            extrinsics=tuple(s.T_base_sensor for s in self.sensors),
            extra=dict(extra or {}),
            platform=platform,
        )

    def with_noise(self, sigma: float) -> SensorRig:
        """The same rig with every sensor's range noise set to ``sigma`` (m)."""
        return replace(self, sensors=tuple(replace(s, noise_sigma=sigma) for s in self.sensors))

    def to_dict(self) -> dict[str, Any]:
        """Plain dict for a sensor rig file (extrinsics as 4x4 lists)."""
        return {"name": self.name, "sensors": [s.to_dict() for s in self.sensors]}

    @classmethod
    def from_dict(cls, data: object, source: str = "rig") -> SensorRig:
        """Rig from :meth:`to_dict` output; errors name ``source`` and the field."""
        if not isinstance(data, dict) or not isinstance(data.get("sensors"), list):
            raise ConfigError(f"{source}: field 'sensors': expected a list of sensors")
        unknown = sorted(set(data) - {"name", "sensors"})
        if unknown:
            raise ConfigError(f"{source}: field '{unknown[0]}': unknown field")
        if not data["sensors"]:  # the file's name was lost in the rig's own error
            raise ConfigError(f"{source}: field 'sensors': the list is empty")
        sensors = [
            _sensor_from_dict(d, source, f"sensors.{i}") for i, d in enumerate(data["sensors"])
        ]
        return cls(tuple(sensors), str(data.get("name", "rig")))


_TYPES: dict[str, type[Scanner2D] | type[SpinningLidar]] = {
    "scanner2d": Scanner2D,
    "lidar": SpinningLidar,
}


def _sensor_from_dict(d: object, source: str, field: str) -> Sensor:
    """One sensor from its dict; errors read ``source: field 'sensors.i.key': message``."""
    if not isinstance(d, dict) or d.get("type") not in _TYPES:
        raise ConfigError(f"{source}: field '{field}.type': expected one of {sorted(_TYPES)}")
    cls = _TYPES[d["type"]]
    kwargs = {k: v for k, v in d.items() if k != "type"}
    unknown = sorted(set(kwargs) - {f.name for f in fields(cls)})
    if unknown:
        raise ConfigError(f"{source}: field '{field}.{unknown[0]}': unknown field")
    for key, value in sorted(kwargs.items()):
        problem = _not_a_number(cls, key, value)
        if problem:
            raise ConfigError(f"{source}: field '{field}.{key}': {problem}")
    if "vfov_deg" in kwargs:
        kwargs["vfov_deg"] = tuple(kwargs["vfov_deg"])
    try:
        return cls(**kwargs)
    except (TypeError, ValueError, ConfigError) as exc:
        raise ConfigError(f"{source}: field '{field}': {exc}") from exc


def _not_a_number(cls: type, key: str, value: Any) -> str | None:
    """What is wrong with ``value`` for the numeric field ``key`` of sensor class ``cls``
    (every field but ``name`` is numeric), or None: true / false (read as 1 / 0 before), a
    string (a bare ``'>' not supported`` before), a fraction for a count (``n_beams: 2.5``
    failed deep in the simulator)."""
    if key == "name":
        return None
    if holds_bool(value):
        return f"expected a number, not a boolean ({value!r})"
    if typing.get_type_hints(cls).get(key) is int:
        if not isinstance(value, int | np.integer):
            return f"expected a whole number, got {value!r}"
        return None
    try:
        np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return f"expected numbers, got {value!r:.60}"
    return None


def save_sensor_rig(rig: SensorRig, path: str | Path) -> None:
    """Write ``rig`` as YAML (the form of a simulated dataset's ``rig.yaml: sensor_rig``)."""
    Path(path).write_text(yaml.safe_dump(rig.to_dict(), sort_keys=False))


def load_sensor_rig(path: str | Path) -> SensorRig:
    """Read a sensor rig file; raises :class:`DatasetError` naming the file and field."""
    path = Path(path)
    data = read_yaml_file(path, "rig", DatasetError)
    try:
        return SensorRig.from_dict(data, source=str(path))
    except ConfigError as exc:
        raise DatasetError(str(exc)) from exc


# --------------------------------------------------------------------------- geometry


def scanner_pose(origin, normal, look) -> np.ndarray:
    """``T_base_sensor`` (4, 4) of a 2D scanner at ``origin`` (3,) m whose scan plane has
    unit ``normal`` (3,) (its z axis) and whose field of view is centred on the projection
    of ``look`` (3,) onto the scan plane (its x axis)."""
    z = np.asarray(normal, dtype=np.float64)
    z = z / np.linalg.norm(z)
    look = np.asarray(look, dtype=np.float64)
    x = look - (look @ z) * z
    if np.linalg.norm(x) < 1e-9:
        raise ConfigError("scanner look direction is perpendicular to its scan plane")
    x = x / np.linalg.norm(x)
    return make_transform(np.column_stack([x, np.cross(z, x), z]), origin)


def isoclinal_normals(meet_deg: float, inclination_deg: float) -> np.ndarray:
    """(2, 3) scan-plane normals of a pair inclined by ``inclination_deg`` to the horizontal,
    rolled in opposite senses about the horizontal direction at azimuth ``meet_deg``
    (where they meet: ``h = m1 x m2`` is along it)."""
    g, th = np.deg2rad(meet_deg), np.deg2rad(inclination_deg)
    w = np.array([-np.sin(g), np.cos(g), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return np.stack([np.cos(th) * up + np.sin(th) * w, np.cos(th) * up - np.sin(th) * w])


def isoclinal_rig(
    inclination_deg: float = 25.0,
    meet_deg: tuple[float, float] = (45.0, -45.0),
    look_down_deg: float = 10.0,
    mount_height: float = 0.8,
    **scanner: Any,
) -> SensorRig:
    """Two isoclinal pairs of :class:`Scanner2D` (see the module docstring).

    Args:
        inclination_deg: angle of every scan plane to the horizontal, degrees.
        meet_deg: for the forward and the backward pair, the azimuth (deg, base frame,
            from +x towards +y) of the horizontal direction along which its scan planes meet.
        look_down_deg: the field of view is centred on the forward (backward) direction
            tilted down by this angle (deg), projected onto each scan plane.
        mount_height: metres above the base origin.
        scanner: per-scanner fields of :class:`Scanner2D` (``step_deg``, ``rate_hz``,
            ``max_range`` m, ``noise_sigma`` m; its defaults otherwise: an LMS 221).

    Scanners sit at (+-1.0, +-0.5, mount_height) m in the base frame. Rings: 0 front-left,
    1 front-right, 2 rear-left, 3 rear-right.
    """
    sensors = []
    for meet, sign, label in zip(meet_deg, (1.0, -1.0), ("front", "rear"), strict=True):
        look = np.array([sign, 0.0, -np.tan(np.deg2rad(look_down_deg))])
        normals = isoclinal_normals(meet, inclination_deg)
        for k, (m, side) in enumerate(zip(normals, ("left", "right"), strict=True)):
            T = scanner_pose([sign * 1.0, 0.5 - k, mount_height], m, look)
            sensors.append(Scanner2D(T, name=f"{label}-{side}", **scanner))
    return SensorRig(tuple(sensors), "isoclinal")


def lidar_rig(
    n_beams: int = 32,
    vfov_deg: tuple[float, float] = (-25.0, 15.0),
    mount_height: float = 0.8,
    **lidar: Any,
) -> SensorRig:
    """One :class:`SpinningLidar` on the roof, ``mount_height`` m above the base origin:
    ``n_beams`` rings over ``vfov_deg`` (lowest, highest elevation, deg); ``lidar``: its
    other fields (``n_columns`` firings per revolution, ``rate_hz`` revolutions/s,
    ``max_range`` and ``noise_sigma`` m; its defaults otherwise)."""
    T = make_transform(np.eye(3), np.array([0.0, 0.0, mount_height]))
    sensor = SpinningLidar(T, name=f"lidar{n_beams}", n_beams=n_beams, vfov_deg=vfov_deg, **lidar)
    return SensorRig((sensor,), f"lidar{n_beams}")


RIGS: dict[str, Callable[[], SensorRig]] = {
    "isoclinal": isoclinal_rig,
    "lidar16": lambda: lidar_rig(16, (-15.0, 15.0)),
    "lidar32": lambda: lidar_rig(32),
    "lidar64": lambda: lidar_rig(64, (-24.8, 2.0)),
}


def rig_from_name(name: str) -> SensorRig:
    """A built-in rig by name: ``isoclinal``, ``lidar16``, ``lidar32`` or ``lidar64``."""
    if name not in RIGS:
        raise ConfigError(f"unknown rig '{name}' (choose from {', '.join(RIGS)})")
    return RIGS[name]()
