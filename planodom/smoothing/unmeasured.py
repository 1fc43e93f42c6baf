"""The deskewing error of epochs no step into was measured
(``smoothing.sandwich_unmeasured``).

The sandwich covariances (:mod:`.sandwich`) give each epoch's deskewing error the
covariance of the run's changes of motion around it (:mod:`.deskew_scale`): right for an
epoch deskewed with a measured twist, whose error is the change of the twist from one
interval to the next. An epoch the odometry could not resolve (its delta = 1 step into
it unresolved: bridged by the held velocity) was deskewed, if at all, with a twist no
step measured (predicted across the gap, or fitted to its own few planes), and in a gap
of several such epochs no change of motion is measured around it either (the run's
figure is used). Its planes can be off by much more: on the 2D-rig lap of world 292 at
6 mm (a lap turning 1.5-5 degrees per epoch) the planes of the unresolved epochs 38-41
sit at 23-131 per degree of freedom against the true surfaces under ``I + A Q_k A^T``
(1 where ``Q_k`` is right; the lap's other epochs 7 in median, 0.4-2 around them), and
the smoothed poses' NEES5 jumps there from about 5 to 80 and stays for the rest of the
lap (``experiments/nees_where.py``; docs/RESULTS.md, NEESLAP).

Here such an epoch's error is bounded as :mod:`.undeskewed` bounds an epoch kept without
deskewing: by the whole motion over its points' times, the bridged step's motion (the
odometry's held velocity, the best knowledge of the motion there) times the points' span
over the interval,

    d_k = -(span_k / dt_k) Log(T_{k-1, k}),

and ``diag(d_k^2)`` is added to its ``Q_k`` (per axis, not the outer product: see
:mod:`.undeskewed`). Where the bridged step does not carry its epoch's point times (the
smoothing's bridges do not), ``span / dt`` is the run's median over the steps that do, 1
where none does (the points spread over the whole interval). Epochs taken at one instant,
the first epoch, and epochs :mod:`.undeskewed` already covers are left as they are. No
constant is fitted.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_log
from planodom.smoothing.undeskewed import plus_diagonal, undeskewed_errors


def span_ratio(relative_poses: Sequence[RelativePose]) -> float:
    """The run's median ``max(|first|, |last|) / interval`` of the delta = 1 steps that
    carry their epoch's point times (``deskew_times``) and a positive interval; 1 where
    none does."""
    ratios = [own_ratio(r) for r in relative_poses if r.delta == 1]
    known = [r for r in ratios if r is not None]
    return float(np.median(known)) if known else 1.0


def own_ratio(rel: RelativePose) -> float | None:
    """``max(|first|, |last|) / interval`` of ``rel``'s own point times (``deskew_times``),
    None where it carries none or its interval is not positive."""
    if rel.deskew_times is None or not (np.isfinite(rel.interval_s) and rel.interval_s > 0):
        return None
    return max(abs(rel.deskew_times[0]), abs(rel.deskew_times[1])) / rel.interval_s


def unmeasured_errors(relative_poses: Sequence[RelativePose], n_epochs: int) -> np.ndarray:
    """(E, 6) ``d_k`` of the module docstring (rad, m) for every epoch k >= 1 whose
    delta = 1 step is not measured (unresolved) and whose points were spread in time
    (``time_spread`` not False), unless :func:`.undeskewed.undeskewed_errors` gives it
    one; NaN for the others."""
    out = np.full((n_epochs, 6), np.nan)
    into: dict[int, RelativePose] = {}
    for rel in relative_poses:
        if rel.delta == 1 and 1 <= rel.curr < n_epochs:
            # a measured step into the epoch wins over a bridge of the same epochs
            if rel.curr not in into or (rel.measured and not into[rel.curr].measured):
                into[rel.curr] = rel
    kept = np.all(np.isfinite(undeskewed_errors(relative_poses, n_epochs)), axis=1)
    ratio = span_ratio(relative_poses)
    for k, rel in into.items():
        if rel.measured or rel.time_spread is False or kept[k]:
            continue
        own = own_ratio(rel)
        r = ratio if own is None else own
        out[k] = -r * se3_log(np.asarray(rel.T_prev_curr, dtype=float))
    return out


def with_unmeasured(Q: np.ndarray, relative_poses: Sequence[RelativePose]) -> np.ndarray:
    """(E, 6, 6) ``Q`` plus ``diag(d_k^2)`` for the epochs of :func:`unmeasured_errors`;
    ``Q`` itself when there are none."""
    return plus_diagonal(Q, unmeasured_errors(relative_poses, len(Q)))
