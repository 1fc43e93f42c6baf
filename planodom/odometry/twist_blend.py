"""The angular rate weighed against its prediction by their covariances
(``odometry.twist_blend``).

By default a step's own angular rate replaces the prediction wherever it differs by more
than a tolerance: it deskews the epoch again (:mod:`planodom.odometry.deskew`, step 2) and
is the rate predicted for the next epoch. A degenerate step on walls alone measures roll
and pitch through the walls' small vertical components, and a 2D rig sees a wall on two
scan lines: on issue 11's world 166 at 2 cm (``extraction.noise_estimate: range``) steps
53-55 were 1.1-3.2 deg off in roll and pitch (5-16 deg/s over 0.2 s) and the epochs after
them were deskewed with roll and pitch rates of 6-22 deg/s where the truth was about 1
(docs/RESULTS.md, RANGE166).

With ``twist_blend: rate`` the rate is a Kalman filter's, one update a committed step:

- the prediction is the rate predicted for the epoch (the previous posterior), its
  covariance the previous posterior's plus the process noise of one epoch: the model of
  :mod:`planodom.odometry.twist_sigma` (the mean square change of the measured rate
  between successive OK steps less both steps' variances; the deskewing tolerance until
  two OK steps followed each other), split evenly over the three axes (estimated per
  axis from the few steps of its window, a roll or pitch change came out zero and the
  filter stopped following it);
- the measurement is the step's own rate, its covariance the rotation block of the step's
  covariance over ``dt`` squared;
- the update weighs the two by their information (:func:`blended`): an axis the step
  hardly measures keeps the prediction, an axis it measures well follows it.

The posterior deskews the epoch again and is the rate predicted for the next. With
``twist_blend: degenerate`` only a step that is not OK is weighed so; an OK step's rate
replaces the prediction as without the option, its covariance the posterior's (on an easy
world the OK steps' rates are noisy, but two epochs deskewed with them share their error,
which the step between them cancels; weighed, the rotation rms rose, 2D-rig world 152 at
2 cm 0.043 -> 0.059 deg, where the twists were nearer the truth). An
unresolved epoch measures nothing: the covariance only grows. A step whose covariance is
unknown replaces the rate, as without the option (nothing to weigh it by). The linear
velocity keeps its own model (the median of the recent measured ones). Written here, not
with a filter library: a three-state update with a per-axis process noise is a few lines,
and gtsam's incremental solvers hold no state of this kind.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.relative import RelativePose, Status


def information(cov: np.ndarray) -> np.ndarray:
    """(n, n) the information matrix of a covariance ``cov`` (n, n) whose axes with a
    non-finite variance hold no information (zero rows and columns); the rest is the
    pseudo-inverse of the finite block (:func:`scaled_pinv`)."""
    cov = np.asarray(cov, dtype=np.float64)
    finite = np.isfinite(np.diag(cov))
    out = np.zeros_like(cov)
    if np.any(finite):
        out[np.ix_(finite, finite)] = scaled_pinv(cov[np.ix_(finite, finite)])
    return out


def covariance(info: np.ndarray) -> np.ndarray:
    """(n, n) the covariance of an information matrix ``info`` (n, n): its pseudo-inverse
    (:func:`scaled_pinv`), with an infinite variance (and zero covariances) on axes
    holding no information."""
    info = np.asarray(info, dtype=np.float64)
    empty = ~np.any(info != 0.0, axis=1)
    out = scaled_pinv(info)
    out[empty, :] = 0.0
    out[:, empty] = 0.0
    out[empty, empty] = np.inf
    return out


def scaled_pinv(a: np.ndarray) -> np.ndarray:
    """(n, n) the pseudo-inverse of a symmetric positive semi-definite ``a`` (n, n), taken
    of ``a`` scaled to a unit diagonal (Jacobi) and scaled back: a rate's variances span
    ten decades (roll from the ground, yaw from one far wall), and numpy's pseudo-inverse
    cuts singular values relative to the largest, which loses the small axes unscaled."""
    d = np.sqrt(np.abs(np.diag(a)))
    d = np.where(d > 0.0, d, 1.0)
    scale = np.outer(d, d)
    return np.linalg.pinv(a / scale, hermitian=True) / scale


def blended(
    prior: np.ndarray, prior_cov: np.ndarray, measured: np.ndarray, measured_cov: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The Kalman update of ``prior`` (n,) of covariance ``prior_cov`` (n, n) by a direct
    measurement ``measured`` (n,) of covariance ``measured_cov`` (n, n), in information
    form so that an infinite variance (no information) may stand on either side: returns
    the posterior mean (n,) and covariance (n, n). Per axis, for diagonal covariances:
    ``(p / P + m / M) / (1 / P + 1 / M)`` and ``P M / (P + M)``; an axis the measurement
    does not inform keeps ``p``, one the prior does not inform takes ``m``."""
    prior, measured = np.asarray(prior, np.float64), np.asarray(measured, np.float64)
    info_p, info_m = information(prior_cov), information(measured_cov)
    total = info_p + info_m
    gain = scaled_pinv(total) @ info_m  # zero rows where the measurement informs nothing
    return prior + gain @ (measured - prior), covariance(total)


class RateBlend:
    """The filter's state in the streaming odometry (module docstring): the posterior of
    the angular rate; ``change()`` gives the process model's rms change of the rate over
    one epoch (rad/s, first of its (2,)).

    Attributes:
        on: ``odometry.twist_blend`` is not ``off``.
        rate: (3,) the posterior rate, predicted for the next epoch, rad/s (None: none).
        cov: (3, 3) its covariance, rad^2/s^2 (infinite variances: no information).
    """

    def __init__(self, config: OdometryConfig, change: Callable[[], np.ndarray]):
        self.on = config.twist_blend != "off"
        self._ok_replaces = config.twist_blend == "degenerate"
        self.rate: np.ndarray | None = None
        self.cov = _UNKNOWN.copy()
        self._change = change

    def process(self) -> np.ndarray:
        """(3,) variance of the rate's change over one epoch per axis, rad^2/s^2: the
        squared rms change of :meth:`.twist_sigma.TwistUncertainty.change` split evenly
        over the three axes."""
        return np.full(3, float(self._change()[0]) ** 2 / 3.0)

    def prior(self) -> np.ndarray:
        """(3, 3) covariance of the rate predicted for the epoch being registered."""
        return self.cov + np.diag(self.process())

    def blend(self, own: np.ndarray, relative: RelativePose, dt: float) -> np.ndarray:
        """(6,) ``own`` (a step's own twist over ``dt`` s, rad/s and m/s) with its angular
        rate weighed against :attr:`rate` of covariance :meth:`prior` by the step's
        (``relative``'s) covariance; ``own`` itself when off, without a prediction, or
        when the step measured no rate or states no covariance. The state is not changed."""
        measured = _measured_cov(relative, dt)
        if not self.on or self.rate is None or measured is None or self._replaces(relative):
            return own
        out = np.array(own, dtype=np.float64, copy=True)
        out[:3] = blended(self.rate, self.prior(), own[:3], measured)[0]
        return out

    def committed(self, own: np.ndarray, relative: RelativePose, dt: float) -> np.ndarray:
        """:meth:`blend` for the epoch committed with step ``relative``, the state updated:
        the posterior, and the change since the last OK step. Unresolved: the prediction
        kept, its covariance grown; no prediction or no covariance: the step's rate."""
        if not self.on:
            return own
        measured = _measured_cov(relative, dt)
        if relative.status is Status.UNRESOLVED:
            self.cov = self.prior()
            return own
        if measured is None or self.rate is None or self._replaces(relative):
            self.rate = np.array(own[:3], dtype=np.float64, copy=True)
            self.cov = _UNKNOWN.copy() if measured is None else measured
            return own
        self.rate, self.cov = blended(self.rate, self.prior(), own[:3], measured)
        out = np.array(own, dtype=np.float64, copy=True)
        out[:3] = self.rate
        return out

    def _replaces(self, relative: RelativePose) -> bool:
        """Whether the step's rate replaces the prediction's whole (``degenerate``: an OK
        step's), its covariance the posterior's."""
        return self._ok_replaces and relative.status is Status.OK

    def reset(self) -> None:
        """Forget the rate (a gap in the epoch times: no motion is carried across it)."""
        self.rate, self.cov = None, _UNKNOWN.copy()

    def bound(
        self, plane_map: object = None
    ) -> Callable[[np.ndarray, RelativePose, float], np.ndarray] | None:
        """:meth:`blend`, for the deskewing's refinement of the epoch being registered
        (:func:`planodom.odometry.deskew.register_deskewed`); None when off, without a
        prediction, or under a plane map (``plane_map`` not None: pairwise only)."""
        if not self.on or self.rate is None or plane_map is not None:
            return None
        return self.blend


#: (3, 3) the covariance of a rate nothing is known of.
_UNKNOWN = np.diag(np.full(3, np.inf))


def _measured_cov(relative: RelativePose, dt: float) -> np.ndarray | None:
    """(3, 3) covariance of the angular rate a step measured over ``dt`` s, rad^2/s^2 (the
    rotation block of its covariance over ``dt`` squared); None when unresolved, unknown
    or not finite."""
    cov = relative.covariance
    if relative.status is Status.UNRESOLVED or cov is None or dt <= 0:
        return None
    block = np.asarray(cov, dtype=np.float64)[:3, :3] / (dt * dt)
    return block if np.all(np.isfinite(block)) else None
