"""The batch's windowed initial guess checked against the odometry it smooths
(``smoothing.batch_initial: checked``, issue 14).

The batch with loops predicts every epoch from its initial guess (the map's landmarks are
placed by it, and each re-identification and loop candidate is searched around it), but
bounds that search by the drift of the *chained odometry* (its measured steps'
covariances, and where a step's translation was not measured the run's own walk,
:class:`.loop_drift.RunWalk`). The default guess is the fixed-lag smoother's; it is a
solution of (nearly) the same graph, and in a corridor the odometry measures only in
rotation it can stop in a minimum metres along the travel from the odometry's constant
velocity (2D-rig lap 362: 4.3 m at 6 mm and 15.6 m at 2 cm of ATE, where the chained
odometry is 0.19 / 0.44 m; LOOP32 saw the same on world 32). Predicted from there, under
bounds of the odometry's drift, the search finds a parallel wall one spacing off and the
map ties to it (57 and 25 wrong ties kept).

:func:`inconsistent_spans` compares the two guesses' relative motion over every span of
epochs (a, b), ``(T_c[a]^-1 T_c[b])^-1 (T_w[a]^-1 T_w[b])`` (chained ``c``, windowed
``w``), as (yaw, x, y) against the run's drift covariance over the span
(:func:`.loop_drift.run_drift`, the loop candidates' "run" drift: the same covariance the
predictions are trusted with): a squared Mahalanobis distance above chi2(3) at
``loop_gate_quantile`` means the windowed guess moved where the odometry's measurements
say it cannot have. "checked" then starts the batch from the chained odometry (the whole
run: a guess stitched from two would break where they meet), else from the windowed guess.

Written here, not taken from a library: a test of this pipeline's two guesses.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, pose5_from_transform
from planodom.odometry.relative import RelativePose
from planodom.odometry.twist_sigma import chi2_quantile
from planodom.smoothing.graph import GraphBuilder, GraphUpdate
from planodom.smoothing.loop_drift import RunWalk, measured_step_terms
from planodom.smoothing.motion import FALLBACK_STEPS


class _Chain(GraphBuilder):
    """A :class:`GraphBuilder` that only chains the initial guess (no planes, no factors
    kept): the poses the batch starts from with ``batch_initial`` "odometry"."""

    def chain(self, relatives: Sequence[RelativePose], n_epochs: int) -> np.ndarray:
        """(E, 4, 4) the chained guess, as :meth:`GraphBuilder.add_epoch` makes it."""
        self.deskew = None  # (no deskewed frames: only the poses are wanted)
        by_epoch: dict[int, list[RelativePose]] = {k: [] for k in range(n_epochs)}
        for r in relatives:
            if 0 <= r.curr < n_epochs:
                by_epoch[r.curr].append(r)
        for k in range(n_epochs):
            usable = [r for r in by_epoch[k] if r.prev < k and r.delta <= self.config.delta_max]
            self.n_epochs = k + 1
            update = GraphUpdate(k, gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
            self._update = update
            self._add_pose(usable, 0, update)
            for rel in usable:  # the steps the fallback repeats (_add_between_factors)
                if rel.measured and rel.delta == 1 and rel.translation_observed:
                    self._last_step = np.asarray(rel.T_prev_curr, dtype=float)
                    self._steps = [*self._steps[1 - FALLBACK_STEPS :], self._last_step]
        return np.stack([self.poses[k] for k in range(n_epochs)])


def run_history(
    poses: np.ndarray, relatives: Sequence[RelativePose], config: PlanodomConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Per epoch the distance driven along ``poses`` (E,) m and the cumulative (xy, yaw)
    variances (E, 2) of the run's drift, as the loop candidates sum them
    (:meth:`.loop_candidates.CandidateLoopBuilder.add_epoch` with ``loop_candidate_drift``
    "run"): a measured delta = 1 step's covariance, else the fallback's variance, bridged
    translation (and yaw with ``loop_drift_yaw`` "run") by :class:`.RunWalk`."""
    c = config.smoothing
    n = len(poses)
    steps = np.linalg.norm(np.diff(poses[:, :2, 3], axis=0), axis=1)
    travelled = np.concatenate([[0.0], np.cumsum(steps)])
    step_of = {r.curr: r for r in relatives if r.delta == 1 and r.measured}
    walk, yaw_walk = RunWalk(), RunWalk()
    variances = np.zeros((n, 2))
    for k in range(1, n):
        var_t, var_r = c.fallback_translation_sigma_m**2, c.fallback_rotation_sigma_rad**2
        step = yaw = None
        r = step_of.get(k)
        if r is not None and r.covariance is not None:
            var_r, yaw, var_t, step = measured_step_terms(r, var_t, step)
        var_t = walk.variance(step, var_t)
        if c.loop_drift_yaw == "run":
            var_r = yaw_walk.variance(yaw, var_r)
        variances[k] = variances[k - 1] + (var_t, var_r)
    return travelled, variances


def inconsistent_spans(
    chained: np.ndarray,
    windowed: np.ndarray,
    travelled: np.ndarray,
    variances: np.ndarray,
    config: PlanodomConfig,
) -> tuple[float, tuple[int, int]]:
    """The largest squared Mahalanobis distance, over every span (a, b), a < b, of the
    windowed guess's relative motion from the chained guess's (yaw, x, y), under the run's
    drift over the span (:func:`.loop_drift.run_drift`: its yaw and per-axis xy variance,
    the floors included), and that span.

    Args:
        chained, windowed: (E, 4, 4) the two guesses ``T_world_base``.
        travelled: (E,) distance driven, m. variances: (E, 2) cumulative (xy, yaw)
            variances, m^2 and rad^2 (:func:`run_history`).
        config: the floors (``loop_min_translation_m``, ``prior_rotation_deg``,
            ``loop_sigmas``).
    """
    c = config.smoothing
    floor_xy = (c.loop_min_translation_m / c.loop_sigmas) ** 2
    floor_r = (np.radians(config.association.prior_rotation_deg) / c.loop_sigmas) ** 2
    inv_c, inv_w = invert_transform(chained), invert_transform(windowed)
    worst, span = 0.0, (0, 0)
    for a in range(len(chained) - 1):
        rel_c = inv_c[a] @ chained[a + 1 :]
        rel_w = inv_w[a] @ windowed[a + 1 :]
        v = pose5_from_transform(invert_transform(rel_c) @ rel_w)[:, 2:]
        distance = travelled[a + 1 :] - travelled[a]
        var_t = variances[a + 1 :, 0] - variances[a, 0]
        var_r = variances[a + 1 :, 1] - variances[a, 1]
        var_xy = 0.5 * var_t + var_r * distance**2 + floor_xy
        stat = v[:, 0] ** 2 / (var_r + floor_r) + (v[:, 1] ** 2 + v[:, 2] ** 2) / var_xy
        b = int(np.argmax(stat))
        if stat[b] > worst:
            worst, span = float(stat[b]), (a, a + 1 + b)
    return worst, span


def checked_guess(
    windowed: np.ndarray,
    relatives: Sequence[RelativePose],
    config: PlanodomConfig,
    first_step: np.ndarray | None,
) -> tuple[np.ndarray | None, float, tuple[int, int]]:
    """``batch_initial`` "checked": None (keep the windowed guess) when its motion agrees
    with the chained odometry's over every span within chi2(3) at ``loop_gate_quantile``
    of the run's drift, else the chained guess (E, 4, 4) (both relative to the first
    pose); with the worst squared Mahalanobis distance and its span."""
    chain = _Chain(config.smoothing)
    chain.first_step = first_step if config.smoothing.fallback_start == "first_step" else None
    chained = chain.chain(relatives, len(windowed))
    first = invert_transform(windowed[0])
    windowed = first[None] @ windowed
    travelled, variances = run_history(chained, relatives, config)
    worst, span = inconsistent_spans(chained, windowed, travelled, variances, config)
    limit = chi2_quantile(config.smoothing.loop_gate_quantile, 3)
    return (chained if worst > limit else None), worst, span
