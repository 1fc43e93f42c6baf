"""A gap's bridge rate that one bad step cannot carry and a turn's onset does not lag
(``odometry.bridge_rate: robust``).

``last`` holds the last measured step's angular rate over a gap: one degenerate step's
rate 20 deg/s off (issue 11's random-outdoor at 2 cm, its stated yaw-rate sd 5.0 deg/s)
is held over eleven epochs. ``median`` outvotes it but lags a turn's onset by about half
its window (world 200 at 6 mm: a step measured +3.9 deg/s, sd 0.06, after four at -5,
replaced by their median; docs/RESULTS.md, BRIDGEMED). The two cases differ in what the
last step states about itself, not in how far it departs from the ones before: so each
angular component of the last rate is weighed against the line through the window's
other rates by their variances, as one Kalman update would (written here: a few lines
of weighted least squares on at most ``velocity_window`` points; scipy's fits neither
take per-point variances and a process noise nor report the prediction's variance).

- The line: the other rates' weighted least-squares line (weights 1 / (stated variance
  + q)), its slope kept only where it is told apart from zero (chi-square 95 %, one
  degree of freedom), else their weighted mean; ``q``, how far the true rate moves about
  such a line, is the others' scatter about their unweighted line beyond their stated
  variances (at least 0). Its value at the last step, ``y_hat``, has variance
  ``P = var(y_hat) + q``.
- The last rate ``y`` with stated variance ``v``: kept as it is (``last``) unless it is
  an outlier, ``(y - y_hat)^2 > chi2_1(0.99) (P + v)``; an outlier is replaced by
  ``y_hat + P / (P + v) (y - y_hat)``: a step that states itself precise (a turn's onset
  measured on good walls, v << P) stays within a fraction of a percent of its own rate,
  one that states itself poor (v >> P) gives way to the line.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.odometry.relative import RelativePose

#: chi-square quantiles of one degree of freedom: the slope told apart from zero (95 %),
#: the last rate an outlier of the line (99 %); textbook levels, not tuned.
SLOPE_CHI2 = 3.841458820694124
OUTLIER_CHI2 = 6.6348966010212145

#: Fewest other rates (besides the last) a line and its scatter are fitted to.
MIN_OTHERS = 3

#: Variance floor, (rad/s)^2, so that exact rates (noise-free tests) give finite weights.
VARIANCE_FLOOR = 1e-12


def rate_variance(relative: RelativePose, dt: float) -> np.ndarray:
    """(3,) the stated variance, (rad/s)^2, of the angular rate (roll, pitch, yaw) a step
    ``relative`` of ``dt`` seconds measured: its covariance's rotation diagonal (rad^2)
    over ``dt``^2; NaN without a covariance or a positive ``dt``."""
    if relative.covariance is None or not dt > 0:
        return np.full(3, np.nan)
    return np.diag(relative.covariance)[:3] / dt**2


def robust_rate(x: np.ndarray, y: np.ndarray, v: np.ndarray) -> float | None:
    """The rate (rad/s) to bridge with from one component's window (module docstring):
    ``x`` (n,) the steps' epochs, ``y`` (n,) their rates (rad/s), ``v`` (n,) their stated
    variances ((rad/s)^2; NaN: unknown, a step left out of the line), the last one last.
    None (keep the last rate) unless it is an outlier of the line; None too with fewer
    than :data:`MIN_OTHERS` known others or an unknown ``v[-1]``."""
    known = np.isfinite(v[:-1]) & np.isfinite(y[:-1])
    xo, yo = x[:-1][known], y[:-1][known]
    vo = np.maximum(v[:-1][known], VARIANCE_FLOOR)
    if len(xo) < MIN_OTHERS or not np.isfinite(v[-1]):
        return None
    dx = xo - xo.mean()
    slope0 = float(dx @ (yo - yo.mean()) / (dx @ dx))
    scatter = yo - yo.mean() - slope0 * dx
    q = max(float(scatter @ scatter) / (len(xo) - 2) - float(vo.mean()), 0.0)
    w = 1.0 / (vo + q)
    xm, ym = float(w @ xo / w.sum()), float(w @ yo / w.sum())
    sxx = float(w @ (xo - xm) ** 2)
    slope = float(w @ ((xo - xm) * (yo - ym))) / sxx
    var_hat = 1.0 / float(w.sum())
    y_hat = ym
    if slope**2 > SLOPE_CHI2 / sxx:  # the slope told apart from zero: the line
        y_hat += slope * (x[-1] - xm)
        var_hat += (x[-1] - xm) ** 2 / sxx
    P, vl, d = var_hat + q, max(float(v[-1]), VARIANCE_FLOOR), float(y[-1]) - y_hat
    if d**2 <= OUTLIER_CHI2 * (P + vl):
        return None
    return y_hat + P / (P + vl) * d


def robust_twist(
    twist: np.ndarray,
    rates: Sequence[tuple[int, np.ndarray]],
    variances: Sequence[np.ndarray],
) -> np.ndarray:
    """(6,) ``twist`` (rad/s, m/s; the prediction, its rate the last step's) with each
    angular component whose last measured rate is an outlier (:func:`robust_rate`) over
    ``rates`` ((epoch, own twist (6,)) of the recent steps that measured their rate,
    oldest first) and ``variances`` ((3,) each, the same steps', :func:`rate_variance`)
    replaced; ``twist`` itself (the same object) where none is, or while they are fewer
    than ``MIN_OTHERS + 1`` or differ in length."""
    if len(rates) < MIN_OTHERS + 1 or len(variances) != len(rates):
        return twist
    x = np.array([j for j, _ in rates], dtype=float)
    y = np.array([tw[:3] for _, tw in rates], dtype=float)
    v = np.array(variances, dtype=float)
    rate = [robust_rate(x, y[:, c], v[:, c]) for c in range(3)]
    if all(r is None for r in rate):
        return twist
    return np.r_[[twist[c] if r is None else r for c, r in enumerate(rate)], twist[3:]]
