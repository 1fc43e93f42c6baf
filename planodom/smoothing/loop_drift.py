"""The drift of the chained guess as the run itself bounds it (``smoothing.loop_candidate_drift``
"run"): a bridged epoch (its step not measured, constant velocity) adds the error of a
velocity that changes by a random walk as large as the run's measured steps changed
(:class:`RunWalk`), and the (yaw, x, y) drift covariance over spans of epochs
(:func:`run_drift`) of :class:`planodom.smoothing.loop_candidates.CandidateLoopBuilder`."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import pose5_from_transform
from planodom.odometry.relative import RelativePose


class RunWalk:
    """Variance one epoch adds to a chained quantity (a step's xy, or its yaw) that the run
    bridges by constant velocity where no step is measured.

    Measured (``step``, its components): the measurement's own ``var``. Bridged (None),
    the n-th in a row: the error of a velocity that changes by a random walk, as much per
    epoch as the run's measured consecutive steps changed so far (mean square over their
    components; their measurement noise makes it cautious): the bridge's variance grows as
    n^3 / 3 times it, so this epoch adds its n^3 - (n - 1)^3 share; at most ``var`` (the
    fallback's variance), and ``var`` itself before two measured steps. The fallback
    factors' 0.5 m per epoch is what lets the graph recover from a wrong step; as the drift
    a loop pose must agree with it let a corridor aliased 4.6 m along pass after 72 bridged
    epochs whose true drift was 0.45 m (2D-rig world 16 at 6 mm with the coplanar twist: 21
    wrong loop factors kept, ATE 3.06 m)."""

    def __init__(self) -> None:
        self.bridged = 0  # epochs bridged in a row
        self.step: np.ndarray | None = None  # the last measured step (None: after a bridge)
        self.change = np.zeros(2)  # sum and count of squared step changes

    def variance(self, step: np.ndarray | None, var: float) -> float:
        """The variance the step into this epoch adds (see the class docstring)."""
        if step is None:
            self.step, self.bridged = None, self.bridged + 1
            if self.change[1] == 0:
                return var
            n = self.bridged
            share = (self.change[0] / self.change[1]) * (n**3 - (n - 1) ** 3) / 3.0
            return min(var, float(share))
        if self.step is not None:
            self.change += (float(np.sum((step - self.step) ** 2)), 1.0)
        self.step, self.bridged = step, 0
        return var


def run_drift(
    travelled: Sequence[float] | np.ndarray,
    variances: Sequence[Sequence[float]] | Sequence[np.ndarray] | np.ndarray,
    spans: Sequence[tuple[int, int]],
    config: PlanodomConfig,
) -> np.ndarray:
    """(3, 3) covariance of the chained guess's (yaw, x, y) drift over epoch ``spans``
    ((a, b) pairs, in any order): ``travelled`` (E,) cumulative distance, m, ``variances``
    (E, 2) cumulative (xy, yaw) variances of the steps, m^2 and rad^2 (the run's, see
    :class:`RunWalk`); half the xy variance per axis, the yaw's lever arm over the
    distance driven, and the minimum bounds' floors (``loop_min_translation_m``, the
    association's ``prior_rotation_deg``, over ``loop_sigmas``)."""
    c = config.smoothing
    distance = var_t = var_r = 0.0
    for a, b in spans:
        distance += abs(travelled[b] - travelled[a])
        var_t += abs(variances[b][0] - variances[a][0])
        var_r += abs(variances[b][1] - variances[a][1])
    var_xy = 0.5 * var_t + var_r * distance**2 + (c.loop_min_translation_m / c.loop_sigmas) ** 2
    floor_r = np.radians(config.association.prior_rotation_deg) / c.loop_sigmas
    return np.diag([var_r + floor_r**2, var_xy, var_xy])


def run_drift_xy(
    travelled: np.ndarray,
    variances: np.ndarray,
    spans: Sequence[tuple[np.ndarray, np.ndarray]],
    config: PlanodomConfig,
) -> np.ndarray:
    """(N,) the per-axis xy variance (:func:`run_drift`'s ``[1, 1]``, m^2) of N span sets at
    once: ``spans`` (a, b) pairs of (N,) int epoch arrays, ``travelled`` (E,) and
    ``variances`` (E, 2) as for :func:`run_drift`. The same operations in the same order,
    elementwise; the square may round differently from ``run_drift``'s scalar power by an
    ulp (:func:`planodom.smoothing.loop_gate._sharpest` re-ranks its near-ties exactly)."""
    c = config.smoothing
    travelled, variances = np.asarray(travelled), np.asarray(variances)
    distance = var_t = var_r = np.zeros(len(spans[0][0]))
    for a, b in spans:
        distance = distance + np.abs(travelled[b] - travelled[a])
        var_t = var_t + np.abs(variances[b, 0] - variances[a, 0])
        var_r = var_r + np.abs(variances[b, 1] - variances[a, 1])
    return 0.5 * var_t + var_r * distance**2 + (c.loop_min_translation_m / c.loop_sigmas) ** 2


def measured_step_terms(
    r: RelativePose, var_t: float, step: np.ndarray | None
) -> tuple[float, np.ndarray, float, np.ndarray | None]:
    """The drift terms of a measured step ``r`` with a covariance: its yaw variance (rad^2),
    its yaw (1,) rad and, where its translation is observed, its xy variance (m^2) and xy
    step (2,) m (else ``var_t`` and ``step`` as given). Shared by the loop candidates' and
    the initial guess check's sums of the run's drift."""
    cov = np.asarray(r.covariance, dtype=float).reshape(5, 5)
    yaw = pose5_from_transform(np.asarray(r.T_prev_curr, dtype=float))[2:3]
    if r.translation_observed:
        var_t = float(cov[3, 3] + cov[4, 4])
        step = np.asarray(r.T_prev_curr, dtype=float)[:2, 3]
    return float(cov[2, 2]), yaw, var_t, step
