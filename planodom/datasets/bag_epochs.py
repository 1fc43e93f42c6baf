"""Epochs from sweep times, and a reference trajectory sampled at the epoch times.

Epochs: the time axis is cut into windows of ``1 / epoch_rate`` seconds, and an epoch is the
set of sweeps whose stamps fall in one window (windows without a sweep make no epoch). The
windows' phase is put in the middle of the largest gap between the sweeps' stamps modulo
the period, so that scanners running at the epoch rate never straddle a window boundary
through jitter. An epoch's reference time is the stamp of its sweep closest to the
window's centre (the earlier one on a tie).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation, Slerp

NS = 1_000_000_000


def window_phase(stamps: np.ndarray, period: int) -> int:
    """Start (ns, in ``[0, period)``) of the windows: mid of the largest gap of the phases.

    Args:
        stamps: (n,) int64 sweep stamps, ns.
        period: window length, ns.
    """
    phases = np.unique(np.mod(stamps, period))
    if len(phases) == 0:
        return 0
    gaps = np.diff(np.append(phases, phases[0] + period))
    k = int(np.argmax(gaps))
    return int((phases[k] + gaps[k] // 2) % period)


def group_epochs(stamps: np.ndarray, period: int) -> tuple[list[np.ndarray], np.ndarray]:
    """Sweeps of each epoch and the epochs' reference times.

    Args:
        stamps: (n,) int64 sweep stamps, ns (any order).
        period: window length ``1 / epoch_rate``, ns.

    Returns:
        ``members``: per epoch, the indices into ``stamps`` of its sweeps, by stamp; and
        ``ref`` (E,) int64 ns, each epoch's reference stamp, strictly increasing.
    """
    stamps = np.asarray(stamps, dtype=np.int64)
    if len(stamps) == 0:
        return [], np.zeros(0, dtype=np.int64)
    phase = window_phase(stamps, period)
    window = np.floor_divide(stamps - phase, period)
    order = np.lexsort((stamps, window))
    splits = np.flatnonzero(np.diff(window[order])) + 1
    members = np.split(order, splits)
    ref = np.empty(len(members), dtype=np.int64)
    for e, idx in enumerate(members):
        centre = window[idx[0]] * period + phase + period // 2
        ref[e] = stamps[idx[np.argmin(np.abs(stamps[idx] - centre))]]
    return members, ref


def interpolate_poses(
    times: np.ndarray, poses: np.ndarray, query: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Poses at ``query`` times by linear (translation) and Slerp (rotation) interpolation.

    Args:
        times: (M,) int64 ns stamps of the reference poses (any order; repeated stamps
            keep the last pose).
        poses: (M, 4, 4) ``T_world_base`` at ``times``.
        query: (E,) int64 ns.

    Returns:
        ``inside`` (E,) bool, the queries within ``[times.min(), times.max()]``, and the
        poses (K, 4, 4) at those K queries (no extrapolation).
    """
    times = np.asarray(times, dtype=np.int64)
    query = np.asarray(query, dtype=np.int64)
    # keep the last pose of repeated stamps, in time order
    order = np.argsort(times, kind="stable")
    times, poses = times[order], np.asarray(poses, dtype=np.float64)[order]
    last = np.append(times[1:] != times[:-1], True)
    times, poses = times[last], poses[last]
    inside = (query >= times[0]) & (query <= times[-1])
    q = query[inside]
    out = np.tile(np.eye(4), (len(q), 1, 1))
    if len(q) == 0:
        return inside, out
    # seconds relative to the first stamp keep full precision in float64
    t = (times - times[0]).astype(np.float64) / NS
    tq = (q - times[0]).astype(np.float64) / NS
    for axis in range(3):
        out[:, axis, 3] = np.interp(tq, t, poses[:, axis, 3])
    rotations = Rotation.from_matrix(poses[:, :3, :3])
    if len(t) == 1:
        out[:, :3, :3] = poses[0, :3, :3]
    else:
        out[:, :3, :3] = Slerp(t, rotations)(tq).as_matrix()
    return inside, out


def reference_gaps(
    times: np.ndarray, query: np.ndarray, period: int
) -> tuple[np.ndarray, tuple[int, int] | None]:
    """The queries within a gap of the reference poses, and its largest gap.

    A query between two reference poses further apart than both twice the poses' median
    spacing (at least one pose missing: a GNSS outage, messages dropped) and the epoch
    ``period`` (a reference slower than the epochs keeps its own rate) is in a gap: a pose
    interpolated across it is a straight line, not the reference. Queries outside the
    poses' span and those on a pose's stamp are in none.

    Args:
        times: (M,) int64 ns stamps of the reference poses (any order, repeats allowed).
        query: (E,) int64 ns. period: ns between epochs.

    Returns:
        ``in_gap`` (E,) bool and the largest gap's ``(start, end)`` ns among those holding
        a query (None without one).
    """
    t = np.unique(np.asarray(times, dtype=np.int64))
    q = np.asarray(query, dtype=np.int64)
    in_gap = np.zeros(len(q), dtype=bool)
    if len(t) < 3:
        return in_gap, None
    limit = max(2 * float(np.median(np.diff(t))), float(period))
    after = np.searchsorted(t, q, side="right")
    inside = (after > 0) & (after < len(t)) & (q != t[np.maximum(after - 1, 0)])
    lo = t[np.clip(after - 1, 0, len(t) - 1)]
    hi = t[np.clip(after, 0, len(t) - 1)]
    in_gap = inside & ((hi - lo) > limit)
    if not in_gap.any():
        return in_gap, None
    widest = int(np.argmax(np.where(in_gap, hi - lo, -1)))
    return in_gap, (int(lo[widest]), int(hi[widest]))
