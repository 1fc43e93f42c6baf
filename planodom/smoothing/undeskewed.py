"""The deskewing error of epochs the odometry kept without deskewing
(``smoothing.sandwich_undeskewed``).

The sandwich covariances (:mod:`.sandwich`) give each epoch's deskewing error the
covariance of the run's changes of motion around it (:mod:`.deskew_scale`): right for an
epoch deskewed with the twist of the interval before it, whose error is the change of the
twist. The deskewing policy (:mod:`planodom.odometry.deskew`) keeps some epochs without
deskewing (after an unresolved epoch no twist is predicted; a degenerate step measures
no velocity to refine with), and such an epoch's planes are off by the whole motion over
their points' times, not by its change: on the held-out 2D-rig world 22 at 2 cm the
planes of epochs 178-181 (kept without deskewing after the unresolved 177, in a turn)
sit where a deskewing error of -37 to -44 mrad in yaw and -35 cm along track puts them
(least squares through their Jacobians against the true surfaces; the true motion over
the epoch 45-58 mrad and 47 cm), against sigmas of 0.2 mrad and 1.3 cm in ``Q_k``, and
the smoothed poses there were 25-32 mrad off in yaw at sigmas of 0.9 mrad.

Here such an epoch's error is the twist it was deskewed with (zero) less the twist over
its points' times, times their span, from the odometry's steps around it as
:func:`.deskew_scale.deskew_differences` weighs them,

    d_k = -span_k sum_j share_j Log(T_j) / dt_j,

and ``diag(d_k^2)`` is added to its ``Q_k``: per axis the squared motion, whose size
the estimate of the motion gives. Not the outer product ``d_k d_k^T``: that holds the
error to the direction of the estimated motion, which is itself off by the steps' error
(and has no vertical motion where the steps did not measure it), so that a component of
the true error across it would have no variance at all. The steps need not have measured
their translation: a bridged step's is the odometry's held velocity, the best knowledge of
the motion there is (a velocity nobody measured is not deskewed with, but it is a fair
size of the error of not deskewing). Epochs taken at one instant, and the first epoch
(its deskewing is not recorded in the relative poses), are left as they are.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_log


def undeskewed_errors(relative_poses: Sequence[RelativePose], n_epochs: int) -> np.ndarray:
    """(E, 6) ``d_k`` of the module docstring (rad, m) for every epoch kept without
    deskewing although its points were spread in time (a delta = 1 relative pose into it
    with ``time_spread`` True, no ``deskew_twist`` and its ``deskew_times``); NaN for the
    others and where no step over its points' times is known."""
    steps: dict[int, RelativePose] = {}  # curr -> the delta = 1 step into it
    kept: dict[int, RelativePose] = {}
    for rel in relative_poses:
        if rel.delta != 1:
            continue
        if np.isfinite(rel.interval_s) and rel.interval_s > 0:
            steps.setdefault(rel.curr, rel)
        if rel.time_spread and rel.deskew_twist is None and rel.deskew_times is not None:
            kept.setdefault(rel.curr, rel)
    out = np.full((n_epochs, 6), np.nan)
    for k, rel in kept.items():
        assert rel.deskew_times is not None
        lo, hi = rel.deskew_times
        if not 0 <= k < n_epochs or hi <= lo:
            continue
        span = max(abs(lo), abs(hi))
        shares = {k: max(-lo, 0.0) / (hi - lo), k + 1: max(hi, 0.0) / (hi - lo)}
        if k + 1 not in steps:  # the last epoch: the step into it is the motion known
            shares = {k: 1.0}
        used = [(steps.get(j), w) for j, w in shares.items() if w > 0.0]
        if not used or any(s is None for s, _ in used):
            continue
        d = np.zeros(6)
        for s, w in used:
            assert s is not None
            d -= span * w / s.interval_s * se3_log(np.asarray(s.T_prev_curr, dtype=float))
        out[k] = d
    return out


def with_undeskewed(Q: np.ndarray, relative_poses: Sequence[RelativePose]) -> np.ndarray:
    """(E, 6, 6) ``Q`` (the epochs' deskewing errors' covariances) plus ``diag(d_k^2)``
    for the epochs kept without deskewing (:func:`undeskewed_errors`); ``Q`` itself when
    there are none."""
    return plus_diagonal(Q, undeskewed_errors(relative_poses, len(Q)))


def plus_diagonal(Q: np.ndarray, d: np.ndarray) -> np.ndarray:
    """(E, 6, 6) ``Q`` plus ``diag(d_k^2)`` for each row ``k`` of ``d`` ((E, 6)) that is
    finite (NaN rows add nothing); ``Q`` itself when there are none."""
    rows = np.flatnonzero(np.all(np.isfinite(d), axis=1))
    if not len(rows):
        return Q
    out = np.array(Q, dtype=float, copy=True)
    idx = np.arange(6)
    out[rows[:, None], idx, idx] += d[rows] ** 2
    return out
