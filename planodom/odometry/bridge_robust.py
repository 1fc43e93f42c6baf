"""A gap's bridge rate that one bad step cannot carry and a turn's onset does not lag
(``odometry.bridge_rate: robust``).

``last`` holds the last measured step's angular rate over a gap: one degenerate step's
rate 20 deg/s off (issue 11's random-outdoor at 2 cm, its stated yaw-rate sd 5.0 deg/s)
is held over eleven epochs. ``median`` outvotes it but lags a turn's onset by about half
its window (world 200 at 6 mm: a step measured +3.9 deg/s, sd 0.06, after four at -5,
replaced by their median; docs/RESULTS.md, BRIDGEMED). The two cases differ in what the
last step states about itself, not in how far it departs from the ones before. So each
angular component is the rate a Kalman filter over the window's steps gives at the last
one: the rate a random walk, each step a measurement of it with its stated variance.

- ``q``, the walk's variance an epoch, is how far the other steps' (all but the last)
  successive rates move beyond their stated variances: the mean of ``(d^2 - v_i - v_j)
  / (x_j - x_i)`` over their successive pairs, at least 0. A turn's onset or a steady
  ramp moves them: ``q`` grows and the last step's own rate is kept (world 200's onset:
  steps that moved by 1 deg/s an epoch, then one at sd 0.06 deg/s: within 0.3 % of its
  rate). Steps that only scatter within their noise give ``q`` = 0: the filter is their
  variance-weighted mean, and a last step that states itself poor (its variance far
  above that mean's) gives way to it.
- The last step is left out of ``q``: its own departure must not make the filter trust
  it.

Written here rather than with a library filter: a few scalar updates an unresolved epoch
(filterpy is not a dependency; scipy has no Kalman filter).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose

#: Fewest other rates (besides the last) the walk's variance is estimated from.
MIN_OTHERS = 3

#: Variance floor, (rad/s)^2, so that exact rates (noise-free tests) give finite gains.
VARIANCE_FLOOR = 1e-12


def rate_variance(relative: RelativePose, dt: float) -> np.ndarray:
    """(3,) the stated variance, (rad/s)^2, of the angular rate (roll, pitch, yaw) a step
    ``relative`` of ``dt`` seconds measured: its covariance's rotation diagonal (rad^2)
    over ``dt``^2; NaN without a covariance or a positive ``dt``."""
    if relative.covariance is None or not dt > 0:
        return np.full(3, np.nan)
    return np.diag(relative.covariance)[:3] / dt**2


def walk_variance(x: np.ndarray, y: np.ndarray, v: np.ndarray) -> float:
    """``q`` (module docstring), (rad/s)^2 an epoch, from steps at epochs ``x`` (m,) with
    rates ``y`` (m,) rad/s and stated variances ``v`` (m,) (rad/s)^2, m >= 2."""
    d, gap = np.diff(y), np.diff(x)
    return max(float(np.mean((d**2 - v[:-1] - v[1:]) / gap)), 0.0)


def robust_rate(x: np.ndarray, y: np.ndarray, v: np.ndarray) -> float | None:
    """The rate (rad/s) to bridge with from one component's window (module docstring):
    ``x`` (n,) the steps' epochs, ``y`` (n,) their rates (rad/s), ``v`` (n,) their stated
    variances ((rad/s)^2; NaN: unknown, a step left out), the last one last. None (keep
    the last rate) with fewer than :data:`MIN_OTHERS` known others or an unknown
    ``v[-1]``."""
    known = np.r_[np.isfinite(v[:-1]) & np.isfinite(y[:-1]), True]
    if known.sum() <= MIN_OTHERS or not np.isfinite(v[-1]):
        return None
    x, y, v = x[known], y[known], np.maximum(v[known], VARIANCE_FLOOR)
    q = walk_variance(x[:-1], y[:-1], v[:-1])
    rate, var = float(y[0]), float(v[0])
    for i in range(1, len(y)):
        var += q * (x[i] - x[i - 1])  # the walk since the step before
        gain = var / (var + v[i])
        rate, var = rate + gain * (y[i] - rate), (1.0 - gain) * var
    return rate


def robust_twist(
    twist: np.ndarray,
    rates: Sequence[tuple[int, np.ndarray]],
    variances: Sequence[np.ndarray],
) -> np.ndarray:
    """(6,) ``twist`` (rad/s, m/s; the prediction, its rate the last step's) with each
    angular component the filtered rate (:func:`robust_rate`) over ``rates`` ((epoch, own
    twist (6,)) of the recent steps that measured their rate, oldest first) and
    ``variances`` ((3,) each, the same steps', :func:`rate_variance`); ``twist`` itself
    (the same object) while they are fewer than ``MIN_OTHERS + 1`` or differ in length,
    or where no component has its variances."""
    if len(rates) < MIN_OTHERS + 1 or len(variances) != len(rates):
        return twist
    x = np.array([j for j, _ in rates], dtype=float)
    y = np.array([tw[:3] for _, tw in rates], dtype=float)
    v = np.array(variances, dtype=float)
    rate = [robust_rate(x, y[:, c], v[:, c]) for c in range(3)]
    if all(r is None for r in rate):
        return twist
    return np.r_[[twist[c] if r is None else r for c, r in enumerate(rate)], twist[3:]]
