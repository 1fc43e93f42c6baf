"""The twist filter against closed forms and a known constant-acceleration twist."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from planodom.odometry.planemap.twist_filter import (
    Joint,
    TwistFilter,
    TwistState,
    fused,
    measurement_information,
    predicted,
    process_noise,
    transition,
)
from planodom.odometry.planemap.twist_kinematics import step_measurement
from planodom.se3 import se3_exp


def _spd(rng, k, scale=1.0):
    A = rng.normal(size=(k, k))
    return scale * (A @ A.T + k * np.eye(k))


def test_fused_is_the_kalman_update():
    """The information-form update equals the covariance-form Kalman update of a
    measurement ``z = E x + noise`` of the first k components."""
    rng = np.random.default_rng(0)
    for k in (6, 12):
        P = _spd(rng, 12, 0.1)
        m = rng.normal(size=12)
        R = _spd(rng, k, 0.01)
        z = rng.normal(size=k)
        E = np.eye(12)[:k]
        K = P @ E.T @ np.linalg.inv(E @ P @ E.T + R)
        Y = np.linalg.inv(R)
        out = fused(TwistState(m, P), Y, Y @ z)
        np.testing.assert_allclose(out.mean, m + K @ (z - E @ m), rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(out.cov, (np.eye(12) - K @ E) @ P, rtol=1e-9, atol=1e-12)


def test_prediction_integrates_the_rate_and_its_random_walk():
    """Over dt the twist gains rate * dt; the covariance of a white jerk of density q
    is the integral of the rate's random walk (closed form against sampled walks)."""
    rng = np.random.default_rng(1)
    q, dt = np.array([4.0, 1, 0.5, 2, 3, 0.1]), 0.1
    s = predicted(TwistState(np.r_[np.ones(6), np.full(6, 2.0)], np.zeros((12, 12))), q, dt)
    np.testing.assert_allclose(s.mean[:6], 1.0 + 2.0 * dt)
    # sampled: 20000 walks of 200 sub-steps
    n, steps = 20000, 200
    h = dt / steps
    jerk = rng.normal(size=(n, steps)) * np.sqrt(q[0] / h)
    rate = np.cumsum(jerk * h, axis=1)
    twist = np.cumsum(rate * h, axis=1)
    sampled = np.cov(np.c_[twist[:, -1], rate[:, -1]].T)
    expected = s.cov[np.ix_([0, 6], [0, 6])]
    np.testing.assert_allclose(sampled, expected, rtol=0.05)


def test_measurement_information_is_the_measurement_alone():
    """A linear problem in (pose (6,), correction (k,)): the information and estimate
    taken out of the posterior with a prior are those of the measurement without it."""
    rng = np.random.default_rng(2)
    for k in (6, 12):
        J = rng.normal(size=(40, 6 + k))
        b = rng.normal(size=40)
        prior_info, prior_mean = _spd(rng, k), rng.normal(size=k)
        P = np.zeros((6 + k, 6 + k))
        P[6:, 6:] = prior_info
        H = J.T @ J + P
        sol = np.linalg.solve(H, J.T @ b + P @ np.r_[np.zeros(6), prior_mean])
        Y, y = measurement_information(H, sol[6:], prior_info, prior_mean)
        alone = np.linalg.lstsq(J, b, rcond=None)[0][6:]
        cov_alone = np.linalg.inv(J.T @ J)[6:, 6:]
        np.testing.assert_allclose(np.linalg.solve(Y, y), alone, rtol=1e-8, atol=1e-10)
        np.testing.assert_allclose(np.linalg.inv(Y), cov_alone, rtol=1e-8, atol=1e-12)


def _run(rng, order, epochs=80, dt=0.1):
    """One filter run over noisy measurements of ``xi(t) = xi0 + a t``; the final
    state's error and covariance, and the filter."""
    xi0 = np.array([0.1, -0.2, 0.5, 2.0, 0.3, -0.1])
    a = np.array([0.3, 0.1, -0.4, 0.5, -0.2, 0.05])
    filt, used = TwistFilter(), np.zeros(6)
    sd = np.full(6, 1.0)
    for k in range(1, epochs + 1):
        t = k * dt
        truth = np.r_[xi0 + a * t, a][: 6 * order]
        R = _spd(rng, 6 * order, 1e-3)
        z = truth + np.linalg.cholesky(R) @ rng.normal(size=6 * order)
        pred = filt.prediction(dt, used, sd)
        Y = np.linalg.inv(R)
        origin = np.r_[used, np.zeros(6 * order - 6)]
        filt = filt.updated(pred, Y, Y @ (z - origin), used, dt)
        assert filt.state is not None
        used = filt.state.mean[:6] + filt.state.mean[6:] * dt  # the next deskewing twist
    err = filt.state.mean - np.r_[xi0 + a * epochs * dt, a]
    return err, filt.state.cov, filt


def test_constant_acceleration_twist_converges_within_its_covariance():
    """Monte Carlo: noisy twist measurements of a constant-acceleration twist (process
    noise zero); the filtered (twist, rate) error's NEES is chi-square with 12 degrees of
    freedom (its mean over runs within the two-sided 99 % bounds) and the error falls well
    below one measurement's."""
    rng = np.random.default_rng(3)
    for order in (1, 2):
        runs = 60
        nees = []
        for _ in range(runs):
            err, cov, filt = _run(rng, order)
            nees.append(err @ np.linalg.solve(cov, err))
        lo, hi = chi2.ppf([0.005, 0.995], 12 * runs) / runs
        assert lo <= np.mean(nees) <= hi, (order, np.mean(nees), lo, hi)
        # the estimated jerk density stays near zero (the truth): the twist's sigma below
        # a single measurement's (R's diagonal about 0.012: 0.11 rad/s per axis)
        assert np.all(np.sqrt(np.diag(cov)[:6]) < 0.08), np.sqrt(np.diag(cov)[:6])


def test_jerk_density_is_estimated_from_the_innovations():
    """A twist whose rate walks randomly with density q: the covariance-matching
    estimate of q from the registered twists alone (no poses given) is within 30 % of
    the truth, or 5 % of the largest density, after 600 scans (measurements precise
    enough for the walk to show; the mean keeps the start's samples, made while q was
    the start's guess: the smallest density, 1, comes out 2)."""
    rng = np.random.default_rng(4)
    q, dt = np.array([30.0, 10.0, 50.0, 5.0, 20.0, 1.0]), 0.1
    state = np.zeros(12)
    filt, used = TwistFilter(), np.zeros(6)
    Lq = np.linalg.cholesky(process_noise(q, dt))
    for _ in range(600):
        state = transition(dt) @ state + Lq @ rng.normal(size=12)
        R = _spd(rng, 6, 1e-5)
        z = state[:6] + np.linalg.cholesky(R) @ rng.normal(size=6)
        pred = filt.prediction(dt, used, np.ones(6))
        Y = np.linalg.inv(R)
        filt = filt.updated(pred, Y, Y @ (z - used), used, dt)
        assert filt.state is not None
        used = filt.state.mean[:6] + filt.state.mean[6:] * dt
    est = filt.q()
    assert est is not None
    np.testing.assert_allclose(est, q, rtol=0.3, atol=0.05 * q.max())


def _pose(rng, rot=1.0, tr=5.0):
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rng.normal(size=3) * rot).as_matrix()
    T[:3, 3] = rng.normal(size=3) * tr
    return T


def test_step_measurement_is_the_mean_twist_of_the_state():
    """Two poses a step apart along ``T_prev exp(span (xi - a span / 2))``: the step's
    twist is ``Hs s`` (closed form), and its covariance the poses' turned into the
    earlier scan's frame over span^2."""
    rng = np.random.default_rng(5)
    span = 0.1
    for _ in range(5):
        s = np.r_[rng.normal(size=3), rng.normal(size=3) * 3, rng.normal(size=6)]
        T_prev = _pose(rng)
        T = T_prev @ se3_exp(span * (s[:6] - 0.5 * span * s[6:]))
        C = np.diag(rng.uniform(1e-6, 1e-4, 6))
        z, Hs, Rz = step_measurement(T_prev, C, T, C, span)
        np.testing.assert_allclose(z, Hs @ s, atol=1e-9)
        Rb = np.kron(np.eye(2), T_prev[:3, :3].T)
        np.testing.assert_allclose(Rz, Rb @ (2 * C) @ Rb.T / span**2, atol=1e-15)


def test_steps_and_twists_track_a_constant_rate_within_the_covariance():
    """Poses along a constant-rate twist (model-exact steps) with independent noise per
    pose, and noisy registered twists: the filter's final (twist, rate) error is within
    its covariance (mean NEES over runs below the chi-square 99.5 % point of 12 degrees of
    freedom; the steps' shared pose errors make it conservative) and its twist error
    below a single registered twist's."""
    rng = np.random.default_rng(6)
    span, epochs, runs = 0.1, 40, 30
    xi0 = np.array([0.2, -0.1, 0.8, 3.0, 0.2, 0.0])
    a = np.array([0.5, 0.2, -1.0, 0.4, -0.3, 0.1])
    C = np.diag([1e-8] * 3 + [1e-6] * 3)  # pose noise: 0.006 deg, 1 mm
    R = np.eye(6) * 0.05**2  # a registered twist: 3 deg/s, 5 cm/s
    nees, errs = [], []
    for _ in range(runs):
        filt, used, T_true = TwistFilter(), xi0.copy(), np.eye(4)
        for k in range(1, epochs + 1):
            xi = xi0 + a * k * span
            T_true = T_true @ se3_exp(span * (xi - 0.5 * span * a))
            T = se3_exp(np.linalg.cholesky(C) @ rng.normal(size=6)) @ T_true
            z = xi + rng.normal(size=6) * 0.05
            pred = filt.prediction(span, used, np.full(6, 1.0))
            Y = np.linalg.inv(R)
            joint = Joint(T, C, Y, Y @ z, np.full(6, 1e3))
            filt = filt.updated(pred, Y, Y @ (z - used), used, span, joint)
            assert filt.state is not None
            used = filt.state.mean[:6] + filt.state.mean[6:] * span
        err = filt.state.mean - np.r_[xi0 + a * epochs * span, a]
        nees.append(err @ np.linalg.solve(filt.state.cov, err))
        errs.append(err[:6])
    assert np.mean(nees) <= chi2.ppf(0.995, 12 * runs) / runs, np.mean(nees)
    assert np.sqrt(np.mean(np.square(errs))) < 0.5 * 0.05
