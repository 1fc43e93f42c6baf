"""Offline re-deskewing through the smoothed trajectory (``smoothing.redeskew_passes``).

The streaming odometry deskews each scan with a twist predicted from the past epochs,
then with the epoch's own estimate; the first epoch is extracted before any twist is
known. After a batch smoothing, every scan can be deskewed again along a curve through
the smoothed poses (:func:`planodom.odometry.run.redeskewed_run`), the odometry and the
relative poses estimated again on the new planes, and the graph solved again.

Which smoothed poses the curve may pass through (``smoothing.redeskew_trust``): never the
first epoch's (see the config field), and with "odometry" not those of the epochs the
odometry bridged by constant velocity either, whose smoothed poses rest on the planes
of the epochs around them and on the map alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction.lidar.sweep import sweep_timed
from planodom.odometry import OdometryRun, RelativePose, Status, with_motion_bounds
from planodom.odometry.deskew import time_spread
from planodom.odometry.run import EpochSequence, redeskewed_run
from planodom.rig import Rig
from planodom.scan import Scan
from planodom.smoothing.batch import SmoothingResult

#: ``smooth(odometry) -> (relatives, result)``: the relative poses and the batch solve.
Smoother = Callable[[OdometryRun], tuple[list[RelativePose], SmoothingResult]]


@dataclass
class Redeskewed:
    """The last pass: its odometry run (planes and relative poses on the re-deskewed
    scans), relative poses delta = 1..D, smoothing result, and the wall time of all
    passes (deskewing, extraction, odometry, relatives, smoothing), s."""

    odometry: OdometryRun
    relatives: list[RelativePose]
    result: SmoothingResult
    seconds: float


def trusted_poses(odometry: OdometryRun, trust: str) -> np.ndarray:
    """(E,) bool: the epochs whose smoothed pose the deskewing curve may pass through
    (``smoothing.redeskew_trust``): all but the first ("smoothed"), and only those the
    odometry measured, rotation at least ("odometry")."""
    if trust == "odometry":
        out = np.array(
            [r is None or r.status is not Status.UNRESOLVED for r in odometry.results], bool
        )
    else:
        out = np.ones(len(odometry.results), dtype=bool)
    out[:1] = False
    return out


def has_point_times(source: EpochSequence) -> bool:
    """Whether the first scan of ``source`` carries point times that differ (a recording
    has them for all its epochs or for none); plane lists have none."""
    item = source[0] if len(source) else None
    return isinstance(item, Scan) and time_spread(item)


def redeskew_passes(
    source: EpochSequence,
    odometry: OdometryRun,
    result: SmoothingResult,
    config: PlanodomConfig,
    rig: Rig,
    smooth: Smoother,
) -> Redeskewed | None:
    """``smoothing.redeskew_passes`` passes of: deskew every scan along the smoothed poses,
    the odometry again, ``smooth`` again. None when there is nothing to do (no pass asked
    or scans without point times).

    Args:
        source: the epochs (:class:`Scan`), as given to the odometry.
        odometry: the streaming odometry run ``result`` was smoothed from (its statuses
            decide the trusted poses of the first pass, then each pass's own).
        result: the batch smoothing of ``odometry``.
        config: the resolved configuration (``odometry.delta`` = 1).
        rig: the vehicle (sensor origins, motion bounds, sweep convention).
        smooth: the relative poses and the batch solve of an odometry run.
    """
    passes = config.smoothing.redeskew_passes
    source = sweep_timed(source, config.extraction.sweep, rig)
    if not passes or not has_point_times(source):
        return None
    cfg = with_motion_bounds(config, rig.motion_bounds)
    start = time.perf_counter()
    relatives: list[RelativePose] = []
    for _ in range(passes):
        trusted = trusted_poses(odometry, config.smoothing.redeskew_trust)
        odometry = redeskewed_run(source, odometry.times, result.poses, cfg, rig, measured=trusted)
        relatives, result = smooth(odometry)
    return Redeskewed(odometry, relatives, result, time.perf_counter() - start)
