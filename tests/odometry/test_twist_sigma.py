"""The per-epoch twist sigma (:mod:`planodom.odometry.twist_sigma`)."""

from __future__ import annotations

import numpy as np
import pytest
from planes_factory import observe, world_planes

from planodom.config import PlanodomConfig
from planodom.geometry import (
    Plane,
    invert_transform,
    se3_exp,
    se3_log,
    transform_from_rpy_xyz,
)
from planodom.odometry import PlaneOdometry, RelativePose, Status
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.surfaces import fragment_count
from planodom.odometry.twist_sigma import TwistUncertainty, step_sigma, widened_if_lost
from planodom.planes import PlaneSet
from planodom.scan import Scan


def _relative(status=Status.OK, sigma_z=np.inf, scale=1.0) -> RelativePose:
    cov = scale * np.diag([1e-6, 4e-6, 4e-6, 9e-4, 16e-4])
    return RelativePose(np.eye(4), cov, status, sigma_z=sigma_z)


def test_step_sigma_is_the_step_error_over_dt():
    s = step_sigma(_relative(), 0.1)
    np.testing.assert_allclose(s, [3e-3 / 0.1, 5e-2 / 0.1])  # sqrt(9e-6), sqrt(25e-4)
    s = step_sigma(_relative(sigma_z=0.0), 0.1)  # z measured exactly: no change
    np.testing.assert_allclose(s, [0.03, 0.5])
    s = step_sigma(_relative(Status.DEGENERATE), 0.1)
    assert np.isclose(s[0], 0.03) and s[1] == np.inf
    assert np.all(step_sigma(_relative(Status.UNRESOLVED), 0.1) == np.inf)


def test_change_per_epoch_is_the_rms_of_successive_twist_differences_less_their_noise():
    cfg = PlanodomConfig().odometry
    model = TwistUncertainty(cfg)
    fallback = [np.radians(cfg.deskew_rate_tolerance_deg_s), cfg.deskew_speed_tolerance_mps]
    np.testing.assert_allclose(model.change(), fallback)  # nothing measured yet
    exact = _relative(scale=0.0)
    for v in ([0, 0, 0.1, 1.0, 0, 0], [0, 0, 0.1, 1.3, 0, 0], [0, 0, 0.14, 1.3, 0.4, 0]):
        model.update(np.array(v, float), exact, 0.1)
    # differences: (0, 0.3) then (0.04, 0.4) -> rms 0.02 * sqrt(2), 0.25 * sqrt(2)
    change = np.array([np.sqrt(0.0008), np.sqrt(0.125)])
    np.testing.assert_allclose(model.change(), change)
    # after the step error (none), two changes; each unresolved epoch since adds one
    np.testing.assert_allclose(model.predicted(), 2 * change)
    model.update(np.zeros(6), _relative(Status.UNRESOLVED), 0.1)
    model.update(np.zeros(6), _relative(Status.UNRESOLVED), 0.1)
    np.testing.assert_allclose(model.predicted(), 4 * change)
    # the twist across the bridge is no measured change
    model.update(np.array([0, 0, 0.14, 1.3, 0.4, 0]) + 5.0, exact, 0.1)
    np.testing.assert_allclose(model.change(), change)
    # twists that differ by no more than their steps' errors (0.03 rad/s, 0.5 m/s each
    # over 0.1 s) show no change
    noisy = TwistUncertainty(cfg)
    for v in ([0, 0, 0.1, 1.0, 0, 0], [0, 0, 0.14, 1.7, 0, 0]):
        noisy.update(np.array(v, float), _relative(), 0.1)
    np.testing.assert_allclose(noisy.change(), [0.0, 0.0])
    np.testing.assert_allclose(noisy.predicted(), [0.03, 0.5])
    # with their errors left in: the raw difference (0.04, 0.7)
    np.testing.assert_allclose(noisy.raw_change(), [0.04, 0.7])
    np.testing.assert_allclose(model.raw_change(), change)  # exact steps: the same
    np.testing.assert_allclose(TwistUncertainty(cfg).raw_change(), fallback)


def test_a_refined_twist_is_given_its_step_error_and_what_was_left_of_the_difference():
    model = TwistUncertainty(PlanodomConfig().odometry)
    for v in ([0, 0, 0.1, 1.0, 0, 0], [0, 0, 0.1, 1.0, 0, 0]):
        model.update(np.array(v, float), _relative(), 0.1)  # change 0 (known)
    T = transform_from_rpy_xyz(0, 0, 0.01, 0.2, 0, 0)
    source = EpochEstimate([], PlaneSet.from_planes([]), None, _relative(), T, [])
    own = se3_log(T) / 0.1
    np.testing.assert_allclose(model.refined(source, 0.1, own), [0.03, 0.5])
    kept = own + np.r_[0, 0, 0, 0.2, 0, 0]  # a velocity within the tolerance kept
    np.testing.assert_allclose(model.refined(source, 0.1, kept), [0.03, 0.7])


def _run(mode: str, extractor_for, wrong=np.r_[0, 0, 0.05, 1.0, 0, 0]):
    """Six epochs of an accelerating turn (times centred on the epoch time: the planes do not
    move with the twist); after epoch 3 the prediction is made ``wrong``. Returns the
    odometry, the calls (epoch, twist, (rate sigma deg/s, speed sigma m/s)) and poses."""
    rng = np.random.default_rng(4)
    world = world_planes(rng, 10)
    poses = [
        transform_from_rpy_xyz(0, 0, 0.003 * k**2, 0.1 * k + 0.01 * k**2, 0, 0) for k in range(6)
    ]
    planes = [observe(world, T) for T in poses]
    calls: list = []
    cfg = PlanodomConfig.from_dict({"odometry": {"twist_sigma": mode, "pipeline": "wocsc"}})
    odo = PlaneOdometry(cfg, extractor=extractor_for(planes, poses, calls))
    for k in range(6):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[-0.05, 0.05]), 0.1 * k)
        if k == 3:
            odo.twist = odo.twist + wrong
    return odo, calls, poses


def _recording(planes, poses, calls):
    def extractor(scan, cfg, twist=None):
        sig = (cfg.twist_rate_sigma_deg_s, cfg.twist_speed_sigma_mps)
        calls.append((int(scan.points[0, 0]), twist, sig))
        return planes[int(scan.points[0, 0])]

    return extractor


def test_the_odometry_passes_each_twist_with_its_own_sigma():
    """A wrong prediction is extracted with a larger sigma than the epoch's own twist
    refined after it, whose sigma covers its true error; ``twist_sigma: fixed`` leaves the
    extraction config as it is."""
    _, calls, _ = _run("fixed", _recording)
    assert all(sig == (0.0, 0.0) for _, _, sig in calls)
    _, calls, poses = _run("always", _recording)
    assert all(sig == (0.0, 0.0) for _, tw, sig in calls if tw is None)
    last = [c for c in calls if c[0] == 4]
    assert len(last) == 2  # the prediction, then the epoch's own twist
    predicted, refined = last[0][2], last[1][2]
    # the rate changes by 0.06 rad/s per epoch: two changes for the prediction, one for
    # the refined twist (the speed's change is below the steps' errors here)
    assert refined[0] < 0.6 * predicted[0]
    true = se3_log(invert_transform(poses[3]) @ poses[4]) / 0.1
    err = last[1][1] - true
    assert np.degrees(np.linalg.norm(err[:3])) <= refined[0]
    assert np.linalg.norm(err[3:]) <= refined[1]


def test_an_epoch_lost_to_a_wrong_twist_is_extracted_again_with_its_sigma():
    """From epoch 2 on, an extraction that finds the planes only with a twist whose
    uncertainty is declared (a smear within the widened tolerance): with ``lost`` the epoch
    after a wrong prediction is extracted again with the same twist and its sigma and
    measured; with ``fixed`` it stays unresolved."""

    def smeared(planes, poses, calls):
        def extractor(scan, cfg, twist=None):
            k = int(scan.points[0, 0])
            sig = (cfg.twist_rate_sigma_deg_s, cfg.twist_speed_sigma_mps)
            calls.append((k, twist, sig))
            if k < 2 or (twist is not None and k != 4):
                return planes[k]
            return planes[k] if twist is not None and min(sig) > 0 else []

        return extractor

    odo, calls, _ = _run("lost", smeared)
    assert odo.results[4].status == "ok"
    first, second = [c for c in calls if c[0] == 4][:2]
    np.testing.assert_array_equal(first[1], second[1])
    assert first[2] == (0.0, 0.0) and min(second[2]) > 0
    odo, _, _ = _run("fixed", smeared)
    assert odo.results[4].status == "unresolved"


def test_a_step_is_consistent_with_the_prediction_within_both_errors_at_the_chi2_quantile():
    """The rate differs from the prediction by d along one axis; predicted sigma 0.03 rad/s
    (the last step's, no change) and the candidate step's 0.03 rad/s: the statistic is
    3 d^2 / (2 * 0.03^2), chi2(3) at 0.99 is 11.345 (table), so d = 0.0825 rad/s passes and
    d = 0.0826 does not; with ``twist`` an OK step's velocity counts too, against chi2(6)."""
    base = PlanodomConfig().odometry
    rate, off = (
        base.model_copy(update={"rescue_gate_quantile": 0.99, "rescue_gate": g})
        for g in ("rate", "off")
    )
    twist = rate.model_copy(update={"rescue_gate": "twist"})
    model = TwistUncertainty(base)
    for _ in range(2):
        model.update(np.zeros(6), _relative(), 0.1)  # sigma (0.03, 0.5), change 0
    limit = np.sqrt(11.345 * 2 * 0.03**2 / 3)  # 0.08250
    prediction = np.zeros(6)

    def candidate(rate, speed, status=Status.OK):
        T = transform_from_rpy_xyz(0, 0, rate * 0.1, speed * 0.1, 0, 0)
        return EpochEstimate([], PlaneSet.from_planes([]), None, _relative(status), T, [])

    assert model.consistent(candidate(limit - 2e-4, 1.7), 0.1, prediction, rate)
    assert not model.consistent(candidate(limit + 2e-4, 0.0), 0.1, prediction, rate)
    # velocity: 3 v^2 / (2 * 0.5^2) = 17.34 beyond chi2(6) at 0.99 = 16.812 for v = 1.7 m/s
    assert model.consistent(candidate(0.0, 1.6), 0.1, prediction, twist)
    assert not model.consistent(candidate(0.0, 1.7), 0.1, prediction, twist)
    assert model.consistent(candidate(0.0, 1.7, Status.DEGENERATE), 0.1, prediction, twist)
    # ``degenerate`` gates the rate of a degenerate step only
    degenerate = rate.model_copy(update={"rescue_gate": "degenerate"})
    assert model.consistent(candidate(limit + 2e-4, 0.0), 0.1, prediction, degenerate)
    deg = Status.DEGENERATE
    assert not model.consistent(candidate(limit + 2e-4, 0.0, deg), 0.1, prediction, degenerate)
    assert model.consistent(candidate(limit - 2e-4, 9.0, deg), 0.1, prediction, degenerate)
    # no gate, no prediction, or a bridge: nothing to compare
    assert model.consistent(candidate(1.0, 9.0), 0.1, prediction, off)
    assert model.consistent(candidate(1.0, 9.0), 0.1, None, rate)
    assert model.consistent(candidate(1.0, 9.0, Status.UNRESOLVED), 0.1, prediction, rate)


def test_a_widened_rescue_that_disagrees_with_the_prediction_is_not_kept():
    def estimate(status, planes):
        rel = _relative(status)
        return EpochEstimate([None] * planes, None, None, rel, np.eye(4), [])  # type: ignore[list-item]

    tight, wide = estimate(Status.UNRESOLVED, 1), estimate(Status.OK, 6)
    pick = lambda s: tight if s is None else wide  # noqa: E731
    assert widened_if_lost(pick, (0.1, 1.0), "lost", 6) is wide
    assert widened_if_lost(pick, (0.1, 1.0), "lost", 6, lambda e: e is not wide) is tight


def test_a_degenerate_step_off_the_prediction_is_reported_inconsistent_and_bridged():
    """The same chi2 limit as above (0.0825 rad/s off the prediction) on every degenerate
    step with ``degenerate_gate: bridge``: beyond it the step becomes the constant-velocity
    bridge ``T_ref_last exp(prediction dt)``, unresolved and ``inconsistent``; OK steps and
    ``off`` are left as they are."""
    odometry = PlanodomConfig().odometry
    base = odometry.model_copy(update={"rescue_gate_quantile": 0.99, "degenerate_gate": "off"})
    bridge = base.model_copy(update={"degenerate_gate": "bridge"})
    model = TwistUncertainty(base)
    for _ in range(2):
        model.update(np.zeros(6), _relative(), 0.1)  # sigma (0.03, 0.5), change 0
    limit = np.sqrt(11.345 * 2 * 0.03**2 / 3)
    prediction = np.r_[0.0, 0.0, 0.2, 2.0, 0.0, 0.0]  # 0.2 rad/s, 2 m/s forward
    T_ref_last = transform_from_rpy_xyz(0, 0, 0.3, 1.0, -2.0, 0.0)

    def candidate(rate, status=Status.DEGENERATE):
        T = transform_from_rpy_xyz(0, 0, rate * 0.1, 0.0, 0, 0)
        rel = _relative(status)
        return EpochEstimate([], PlaneSet.from_planes([]), None, rel, T, [])

    inside, outside = candidate(0.2 + limit - 2e-4), candidate(0.2 + limit + 2e-4)
    assert model.gated(inside, 0.1, prediction, T_ref_last, bridge) is inside
    assert model.gated(outside, 0.1, prediction, T_ref_last, base) is outside  # off
    ok = candidate(0.2 + 1.0, Status.OK)
    assert model.gated(ok, 0.1, prediction, T_ref_last, bridge) is ok
    assert model.gated(outside, 0.1, None, T_ref_last, bridge) is outside
    gated = model.gated(outside, 0.1, prediction, T_ref_last, bridge)
    assert gated.relative.status is Status.UNRESOLVED and gated.relative.inconsistent
    # the bridge: 0.02 rad of yaw and 0.2 m along the arc of a constant twist
    expected = transform_from_rpy_xyz(0, 0, 0.02, 10 * np.sin(0.02), 10 * (1 - np.cos(0.02)), 0)
    np.testing.assert_allclose(gated.step, expected, atol=1e-12)
    np.testing.assert_allclose(gated.relative.T_prev_curr, T_ref_last @ expected, atol=1e-12)
    assert len(gated.relative.associations) == 0 and gated.relative.sources is None


def test_the_gates_measure_the_rate_change_across_degenerate_steps_too():
    """Exact steps: rates 0.1, 0.14 (degenerate), 0.11 rad/s change by 0.04 and 0.03 (rms
    0.025 sqrt(2)) for the gates; the extraction's change is measured only between OK
    steps (none here: the fallback), and so is the velocity's."""
    cfg = PlanodomConfig().odometry
    model = TwistUncertainty(cfg)
    steps = [(0.1, Status.OK), (0.14, Status.DEGENERATE), (0.11, Status.OK)]
    for rate, status in steps:
        model.update(np.r_[0, 0, rate, 1.0, 0, 0], _relative(status, scale=0.0), 0.1)
    fallback = [np.radians(cfg.deskew_rate_tolerance_deg_s), cfg.deskew_speed_tolerance_mps]
    np.testing.assert_allclose(model.change(), fallback)
    np.testing.assert_allclose(model.gate_change(), [0.025 * np.sqrt(2), fallback[1]])
    # exact last step: the prediction's sigma is two changes
    np.testing.assert_allclose(model.predicted(gate=True), [0.05 * np.sqrt(2), 2 * fallback[1]])


def test_remembered_sigmas_are_those_of_a_model_asked_only_at_the_end():
    """change() and predicted() are remembered until the next update: asked after every
    update, they equal a model fed the same updates and asked once."""
    cfg = PlanodomConfig().odometry
    asked, fresh = TwistUncertainty(cfg), TwistUncertainty(cfg)
    rng = np.random.default_rng(3)
    statuses = [Status.OK, Status.OK, Status.DEGENERATE, Status.UNRESOLVED, Status.OK, Status.OK]
    for status in statuses:
        own, relative = rng.normal(size=6), _relative(status, scale=rng.uniform(0.1, 2.0))
        asked.predicted(), asked.predicted(gate=True), asked.change()
        asked.update(own, relative, 0.1)
        fresh.update(own, relative, 0.1)
    assert asked.predicted() == fresh.predicted()
    assert asked.predicted(gate=True) == fresh.predicted(gate=True)
    np.testing.assert_array_equal(asked.change(), fresh.change())


def _wall(yaw_deg: float, offset: float) -> Plane:
    a = np.radians(yaw_deg)
    return Plane(np.array([np.cos(a), np.sin(a), 0.0]), offset)


def test_a_first_extraction_of_wall_fragments_is_lost_with_twist_sigma_fragments():
    """A twist off the truth splits each wall into one plane per sweep (world 166 at 6 mm,
    epoch 74: 13 planes of 4 surfaces, no ground, where the widened extraction held 6
    surfaces). Here two walls, each in three fragments 0.3 deg and 5 cm apart (2 distinct
    surfaces by construction), against a widened extraction of the ground and three walls
    (4): by plane count (the default) the fragments are not lost and are kept; with
    ``odometry.twist_sigma_fragments`` they are, and the widened one wins on surfaces."""
    fragments = [
        _wall(y + f * 0.3, d + f * 0.05) for y, d in ((0, -4.0), (70, -6.0)) for f in range(3)
    ]
    ground = Plane(np.array([0.0, 0.0, 1.0]), 1.5)
    four = [ground, _wall(0, -4.0), _wall(70, -6.0), _wall(150, -9.0)]

    def estimate(planes: list[Plane], status: Status = Status.OK) -> EpochEstimate:
        return EpochEstimate(planes, None, None, _relative(status), np.eye(4), [])  # type: ignore[arg-type]

    tight, wide = estimate(fragments), estimate(four)
    pick = lambda s: tight if s is None else wide  # noqa: E731
    on = PlanodomConfig().updated({"odometry.twist_sigma_fragments": True}, source="test")
    count = fragment_count(on)
    assert fragment_count(PlanodomConfig()) is None
    assert count is not None and count(tight) == 2 and count(wide) == 4
    assert widened_if_lost(pick, (0.1, 1.0), "lost", 6) is tight
    assert widened_if_lost(pick, (0.1, 1.0), "lost", 6, surfaces=count) is wide
    # a widened extraction of fewer surfaces, or a worse status, leaves the fragments
    fewer = estimate([ground])
    assert widened_if_lost(lambda s: tight if s is None else fewer, (0.1, 1.0), "lost", 6,
                           surfaces=count) is tight  # fmt: skip
    worse = estimate(four, Status.DEGENERATE)
    assert widened_if_lost(lambda s: tight if s is None else worse, (0.1, 1.0), "lost", 6,
                           surfaces=count) is tight  # fmt: skip
    # without fragments the first extraction is kept and the widened one never made
    whole = estimate(four[1:])
    made = []
    got = widened_if_lost(lambda s: made.append(s) or (whole if s is None else wide),
                          (0.1, 1.0), "lost", 3, surfaces=count)  # fmt: skip
    assert got is whole and made == [None]


def test_a_bridges_rotation_sigma_sums_the_predicted_rate_sigmas_of_its_steps():
    """``bridged_rotation_sigma``: the held rate's sigma of each bridged step since the last
    measured one (``predicted()`` as it stood before each), summed, times ``dt``; by hand
    for the first: (0.03 + 2 c) * 0.1, ``c`` the rms of the rate changes (0.04 three
    times, then 0.04 less the last step's 0.03 sigma, in squares)."""
    model = TwistUncertainty(PlanodomConfig().odometry)
    for rate in (0.0, 0.04, 0.0, 0.04):  # exact steps: change sqrt(mean(0.04^2)) = 0.04
        model.update(np.r_[0, 0, rate, 1.0, 0, 0], _relative(scale=0.0), 0.1)
    model.update(np.r_[0, 0, 0.0, 1.0, 0, 0], _relative(), 0.1)  # last sigma 0.03 rad/s
    c = np.sqrt((3 * 0.04**2 + 0.04**2 - 0.03**2) / 4)
    assert model.change()[0] == pytest.approx(c)
    assert model.bridged_rotation_sigma(0.1) == pytest.approx((0.03 + 2 * c) * 0.1)
    held = [model.predicted()[0]]
    for _ in range(4):
        model.update(np.zeros(6), _relative(Status.UNRESOLVED), 0.1)
        held.append(model.predicted()[0])
        assert model.bridged_rotation_sigma(0.1) == pytest.approx(0.1 * sum(held))


def test_a_second_gated_step_that_agrees_with_the_first_overrules_the_prediction():
    """``degenerate_gate_release: agreeing``, with the chi2 limit above (0.0825 rad/s): a
    degenerate step 0.3 rad/s off the held prediction is bridged; the next one, within the
    limit of that bridged step's own rate, is kept (bridged with ``off``); one beyond it is
    bridged; and a step kept in between leaves nothing to agree with."""
    odometry = PlanodomConfig().odometry
    bridge = odometry.model_copy(update={"rescue_gate_quantile": 0.99, "degenerate_gate": "bridge"})
    agreeing = bridge.model_copy(update={"degenerate_gate_release": "agreeing"})
    limit = np.sqrt(11.345 * 2 * 0.03**2 / 3)
    prediction, T_ref_last = np.zeros(6), np.eye(4)

    def candidate(rate, status=Status.DEGENERATE):
        T = transform_from_rpy_xyz(0, 0, rate * 0.1, 0.0, 0, 0)
        return EpochEstimate([], PlaneSet.from_planes([]), None, _relative(status), T, [])

    def model_after_one_gated(config):
        model = TwistUncertainty(config)
        for _ in range(2):
            model.update(np.zeros(6), _relative(), 0.1)  # sigma (0.03, 0.5), change 0
        first = model.gated(candidate(0.3), 0.1, prediction, T_ref_last, config)
        assert first.relative.inconsistent
        model.update(np.zeros(6), first.relative, 0.1)  # committed as the bridge
        return model

    near, far = candidate(0.3 + limit - 2e-3), candidate(0.3 + limit + 2e-3)
    assert (
        model_after_one_gated(agreeing).gated(near, 0.1, prediction, T_ref_last, agreeing) is near
    )
    off = model_after_one_gated(bridge).gated(near, 0.1, prediction, T_ref_last, bridge)
    assert off.relative.inconsistent
    gated = model_after_one_gated(agreeing).gated(far, 0.1, prediction, T_ref_last, agreeing)
    assert gated.relative.inconsistent
    model = model_after_one_gated(agreeing)
    model.update(np.zeros(6), _relative(Status.DEGENERATE), 0.1)  # a kept step between
    assert model.gated(near, 0.1, prediction, T_ref_last, agreeing).relative.inconsistent


def _gap_end(status: Status, prev: int, curr: int) -> tuple[EpochEstimate, np.ndarray]:
    """A step ending a 3-epoch bridged stretch under a constant true twist: its relative
    pose from epoch ``prev`` is the truth, its last step holds 2 deg of bridged yaw
    taken back; returns it and the true twist (rad/s, m/s)."""
    true = np.r_[0.0, 0.0, np.radians(40.0), 5.0, 0.0, 0.0]
    dt = 0.1
    relative = RelativePose(se3_exp(true * dt * (curr - prev)), None, status, prev=prev, curr=curr)
    step = se3_exp(true * dt) @ transform_from_rpy_xyz(0.0, 0.0, np.radians(2.0), 0.0, 0.0, 0.0)
    return EpochEstimate([], PlaneSet.from_planes([]), None, relative, step, []), true


@pytest.mark.parametrize("status", [Status.OK, Status.DEGENERATE])
def test_a_gap_end_measures_its_rate_over_the_span_with_span(status: Status) -> None:
    est, true = _gap_end(status, 6, 9)
    dt = 0.1
    on = PlanodomConfig().updated({"odometry.gap_end_rate": "span"}).odometry
    ungated = on.model_copy(update={"degenerate_gate": "off"})
    got = TwistUncertainty(on).gated(est, dt, None, np.eye(4), ungated)
    assert got.span_epochs == 3
    np.testing.assert_allclose(got.own_twist(dt), true, atol=1e-9)  # the truth
    # the step's own rate holds the 2 deg taken back: 20 deg/s off in yaw
    step_rate = est.own_twist(dt)
    assert abs(np.degrees(step_rate[2] - true[2]) - 20.0) < 0.5
    # off (default), an unresolved step, or delta > 1: the step's rate as before
    off = PlanodomConfig().odometry.model_copy(update={"degenerate_gate": "off"})
    assert TwistUncertainty(off).gated(est, dt, None, np.eye(4), off).span_epochs == 1
    lost, _ = _gap_end(Status.UNRESOLVED, 6, 9)
    assert TwistUncertainty(on).gated(lost, dt, None, np.eye(4), ungated).span_epochs == 1
    wide = ungated.model_copy(update={"delta": 3})
    assert TwistUncertainty(on).gated(est, dt, None, np.eye(4), wide).span_epochs == 1
    near, _ = _gap_end(status, 8, 9)  # the epoch before: a plain step
    assert TwistUncertainty(on).gated(near, dt, None, np.eye(4), ungated).span_epochs == 1


def test_a_bad_gap_end_rate_is_named_at_load() -> None:
    with pytest.raises(Exception, match="gap_end_rate"):
        PlanodomConfig().updated({"odometry.gap_end_rate": "mean"})
