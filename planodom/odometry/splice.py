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


def consistent(
    streaming: OdometryRun, passes: OdometryRun, keep: np.ndarray, config: PlanodomConfig
) -> np.ndarray:
    """(N,) bool: ``keep`` (the epochs whose step ``T_{k-1}_k`` comes from ``streaming``)
    with no switch between the runs at an epoch the two runs place differently.

    Why: an epoch's own error (its planes off) enters its step and leaves, with the
    opposite sign, in the next one, so each run's two steps around the epoch cancel it.
    Where the splice takes one of those steps from each run, it keeps the difference of
    the two runs' errors at that epoch for the rest of the trajectory (issue 11's world
    436 at 2 cm: the streaming pass's epoch 81 was -0.30 deg off, its steps 81 and 82
    -0.30 and +0.29 deg; the guard kept step 81 and took the pass's 82, and the -0.30 deg
    stayed). The difference of the two runs' steps, ``D_k``, shows such an epoch as a pair
    ``D_k``, ``D_{k+1}`` of opposite signs; the part that cancels, per component the
    smaller magnitude of the two, is the two runs' difference in placing epoch ``k``.
    Where it exceeds ``odometry.deskew_rate_tolerance_deg_s`` /
    ``deskew_speed_tolerance_mps`` (as rates over the two steps' mean time, the guard's
    own tolerances) at a switch, both steps come from the pass: what differs there is one
    epoch's placement, which cancels within the pass's two steps, not the pass's motion
    over them (the guard judged single steps). Repeated until no switch is at such an
    epoch. Measured offline on the passes' runs of seen worlds (372, 386, 414, 340, 346,
    384, 356 at 6 mm and 2 cm, 436 at 2 cm): see docs/RESULTS.md, SPLICE14."""
    keep = np.asarray(keep, dtype=bool).copy()
    n = len(keep)
    if n < 3 or not keep.any() or len(streaming.poses) != n:
        return keep
    a_steps = invert_transform(streaming.poses[:-1]) @ streaming.poses[1:]
    b_steps = invert_transform(passes.poses[:-1]) @ passes.poses[1:]
    d = se3_log(invert_transform(b_steps) @ a_steps)  # (N - 1, 6): step k + 1's difference
    first, second = d[:-1], d[1:]  # the two steps around epochs 1 .. N - 2
    cancel = np.where(first * second < 0, np.minimum(abs(first), abs(second)), 0.0)
    dt = np.diff(np.asarray(passes.times, dtype=np.float64))
    span = 0.5 * (dt[:-1] + dt[1:])
    span = np.where(span > 0, span, np.inf)
    odo = config.odometry
    spike = np.zeros(n, dtype=bool)  # epoch k: its own placement differs between the runs
    spike[1:-1] = (
        np.degrees(np.linalg.norm(cancel[:, :3], axis=1)) / span > odo.deskew_rate_tolerance_deg_s
    ) | (np.linalg.norm(cancel[:, 3:], axis=1) / span > odo.deskew_speed_tolerance_mps)
    for _ in range(n):  # each round only clears kept steps: at most n rounds
        switch = np.zeros(n, dtype=bool)
        switch[1:-1] = spike[1:-1] & (keep[1:-1] != keep[2:])  # steps k and k + 1 differ
        if not switch.any():
            break
        idx = np.flatnonzero(switch)
        keep[idx] = False
        keep[idx + 1] = False
    return keep


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


def kept_epochs(
    streaming: OdometryRun,
    passes: OdometryRun,
    curve_steps: np.ndarray,
    deskewed: np.ndarray,
    config: PlanodomConfig,
) -> np.ndarray:
    """(N,) bool: the epochs taken from ``streaming`` under ``odometry.deskew_pass_guard``
    (``streaming``: :func:`unconverged`; ``consistent``: those, made :func:`consistent`)."""
    keep = unconverged(streaming, passes, curve_steps, deskewed, config)
    if config.odometry.deskew_pass_guard == "consistent":
        keep = consistent(streaming, passes, keep, config)
    return keep
