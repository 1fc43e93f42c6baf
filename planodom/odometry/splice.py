"""The deskewing passes' result kept only where it agrees with the streaming pass.

A pass deskews each scan along a curve through the poses of the pass before
(:func:`planodom.odometry.run.redeskewed_run`); where those poses are off (a stretch of
few planes, the run's first epochs before the streaming twist has settled), the curve
deskews the scan wrongly and the wrong planes give a step further off than the streaming
pass's, which deskewed the epoch with its own estimate's twist (measured on issue 11's
2D-rig worlds at sigma = 0: steps of 0.1-0.2 deg in the streaming pass became 0.6-3.8
deg, more than doubling the run's rms, while elsewhere the passes took the median step
error from 0.015 to 0.001 deg). A pass that converged reproduces the steps of the curve
it was deskewed along to within the noise; one whose step differs from the curve's by
more than the tolerances the streaming pass itself re-extracts beyond
(``odometry.deskew_rate_tolerance_deg_s`` and ``deskew_speed_tolerance_mps``, as rates
over the step) has not, and the epoch keeps the streaming pass's estimate. (Not the
disagreement with the streaming pass: where that pass is off, e.g. 0.1 deg at a lidar's
epoch, the passes correct it; measured on a lidar world at sigma = 0, comparing with the
streaming steps took the rms from 0.003 back to 0.015 deg.)
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_log
from planodom.odometry.relative import Status

if TYPE_CHECKING:
    from planodom.odometry.run import OdometryRun


def unconverged(
    streaming: OdometryRun,
    passes: OdometryRun,
    curve_steps: np.ndarray,
    deskewed: np.ndarray,
    config: PlanodomConfig,
) -> np.ndarray:
    """(N,) bool: the epochs where the last pass ``passes`` did not converge, whose
    streaming estimate is kept: not ``deskewed`` (N,) along the curve (near an unresolved
    epoch the pass deskews as the streaming pass does, with a twist predicted from other
    poses), with a worse status than in the streaming pass (unresolved, or degenerate
    where it was OK: its translation is then only predicted), not OK before the pass's
    first OK step (its translation predicted from no velocity: standing still), or with
    a step that differs from the curve's ``curve_steps`` (N - 1, 4, 4) ``T_{k-1}_k`` it
    was deskewed along by more than ``odometry.deskew_rate_tolerance_deg_s`` in rotation
    or ``deskew_speed_tolerance_mps`` in translation, as a rate over the step's time
    (measured on issue 11's world 6 at 6 mm: the passes' epochs 1-3 came out degenerate
    with a translation 45 cm off, where the streaming pass's, degenerate too, were 4-6 cm
    off)."""
    n = len(passes.poses)
    out = np.zeros(n, dtype=bool)
    if n < 2 or len(streaming.poses) != n:
        return out
    step = invert_transform(passes.poses[:-1]) @ passes.poses[1:]
    xi = se3_log(invert_transform(curve_steps) @ step)  # (N - 1, 6): rotation, translation
    dt = np.diff(np.asarray(passes.times, dtype=np.float64))
    dt = np.where(dt > 0, dt, np.inf)  # no time between them: no rate to compare
    rate = np.degrees(np.linalg.norm(xi[:, :3], axis=1)) / dt
    speed = np.linalg.norm(xi[:, 3:], axis=1) / dt
    odo = config.odometry
    a, b = _statuses(streaming)[1:], _statuses(passes)[1:]
    out[1:] = (
        ~np.asarray(deskewed, dtype=bool)[1:]
        | (b < a)
        | ((b < Status.OK.rank) & (np.cumsum(b == Status.OK.rank) == 0))
        | (rate > odo.deskew_rate_tolerance_deg_s)
        | (speed > odo.deskew_speed_tolerance_mps)
    )
    return out


def spliced(streaming: OdometryRun, passes: OdometryRun, keep: np.ndarray) -> OdometryRun:
    """``passes`` with the epochs ``keep`` (N,) bool taken from ``streaming``: their
    results, planes and plane counts, and the poses chained from the steps of the run each
    epoch comes from (an epoch's step, ``T_{k-1}_k``, from its own run). An epoch whose
    result relates its planes to a reference epoch taken from the other run is marked
    superseded (its result indexes planes the returned run does not hold), as are those
    its own run superseded."""
    keep = np.asarray(keep, dtype=bool)
    if not keep.any():
        return passes
    n = len(passes.poses)
    runs = (passes, streaming)
    poses = np.empty_like(passes.poses)
    poses[0] = runs[int(keep[0])].poses[0]
    for k in range(1, n):
        P = runs[int(keep[k])].poses
        poses[k] = poses[k - 1] @ (invert_transform(P[k - 1]) @ P[k])
    results = [runs[int(keep[k])].results[k] for k in range(n)]
    planes = passes.planes  # a run of plane lists holds none
    if len(passes.planes) == n and len(streaming.planes) == n:
        planes = [runs[int(keep[k])].planes[k] for k in range(n)]
    superseded = set()
    for k, r in enumerate(results):
        own = runs[int(keep[k])]
        if k in own.superseded or (r is not None and 0 <= r.prev < n and keep[r.prev] != keep[k]):
            superseded.add(k)
    return replace(
        passes,
        poses=poses,
        results=results,
        n_planes=np.where(keep, streaming.n_planes, passes.n_planes),
        planes=planes,
        superseded=sorted(superseded),
    )


def _statuses(run: OdometryRun) -> np.ndarray:
    """(N,) the rank of each epoch's status (the first: OK's)."""
    return np.array([Status.OK.rank if r is None else r.status.rank for r in run.results])
