"""A bridged stretch's steps interpolated between the steps measured at its two ends
(``odometry.bridge_ends: interpolated``).

The streaming odometry bridges an unresolved epoch with the prediction: the last measured
step's twist held (:mod:`.bridge_trend`). When the stretch of unresolved epochs ends with
a measured step, the twist is known at both ends; this pass, after the streaming run,
makes each bridged step again with the twist interpolated linearly in time between the
step measured into the epoch before the stretch and the step measured out of its last
epoch (each at its step's middle time), and chains the poses through the new steps. The
streaming estimates (and the planes, the measured steps) are not changed: only the
bridged steps, and through them the poses after each stretch.

A stretch is interpolated only when both ends are measured steps between consecutive
epochs (status ok or degenerate: the rotation measured; the step before from epoch
``a - 2`` to ``a - 1``, the step after from ``b`` to ``b + 1``), so a stretch at either
end of the run, or one whose next epoch was measured against an earlier reference, keeps
its bridge.

Found on the built-in random-outdoor at sigma = 0 (docs/RESULTS.md, SIGMA0): epochs
563-573 bridged with step 562's 5.72 deg/s while the true rate climbed to 5.99 deg/s,
-0.14 deg of heading over the stretch with the true deskewing (-0.18 deg with the
odometry's own); interpolated -0.011 deg.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.geometry import invert_transform, orthonormalised, se3_exp, se3_log
from planodom.odometry.chain import rechained, run_steps
from planodom.odometry.relative import RelativePose, Status, replaced

#: Statuses whose step measured the rotation (a stretch's ends).
MEASURED = (Status.OK, Status.DEGENERATE)


def bridged_stretches(results: Sequence[RelativePose | None]) -> list[tuple[int, int]]:
    """(a, b) of every maximal stretch of unresolved epochs ``a..b`` whose ends are
    measured steps between consecutive epochs (module docstring)."""
    out, n, k = [], len(results), 1
    while k < n:
        r = results[k]
        if r is None or r.status is not Status.UNRESOLVED:
            k += 1
            continue
        a = k
        while k < n and (r := results[k]) is not None and r.status is Status.UNRESOLVED:
            k += 1
        b = k - 1
        before = results[a - 1] if a >= 2 else None
        after = results[b + 1] if b + 1 < n else None
        if (
            before is not None
            and after is not None
            and before.status in MEASURED
            and after.status in MEASURED
            and before.prev == a - 2
            and after.prev == b
        ):
            out.append((a, b))
    return out


def interpolated_steps(steps: np.ndarray, times: np.ndarray, a: int, b: int) -> np.ndarray:
    """(b - a + 1, 4, 4) the steps ``T_{j-1}_j`` of epochs ``j = a..b``, each made with the
    twist interpolated linearly in time between the twists of ``steps[a - 1]`` (``T_{a-2}_
    {a-1}``) and ``steps[b + 1]`` (``T_b_{b+1}``), each at its step's middle time;
    ``steps`` (E, 4, 4) with ``steps[j] = T_{j-1}_j``, ``times`` (E,) s."""
    mid = lambda j: 0.5 * (times[j - 1] + times[j])  # noqa: E731
    dt = lambda j: times[j] - times[j - 1]  # noqa: E731
    w0 = se3_log(steps[a - 1]) / dt(a - 1)
    w1 = se3_log(steps[b + 1]) / dt(b + 1)
    t0, t1 = mid(a - 1), mid(b + 1)
    out = []
    for j in range(a, b + 1):
        f = (mid(j) - t0) / (t1 - t0)
        out.append(orthonormalised(se3_exp(((1.0 - f) * w0 + f * w1) * dt(j))))
    return np.array(out)


def interpolated_bridges(
    poses: np.ndarray, times: np.ndarray, results: Sequence[RelativePose | None]
) -> tuple[np.ndarray, list[RelativePose | None]]:
    """``poses`` (E, 4, 4) and ``results`` with every bridged stretch's steps interpolated
    (module docstring): the poses from the first stretch on chained through the steps
    (the others' steps as they were), each bridged result's ``T_prev_curr`` from the new
    poses. Unchanged (the same objects) when no stretch qualifies."""
    stretches = bridged_stretches(results)
    if not stretches:
        return poses, list(results)
    steps = run_steps(poses)
    for a, b in stretches:
        steps[a : b + 1] = interpolated_steps(steps, times, a, b)
    out = rechained(poses, steps, stretches[0][0])
    new = list(results)
    for a, b in stretches:
        for j in range(a, b + 1):
            r = results[j]
            assert r is not None
            new[j] = replaced(r, T_prev_curr=invert_transform(out[r.prev]) @ out[j])
    return out, new
