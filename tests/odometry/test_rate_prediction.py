"""The angular rate predicted for the next epoch (``odometry.rate_prediction``,
:mod:`planodom.odometry.rate_prediction`), against closed forms and a swaying vehicle."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry
from planodom.odometry.rate_prediction import RatePredictor, autoregressive_next
from planodom.odometry.relative import RelativePose, Status

AR = OdometryConfig(rate_prediction="autoregressive")
TWIST = np.array([0.01, -0.02, 0.1, 3.0, 0.0, 0.0])


def _relative(status: Status) -> RelativePose:
    return RelativePose(np.eye(4), None, status)


def test_a_sampled_sinusoid_is_continued_exactly():
    """x_n = a sin(w n + p) + c obeys x_{n+1} = 2 cos(w) x_n - x_{n-1} + 2 c (1 - cos w):
    an order-2 fit recovers it, and its next value is the sinusoid's (closed form)."""
    n = np.arange(30)
    cols = [0.3 * np.sin(0.7 * n + 0.2) + 0.05, 1.2 * np.sin(0.25 * n - 1.0) - 0.4]
    x = np.column_stack(cols)
    got = autoregressive_next(x, 2)
    want = [0.3 * np.sin(0.7 * 30 + 0.2) + 0.05, 1.2 * np.sin(0.25 * 30 - 1.0) - 0.4]
    np.testing.assert_allclose(got, want, atol=1e-9)


def test_a_ramp_is_continued_and_a_short_history_keeps_the_last():
    ramp = (0.1 + 0.02 * np.arange(12))[:, None]
    assert autoregressive_next(ramp, 1)[0] == pytest.approx(0.1 + 0.02 * 12, abs=1e-12)
    short = ramp[:7]  # 6 equations for an order-2 fit's 3 terms: too few
    np.testing.assert_array_equal(autoregressive_next(short, 2), short[-1])


def test_an_explosive_fit_keeps_the_last_value():
    """A doubling sequence is fitted exactly (x_{n+1} = 2 x_n), and its next value leaves
    the history's range widened by its span: the last value is kept."""
    x = (2.0 ** np.arange(10))[:, None]
    assert autoregressive_next(x, 1)[0] == x[-1, 0]


def test_constant_and_plane_map_return_the_prediction_itself():
    """``constant`` (the default) and a plane map: the same object (outputs cannot move)."""
    ok = _relative(Status.OK)
    assert RatePredictor(OdometryConfig()).after(5, TWIST, ok, TWIST, None) is TWIST
    assert RatePredictor(AR).after(5, TWIST, ok, TWIST, object()) is TWIST


def _fed(pred: RatePredictor, rates: np.ndarray, first: int = 0) -> np.ndarray:
    out = TWIST
    for j, r in enumerate(rates):
        out = pred.after(first + j, np.r_[r, 3.0, 0.0, 0.0], _relative(Status.OK), TWIST, None)
    return out


def test_a_run_restarts_after_an_unresolved_or_missing_epoch():
    """The fit sees only the contiguous run of measured rates: after a break the rate is
    the prediction's until the run is long enough again."""
    k = np.arange(20)
    rates = np.column_stack([0.02 * np.sin(0.6 * k), 0.01 * np.cos(0.4 * k), 0.1 + 0.0 * k])
    pred = RatePredictor(AR)
    got = _fed(pred, rates)
    assert not np.allclose(got[:3], TWIST[:3])  # predicted: the run is long enough
    unresolved = pred.after(20, TWIST, _relative(Status.UNRESOLVED), TWIST, None)
    assert unresolved is TWIST
    np.testing.assert_array_equal(_fed(pred, rates[:5], first=21), TWIST)  # run restarted
    pred = RatePredictor(AR)
    _fed(pred, rates)
    np.testing.assert_array_equal(_fed(pred, rates[:5], first=25), TWIST)  # epochs 20-24 missing


def test_a_zero_rate_prediction_stays_zero():
    """``deskew_significance_gate`` set the prediction's rate to zero: it is kept."""
    still = np.r_[0.0, 0.0, 0.0, TWIST[3:]]
    pred = RatePredictor(AR)
    k = np.arange(20)
    rates = np.column_stack([0.02 * np.sin(0.6 * k), 0 * k, 0 * k])
    for j, r in enumerate(rates):
        out = pred.after(j, np.r_[r, 3.0, 0, 0], _relative(Status.OK), still, None)
    assert out is still


def test_config_refuses_a_bad_value_naming_the_key():
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction": "ar2"}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction_order': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction_order": 0}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction_window': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction_window": 4}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction_fit': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction_fit": "ok"}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction_bound': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction_bound": "tight"}})
    with pytest.raises(ConfigError, match="^config: field 'odometry.rate_prediction_use': "):
        PlanodomConfig.from_dict({"odometry": {"rate_prediction_use": "deskew"}})


@pytest.mark.parametrize("mode", ["constant", "autoregressive"])
def test_a_swaying_vehicle_s_next_rate(mode):
    """Roll swaying as 2 deg sin(2 pi 0.4 t) while driving at 3 m/s, planes seen exactly at
    10 Hz: each step's rate is a sampled sinusoid. The odometry's predicted roll rate for
    the next step lags it by one epoch's change with ``constant``; the autoregression
    predicts it (closed form: the true next step's mean rate)."""
    rng = np.random.default_rng(7)
    world = world_planes(rng, 10)
    dt, n = 0.1, 40
    roll = np.radians(2.0) * np.sin(2 * np.pi * 0.4 * dt * np.arange(n + 1))
    poses = [transform_from_rpy_xyz(roll[k], 0.0, 0.0, 0.3 * k, 0.0, 0.0) for k in range(n)]
    cfg = {"pipeline": "wocsc", "rate_prediction": mode}
    odo = PlaneOdometry(PlanodomConfig.from_dict({"odometry": cfg}))
    for k, T in enumerate(poses):
        odo.register_planes(observe(world, T), time=dt * k)
    assert odo.twist is not None
    true_next = (roll[n] - roll[n - 1]) / dt  # the step after the last epoch (no pitch, yaw)
    last = (roll[n - 1] - roll[n - 2]) / dt
    if mode == "constant":
        assert odo.twist[0] == pytest.approx(last, abs=1e-6)
    else:
        assert odo.twist[0] == pytest.approx(true_next, abs=1e-6)
        assert abs(true_next - last) > 0.005  # the constant one is off by 0.46 deg/s


def test_selected_waits_for_a_full_check_and_then_follows_the_better_forecast():
    """``selected`` on a sampled sinusoid (the autoregression exact, the constant rate
    off): the prediction's rate until the autoregression has been checked on
    ``rate_prediction_check`` rates, then the autoregression's (as ``autoregressive``)."""
    cfg = OdometryConfig(rate_prediction="selected", rate_prediction_check=5)
    k = np.arange(40)
    rates = np.column_stack([0.05 * np.sin(0.5 * k), 0.03 * np.sin(0.3 * k + 1), 0.1 + 0 * k])
    first = 3 * cfg.rate_prediction_order + 2  # rates before the autoregression predicts
    sel, ar = RatePredictor(cfg), RatePredictor(AR)
    for j, r in enumerate(rates):
        own, ok = np.r_[r, 3.0, 0.0, 0.0], _relative(Status.OK)
        got, want = sel.after(j, own, ok, TWIST, None), ar.after(j, own, ok, TWIST, None)
        if j + 1 < first + 5:
            assert got is TWIST
        else:
            np.testing.assert_allclose(got, want, atol=1e-12)
            assert not np.allclose(got[:3], TWIST[:3])


def _sinusoids(k: np.ndarray) -> np.ndarray:
    """(K, 3) rates (rad/s) of epochs ``k``: each an exact order-2 recurrence."""
    return np.column_stack([0.02 * np.sin(0.6 * k), 0.01 * np.cos(0.4 * k), 0.1 + 0.0 * k])


@pytest.mark.parametrize("wrong", ["degenerate", "partly"])
def test_fit_ok_keeps_a_badly_measured_rate_out_of_the_fit(wrong):
    """A sinusoidal rate, epoch 20's measured 0.2 rad/s wrong (degenerate, or a rotation
    partly observed). ``fit: ok`` predicts the sinusoid's exact rates after it (closed
    form); ``measured`` fits the wrong rate and misses them by more than 1e-3 rad/s."""
    k = np.arange(30)
    rates = _sinusoids(k)
    wrong_rate = np.r_[rates[20] + 0.2, 3.0, 0.0, 0.0]
    bad = (
        _relative(Status.DEGENERATE)
        if wrong == "degenerate"
        else RelativePose(np.eye(4), None, Status.OK, rotation_partly_observed=True)
    )
    for fit, exact in (("ok_filled", True), ("measured", False)):
        cfg = OdometryConfig(rate_prediction="autoregressive", rate_prediction_order=2)
        pred = RatePredictor(cfg.model_copy(update={"rate_prediction_fit": fit}))
        _fed(pred, rates[:20])
        after = pred.after(20, wrong_rate, bad, TWIST, None)
        later = _fed(pred, rates[21:29], first=21)
        for got, want in ((after, rates[21]), (later, rates[29])):
            close = np.allclose(got[:3], want, atol=1e-9)
            assert close if exact else np.max(np.abs(got[:3] - want)) > 1e-3


def test_the_bound_limits_the_change_to_the_window_s_largest_step():
    """A rate growing by 10 % a step (an exact order-1 fit predicts x 1.1): bounded, the
    prediction is the last rate plus the window's largest step, 0.1 x the one before."""
    x = 0.01 * 1.1 ** np.arange(12)
    rates = np.column_stack([x, -x, 0.1 + 0.0 * x])
    cfg = OdometryConfig(rate_prediction="autoregressive", rate_prediction_order=1)
    free = _fed(RatePredictor(cfg), rates)
    np.testing.assert_allclose(free[:3], [x[-1] * 1.1, -x[-1] * 1.1, 0.1], atol=1e-12)
    bounded = RatePredictor(cfg.model_copy(update={"rate_prediction_bound": True}))
    step = 0.1 * x[-2]
    np.testing.assert_allclose(
        _fed(bounded, rates)[:3], [x[-1] + step, -x[-1] - step, 0.1], atol=1e-12
    )


def test_fit_ok_runs_restarts_the_run_after_a_degenerate_step():
    """``ok_runs``: after a degenerate step the prediction is the constant rate's until a
    new run of ok steps is long enough, then the sinusoid's exact rate (closed form)."""
    k = np.arange(60)
    rates = _sinusoids(k)
    cfg = OdometryConfig(
        rate_prediction="autoregressive", rate_prediction_order=2, rate_prediction_fit="ok_runs"
    )
    pred = RatePredictor(cfg)
    _fed(pred, rates[:20])
    wrong = pred.after(20, np.r_[rates[20] + 0.2, 3.0, 0.0, 0.0], _degenerate(), TWIST, None)
    assert wrong is TWIST
    np.testing.assert_array_equal(_fed(pred, rates[21:28], first=21), TWIST)  # 7 < 3 * 2 + 2
    np.testing.assert_allclose(_fed(pred, rates[28:40], first=28)[:3], rates[40], atol=1e-9)


def _degenerate() -> RelativePose:
    return _relative(Status.DEGENERATE)


@pytest.mark.parametrize("use", ["all", "first_deskew"])
def test_first_deskew_gets_the_prediction_and_the_prior_keeps_the_constant_rate(use, monkeypatch):
    """A swaying vehicle's epochs as time-spread scans, their planes given exactly by a stub
    extractor (the deskewing twist recorded; point times centred, so no twist offset):
    the epochs' own rates are a sampled sinusoid. ``first_deskew``: the last epoch is
    first deskewed with the autoregression's rate, the true step's (closed form), while
    the prior of its relative pose, and ``twist``, keep the last step's rate; ``all``:
    both get the prediction."""
    import planodom.odometry.odometry as odometry_module
    from planodom.geometry import se3_log
    from planodom.scan import Scan

    rng = np.random.default_rng(7)
    world = world_planes(rng, 10)
    dt, n = 0.1, 44
    roll = np.radians(2.0) * np.sin(2 * np.pi * 0.4 * dt * np.arange(n + 1))
    poses = [transform_from_rpy_xyz(roll[k], 0.0, 0.0, 0.3 * k, 0.0, 0.0) for k in range(n)]
    scans = [Scan(np.zeros((2, 3)), t=np.array([-0.05, 0.05])) for _ in range(n)]
    first_twist: dict[int, np.ndarray | None] = {}

    def extractor(scan, config, twist=None, **_):
        k = next(j for j, s in enumerate(scans) if s is scan)
        first_twist.setdefault(k, None if twist is None else np.array(twist))
        return observe(world, poses[k])

    priors: list[np.ndarray | None] = []
    solve = odometry_module.estimate_relative_pose

    def recording(*args, **kwargs):
        priors.append(args[3])
        return solve(*args, **kwargs)

    monkeypatch.setattr(odometry_module, "estimate_relative_pose", recording)
    cfg = {"pipeline": "wocsc", "rate_prediction": "autoregressive", "rate_prediction_use": use}
    odo = PlaneOdometry(PlanodomConfig.from_dict({"odometry": cfg}), extractor=extractor)
    for k in range(n - 1):
        odo.register_epoch(scans[k], time=dt * k)
    assert odo.twist is not None
    constant = (roll[n - 2] - roll[n - 3]) / dt  # the last step's rate (no pitch, yaw)
    true_next = (roll[n - 1] - roll[n - 2]) / dt
    assert abs(true_next - constant) > 0.015  # the two are 1.1 deg/s apart
    priors.clear()
    odo.register_epoch(scans[n - 1], time=dt * (n - 1))
    assert priors[0] is not None
    prior_rate = se3_log(priors[0])[0] / dt  # delta 1: the prior is the predicted step
    deskewed_with = first_twist[n - 1]
    assert deskewed_with is not None
    assert deskewed_with[0] == pytest.approx(true_next, abs=1e-6)
    expected_prior = constant if use == "first_deskew" else true_next
    assert prior_rate == pytest.approx(expected_prior, abs=1e-6)
    last_rate, next_rate = (roll[n - 1] - roll[n - 2]) / dt, (roll[n] - roll[n - 1]) / dt
    want = last_rate if use == "first_deskew" else next_rate  # the twist after the last
    assert odo.twist[0] == pytest.approx(want, abs=1e-6)


def test_deskewing_returns_the_twist_itself_unless_first_deskew():
    """``all`` (the default): the twist passed; ``first_deskew``: the prediction made
    with it, and for any other twist (held across a change) that twist."""
    k = np.arange(20)
    ar = RatePredictor(AR)
    got = _fed(ar, _sinusoids(k))
    assert ar.deskewing(TWIST) is TWIST and not np.allclose(got[:3], TWIST[:3])
    first = RatePredictor(AR.model_copy(update={"rate_prediction_use": "first_deskew"}))
    assert _fed(first, _sinusoids(k)) is TWIST
    np.testing.assert_allclose(first.deskewing(TWIST), got, atol=1e-12)
    other = TWIST.copy()
    assert first.deskewing(other) is other and first.deskewing(None) is None
