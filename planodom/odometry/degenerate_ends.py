"""A degenerate stretch's unmeasured direction made again from the velocities measured at
its two ends (``odometry.degenerate_ends: interpolated``).

A degenerate step measures the rotation and, at best, the translation across a corridor;
along it (the direction its planes leave unmeasured or measure only weakly) the step is
the constant-velocity prediction's, or the weak planes' where they beat the prediction's
stated sigma. After the run, the velocity is known on both sides of a stretch of such
steps. This pass makes each degenerate step's translation along its unmeasured direction
again from the velocity interpolated linearly in time between the two ends, each end the
median (as the streaming prediction's, ``velocity_window``) of the OK steps next to the
stretch, up to ``velocity_window`` of them, and chains the poses through the new steps.
The rotation and the measured direction of every step are kept; only the poses after a
stretch move. The unmeasured direction is the horizontal eigenvector of the larger
eigenvalue of the step's x, y covariance (frame of the epoch before).

A stretch is made again only when both ends are OK steps between consecutive epochs
(the stretch's own steps too), so a stretch at either end of the run, or next to an
unresolved epoch, keeps its translation.

Found on the built-in urban canyon at 6 mm with one deskewing pass and the moments
(docs/RESULTS.md, P1MP14): the passes' OK steps are 1.6 mm rms along track, the degenerate
steps 13.7 mm (weak planes, some steps 25-50 mm off), summing to +88 mm over 123 steps
at a constant 2 m/s; made again from the ends, the run's ATE xy 0.089 -> 0.031 m.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.chain import rechained, run_steps
from planodom.odometry.relative import RelativePose, Status, replaced


def _chained(results: Sequence[RelativePose | None], k: int, status: Status) -> bool:
    """Whether epoch ``k``'s step is ``status`` against epoch ``k - 1``."""
    r = results[k] if 0 < k < len(results) else None
    return r is not None and r.status is status and r.prev == k - 1


def degenerate_stretches(results: Sequence[RelativePose | None]) -> list[tuple[int, int]]:
    """(a, b) of every maximal stretch of degenerate steps ``a..b`` (each against the epoch
    before) whose ends, the steps into ``a - 1`` and ``b + 1``, are OK (module docstring)."""
    out, n, k = [], len(results), 1
    while k < n:
        if not _chained(results, k, Status.DEGENERATE):
            k += 1
            continue
        a = k
        while k < n and _chained(results, k, Status.DEGENERATE):
            k += 1
        if _chained(results, a - 1, Status.OK) and _chained(results, k, Status.OK):
            out.append((a, k - 1))
    return out


def _end(steps: np.ndarray, times: np.ndarray, ks: list[int]) -> tuple[np.ndarray, float]:
    """The velocity (3,) m/s, frame of each step's first epoch, median over the steps
    ``ks`` (``steps[k] = T_{k-1}_k``) and the mean of their middle times, s."""
    v = [steps[k][:3, 3] / (times[k] - times[k - 1]) for k in ks]
    t = [0.5 * (times[k] + times[k - 1]) for k in ks]
    return np.median(np.array(v), axis=0), float(np.mean(t))


def _ok_run(results: Sequence[RelativePose | None], k: int, step: int, window: int) -> list[int]:
    """Up to ``window`` consecutive OK steps from ``k`` on, in direction ``step`` (+-1)."""
    out: list[int] = []
    while len(out) < window and _chained(results, k, Status.OK):
        out.append(k)
        k += step
    return out


def unmeasured_direction(covariance: np.ndarray | None) -> np.ndarray | None:
    """(3,) the horizontal unit vector of the larger eigenvalue of a step's x, y covariance
    (``covariance`` 5 x 5: roll, pitch, yaw, x, y); None without a finite one."""
    if covariance is None or not np.all(np.isfinite(covariance[3:5, 3:5])):
        return None
    _, V = np.linalg.eigh(covariance[3:5, 3:5])
    return np.r_[V[:, 1], 0.0]


def interpolated_degenerate(
    poses: np.ndarray,
    times: np.ndarray,
    results: Sequence[RelativePose | None],
    window: int,
) -> tuple[np.ndarray, list[RelativePose | None]]:
    """``poses`` (E, 4, 4) and ``results`` with every degenerate stretch's unmeasured
    direction made again (module docstring; ``window``: ``odometry.velocity_window``):
    the poses from the first stretch on chained through the steps, each changed result's
    ``T_prev_curr`` the new step. Unchanged (the same objects) when no stretch qualifies."""
    stretches = degenerate_stretches(results)
    if not stretches:
        return poses, list(results)
    times = np.asarray(times, dtype=np.float64)
    steps = run_steps(poses)
    new = list(results)
    for a, b in stretches:
        (v0, t0), (v1, t1) = (_end(steps, times, _ok_run(results, a - 1, -1, window)),
                              _end(steps, times, _ok_run(results, b + 1, 1, window)))  # fmt: skip
        for j in range(a, b + 1):
            r = results[j]
            assert r is not None
            u = unmeasured_direction(r.covariance)
            if u is None:
                continue
            f = (0.5 * (times[j] + times[j - 1]) - t0) / (t1 - t0)
            dt = times[j] - times[j - 1]
            t = steps[j][:3, 3].copy()
            steps[j][:3, 3] = t + u * (u @ ((1.0 - f) * v0 + f * v1) * dt - u @ t)
            new[j] = replaced(r, T_prev_curr=steps[j].copy())
    out = rechained(poses, steps, stretches[0][0])
    return out, new
