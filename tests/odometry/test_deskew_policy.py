"""The deskewing policy (:func:`planodom.odometry.deskew.register_deskewed`) on a linear
model of how a deskewing error moves an epoch's estimate."""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig
from planodom.geometry import Plane, se3_exp
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.planes import PlaneSet

DT = 0.1
TRUE = np.array([0.0, 0.0, 0.3, 3.0, 0.2, 0.0])  # rad/s, m/s
PREDICTED = np.array([0.0, 0.0, 0.1, 2.0, 0.0, 0.0])


def _estimate(twist: np.ndarray | None, own: np.ndarray, status: Status) -> EpochEstimate:
    planes = [Plane(np.array([1.0, 0, 0]), -5.0), Plane(np.array([0, 0, 1.0]), 0.0)]
    step = se3_exp(own * DT)
    rel = RelativePose(step, None, status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, step, planes)


def _map_model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
    """Against a map, an epoch deskewed with ``used`` gives the twist ``2 true - used``."""
    used = np.zeros(6) if twist is None else twist
    return _estimate(twist, 2.0 * TRUE - used, Status.OK)


def test_against_a_map_the_mean_of_used_and_own_reaches_the_true_twist():
    config = OdometryConfig()
    best = register_deskewed(
        PREDICTED, DT, _map_model, lambda t: False, config, 2, against_map=True
    )
    assert best.twist is not None
    np.testing.assert_allclose(best.twist, TRUE, atol=1e-12)
    # Taking the own twist as it is swings between 2 true - predicted and predicted.
    plain = register_deskewed(
        PREDICTED, DT, _map_model, lambda t: False, config, 2, against_map=False
    )
    assert plain.twist is not None
    assert np.linalg.norm(plain.twist - TRUE) > 0.5


def test_an_estimate_against_a_refreshed_reference_is_not_kept():
    """Once the reference is extracted again, the first estimate (made against its old
    planes) is dropped even when the new one's status is worse."""

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        if twist is None:
            return _estimate(None, TRUE, Status.OK)
        return _estimate(twist, TRUE, Status.DEGENERATE)

    config = OdometryConfig(deskew_iterations=1)
    refreshed = register_deskewed(None, DT, model, lambda t: True, config, 2)
    assert refreshed.twist is not None and refreshed.relative.status is Status.DEGENERATE
    kept = register_deskewed(None, DT, model, lambda t: False, config, 2)
    assert kept.twist is None and kept.relative.status is Status.OK


def test_the_own_twist_removes_what_the_deskewing_of_both_epochs_put_in():
    """A plane's points are seen at the mean point time tm: deskewed with a twist off by
    e, the epoch looks displaced by -e tm. With the step of that model (the reference
    deskewed with its own twist), the epoch's own twist is the true one, and the policy
    extracts again with it."""
    from planodom.odometry.deskew import twist_offset
    from planodom.scan import Scan

    t = np.linspace(0.0, DT, 11)  # tm = DT / 2
    scan = Scan(np.zeros((11, 3)), t=t)
    used_ref = np.array([0.0, 0.0, 0.25, 2.9, 0.1, 0.0])
    tm = float(np.mean(t))

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        assert twist is not None
        # the step from the reference: true motion, displaced by both deskewing errors
        step_twist = TRUE + (tm / DT) * ((used_ref - TRUE) - (twist - TRUE))
        est = _estimate(twist, step_twist, Status.OK)
        offset = twist_offset(scan, twist, used_ref, DT)
        return EpochEstimate(est.planes, est.plane_set, twist, est.relative, est.step,
                             est.reference_planes, twist_offset=offset)  # fmt: skip

    np.testing.assert_allclose(model(PREDICTED).own_twist(DT), TRUE, atol=1e-9)
    best = register_deskewed(PREDICTED, DT, model, lambda t: False, OdometryConfig(), 2)
    assert best.twist is not None
    np.testing.assert_allclose(best.twist, TRUE, atol=1e-9)
    # against a map with map_twist_offset the same own twist is used as it is (no mean
    # with the twist used, which would stop halfway)
    config = OdometryConfig(map_twist_offset=True, deskew_iterations=1)
    mapped = register_deskewed(PREDICTED, DT, model, lambda t: False, config, 2, against_map=True)
    assert mapped.twist is not None
    np.testing.assert_allclose(mapped.twist, TRUE, atol=1e-9)
    # without a twist (the 2D rig's time windows) nothing is offset
    assert twist_offset(scan, None, used_ref, DT) is None


def test_the_own_twist_is_the_steps_twist_on_every_call():
    """The step's log is computed once per estimate: later calls (another dt, a caller that
    changed an earlier result in place) still give the step's twist over dt."""
    est = _estimate(None, TRUE, Status.OK)  # step = exp(TRUE DT)
    first = est.own_twist(DT)
    np.testing.assert_allclose(first, TRUE, atol=1e-12)
    first += 1.0
    np.testing.assert_allclose(est.own_twist(DT), TRUE, atol=1e-12)
    np.testing.assert_allclose(est.own_twist(2 * DT), TRUE / 2, atol=1e-12)


def test_a_suspect_epoch_tries_the_trend_twist_before_none():
    """Deskewed with a lagging prediction or without deskewing the epoch is lost; with the
    trend's twist (close to the truth) it resolves, and that extraction is kept."""
    tried: list[np.ndarray | None] = []

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        tried.append(None if twist is None else twist.copy())
        close = twist is not None and np.linalg.norm(twist - TRUE) < 0.2
        return _estimate(twist, TRUE, Status.OK if close else Status.UNRESOLVED)

    trend = TRUE + 0.05
    config = OdometryConfig(deskew_iterations=0)
    best = register_deskewed(PREDICTED, DT, model, lambda t: False, config, 2, trend=trend)
    assert best.relative.status is Status.OK and best.twist is not None
    np.testing.assert_array_equal(best.twist, trend)
    assert tried[1] is not None and np.array_equal(tried[1], trend) and tried[2] is None
    # an epoch that resolves with the prediction never tries it
    tried.clear()
    ok = register_deskewed(TRUE, DT, model, lambda t: False, config, 2, trend=trend)
    assert ok.relative.status is Status.OK and len(tried) == 1


def test_a_lost_trend_is_tried_last_and_only_for_a_lost_epoch():
    """The pairwise pipelines' trend is tried after the prediction and none, and only while
    the epoch is still unresolved; a degenerate epoch (its rate measured) does not try it."""
    tried: list[np.ndarray | None] = []
    trend = TRUE + 0.05

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        tried.append(None if twist is None else twist.copy())
        close = twist is not None and np.linalg.norm(twist - TRUE) < 0.2
        return _estimate(twist, TRUE, Status.OK if close else status_far)

    config = OdometryConfig(deskew_iterations=0)
    status_far = Status.UNRESOLVED
    best = register_deskewed(PREDICTED, DT, model, lambda t: False, config, 2, lost_trend=trend)
    assert best.relative.status is Status.OK
    assert tried[1] is None and np.array_equal(tried[2], trend) and len(tried) == 3
    tried.clear()
    status_far = Status.DEGENERATE
    best = register_deskewed(PREDICTED, DT, model, lambda t: False, config, 2, lost_trend=trend)
    assert best.relative.status is Status.DEGENERATE and len(tried) == 2


def test_an_unmeasured_vertical_takes_no_deskewing_offset():
    """Walls alone do not measure z: the step's z is the prediction's (no vertical motion
    here), and the vertical velocities of the twists the two epochs were deskewed with
    (which the walls do not fix either) must not enter the own twist, else it walks from
    epoch to epoch (HEIGHT: 2D-rig world 142's corridors, -1.3 m an epoch). Measured, z
    takes the offset as x and y do; without ``z_offset_measured_only`` it always does."""
    from planodom.odometry.kept_epoch import KeptEpoch
    from planodom.odometry.vertical_offset import step_twist_offset
    from planodom.scan import Scan

    t = np.linspace(0.0, DT, 11)  # tm = DT / 2
    used = np.array([0.0, 0.0, 0.12, 2.4, 0.1, 13.0])  # deskewed with vz 13 m/s
    used_ref = np.array([0.0, 0.0, 0.1, 2.0, 0.0, -6.0])
    expected = 0.5 * (used - used_ref)  # (tm / dt) (u - u_r)
    planes = [Plane(np.array([1.0, 0, 0]), -5.0), Plane(np.array([0, 1.0, 0]), -2.0)]
    scan = Scan(np.zeros((11, 3)), t=t)
    epoch = KeptEpoch(1, planes, PlaneSet.from_planes(planes), scan, used)
    step = se3_exp(PREDICTED * DT)  # z = 0: the prediction's
    on, off = OdometryConfig(z_offset_measured_only=True), OdometryConfig()
    for z_observed in (False, True):
        rel = RelativePose(step, None, Status.OK, z_observed=z_observed)
        for config in (on, off):
            offset = step_twist_offset(epoch, used_ref, DT, rel, config)
            assert offset is not None
            est = EpochEstimate(planes, PlaneSet.from_planes(planes), used, rel, step,
                                planes, twist_offset=offset)  # fmt: skip
            own = est.own_twist(DT)
            np.testing.assert_allclose(own[:5], PREDICTED[:5] + expected[:5], atol=1e-9)
            vz = expected[5] if z_observed or config is off else 0.0
            np.testing.assert_allclose(own[5], vz, atol=1e-9)
