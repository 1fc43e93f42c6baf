"""The angular rate predicted for the next epoch of a pairwise pipeline
(``odometry.rate_prediction``).

The constant-velocity prediction repeats the last step's rate. On a vehicle that sways on
its suspension (and turns through curves) the rate changes by about a degree per second
from one step to the next (docs/RESULTS.md, RIG2DPASS: a median 1.35 / 1.82 deg/s from
the rate used at 6 mm / 2 cm on the 2D rig), so the epoch is extracted again with its own.
``autoregressive`` predicts each component of the rate by an autoregression fitted online
(least squares, with an intercept) on the last ``rate_prediction_window`` steps that
measured it one after the other: a generic linear predictor of a stationary sequence (an
oscillation, a steady turn, a trend), not a model of any one vehicle. Where the run of
measured steps is shorter than twice the model's terms, or the fit extrapolates beyond the
window's range widened by its span (a fit of a few noisy points can be explosive), the
last rate is kept. ``rate_prediction_fit`` ``ok_filled`` and ``ok_runs`` keep the rates of
steps that did not measure the whole rotation and translation out of the fit (a
degenerate step's wrong rate was extrapolated, docs/RESULTS.md, PREDICT2): the rate
predicted for such a step stands in for it, or the run restarts after it;
``rate_prediction_bound`` limits the
predicted change to the window's largest step-to-step change. With
``rate_prediction_use: first_deskew`` the predicted rate is only the twist an epoch is
first deskewed with (:meth:`RatePredictor.deskewing`); the prior, the bridge, the gates
and the retries keep the constant rate (docs/RESULTS.md, PREDICT3).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.relative import RelativePose, Status


def autoregressive_next(history: np.ndarray, order: int) -> np.ndarray:
    """(D,) the next row of ``history`` (H, D), oldest first, predicted per column by an
    autoregression of ``order`` with an intercept, fitted by least squares on the whole
    history (the last row where H < 2 (order + 1) + order, or where the prediction leaves
    the column's range widened by its span on either side). numpy's least squares on a
    (H - order, order + 1) design, one column at a time."""
    h = np.asarray(history, dtype=np.float64)
    n = len(h) - order
    last = h[-1].copy()
    if n < 2 * (order + 1):
        return last
    out = last
    for j in range(h.shape[1]):
        x = h[:, j]
        lags = [x[order - i - 1 : len(x) - i - 1] for i in range(order)]
        A = np.column_stack([np.ones(n), *lags])
        coef = np.linalg.lstsq(A, x[order:], rcond=None)[0]
        value = float(coef[0] + coef[1:] @ x[::-1][:order])
        lo, hi = float(x.min()), float(x.max())
        if lo - (hi - lo) <= value <= hi + (hi - lo):
            out[j] = value
    return out


class RatePredictor:
    """The measured angular rates of a pairwise pipeline's last steps, and the rate they
    predict for the next epoch (``config.rate_prediction``)."""

    def __init__(self, config: OdometryConfig) -> None:
        self.mode = config.rate_prediction
        self.order = config.rate_prediction_order
        self.fit = config.rate_prediction_fit
        self.bound = config.rate_prediction_bound
        self.use = config.rate_prediction_use
        # first_deskew: (the twist predicted as before, the same with the predicted rate)
        self._deskew: tuple[np.ndarray, np.ndarray] | None = None
        self._rates: deque[np.ndarray] = deque(maxlen=config.rate_prediction_window)
        # (autoregression's, constant's) squared errors on the last rates ("selected")
        self._errors: deque[tuple[float, float]] = deque(maxlen=config.rate_prediction_check)
        self._pending: np.ndarray | None = None  # the autoregression's last prediction
        self._last = -2  # the epoch of the last rate kept

    def after(
        self, k: int, own: np.ndarray, relative: RelativePose, twist: np.ndarray, plane_map: object
    ) -> np.ndarray:
        """(6,) the twist predicted for the epoch after ``k``: :meth:`predicted_after`'s with
        ``rate_prediction_use: all``; with ``first_deskew``, ``twist`` itself (the prior,
        bridge and gates keep it), the prediction kept for :meth:`deskewing`."""
        predicted = self.predicted_after(k, own, relative, twist, plane_map)
        if self.use == "all":
            return predicted
        self._deskew = (twist, predicted)
        return twist

    def deskewing(self, twist: np.ndarray | None) -> np.ndarray | None:
        """(6,) the twist the next epoch is first deskewed with, given ``twist``, the one
        :meth:`after` returned for it (rad/s, m/s; None: none): with ``rate_prediction_use:
        first_deskew`` the same with the predicted rate; else (or for any other twist)
        ``twist`` itself."""
        if self._deskew is None or self._deskew[0] is not twist:
            return twist
        return self._deskew[1]

    def predicted_after(
        self, k: int, own: np.ndarray, relative: RelativePose, twist: np.ndarray, plane_map: object
    ) -> np.ndarray:
        """(6,) ``twist`` (the constant-velocity prediction after epoch ``k``, rad/s and
        m/s) with its angular rate predicted from the run of measured steps ending at
        ``k`` (its own twist ``own`` (6,) appended unless ``relative``'s status is
        unresolved; a run restarts after an epoch that did not measure its rate).
        ``twist`` as it is with ``rate_prediction: constant``, under a plane map
        (``plane_map`` not None: it predicts its own) and where the prediction's rate is
        zero (``deskew_significance_gate``); with ``selected``, also unless the
        autoregression predicted the last ``rate_prediction_check`` rates better than the
        constant rate did (summed squared error)."""
        if self.mode == "constant" or plane_map is not None:
            return twist
        rate = np.array(own[:3], dtype=np.float64)
        if relative.status is Status.UNRESOLVED or k != self._last + 1:
            self._rates.clear()
            self._errors.clear()
            self._pending = None
        if relative.status is Status.UNRESOLVED:
            return twist
        if self.fit != "measured" and not _well_measured(relative):
            if self.fit == "ok_filled":
                return self._stand_in(k, twist)
            self._rates.clear()  # ok_runs: the next run starts after it
            self._errors.clear()
            self._pending = None
            return twist
        if self._pending is not None:
            self._errors.append(_squared(self._pending, rate, self._rates[-1]))
        self._rates.append(rate)
        self._last = k
        return self._predicted(twist)

    def _stand_in(self, k: int, twist: np.ndarray) -> np.ndarray:
        """``rate_prediction_fit: ok_filled``, after epoch ``k`` that measured its rate not well
        enough: the run goes on with the rate predicted for it (the last rate before a
        prediction; none in an empty run), and ``twist`` (6,) gets the fit's next rate."""
        self._last = k
        if not self._rates:
            return twist
        self._rates.append(self._rates[-1] if self._pending is None else self._pending)
        return self._predicted(twist)

    def _predicted(self, twist: np.ndarray) -> np.ndarray:
        """(6,) ``twist`` with the rate the run of rates predicts (as it is where the run
        is too short, the prediction's rate is zero or ``selected`` does not choose it)."""
        self._pending = None
        if len(self._rates) < 3 * self.order + 2:
            return twist  # too few equations (autoregressive_next): the last step's rate
        history = np.array(self._rates)
        self._pending = autoregressive_next(history, self.order)
        if self.bound:
            step = np.max(np.abs(np.diff(history, axis=0)), axis=0)
            self._pending = np.clip(self._pending, history[-1] - step, history[-1] + step)
        if not np.any(twist[:3]) or not self._chosen():
            return twist
        out = np.array(twist, dtype=np.float64, copy=True)
        out[:3] = self._pending
        return out

    def _chosen(self) -> bool:
        """Whether the autoregression's prediction is used (``selected``: it predicted a
        full window of the last rates better than the constant rate)."""
        if self.mode == "autoregressive":
            return True
        if len(self._errors) < (self._errors.maxlen or 0):
            return False
        return sum(a for a, _ in self._errors) < sum(c for _, c in self._errors)


def _well_measured(relative: RelativePose) -> bool:
    """Whether ``relative`` measured the whole rotation and the horizontal translation
    (status ok, no axis of the rotation taken from the prediction)."""
    return relative.status is Status.OK and not relative.rotation_partly_observed


def _squared(predicted: np.ndarray, rate: np.ndarray, last: np.ndarray) -> tuple[float, float]:
    """(autoregression's, constant's) squared error (rad^2/s^2) on ``rate`` (3,): of
    ``predicted`` (3,) and of the last rate ``last`` (3,)."""
    return float(np.sum((predicted - rate) ** 2)), float(np.sum((last - rate) ** 2))
