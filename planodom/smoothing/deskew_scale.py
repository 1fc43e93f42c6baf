"""A run-level scale of the sandwich's deskewing error (``smoothing.sandwich_motion_scale``).

The sandwich covariances (:mod:`.sandwich`) take each epoch's deskewing error ``e_k`` (the
twist its points were deskewed with less the true one, per epoch span: rad, m) to have
the covariance ``Q_k`` of the run's changes of motion around it
(:meth:`.DeskewNoise.plane_motion_change`). That shape follows the motion (large in turns,
small on straights), but its size is not the error's: the batch's odometry deskews with
the twist fit to the epoch's own planes (``smoothing.odometry_deskew_twist``), which errs
a fraction of a change of motion (on four 2D-rig laps the true errors' rms is 0.04-0.8 of
the changes' sigma per axis).

Here the size is estimated from the run itself, one factor per axis ``i``,
``Q_k -> s_i s_j (Q_k)_ij`` with

    s_i^2 = sum_k d_ki^2 / sum_k (Q_k)_ii,   d_k = span_k (w_k - Log(T_k,k+1) / dt_k+1),

``w_k`` the twist epoch k was deskewed with, ``span_k`` its points' span and
``Log(T_k,k+1) / dt`` the odometry's step out of it (the twist over the interval its
points were taken in, from the planes of two epochs). ``d_k`` is the deskewing error
``e_k`` less the step's error ``eta_k``: ``E[d d^T] = E[e e^T] + E[eta eta^T] - 2
E[e eta^T]``; unbiased for the error's mean square when the step's error is small against
it and uncorrelated with it. Neither holds exactly (a step measured from planes deskewed
with ``w_k`` takes part of ``e_k``; the twist over the interval is not the best constant
twist over the points' times); tests/smoothing/test_deskew_scale.py checks the arithmetic
on seeded draws, the NEES experiment the approximation (docs/RESULTS.md).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose
from planodom.se3 import se3_log


def deskew_differences(
    relative_poses: Sequence[RelativePose], n_epochs: int
) -> tuple[np.ndarray, np.ndarray]:
    """(E, 6) per epoch ``d_k`` of the module docstring (rad, m; NaN where epoch k has no
    recorded deskewing twist or a step its points' times reach was not measured; the
    vertical velocity NaN where such a step did not measure z) and (E, 6) the variance
    the steps' covariances declare for their part of ``d_k`` (rad^2, m^2).

    The steps' twist is that over the points' times ``[lo, hi]`` (relative to the
    epoch's): the steps into and out of the epoch weighted by the share of ``[lo, hi]``
    before and after it (the simulated scans: all after; a sweep stamped at its middle:
    half each)."""
    own: dict[int, RelativePose] = {}
    step: dict[int, RelativePose] = {}  # curr -> the measured delta = 1 step into it
    for rel in relative_poses:
        if rel.delta != 1:
            continue
        if rel.deskew_twist is not None and rel.deskew_times is not None:
            own.setdefault(rel.curr, rel)
        if rel.translation_observed and np.isfinite(rel.interval_s) and rel.interval_s > 0:
            step.setdefault(rel.curr, rel)
    out = np.full((n_epochs, 6), np.nan)
    var = np.zeros((n_epochs, 6))
    for k, rel in own.items():
        assert rel.deskew_twist is not None and rel.deskew_times is not None
        lo, hi = rel.deskew_times
        span = max(abs(lo), abs(hi))
        shares = {k: max(-lo, 0.0) / (hi - lo), k + 1: max(hi, 0.0) / (hi - lo)}
        used = [(step.get(j), w) for j, w in shares.items() if w > 0.0]
        if not 0 <= k < n_epochs or hi <= lo or any(s is None for s, _ in used):
            continue
        d = span * np.asarray(rel.deskew_twist, dtype=float)
        z_known = True
        for s, w in used:
            assert s is not None
            ratio = span * w / s.interval_s
            d = d - ratio * se3_log(np.asarray(s.T_prev_curr, dtype=float))
            if s.covariance is not None and np.all(np.isfinite(s.covariance)):
                var[k, :5] += ratio**2 * np.diag(np.asarray(s.covariance, dtype=float))
            z_known = z_known and s.z_observed and bool(np.isfinite(s.sigma_z))
            var[k, 5] += (ratio * s.sigma_z) ** 2 if z_known else 0.0
        out[k] = d
        if not z_known:
            out[k, 5], var[k, 5] = np.nan, 0.0
    return out, var


def axis_scales(
    differences: np.ndarray, motion_change: np.ndarray, step_variance: np.ndarray | None = None
) -> np.ndarray:
    """(6,) ``s_i`` of the module docstring from ``differences`` (E, 6) ``d_k`` (NaN: not
    measured) and ``motion_change`` (E, 6, 6) ``Q_k``, over the epochs where both are
    known and ``Q_k`` is not zero; 1 on an axis without any (the changes kept there).
    ``step_variance`` (E, 6): subtracted from ``d_k``'s squares (at least 0 in total)."""
    q = np.diagonal(np.asarray(motion_change, dtype=float), axis1=1, axis2=2)
    d = np.asarray(differences, dtype=float)
    scales = np.ones(6)
    for i in range(6):
        ok = np.isfinite(d[:, i]) & (q[:, i] > 0.0)
        if np.any(ok):
            square = np.sum(d[ok, i] ** 2)
            if step_variance is not None:
                square = max(square - float(np.sum(step_variance[ok, i])), 0.0)
            scales[i] = np.sqrt(square / np.sum(q[ok, i]))
    return scales


def scaled_motion_change(
    motion_change: np.ndarray, relative_poses: Sequence[RelativePose], net: bool = False
) -> tuple[np.ndarray, np.ndarray]:
    """(E, 6, 6) ``Q_k`` scaled per axis (module docstring) and the (6,) scales; ``net``:
    less the variance the steps' covariances declare."""
    Q = np.asarray(motion_change, dtype=float)
    d, var = deskew_differences(relative_poses, len(Q))
    s = axis_scales(d, Q, var if net else None)
    return Q * np.outer(s, s)[None], s
