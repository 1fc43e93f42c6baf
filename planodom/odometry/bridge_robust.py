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

- ``q``, the walk's variance an epoch, must be seen twice in the steps before the last:
  their neighbours' squared differences beyond their stated variances, and the growth of
  their variogram (second neighbours' squared differences over neighbours', which a walk
  makes grow with the gap and noise of any size, stated or not, does not); ``q`` is the
  smaller, at least 0. A turn's onset or a steady ramp makes both large and a precise
  last step is kept (world 200's onset: within 0.5 % of its departure). Steps that scatter
  within their stated noise, or more widely but from step to step (a deskewing chain,
  random-outdoor at 2 cm in another noise draw: 2, 0, +20, -21 deg/s, each stated sd 4.5),
  give ``q`` = 0: the filter is their variance-weighted mean, to which a last step that
  states itself poor gives way. (BRIDGE3's first filter had the stated differences alone:
  such a chain made it trust its last step.)
- The last step is left out of ``q``: its own departure must not make the filter trust
  it.

Written here rather than with a library filter: a few scalar updates an unresolved epoch
(filterpy is not a dependency; scipy has no Kalman filter).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose

#: Fewest other rates (besides the last) the walk's variance is estimated from (two
#: neighbours' differences and one second neighbours').
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


def variogram_walk(x: np.ndarray, y: np.ndarray) -> float:
    """A walk's variance, (rad/s)^2 an epoch, from steps at epochs ``x`` (m,), m >= 3,
    with rates ``y`` (m,) rad/s: the growth of the rates' variogram from neighbours to
    second neighbours, ``(mean(d2^2) - mean(d1^2)) / (mean(gap2) - mean(gap1))``, at
    least 0. A walk's squared differences grow with their gap, white noise's do not, and
    the noise cancels in the difference whatever its size (stated or not)."""
    d1, g1 = np.diff(y), np.diff(x)
    d2, g2 = y[2:] - y[:-2], x[2:] - x[:-2]
    growth = float(np.mean(g2) - np.mean(g1))
    return max(float(np.mean(d2**2) - np.mean(d1**2)) / growth, 0.0)


def stated_walk(x: np.ndarray, y: np.ndarray, v: np.ndarray) -> float:
    """A walk's variance from the neighbours' squared differences beyond their stated
    variances ``v`` (m,): ``mean((d^2 - v_i - v_j) / gap)``, at least 0."""
    d, gap = np.diff(y), np.diff(x)
    return max(float(np.mean((d**2 - v[:-1] - v[1:]) / gap)), 0.0)


def walk_variance(x: np.ndarray, y: np.ndarray, v: np.ndarray) -> float:
    """``q`` (module docstring), (rad/s)^2 an epoch, of steps at epochs ``x`` (m,), m >= 3,
    with rates ``y`` (m,) rad/s and stated variances ``v`` (m,) (rad/s)^2: the smaller of
    :func:`variogram_walk` and :func:`stated_walk` (the rate moves only where both say
    so)."""
    return min(variogram_walk(x, y), stated_walk(x, y, v))


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
