"""Offline re-deskewing through the smoothed trajectory (``smoothing.redeskew_passes``,
and of the first epoch alone, ``smoothing.first_epoch_refresh``).

The streaming odometry deskews each scan with a twist predicted from the past epochs,
then with the epoch's own estimate; the first epoch is extracted before any twist is
known. After a batch smoothing, every scan can be deskewed again along a curve through
the smoothed poses (:func:`planodom.odometry.run.redeskewed_run`), the odometry and the
relative poses estimated again on the new planes, and the graph solved again.

Which smoothed poses the curve may pass through (``smoothing.redeskew_trust``): never the
first epoch's (see the config field), and with "odometry" not those of the epochs the
odometry bridged by constant velocity either, whose smoothed poses rest on the planes
of the epochs around them and on the map alone.

The curve is the odometry's (``odometry.deskew_order``, ``deskew_fit``); a least-squares
fit weighs the trusted smoothed poses equally (the smoother's marginals are not passed).
Measured with loops (``planodom experiment loops``, worlds 8 and 6, 6 mm / 2 cm, ATE m,
batch+loops -> redeskewed along the interpolation / the degree-3 increment fit): world 8
0.077 -> 0.076 / 0.076 and 0.092 -> 0.098 / 0.098, world 6 0.122 -> 0.243 / 0.241 and
1.69 -> 0.95 / 1.38; the oracle's odometry 0.003 / 0.016 and 0.017 / 0.059.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction import extract_planes
from planodom.extraction.lidar.sweep import sweep_timed
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import (
    OdometryRun,
    RelativePose,
    Status,
    estimate_relative_pose,
    with_motion_bounds,
)
from planodom.odometry.run import EpochSequence, any_time_spread, redeskewed_run
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
    if not passes or not any_time_spread(source):
        return None
    cfg = with_motion_bounds(config, rig.motion_bounds)
    start = time.perf_counter()
    relatives: list[RelativePose] = []
    for _ in range(passes):
        trusted = trusted_poses(odometry, config.smoothing.redeskew_trust)
        odometry = redeskewed_run(source, odometry.times, result.poses, cfg, rig, measured=trusted)
        relatives, result = smooth(odometry)
    return Redeskewed(odometry, relatives, result, time.perf_counter() - start)


def refresh_first_epoch(
    source: EpochSequence,
    odometry: OdometryRun,
    result: SmoothingResult,
    config: PlanodomConfig,
    rig: Rig,
    smooth: Smoother,
) -> Redeskewed | None:
    """The first epoch extracted again with the constant twist of its smoothed step to
    the second (``smoothing.first_epoch_refresh`` times, each time with the step
    estimated again on its new planes), the relative poses from it estimated again, and
    ``smooth`` again. None when off, or without two epochs of scans with point times.

    Why: the streaming odometry extracts the first epoch before any twist is known, then
    again with the twist of a step measured on those planes; every relative pose from it
    fixes the whole trajectory's frame, which loop closure ties back to its landmarks.
    Measured on the 2D-rig laps at 6 mm: extracted with the true twist, the batch with
    loops ends at 0.023 against 0.077 m on world 8 and 0.012 against 0.029 on world 0.
    With a twist (unlike :func:`redeskew_passes`' curve), the extraction widens its
    tolerances by the twist's declared uncertainty (``extraction.twist_*_sigma_*``).

    Args: as :func:`redeskew_passes`.
    """
    rounds = config.smoothing.first_epoch_refresh
    source = sweep_timed(source, config.extraction.sweep, rig)
    if not rounds or len(source) < 2 or not any_time_spread(source):
        return None
    start = time.perf_counter()
    cfg = with_motion_bounds(config, rig.motion_bounds)
    scan = source[0]
    if not isinstance(scan, Scan):
        return None
    dt = float(odometry.times[1] - odometry.times[0])
    step = invert_transform(result.poses[0]) @ result.poses[1]
    planes = odometry.planes[0]
    for _ in range(rounds):  # kept only when its step to the second epoch is measured
        again = extract_planes(scan, cfg.extraction, se3_log(step) / dt, rig.sensor_origins)
        rel = estimate_relative_pose(again, odometry.planes[1], cfg, step)
        if not rel.measured:
            break
        planes, step = again, rel.T_prev_curr
    from_first = {k for k, r in enumerate(odometry.results) if r is not None and r.prev == 0}
    superseded = sorted(set(odometry.superseded) | from_first)
    run = replace(odometry, planes=[planes, *odometry.planes[1:]], superseded=superseded)
    relatives, result = smooth(run)
    return Redeskewed(run, relatives, result, time.perf_counter() - start)
