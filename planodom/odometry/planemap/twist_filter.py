"""A Kalman filter on a scan's twist and its rate (``planemap.twist_filter: kalman``).

The continuous-time registration (:mod:`.ctreg`) measures each scan's twist from its own
planes; alone, that measurement is noisier than the lag of the constant-velocity twist it
replaces (vehicle lidar worlds at 6 mm). The filter fuses, over time, what each scan's
registration says about the twist:

- state ``s = (xi, a)`` (12,): the twist ``xi`` (6,) rad/s, m/s (body frame, at the
  scan's reference time) and its rate ``a`` (6,) rad/s^2, m/s^2; covariance (12, 12);
- prediction over ``dt`` s: ``xi += a dt``; process noise a random walk on the rate
  (white jerk of spectral density ``q`` (6,) per axis, rad^2/s^5 and m^2/s^5:
  ``Q = q [[dt^3/3, dt^2/2], [dt^2/2, dt]]``);
- the prediction is the registration's prior on its twist correction
  (:meth:`TwistFilter.prior`); the registered twist's own information is the joint
  solve's (the pose marginalised: a Schur complement) less that prior's
  (:func:`measurement_information`);
- measurements: the step from the last scan's registered pose (its mean twist ``xi - a
  span / 2``, precise but half a step late: :mod:`.twist_kinematics`), and the scan's
  registered twist (current, noisier), fused in information form (:func:`fused`);
- the registered twist's covariance is its registration's times a scale ``lam`` >= 1:
  the one at which the median, over the last ``NIS_WINDOW`` scans, of its normalised
  innovation ``nu^T (P + lam R)^-1 nu`` is the chi-square median of 6 degrees of
  freedom; a scan whose innovation so normalised exceeds the chi-square 99.9 % point
  gives its step only (the gate). Against the simulator's true twist, the registered
  twist's own information was not honest: NEES median 26-36 (32 beams, hand-held
  world 41) and 500-1300 (16 beams, 20 Hz, world 44) where 6 is expected;
- ``q`` from the steps (covariance matching): each step's squared innovation against the
  state predicted without process noise, less what that state's covariance and the two
  poses' explain (at least zero), over ``3 span^3 / 20``, rotation's three axes alike and
  translation's alike; ``q`` is the mean of those so far (at least ``Q_FLOOR``): a
  vehicle gets a small ``q`` (many scans averaged), a swinging hand-held lidar a large
  one. Before the first step, the constant-velocity deviations' prior (as without the
  filter), and the first scan's twist alone.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.stats import chi2

from planodom.odometry.planemap.ctreg import TwistRegistration, register_twist
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.register import Registration, ScanPlanes
from planodom.odometry.planemap.twist_kinematics import step_measurement, step_q_sample

#: Scans whose innovations set the measurement's scale (``lam``).
NIS_WINDOW = 30
#: Chi-square (6 degrees of freedom) median, and the gate's 99.9 % point.
NIS_MEDIAN, NIS_GATE = float(chi2.ppf(0.5, 6)), float(chi2.ppf(0.999, 6))
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


def measurement_scale(innovations: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]) -> float:
    """``lam`` >= 1 at which the median of ``nu^T (P + lam R)^-1 nu`` over the
    ``innovations`` ((nu (6,), P (6, 6), R (6, 6)), ...) is ``NIS_MEDIAN`` (bisection on
    log ``lam``, up to 1e8)."""

    def median_nis(lam: float) -> float:
        return float(np.median([nu @ np.linalg.solve(P + lam * R, nu) for nu, P, R in innovations]))

    if median_nis(1.0) <= NIS_MEDIAN:
        return 1.0
    lo, hi = 0.0, 8.0  # log10 lam
    for _ in range(30):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if median_nis(10.0**mid) > NIS_MEDIAN else (lo, mid)
    return float(10.0**hi)


@dataclass(frozen=True, eq=False)
class Joint:
    """A registration's joint measurement of its pose and twist correction.

    Attributes:
        T: (4, 4) its pose. pose_cov: (6, 6) the pose's covariance (world-frame
            perturbation): the pose registration's (the twist as deskewed; the joint
            solve's pose marginal holds the twist prior's uncertainty, 30x the steps'
            true errors on a vehicle world).
        Y, y: (k, k), (k,) its own information and information vector of the twist (and
            rate) about zero (:func:`measurement_information`, the pose marginalised).
        q0: (6,) the jerk density before any sample (the constant-velocity deviations').
    """

    T: np.ndarray
    pose_cov: np.ndarray
    Y: np.ndarray
    y: np.ndarray
    q0: np.ndarray


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
        innovations: the last ``NIS_WINDOW`` scans' twist innovations (6,), prediction
            covariances (6, 6) and measurement covariances (6, 6) (for ``lam``).
        pose, pose_cov: (4, 4) world from scan at the last scan measured and (6, 6) its
            covariance (world-frame perturbation), None before
            (:mod:`.twist_kinematics`).
    """

    state: TwistState | None = None
    elapsed: float = 0.0
    q_sum: np.ndarray = field(default_factory=lambda: np.zeros(6))
    q_count: int = 0
    updates: int = 0
    innovations: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...] = ()
    pose: np.ndarray | None = None
    pose_cov: np.ndarray | None = None

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

    def scale(self) -> float:
        """``lam`` (module docstring): 1 before ``NIS_WINDOW / 3`` innovations."""
        if len(self.innovations) < NIS_WINDOW // 3:
            return 1.0
        return measurement_scale(self.innovations)

    def updated(
        self,
        pred: TwistState,
        Y: np.ndarray,
        y: np.ndarray,
        used: np.ndarray,
        dt: float,
        joint: Joint | None = None,
    ) -> TwistFilter:
        """The filter after a scan ``dt`` s on, predicted as ``pred``, measured (about
        the twist ``used``) as ``Y``, ``y`` (:func:`measurement_information`): its
        covariance scaled by ``lam``, gated (module docstring); with ``joint``, the
        registration's joint measurement of pose and twist through the step from the
        last pose instead (:mod:`.twist_kinematics`), the jerk density from the step's
        innovation."""
        k = len(y)
        origin = np.r_[used, np.zeros(k - 6)]
        y_state = y + Y @ origin  # the measurement's information vector about zero
        Yr = Y + 1e-9 * max(float(np.linalg.eigvalsh(Y)[-1]), 1e-300) * np.eye(k)
        R = np.linalg.inv(Yr)
        nu = (R @ y_state)[:6] - pred.mean[:6]
        lam = self.scale()
        nis = float(nu @ np.linalg.solve(pred.cov[:6, :6] + lam * R[:6, :6], nu))
        recent = (*self.innovations, (nu, pred.cov[:6, :6], R[:6, :6]))[-NIS_WINDOW:]
        q_sum, q_count = self.q_sum, self.q_count
        sample = self._sample(Y, y_state, dt, lam)
        if joint is not None and self.state is not None and self.pose is not None:
            post, sample = self._joint_update(pred, joint, used, dt, lam, nis > NIS_GATE)
        else:  # no step yet (or none given): the twist alone, as registered
            post = fused(pred, Y, y_state)
        if sample is not None and self.updates >= 2:
            q_sum, q_count = q_sum + sample, q_count + 1
        pose = (None, None) if joint is None else (joint.T, joint.pose_cov)
        return TwistFilter(post, 0.0, q_sum, q_count, self.updates + 1, recent, *pose)

    def _joint_update(
        self, pred: TwistState, joint: Joint, used: np.ndarray, dt: float, lam: float,
        gated: bool,
    ) -> tuple[TwistState, np.ndarray]:  # fmt: skip
        """The update by the step from the last pose and the registration's twist, and
        the step's jerk-density sample (:mod:`.twist_kinematics`)."""
        assert self.state is not None and self.pose is not None and self.pose_cov is not None
        span = self.elapsed + dt
        q = self.q()
        q = joint.q0 if q is None else q
        z, Hs, Rz = step_measurement(self.pose, self.pose_cov, joint.T, joint.pose_cov, span)
        info = np.linalg.inv(Rz + np.diag(q * span**3 / 20.0))
        Y = Hs.T @ info @ Hs
        y = Hs.T @ info @ z
        if not gated:
            k = len(joint.y)
            Y[:k, :k] += joint.Y / lam
            y[:k] += joint.y / lam
        base = predicted(self.state, np.zeros(6), span)
        return fused(pred, Y, y), step_q_sample(z, Hs, base.mean, base.cov, Rz, span)

    def _sample(self, Y: np.ndarray, y: np.ndarray, dt: float, lam: float) -> np.ndarray | None:
        """(6,) one covariance-matching sample of ``q`` (module docstring); None when the
        measurement is not of full rank or the rate not measured yet."""
        ev = np.linalg.eigvalsh(Y)
        if self.state is None or self.updates < 2 or ev[0] <= 1e-9 * ev[-1]:
            return None
        R = np.linalg.inv(Y)
        span = self.elapsed + dt
        base = predicted(self.state, np.zeros(6), span)
        nu = (R @ y)[:6] - base.mean[:6]
        return (nu**2 - np.diag(base.cov)[:6] - lam * np.diag(R)[:6]) / (span**3 / 3.0)

    def after(self, unresolved: bool, new: TwistFilter | None, dt: float | None) -> TwistFilter:
        """The filter once a scan ``dt`` s on (None: unknown, or after a gap in the scan
        times, :func:`planodom.odometry.epoch_time.is_gap`) is committed: started again
        after an unresolved scan (a twist never outlives one) or an unknown ``dt``;
        ``new``, its update, when it measured its twist; else carried on."""
        if unresolved or dt is None:
            return TwistFilter()
        if new is not None:
            return new
        if self.state is None:
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
    origin = np.r_[used, np.zeros(6 * order - 6)]
    joint = Joint(ct.T, np.linalg.pinv(reg.H), Y, y + Y @ origin, 3.0 * sd**2 / dt**3)
    return ct, filt.updated(pred, Y, y, used, dt, joint)
