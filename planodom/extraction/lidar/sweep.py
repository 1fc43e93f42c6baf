"""Per-point times of a spinning lidar's cloud from the azimuth, by a declared convention.

A spinning lidar fires its columns at a constant rate while it turns about its z axis,
so a point's acquisition time follows from its azimuth in the sensor frame once the
convention is declared (:class:`planodom.config.extraction.SweepConfig`: sense of
rotation, azimuth of the first column, period, time of the first column). Clouds stored
without times (KITTI's ``.bin``, most PCD / PLY files) can then be deskewed like clouds
that carry them; KISS-ICP does the same for KITTI (times from the yaw angle).

Points are in the base frame, each in the base frame of its own time (:class:`Scan`);
the azimuth is taken in the sensor frame, ``p_sensor = T_base_sensor^-1 p_base``, so a
lidar mounted off the base origin or turned about z gets its own azimuths. Because each
point is expressed at its own time, its azimuth is the azimuth the sensor fired it at:
no motion model is needed.

Times recovered so are not a recording's: they deskew the cloud, but the cloud stays what
it was, unorganised (:class:`AzimuthTimedScan`): the lidar path segments it exactly as
without times (rows of the raw cloud, a range image of the deskewed points,
:mod:`planodom.extraction.lidar.path`). Taking the recovered rows as rings with these
times instead (the path of a cloud that carries times) cut KITTI's walls into pieces:
measured on raw drive 0005, 451 planes on a scan where the organised path finds 95, and
0.40 deg rms rotation error per scan against 0.072 deg when only deskewing.
"""

from __future__ import annotations

from typing import Any, Protocol

import numba
import numpy as np

from planodom.config.extraction import SweepConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform
from planodom.rig import Rig
from planodom.scan import Scan

#: Fractions of a turn this close below 1 are taken as 0: a point of the first column
#: whose azimuth round-off crosses the seam (2 pi 1e-6 rad = 0.0004 deg, far below the
#: column step of any lidar, ~0.1-0.4 deg) is not put a whole period late.
SEAM_TOLERANCE = 1e-6


class AzimuthTimedScan(Scan):
    """A :class:`Scan` whose times ``t`` were recovered from the azimuth by a declared
    sweep convention (:func:`with_sweep_times`), not recorded: they serve the deskewing
    only (module docstring). Kept by ``dataclasses.replace``."""


def sweep_times(
    points: np.ndarray, sweep: SweepConfig, T_base_sensor: np.ndarray | None = None
) -> np.ndarray:
    """Acquisition times of a lidar's points from their azimuths.

    Args:
        points: (N, 3) metres in the base frame (each at its own time).
        sweep: the declared convention (``rotation`` must not be "none").
        T_base_sensor: (4, 4) the lidar's pose in the base frame; None: the identity
            (points in the sensor frame).

    Returns:
        (N,) seconds relative to the epoch's reference time, in
        ``[start_time_s, start_time_s + period_s)``.
    """
    if sweep.rotation == "none":
        raise ConfigError("extraction.sweep.rotation: 'none' declares no convention")
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    if T_base_sensor is not None:
        T_sensor_base = invert_transform(np.asarray(T_base_sensor, dtype=np.float64))
        pts = pts @ T_sensor_base[:3, :3].T + T_sensor_base[:3, 3]
    azimuth = np.arctan2(pts[:, 1], pts[:, 0])
    sense = 1.0 if sweep.rotation == "ccw" else -1.0
    start = float(np.radians(sweep.start_azimuth_deg))
    return _times_kernel(azimuth, sense, start, float(sweep.start_time_s), float(sweep.period_s))


@numba.njit(cache=True)
def _times_kernel(azimuth, sense, start, t0, period):  # pragma: no cover - compiled
    """(N,) s: ``t0 + period * frac``, ``frac = mod(sense * (azimuth - start) / (2 pi),
    1)`` (numpy's floor modulo: ``fmod``, plus 1 when negative, +0 for 0), 0 above
    ``1 - SEAM_TOLERANCE``; the numpy expression's IEEE operations in its order, in one
    compiled pass (numba, no fast-math) instead of seven numpy passes
    (tests/extraction/test_sweep.py checks it against numpy)."""
    out = np.empty(azimuth.shape[0])
    two_pi = 2.0 * np.pi
    edge = 1.0 - SEAM_TOLERANCE
    for i in range(azimuth.shape[0]):
        turn = sense * (azimuth[i] - start) / two_pi
        frac = np.fmod(turn, 1.0)
        if frac < 0.0:
            frac += 1.0
        elif frac == 0.0:
            frac = 0.0
        if frac > edge:
            frac = 0.0
        out[i] = t0 + period * frac
    return out


def with_sweep_times(
    scan: Scan, sweep: SweepConfig, T_base_sensor: np.ndarray | None = None
) -> Scan:
    """``scan`` as an :class:`AzimuthTimedScan` with times from :func:`sweep_times` when
    it has none and a convention is declared; else ``scan`` itself."""
    if scan.t is not None or sweep.rotation == "none":
        return scan
    t = sweep_times(scan.points, sweep, T_base_sensor)
    return AzimuthTimedScan(scan.points, scan.ring, t, scan.label)


def rig_lidar_pose(rig: Rig | None) -> np.ndarray | None:
    """The lidar's ``T_base_sensor`` (4, 4) a rig states: its one extrinsic (several equal
    ones count as one); None without extrinsics (points are taken in the sensor frame, as
    KITTI's are). Raises :class:`ConfigError` for several different sensors (which one's
    sweep would the times follow?)."""
    extrinsics = () if rig is None else rig.extrinsics
    if not extrinsics:
        return None
    first = np.asarray(extrinsics[0], dtype=np.float64)
    if any(not np.allclose(T, first) for T in extrinsics[1:]):
        raise ConfigError(
            f"extraction.sweep: the rig has {len(extrinsics)} sensors with different "
            "extrinsics; times from the azimuth need one spinning lidar"
        )
    return first


class Epochs(Protocol):
    """A sequence of epochs (``len``, ``[k]``: a :class:`Scan` or the epoch's planes), as
    :class:`planodom.odometry.run.EpochSequence`."""

    def __len__(self) -> int: ...

    def __getitem__(self, index: int, /) -> Any: ...


class SweepTimedEpochs:
    """A sequence of epochs whose scans without times get them from the declared sweep
    convention (:func:`with_sweep_times`), lazily; plane lists and scans with times pass
    through. ``len``, indexing and the ``times`` / ``rig`` attributes of the source."""

    def __init__(
        self, source: Epochs, sweep: SweepConfig, T_base_sensor: np.ndarray | None
    ) -> None:
        self.source, self.sweep, self.T_base_sensor = source, sweep, T_base_sensor
        self.times = getattr(source, "times", None)
        self.rig = getattr(source, "rig", None)

    def __len__(self) -> int:
        return len(self.source)

    def __getitem__(self, k: int) -> Any:
        item = self.source[k]
        if isinstance(item, Scan):
            return with_sweep_times(item, self.sweep, self.T_base_sensor)
        return item


def sweep_timed(source: Epochs, sweep: SweepConfig, rig: Rig | None) -> Epochs:
    """``source`` itself without a declared convention, else :class:`SweepTimedEpochs`
    with the rig's lidar pose (:func:`rig_lidar_pose`)."""
    if sweep.rotation == "none":
        return source
    return SweepTimedEpochs(source, sweep, rig_lidar_pose(rig))
