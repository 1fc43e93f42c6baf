"""The first epoch's deskewing error sized by its first step (``smoothing.sandwich_first_epoch``).

The sandwich covariances (:mod:`.sandwich`) give every epoch's deskewing error the
covariance ``Q_k`` of the run's changes of motion around it, scaled per run
(:mod:`.deskew_scale`): the error of deskewing with a twist measured before or on the epoch
itself. The first epoch has no twist before it: the deskewing policy deskews it again with
its first step's twist (at the first measured step when the first ones were not,
docs/RESULTS.md, FIRSTEPOCH), so besides the change of motion its planes carry that step's
own error, times its points' span over the step's interval. Where that step is degenerate
its velocity was not measured (the 2D-rig world 144 at 2 cm: epoch 0's planes sit where 94
mm along y and 0.74 mrad of yaw put them, against ``Q_0`` sigmas of 0.67 mm and 0.01 mrad;
the step declares 70 mm and 1.6 mrad), and the changes of motion cannot see it. And through
the first pose, the gauge, the loop factors that close on epoch 0 turn the whole lap by it
(docs/RESULTS.md, NEES2CM, NEESJAC).

"step" adds to ``Q_0``

    (span / interval)^2 Sigma_01,

``Sigma_01`` the step 0 -> 1's declared covariance (roll, pitch, yaw, x, y; z its
``sigma_z`` where measured; a degenerate step declares the motion bound for the velocity it
did not measure, a cautious size of the later step's twist used then), ``span`` the largest
|time| of epoch 1's points about its stamp (the first epoch's are not recorded; one rig),
``interval`` the step's: the first order error of a twist ``Log(T_01) / interval`` applied
over ``span``. Added, not in place of ``Q_0``: the twist's error and the motion's change
within the epoch are two sources.

"degenerate_step" adds it only where that step did not measure its translation (degenerate):
a measured step's error is of the size the run's scale already gives every epoch's twist
(:mod:`.deskew_scale`; on world 30 at 6 mm the step's declared covariance sizes epoch 0's
planes' errors at chi2 48.8 on 30 dof, the changes of motion at 23.4, and "step" takes the
lap's NEES5 out of the interval, 0.92 -> 0.62: docs/RESULTS.md, NEESFIRST), a velocity
nobody measured is not."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose


def first_step_covariance(
    relative_poses: Sequence[RelativePose], degenerate_only: bool = False
) -> np.ndarray | None:
    """(6, 6) ``(span / interval)^2 Sigma_01`` of the module docstring (rad^2, m^2; the
    order roll, pitch, yaw, x, y, z of the sandwich's ``Q``), or None where the step
    0 -> 1 is unknown, unmeasured (unresolved), without a covariance, or its epoch's
    points were not spread in time; with ``degenerate_only`` also where it measured its
    translation (status OK)."""
    step = next((r for r in relative_poses if r.prev == 0 and r.curr == 1), None)
    if step is None or not step.measured or step.covariance is None:
        return None
    if degenerate_only and step.translation_observed:
        return None
    if not step.time_spread or step.deskew_times is None:
        return None
    interval = float(step.interval_s)
    cov = np.asarray(step.covariance, dtype=float).reshape(5, 5)
    if not (np.isfinite(interval) and interval > 0.0 and np.all(np.isfinite(cov))):
        return None
    lo, hi = step.deskew_times
    out = np.zeros((6, 6))
    out[:5, :5] = cov
    if step.z_observed and np.isfinite(step.sigma_z):
        out[5, 5] = step.sigma_z**2
    return out * (max(abs(lo), abs(hi)) / interval) ** 2


def with_first_step(
    Q: np.ndarray, relative_poses: Sequence[RelativePose], degenerate_only: bool = False
) -> np.ndarray:
    """(E, 6, 6) ``Q`` (the epochs' deskewing errors' covariances) with
    :func:`first_step_covariance` added to ``Q[0]``; ``Q`` itself where there is none."""
    add = first_step_covariance(relative_poses, degenerate_only)
    if add is None or not len(Q):
        return Q
    out = np.array(Q, dtype=float, copy=True)
    out[0] += add
    return out
