"""What a dataset says about the vehicle that recorded it: the typed ``rig.yaml``.

A :class:`Rig` is read and validated once, where a dataset is read (``rig.yaml``) or
simulated; the odometry and the extraction take it as a typed object and never see YAML.
Every field is optional: a recording without ``rig.yaml`` is ``Rig()``.

``rig.yaml`` (all keys optional)::

    epoch_rate: 10.0                      # Hz: epoch k starts at k / epoch_rate seconds
    sensor_origins: [[x, y, z], ...]      # metres, base frame, one row per ring (scanner)
    motion_bounds: {max_translation_m: 3.0, max_rotation_deg: 45.0}   # per epoch
    extrinsics: [[16 numbers row-major], ...]   # T_base_sensor (4, 4) per sensor
    platform: vehicle                     # or handheld; absent: unknown

Unknown keys are kept in :attr:`Rig.extra` (and written back) so that a dataset's own notes
survive a round trip; those planodom does not write itself are named by
:func:`unread_keys`, for a note (``epoch_rate_hz: 20`` read as no rate at all, silently).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from planodom.config.section import holds_bool
from planodom.errors import DatasetError, GeometryError
from planodom.geometry import first_non_rotation
from planodom.mounts import check_mounts

#: The keys of ``rig.yaml`` planodom reads.
RIG_KEYS = ("epoch_rate", "sensor_origins", "motion_bounds", "extrinsics", "platform")
#: What carries the sensors (``rig.yaml``'s ``platform``; absent: unknown): a wheeled
#: vehicle, whose base frame is its own (x forward, z up), or a hand-held sensor. The
#: config's ``odometry.platform: auto`` takes it (:mod:`planodom.odometry.platform`).
PLATFORMS = ("vehicle", "handheld")
#: Keys planodom itself puts in ``extra`` (and so in a ``rig.yaml`` it writes): a
#: simulated dataset's sensor models and simulation, a bag's or a KITTI sequence's source.
WRITTEN_EXTRA = frozenset(
    {"sensor_rig", "simulation", "source", "bag", "base_frame", "gt_topic", "topics"}
    | {"sequence", "T_cam0_velo"}
)


@dataclass(frozen=True)
class MotionBounds:
    """Largest motion a dataset's vehicle makes between consecutive epochs.

    Attributes:
        max_translation_m: metres per epoch (None: not stated).
        max_rotation_deg: degrees per epoch (None: not stated).
    """

    max_translation_m: float | None = None
    max_rotation_deg: float | None = None


@dataclass(frozen=True, eq=False)
class Rig:
    """The vehicle and its sensors, as far as a dataset states them.

    Attributes:
        epoch_rate_hz: epochs per second (None: not stated).
        sensor_origins: (S, 3) float64, metres: the position of sensor / ring ``s`` in the
            base frame, used to orient measured normals towards the sensor (None: not
            stated).
        motion_bounds: the largest motion per epoch, or None.
        extrinsics: ``T_base_sensor`` (4, 4) per sensor (may be empty).
        platform: "vehicle" | "handheld" (:data:`PLATFORMS`), or None: not stated.
        extra: keys of ``rig.yaml`` this class does not interpret, kept as read.
    """

    epoch_rate_hz: float | None = None
    sensor_origins: np.ndarray | None = None
    motion_bounds: MotionBounds | None = None
    extrinsics: tuple[np.ndarray, ...] = ()
    extra: Mapping[str, Any] = field(default_factory=dict)
    platform: str | None = None

    def __post_init__(self) -> None:
        if self.platform is not None and self.platform not in PLATFORMS:
            raise DatasetError(
                f"Rig: platform must be {' or '.join(PLATFORMS)} (None: not stated), "
                f"got {self.platform!r}"
            )
        # Built in code (a simulated rig) as well as from YAML: hold arrays of one form.
        # A (3,) origin is one sensor; any other shape than (S, 3) is refused, not
        # reshaped: a (3, 2) array read as (2, 3) was two made-up origins.
        if self.sensor_origins is not None:
            origins = _numbers(self.sensor_origins, "sensor_origins")
            if origins.shape == (3,) or origins.size == 0:
                origins = origins.reshape(-1, 3)
            if origins.ndim != 2 or origins.shape[1] != 3:
                raise GeometryError(
                    f"Rig: sensor_origins must have shape (S, 3) or (3,), got {origins.shape}"
                )
            object.__setattr__(self, "sensor_origins", origins)
        extrinsics = tuple(_numbers(T, "extrinsics") for T in self.extrinsics)
        shapes = [T.shape for T in extrinsics if T.shape != (4, 4)]
        if shapes:
            raise GeometryError(f"Rig: extrinsics must be (4, 4) each, got {shapes[0]}")
        object.__setattr__(self, "extrinsics", extrinsics)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any] | None, source: str = "rig.yaml") -> Rig:
        """Validate the mapping of a ``rig.yaml``; errors name ``source`` and the field."""
        if data is None:
            return cls()
        if not isinstance(data, Mapping):
            raise DatasetError(f"{source}: rig file must hold a mapping, not {type(data).__name__}")
        rate = data.get("epoch_rate")
        origins = data.get("sensor_origins")
        if origins is not None:
            origins = _array(origins, source, "sensor_origins", (-1, 3))
        rig = cls(
            epoch_rate_hz=None if rate is None else _positive(rate, source, "epoch_rate"),
            sensor_origins=origins if origins is not None and len(origins) else None,
            motion_bounds=_motion_bounds(data.get("motion_bounds"), source),
            extrinsics=_extrinsics(data.get("extrinsics"), source),
            extra={k: v for k, v in data.items() if k not in RIG_KEYS},
            platform=_platform(data.get("platform"), source),
        )
        check_mounts(rig_mounts(rig, source), "")  # millimetres: refused
        return rig

    def to_dict(self) -> dict[str, Any]:
        """The ``rig.yaml`` mapping (plain Python types; absent fields are left out)."""
        out: dict[str, Any] = dict(self.extra)
        if self.epoch_rate_hz is not None:
            out["epoch_rate"] = float(self.epoch_rate_hz)
        if self.sensor_origins is not None:
            out["sensor_origins"] = np.asarray(self.sensor_origins).tolist()
        if self.motion_bounds is not None:
            mb = {
                "max_translation_m": self.motion_bounds.max_translation_m,
                "max_rotation_deg": self.motion_bounds.max_rotation_deg,
            }
            out["motion_bounds"] = {k: v for k, v in mb.items() if v is not None}
        if self.extrinsics:
            out["extrinsics"] = [np.asarray(T).tolist() for T in self.extrinsics]
        if self.platform is not None:
            out["platform"] = self.platform
        return out


def rig_mounts(rig: Rig, source: str) -> list[tuple[str, np.ndarray]]:
    """``(where, translation (3,) m)`` of each distinct sensor origin and extrinsic of
    ``rig`` (:func:`planodom.mounts.check_mounts`), ``where`` naming ``source`` and the field."""
    mounts = []
    origins = () if rig.sensor_origins is None else rig.sensor_origins
    _, first = np.unique(np.asarray(origins).reshape(-1, 3), axis=0, return_index=True)
    for k in sorted(first):
        mounts.append((f"{source}: field 'sensor_origins.{k}'", np.asarray(origins)[k]))
    for k, T in enumerate(rig.extrinsics):
        mounts.append((f"{source}: field 'extrinsics.{k}'", T[:3, 3]))
    return mounts


def unread_keys(rig: Rig) -> list[str]:
    """The keys of ``rig.extra`` planodom neither reads nor writes (:data:`WRITTEN_EXTRA`):
    a typo of a key it reads, or a dataset's own note."""
    return [str(k) for k in rig.extra if k not in WRITTEN_EXTRA]


def _numbers(value: Any, name: str) -> np.ndarray:
    """``value`` as a finite float64 array, or GeometryError naming the field."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise GeometryError(f"Rig: {name} must be numbers, got {type(value).__name__}") from None
    if not np.all(np.isfinite(array)):
        raise GeometryError(f"Rig: {name} must be finite")
    return array


def _platform(value: Any, source: str) -> str | None:
    """``rig.yaml``'s ``platform`` (None when absent), or DatasetError naming the value."""
    if value is None or value in PLATFORMS:
        return value
    raise DatasetError(
        f"{source}: field 'platform' must be {' or '.join(PLATFORMS)} (or left out: "
        f"unknown), got {value!r}"
    )


def _motion_bounds(bounds: Any, source: str) -> MotionBounds | None:
    """The ``motion_bounds`` mapping as :class:`MotionBounds` (None when absent)."""
    if bounds is None:
        return None
    if not isinstance(bounds, Mapping):
        raise DatasetError(
            f"{source}: field 'motion_bounds' must be a mapping with max_translation_m "
            f"and/or max_rotation_deg, got {bounds!r}"
        )
    keys = ("max_translation_m", "max_rotation_deg")
    unknown = set(bounds) - set(keys)
    if unknown:
        raise DatasetError(f"{source}: field 'motion_bounds' has unknown keys {sorted(unknown)}")
    values = [
        None if bounds.get(k) is None else _positive(bounds[k], source, f"motion_bounds.{k}")
        for k in keys
    ]
    return MotionBounds(*values)


def _extrinsics(value: Any, source: str) -> tuple[np.ndarray, ...]:
    """The ``extrinsics`` list as (4, 4) rigid transforms (() when absent)."""
    if value is None:
        return ()
    arr = _array(value, source, "extrinsics", (-1, 4, 4))
    if not np.allclose(arr[:, 3], [0.0, 0.0, 0.0, 1.0]):
        raise DatasetError(f"{source}: field 'extrinsics': last row of each must be 0 0 0 1")
    bad = first_non_rotation(arr[:, :3, :3])
    if bad is not None:
        raise DatasetError(
            f"{source}: field 'extrinsics.{bad[0]}': not a rigid transform ({bad[1]})"
        )
    return tuple(arr)


def _positive(value: Any, source: str, name: str) -> float:
    """``value`` as a finite positive float, or DatasetError naming the field."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.number):
        raise DatasetError(f"{source}: field '{name}' must be a positive number, got {value!r}")
    if not (math.isfinite(value) and value > 0):
        raise DatasetError(f"{source}: field '{name}' must be positive and finite, got {value!r}")
    return float(value)


def _array(value: Any, source: str, name: str, shape: tuple[int, ...]) -> np.ndarray:
    """``value`` as a finite float64 array of ``shape`` (-1: any length), or DatasetError
    (also for ``true`` / ``false`` among the numbers, which numpy would read as 1 / 0)."""
    if holds_bool(value):
        raise DatasetError(f"{source}: field '{name}' must be numbers, not booleans")
    try:
        arr = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise DatasetError(f"{source}: field '{name}' must be numbers, got {value!r}") from None
    want = "x".join("N" if s < 0 else str(s) for s in shape)
    if arr.size == 0:
        return arr.reshape((0,) + shape[1:])
    if arr.ndim == len(shape) - 1:
        arr = arr[None]
    if arr.ndim != len(shape) or arr.shape[1:] != shape[1:]:
        raise DatasetError(
            f"{source}: field '{name}' must have shape {want}, got shape {arr.shape}"
        )
    if not np.all(np.isfinite(arr)):
        raise DatasetError(f"{source}: field '{name}' must be finite")
    return arr
