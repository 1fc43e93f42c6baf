"""A Kalman filter on a scan's twist and its rate (``planemap.twist_filter: kalman``).

The continuous-time registration (:mod:`.ctreg`) measures each scan's twist from its own
planes; alone, that measurement is noisier than the lag of the constant-velocity twist it
replaces (vehicle lidar worlds at 6 mm). The filter fuses the measurements over time:

- state ``x = (xi, a)`` (12,): the twist ``xi`` (6,) rad/s, m/s (body frame, at the
  scan's reference time) and its rate ``a`` (6,) rad/s^2, m/s^2; covariance (12, 12);
- prediction over ``dt`` s: ``xi += a dt``; process noise a random walk on the rate
  (white jerk of spectral density ``q`` (6,) per axis, rad^2/s^5 and m^2/s^5:
  ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``);
- measurement: the registration's Gauss-Newton, with the prediction as its prior on the
  twist correction (:meth:`TwistFilter.prior`), gives the posterior of the twist (and,
  with ``registered_acceleration``, the rate) jointly with the pose; the measurement's
  own information is that posterior's (the pose marginalised: a Schur complement) less
  the prior's (:func:`measurement_information`), fused in information form
  (:func:`fused`), so the rate is updated through its correlation with the twist;
- ``q`` from the data (covariance matching): each scan whose measurement is of full rank
  gives, per axis, ``(nu^2 - P_ii - R_ii) / (dt^3 / 3)`` (``nu`` the twist's innovation,
  ``P`` the prediction's covariance without the process noise, ``R`` the measurement's),
  and ``q`` is the mean of those so far (at least ``Q_FLOOR``): a vehicle whose twist
  changes smoothly gets a small ``q`` (the measurements averaged over many scans), a
  swinging hand-held lidar a large one (each scan's measurement followed). Before any
  such sample the prior is the constant-velocity deviations' (as without the filter).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from planodom.odometry.planemap.ctreg import TwistRegistration, register_twist
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.register import Registration, ScanPlanes

#: Floor of ``q`` per axis (rad^2/s^5, m^2/s^5): keeps the predicted covariance positive
#: definite; far below any motion (a twist change of 1e-4 rad/s over 1 s).
Q_FLOOR = 1e-8


@dataclass(frozen=True, eq=False)
class TwistState:
    """Gaussian of ``(xi, a)``: ``mean`` (12,) rad/s, m/s, rad/s^2, m/s^2; ``cov`` (12, 12)."""

    mean: np.ndarray
    cov: np.ndarray


def transition(dt: float) -> np.ndarray:
    """(12, 12) ``F``: the twist grows by its rate over ``dt`` s, the rate is kept."""
    F = np.eye(12)
    F[:6, 6:] = dt * np.eye(6)
    return F


def process_noise(q: np.ndarray, dt: float) -> np.ndarray:
    """(12, 12) ``Q`` of a random walk on the rate (white jerk of density ``q`` (6,))."""
    Q = np.zeros((12, 12))
    i = np.arange(6)
    Q[i, i] = q * dt**3 / 3.0
    Q[i, i + 6] = Q[i + 6, i] = q * dt**2 / 2.0
    Q[i + 6, i + 6] = q * dt
    return Q


def predicted(state: TwistState, q: np.ndarray, dt: float) -> TwistState:
    """``state`` carried ``dt`` s on (module docstring)."""
    F = transition(dt)
    return TwistState(F @ state.mean, F @ state.cov @ F.T + process_noise(q, dt))


def measurement_information(
    H: np.ndarray, x: np.ndarray, prior_info: np.ndarray, prior_mean: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The information ``Y`` (k, k) and information vector ``y`` (k,) of a registration's
    own measurement of its twist correction (k = 6 or 12), from its Gauss-Newton
    information ``H`` (6 + k, 6 + k; pose first, prior included) at its solution ``x``
    (k,), with the prior ``prior_info`` (k, k) about ``prior_mean`` (k,): the posterior of
    the correction, the pose marginalised (Schur complement), is the product of the
    prior and the measurement, so ``Y = Y_post - prior_info``, ``y = Y_post x -
    prior_info prior_mean`` (``Y x_m = y`` where ``Y`` has full rank)."""
    Hpp, Hpt, Htt = H[:6, :6], H[:6, 6:], H[6:, 6:]
    Y_post = Htt - Hpt.T @ np.linalg.lstsq(Hpp, Hpt, rcond=1e-12)[0]
    Y = Y_post - prior_info
    Y = 0.5 * (Y + Y.T)
    ev, V = np.linalg.eigh(Y)
    Y = (V * np.maximum(ev, 0.0)) @ V.T  # rounding: information is never negative
    return Y, Y_post @ x - prior_info @ prior_mean


def fused(pred: TwistState, Y: np.ndarray, y: np.ndarray) -> TwistState:
    """The Kalman update of ``pred`` by a measurement of its first k components given in
    information form (``Y`` (k, k), ``y`` (k,) about the state's origin)."""
    k = len(y)
    info = np.linalg.inv(pred.cov)
    vec = info @ pred.mean
    info[:k, :k] += Y
    vec[:k] += y
    cov = np.linalg.inv(info)
    cov = 0.5 * (cov + cov.T)
    return TwistState(cov @ vec, cov)


@dataclass(frozen=True, eq=False)
class TwistFilter:
    """The filter between scans (module docstring); immutable, each scan's update gives
    a new one (committed with the scan's estimate).

    Attributes:
        state: the posterior at the last scan measured (None: not started).
        elapsed: seconds from that scan to the last one committed.
        q_sum, q_count: the sum (6,) and count of the covariance-matching samples.
        updates: the scans measured since the filter started (samples are taken from
            the third on: before, the rate is not measured yet and its covariance is the
            start's guess).
    """

    state: TwistState | None = None
    elapsed: float = 0.0
    q_sum: np.ndarray = field(default_factory=lambda: np.zeros(6))
    q_count: int = 0
    updates: int = 0

    def q(self) -> np.ndarray | None:
        """(6,) the jerk density per axis, None before any sample."""
        if self.q_count == 0:
            return None
        return np.maximum(self.q_sum / self.q_count, Q_FLOOR)

    def prediction(self, dt: float, used: np.ndarray, sd: np.ndarray) -> TwistState:
        """The state predicted ``dt`` s after the last scan committed; before a state,
        the twist ``used`` (6,) with the per-axis sigmas ``sd`` (6,) (the
        constant-velocity deviations', :meth:`PlaneMapOdometry._registered_twist`) and a
        rate of zero with twice ``sd / dt``; before a ``q``, the one that adds ``sd``'s
        variance over ``dt``."""
        if self.state is None:
            return TwistState(np.r_[used, np.zeros(6)], np.diag(np.r_[sd, 2 * sd / dt] ** 2))
        q = self.q()
        return predicted(self.state, 3.0 * sd**2 / dt**3 if q is None else q, self.elapsed + dt)

    @staticmethod
    def prior(pred: TwistState, used: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray]:
        """The registration's prior on its correction (6 order,) of the twist ``used``:
        mean and information (the marginal of the first 6 order components)."""
        k = 6 * order
        mean = pred.mean[:k] - np.r_[used, np.zeros(k - 6)]
        return mean, np.linalg.inv(pred.cov[:k, :k])

    def updated(
        self, pred: TwistState, Y: np.ndarray, y: np.ndarray, used: np.ndarray, dt: float
    ) -> TwistFilter:
        """The filter after a scan ``dt`` s on, predicted as ``pred``, measured (about
        the twist ``used``) as ``Y``, ``y`` (:func:`measurement_information`)."""
        k = len(y)
        origin = np.r_[used, np.zeros(k - 6)]
        y_state = y + Y @ origin  # the measurement's information vector about zero
        q_sum, q_count = self.q_sum, self.q_count
        sample = self._sample(Y, y_state, dt)
        if sample is not None:
            q_sum, q_count = q_sum + sample, q_count + 1
        return TwistFilter(fused(pred, Y, y_state), 0.0, q_sum, q_count, self.updates + 1)

    def _sample(self, Y: np.ndarray, y: np.ndarray, dt: float) -> np.ndarray | None:
        """(6,) one covariance-matching sample of ``q`` (module docstring); None when the
        measurement is not of full rank or the rate not measured yet."""
        ev = np.linalg.eigvalsh(Y)
        if self.state is None or self.updates < 2 or ev[0] <= 1e-9 * ev[-1]:
            return None
        R = np.linalg.inv(Y)
        span = self.elapsed + dt
        base = predicted(self.state, np.zeros(6), span)
        nu = (R @ y)[:6] - base.mean[:6]
        return (nu**2 - np.diag(base.cov)[:6] - np.diag(R)[:6]) / (span**3 / 3.0)

    def after(self, unresolved: bool, new: TwistFilter | None, dt: float | None) -> TwistFilter:
        """The filter once a scan ``dt`` s on (None: unknown) is committed: started
        again after an unresolved scan (a twist never outlives one); ``new``, its update,
        when it measured its twist; else carried on."""
        if unresolved:
            return TwistFilter()
        if new is not None:
            return new
        if dt is None or self.state is None:
            return self
        return replace(self, elapsed=self.elapsed + dt)


def filtered_registration(
    M: PlaneMap,
    reg: Registration,
    cur: ScanPlanes,
    deskew: tuple[np.ndarray, float],
    sd: np.ndarray,
    order: int,
    filt: TwistFilter,
    iterations: int,
) -> tuple[TwistRegistration | None, TwistFilter | None]:
    """The continuous-time registration (:func:`.ctreg.register_twist`) of the scan
    ``cur`` (deskewed with the twist ``deskew[0]`` (6,), ``deskew[1]`` s after the last
    scan) from ``reg``, with the filter's prediction as its prior, and the filter after
    it (None when not registered); ``sd`` (6,) the constant-velocity deviations'
    per-axis sigmas of the twist (the prior before the filter has started), ``order`` 1
    (twist) or 2 (and its rate)."""
    used, dt = deskew
    assert cur.time_moments is not None
    pred = filt.prediction(dt, used, sd)
    prior = TwistFilter.prior(pred, used, order)
    prior_sd = np.sqrt(np.diag(pred.cov)[: 6 * order])
    ct = register_twist(M, reg, cur, cur.time_moments, prior_sd, iterations, prior=prior)
    if ct is None:
        return None, None
    x = np.r_[ct.correction, ct.acceleration][: 6 * order]
    Y, y = measurement_information(ct.H, x, prior[1], prior[0])
    return ct, filt.updated(pred, Y, y, used, dt)
