"""An epoch deskewed with the twist its own planes give (odometry.deskew_twist: coplanar)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction import extract_planes
from planodom.geometry import invert_transform, se3_exp, se3_log
from planodom.odometry import PlaneOdometry
from planodom.odometry.coplanar import (
    PRIOR_SIGMA_FLOOR,
    coplanar_by,
    coplanar_extraction,
    prior_information,
)
from tests.extraction.synth_scans import Rect, default_scene, plane_errors, planes_in_base, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])  # rad/s, m/s: a brisk turn
#: a prediction's error: 2 deg/s of yaw rate, 0.15 m/s (twice that, only the ground is
#: extracted, and it observes no yaw rate nor horizontal velocity: they keep the prior)
OFF = np.array([np.radians(0.5), np.radians(-0.5), np.radians(2.0), 0.15, -0.1, 0.025])
#: every pass extracts again (exact at sigma = 0; "moved" stops within the
#: points' noise: its own tests below)
COPLANAR = PlanodomConfig().updated(
    {
        "odometry.deskew_twist": "coplanar",
        "odometry.coplanar_passes": 2,
        "odometry.coplanar_reextract": "always",
    }
)


def test_prior_information_is_a_third_of_the_vector_variance_per_axis():
    info = prior_information((0.02, 0.5))
    np.testing.assert_allclose(np.diag(info), [3 / 0.02**2] * 3 + [3 / 0.5**2] * 3)
    assert np.count_nonzero(info - np.diag(np.diag(info))) == 0
    np.testing.assert_array_equal(prior_information(None), np.zeros((6, 6)))
    unknown = prior_information((0.02, float("inf")))
    np.testing.assert_array_equal(np.diag(unknown)[3:], 0.0)
    floored = prior_information((0.0, 0.0))
    np.testing.assert_allclose(
        np.diag(floored), [3 / PRIOR_SIGMA_FLOOR[0] ** 2] * 3 + [3 / PRIOR_SIGMA_FLOOR[1] ** 2] * 3
    )


def test_a_rig_epoch_extracted_with_a_wrong_twist_gets_the_true_one():
    # A constant twist (the model is exact): from a prediction 2 deg/s and 0.15 m/s off,
    # the fitted twist is the truth and the planes the true walls (ground truth). No
    # prior information (a sigma of None): with one, the estimate is the MAP, pulled
    # towards the prediction by the prior's weight against the points' 6 mm.
    scene = default_scene()
    scan = scan_rig(scene, twist=XI)
    got = coplanar_extraction(scan, COPLANAR, XI + OFF, None)
    assert got.fit is not None
    np.testing.assert_allclose(got.twist, XI, atol=1e-7)
    assert len(got.planes) >= 3
    ang, off = plane_errors(got.planes, planes_in_base(scene))
    assert ang < 1e-7 and off < 1e-7


def test_with_noise_the_fit_is_closer_than_the_prediction_and_within_its_sigma():
    scene = default_scene()
    scan = scan_rig(scene, twist=XI, sigma=0.006, seed=3)
    got = coplanar_extraction(scan, COPLANAR, XI + OFF, (np.radians(5.0), 0.5))
    assert got.fit is not None
    e = got.twist - XI
    assert np.linalg.norm(e) < 0.2 * np.linalg.norm(OFF)
    # the estimate against its own covariance: chi-square 6 at 99.9 % is 22.5
    assert float(e @ got.fit.information @ e) < 22.5


def test_only_the_default_extractor_or_a_timed_wrapper_of_it_is_fit():
    scan = scan_rig(default_scene(), twist=XI)
    ecfg = COPLANAR.extraction
    args = (scan, COPLANAR, ecfg, XI + OFF, (0.1, 0.5), None)
    assert coplanar_by(lambda *a, **k: [], *args) is None
    assert coplanar_by(None, *args) is not None
    assert coplanar_by(extract_planes, *args) is not None

    class Timed:
        extractor = None
        calls = 0

        def timed(self, function, *a):
            Timed.calls += 1
            return function(*a)

    got = coplanar_by(Timed(), *args)
    assert got is not None and Timed.calls == 1


def _run(mode: str) -> tuple[float, np.ndarray]:
    """Three epochs of one constant twist (the scene seen from the poses exp(0.1 k xi)):
    the largest pose error (norm of the tangent error against the truth) and the twist
    the last epoch was deskewed with."""
    odo = PlaneOdometry(PlanodomConfig().updated({"odometry.deskew_twist": mode}))
    scene = default_scene()
    worst = 0.0
    for k in range(3):
        pose = odo.register_epoch(scan_rig(_moved(scene, XI, 0.1 * k), twist=XI), time=0.1 * k)
        err = invert_transform(se3_exp(0.1 * k * XI)) @ pose
        worst = max(worst, float(np.linalg.norm(se3_log(err))))
    used = odo._history[-1].twist
    assert used is not None
    return worst, used


def test_the_odometry_on_a_constant_twist_follows_the_truth():
    # Deskewed with the fitted twist (the MAP with the prediction's prior: within 5e-3 of
    # the truth), the poses are closer to the truth than with the predicted twist.
    predicted, _ = _run("predicted")
    coplanar, used = _run("coplanar")
    np.testing.assert_allclose(used, XI, atol=5e-3)
    assert coplanar < min(0.5 * predicted, 5e-4)


def _moved(scene, xi, t):
    """The scene in the base frame at time ``t`` of the motion ``exp(t xi)``."""
    T = invert_transform(se3_exp(t * xi))
    R, p = T[:3, :3], T[:3, 3]
    return [Rect(R @ r.center + p, R @ r.normal, R @ r.u, r.half_u, r.half_v) for r in scene]


def test_prior_information_scale_multiplies_the_sigmas():
    base = np.diag(prior_information((0.02, 0.5)))
    np.testing.assert_allclose(np.diag(prior_information((0.02, 0.5), 3.0)), base / 9.0)
    floored = np.diag(prior_information((0.0, 0.0), 2.0))
    np.testing.assert_allclose(floored[:3], 3 / (2 * PRIOR_SIGMA_FLOOR[0]) ** 2)


def test_tilt_axes_keep_the_yaw_rate_and_horizontal_velocity_of_the_prior():
    # The rig's scan at sigma = 0 from a prediction OFF away: with coplanar_axes "tilt" the
    # yaw rate and horizontal velocity stay the prediction's, the other three are fit
    # towards the truth XI (closer than the prediction); with "all" all six move.
    scan = scan_rig(default_scene(), twist=XI)
    sigma = (np.radians(5.0), 0.5)
    tilt = COPLANAR.updated({"odometry.coplanar_axes": "tilt"})
    got = coplanar_extraction(scan, tilt, XI + OFF, sigma).twist
    np.testing.assert_allclose(got[[2, 3, 4]], (XI + OFF)[[2, 3, 4]], atol=1e-6)
    assert np.all(np.abs(got - XI)[[0, 1, 5]] < np.abs(OFF[[0, 1, 5]]))
    free = coplanar_extraction(scan, COPLANAR, XI + OFF, sigma).twist
    assert np.all(np.abs(free - XI)[[2, 3, 4]] < 0.5 * np.abs(OFF[[2, 3, 4]]))


def test_without_a_twist_the_first_extraction_is_not_deskewed_and_the_prior_is_zero():
    # The first epoch (no motion known): extracted in time windows, then fit from a zero
    # twist with a weak prior (30 deg/s, 10 m/s). The roll and pitch rates are found
    # (ground truth); the brisk turn's yaw rate (34 deg/s) is not, from zero.
    scene = default_scene()
    scan = scan_rig(scene, twist=XI, sigma=0.006, seed=3)
    got = coplanar_extraction(scan, COPLANAR, None, (np.radians(30.0), 10.0))
    assert got.fit is not None and got.twist is not None
    np.testing.assert_allclose(got.twist[:2], XI[:2], atol=0.005)
    assert coplanar_extraction(scan_rig(scene), COPLANAR, None, None).twist is not None


def test_moved_extracts_again_only_when_the_fit_moves_the_points(monkeypatch):
    # odometry.coplanar_reextract: moved. From a wrong prediction the epoch is extracted
    # again and gets the truth (as "always"); from the true twist (sigma = 0: the fit
    # stays there) the first extraction is kept: one extraction, not three.
    import planodom.odometry.coplanar as coplanar

    calls = []
    real = coplanar.extract
    monkeypatch.setattr(coplanar, "extract", lambda *a: calls.append(1) or real(*a))
    moved = COPLANAR.updated({"odometry.coplanar_reextract": "moved"})
    scene = default_scene()
    scan = scan_rig(scene, twist=XI)
    got = coplanar_extraction(scan, moved, XI + OFF, None)
    # kept once the truth (the last fit, to 1e-7) moves the inliers by less than their
    # noise (the 1 mm floor at sigma = 0), summed: within that of the truth
    assert got.fit is not None and got.twist is not None
    np.testing.assert_allclose(got.fit.twist, XI, atol=1e-7)
    e = got.twist - XI
    assert 0 < float(e @ got.fit.displacement_information @ e) <= 1.0 and len(calls) >= 2
    ang, off = plane_errors(got.planes, planes_in_base(scene))
    assert ang < np.radians(0.01) and off < 1e-3
    calls.clear()
    kept = coplanar_extraction(scan_rig(scene, twist=XI), moved, XI, None)
    assert len(calls) == 1
    np.testing.assert_array_equal(kept.twist, XI)
    ang, off = plane_errors(kept.planes, planes_in_base(scene))
    assert ang < 1e-7 and off < 1e-7


def test_reuse_starts_an_epoch_extracted_again_from_its_last_planes(monkeypatch):
    # odometry.coplanar_reuse: the same scan again (the deskewing policy's refined twist,
    # here a wrong one: the planes observe every direction, so the fit leaves it) needs
    # no extraction when the fit on the last planes stays at their twist; another scan
    # (a copy of its points), or another extraction config, is extracted.
    import planodom.odometry.coplanar as coplanar

    calls = []
    real = coplanar.extract
    monkeypatch.setattr(coplanar, "extract", lambda *a: calls.append(1) or real(*a))
    reuse = COPLANAR.updated(
        {"odometry.coplanar_reextract": "moved", "odometry.coplanar_reuse": True}
    )
    scene = default_scene()
    scan = scan_rig(scene, twist=XI)
    first = coplanar_extraction(scan, reuse, XI, None)
    assert len(calls) == 1
    again = coplanar_extraction(scan, reuse, XI + 0.1 * OFF, None)
    assert len(calls) == 1 and again.planes is first.planes
    np.testing.assert_array_equal(again.twist, XI)
    copy = replace(scan, points=scan.points.copy())
    coplanar_extraction(copy, reuse, XI, None)
    assert len(calls) == 2
    wider = reuse.extraction.model_copy(update={"min_plane_points": 25})
    coplanar_extraction(copy, reuse, XI, None, extraction=wider)
    assert len(calls) == 3
