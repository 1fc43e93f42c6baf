"""The led twist's error as one unknown of the registration (``planemap.lead_weights:
unknown``): recovered within its stated sigma."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, se3_exp, se3_log
from planodom.odometry.planemap.deskew_weights import led_weights
from planodom.odometry.planemap.led_twist import led_registration, timed_planes
from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.register import Registration, ScanPlanes
from tests.odometry.planemap.test_ctreg import _map, _scan

#: the led twist's error sigma per axis (rad/s, m/s): about the stated ones of LIDARW's
#: probe (0.3 deg/s in roll and pitch, a few cm/s), larger in yaw to be seen here
PRIOR_SD = np.array([0.005, 0.005, 0.01, 0.03, 0.03, 0.03])


def _draw(rng, M, T_true, xi_true, sigma):
    """One scan deskewed with the true twist plus an error drawn from the prior, registered
    with the prior: (the error before, the error after, the correction's covariance)."""
    error = rng.normal(size=6) * PRIOR_SD
    used = xi_true + error
    m, normals, tm = _scan(T_true, xi_true, used, rng, sigma=sigma)
    cur = ScanPlanes.of(m, normals, sigma, 0.0)
    cur = ScanPlanes(**{**cur.__dict__, "time_moments": tm, "led_var": PRIOR_SD**2})
    k = np.arange(len(m))
    reg = Registration(T_true, np.eye(6), k, k, np.ones(len(m)), "map")
    got = led_registration(M, reg, cur, 10)
    assert got is not None
    P = np.linalg.inv(got.H)[6:, 6:]  # the correction's marginal covariance
    return error, used + got.correction - xi_true, P


def test_recovers_the_true_twist_within_its_stated_sigma():
    """Monte Carlo: a sweep of a room under a known twist, deskewed with that twist off by
    an error drawn from the prior, points with 1 cm noise. The corrected twist's error,
    whitened by the posterior covariance the solve states, is standard normal (its sum of
    squares over 40 draws x 6 axes is chi-square's); and the correction takes most of
    the error away (the planes measure it: a shared error, not independent per plane)."""
    rng = np.random.default_rng(11)
    M = _map()
    T_true = se3_exp(np.array([0.02, -0.01, 0.3, 0.2, -0.1, 0.05]))
    xi_true = np.array([0.01, -0.02, 0.2, 8.0, 0.3, 0.05])  # a vehicle: 11 deg/s, 8 m/s
    z2, before, after = [], [], []
    for _ in range(40):
        error, left, P = _draw(rng, M, T_true, xi_true, 0.01)
        z = np.linalg.solve(np.linalg.cholesky(P), left)
        z2.append(z @ z)
        before.append((error / PRIOR_SD) ** 2)
        after.append((left / PRIOR_SD) ** 2)
    n = 6 * len(z2)
    mean = float(np.sum(z2)) / n  # chi-square(n) / n: mean 1, sd sqrt(2 / n) = 0.065
    assert 0.75 < mean < 1.25, mean
    # in prior units, the error left is a small part of the error drawn
    assert np.mean(after) < 0.3 * np.mean(before)
    assert np.all(np.mean(after, axis=0) < np.mean(before, axis=0))


def test_a_tight_prior_keeps_the_twist_used():
    """With the prior's sigma far below what the planes measure, the correction stays
    about zero whatever the error (the prior is the led twist's own uncertainty)."""
    rng = np.random.default_rng(12)
    M = _map()
    xi_true = np.array([0.0, 0.0, 0.2, 5.0, 0.0, 0.0])
    used = xi_true + np.array([0.0, 0.0, 0.05, 0.2, 0.0, 0.0])
    m, normals, tm = _scan(np.eye(4), xi_true, used, rng)
    cur = ScanPlanes(**{**ScanPlanes.of(m, normals, 0.001, 0.0).__dict__, "time_moments": tm,
                        "led_var": np.full(6, 1e-14)})  # fmt: skip
    k = np.arange(len(m))
    got = led_registration(M, Registration(np.eye(4), np.eye(6), k, k, np.ones(len(m)), "map"),
                           cur, 5)  # fmt: skip
    assert got is not None
    assert np.all(np.abs(got.correction) < 1e-4 * np.abs(used - xi_true).max())


def _plane(with_moments: bool) -> Plane:
    tm = np.zeros((5, 4, 4)) if with_moments else None
    support = PlaneSupport(np.zeros(3), np.zeros((0, 3)), 100, np.eye(3), 4, tm)
    return Plane(np.array([0.0, 0.0, 1.0]), 1.0, np.eye(3) * 1e-6, 1.0, support)


def test_only_a_led_scan_carries_the_prior():
    """``unknown``: the led scan's variance and time moments reach the registration, with
    the led bias and no per-plane term; a scan not led, or the option off, gets neither."""
    cfg = PlanodomConfig.model_validate({"planemap": {"lead_weights": "unknown"}})
    assert cfg.extraction.time_moments and not cfg.extraction.deskew_jacobian
    assert not PlanodomConfig().extraction.time_moments
    pm, used = cfg.planemap, np.arange(2)
    planes = [_plane(True), _plane(True)]
    led = (np.arange(1.0, 7.0), 0.05)
    assert led_weights(pm, planes, used, led) == (pm.led_bias_m, None)
    assert led_weights(pm, planes, used, None) is None
    m = Moments(np.full(2, 100.0), np.zeros((2, 3)), np.tile(np.eye(3), (2, 1, 1)), np.full(2, 4.0))
    cur = ScanPlanes.of(m, np.tile([0.0, 0.0, 1.0], (2, 1)), 0.01, 0.005)
    got = timed_planes(pm, cur, planes, used, led)
    np.testing.assert_array_equal(got.led_var, led[0])
    assert got.time_moments is not None and got.time_moments.shape == (2, 5, 4, 4)
    assert timed_planes(pm, cur, planes, used, None) is cur
    assert timed_planes(PlanodomConfig().planemap, cur, planes, used, led) is cur
    assert timed_planes(pm, cur, [_plane(True), _plane(False)], used, led) is cur
    assert led_registration(_map(), None, cur, 3) is None  # type: ignore[arg-type]


def _planes(m: Moments, normals: np.ndarray, tm: np.ndarray) -> list[Plane]:
    out = []
    for k in range(len(m)):
        n, c = normals[k], m.c[k]
        support = PlaneSupport(c, np.zeros((0, 3)), int(m.N[k]), m.S[k], 16, tm[k])
        out.append(Plane(n, float(-n @ c), np.eye(4) * 1e-8, 1.0, support))
    return out


def test_the_odometry_registers_a_led_scan_with_its_twist_unknown():
    """End to end through :class:`PlaneMapOdometry`: a room mapped from a scan deskewed
    with its true twist, then a scan taken after a step, deskewed with a twist off by
    a shared error and handed in with its led variance (the map and the scan weighted by
    their points' noise: with a laser bias of centimetres the map's planes are too
    uncertain to measure the error, and the prior holds it). With ``unknown`` the rotation
    is nearer the truth than the registration's alone (off), and the epoch's twist is not
    replaced by the correction (the lead stays the steps')."""
    from planodom.odometry.planemap import PlaneMapOdometry

    rng = np.random.default_rng(13)
    xi_true = np.array([0.0, 0.0, 0.2, 8.0, 0.0, 0.0])
    error = np.array([0.004, -0.004, 0.01, 0.04, -0.03, 0.02])  # 1-1.5 sigma per axis
    T_true = se3_exp(xi_true * 0.1)
    first = _planes(*_scan(np.eye(4), xi_true, xi_true, np.random.default_rng(1), 0.002))
    m, normals, tm = _scan(T_true, xi_true, xi_true + error, rng, 0.002)
    led = (PRIOR_SD**2, 0.05)
    errors = {}
    for mode in ("off", "unknown"):
        bias = {"laser_bias_m": 0.0005, "led_bias_m": 0.0005}  # the points' own: no lasers'
        cfg = PlanodomConfig.model_validate(
            {"planemap": {"lead_weights": mode, **bias}, "extraction": {"range_noise_m": 0.002}}
        )
        odo = PlaneMapOdometry(cfg)
        odo.commit(odo.estimate(first))
        est = odo.estimate(_planes(m, normals, tm), xi_true + error, 0.1, led)
        assert est.twist is None
        errors[mode] = np.linalg.norm(se3_log(np.linalg.inv(T_true) @ est.T)[:3])
    # the rotation 0.034 -> 0.004 deg: the twist's error no longer turns the scan's planes
    assert errors["unknown"] < 0.3 * errors["off"], errors
