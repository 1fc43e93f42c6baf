"""Whether an epoch's own twist tells a better deskewing twist (``odometry.deskew_change_gate``).

The deskewing policy (:mod:`planodom.odometry.deskew`, step 2) extracts an epoch again with
its own twist wherever that differs from the twist used by more than a fixed tolerance
(``deskew_rate_tolerance_deg_s``, ``deskew_speed_tolerance_mps``). The own twist is measured
by one step, with that step's error (:func:`step_sigma`). When the twist used lies within
that error of the own one, the step does not show it wrong: an extraction with the own
twist swaps one twist for another the data do not tell apart from it, at the cost of a
whole extraction and estimate (about a third of the 2D rig's CPU time an epoch). With the
gate on, each part (angular rate; linear velocity when the step measured it) is replaced
only when the difference is beyond the chi-square 95 % bound (3 DoF) of the own twist's
error: ``3 |d|^2 / s^2 > chi2(0.95, 3)``, ``s`` the root of the trace of its block, as in
:meth:`planodom.odometry.twist_sigma.TwistUncertainty.consistent`.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from planodom.odometry.relative import RelativePose, Status

#: chi-square 95 % quantile, 3 DoF (scipy.stats.chi2.ppf(0.95, 3)).
CHI2_95_3 = float(chi2.ppf(0.95, 3))


def step_sigma(relative: RelativePose, dt: float) -> np.ndarray:
    """(2,) standard deviations of the twist a measured step gives over ``dt`` seconds:
    angular rate (rad/s) and linear velocity (m/s), from its 5-DoF covariance (the root of
    the trace of each block, over ``dt``; ``sigma_z`` added when the vertical was measured);
    inf when unknown or not measured (degenerate: the velocity)."""
    cov = relative.covariance
    if cov is None or dt <= 0 or relative.status is Status.UNRESOLVED:
        return np.full(2, np.inf)
    rate = np.sqrt(max(float(np.trace(cov[:3, :3])), 0.0)) / dt
    if relative.status is not Status.OK:
        return np.array([rate, np.inf])
    var_t = float(np.trace(cov[3:, 3:]))
    if np.isfinite(relative.sigma_z):
        var_t += relative.sigma_z**2
    return np.array([rate, np.sqrt(max(var_t, 0.0)) / dt])


def significant_change(
    new: np.ndarray, used: np.ndarray, relative: RelativePose, dt: float
) -> np.ndarray:
    """(6,) ``new`` (rad/s, m/s), the twist refined from the epoch's own, with each part
    (``[:3]``, ``[3:]``) set back to ``used``'s where their difference is within the 95 %
    bound of the error of the own twist measured by ``relative`` over ``dt`` s (module
    docstring); a part whose error is unknown (inf, zero) is kept as ``new`` has it."""
    sigma = step_sigma(relative, dt)
    out = np.array(new, dtype=np.float64, copy=True)
    for part, s in ((slice(0, 3), sigma[0]), (slice(3, 6), sigma[1])):
        d = out[part] - used[part]
        if not np.isfinite(s) or s <= 0.0:
            continue
        if 3.0 * float(d @ d) <= CHI2_95_3 * s * s:
            out[part] = used[part]
    return out
