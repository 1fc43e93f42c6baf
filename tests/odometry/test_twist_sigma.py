"""The per-epoch twist sigma (:mod:`planodom.odometry.twist_sigma`)."""

from __future__ import annotations

import numpy as np
from planes_factory import observe, world_planes

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_log, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry, RelativePose, Status
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.twist_sigma import TwistUncertainty, step_sigma
from planodom.planes import PlaneSet
from planodom.scan import Scan


def _relative(status=Status.OK, sigma_z=np.inf) -> RelativePose:
    cov = np.diag([1e-6, 4e-6, 4e-6, 9e-4, 16e-4])
    return RelativePose(np.eye(4), cov, status, sigma_z=sigma_z)


def test_step_sigma_is_the_step_error_over_dt():
    s = step_sigma(_relative(), 0.1)
    np.testing.assert_allclose(s, [3e-3 / 0.1, 5e-2 / 0.1])  # sqrt(9e-6), sqrt(25e-4)
    s = step_sigma(_relative(sigma_z=0.0), 0.1)  # z measured exactly: no change
    np.testing.assert_allclose(s, [0.03, 0.5])
    s = step_sigma(_relative(Status.DEGENERATE), 0.1)
    assert np.isclose(s[0], 0.03) and s[1] == np.inf
    assert np.all(step_sigma(_relative(Status.UNRESOLVED), 0.1) == np.inf)


def test_change_per_epoch_is_the_rms_of_successive_twist_differences():
    cfg = PlanodomConfig().odometry
    model = TwistUncertainty(cfg)
    fallback = [np.radians(cfg.deskew_rate_tolerance_deg_s), cfg.deskew_speed_tolerance_mps]
    np.testing.assert_allclose(model.change(), fallback)  # nothing measured yet
    for v in ([0, 0, 0.1, 1.0, 0, 0], [0, 0, 0.1, 1.3, 0, 0], [0, 0, 0.14, 1.3, 0.4, 0]):
        model.update(np.array(v, float), _relative(), 0.1)
    # differences: (0, 0.3) then (0.04, 0.4) -> rms 0.02 * sqrt(2), 0.25 * sqrt(2)
    np.testing.assert_allclose(model.change(), [np.sqrt(0.0008), np.sqrt(0.125)])
    change = np.array([np.sqrt(0.0008), np.sqrt(0.125)])
    # after the step error, two changes; each unresolved epoch since adds one
    np.testing.assert_allclose(model.predicted(), [0.03, 0.5] + 2 * change)
    model.update(np.zeros(6), _relative(Status.UNRESOLVED), 0.1)
    model.update(np.zeros(6), _relative(Status.UNRESOLVED), 0.1)
    np.testing.assert_allclose(model.predicted(), [0.03, 0.5] + 4 * change)
    # the twist across the bridge is no measured change
    model.update(np.array([0, 0, 0.14, 1.3, 0.4, 0]) + 5.0, _relative(), 0.1)
    np.testing.assert_allclose(model.change(), change)


def test_a_refined_twist_is_given_its_step_error_and_what_was_left_of_the_difference():
    model = TwistUncertainty(PlanodomConfig().odometry)
    for v in ([0, 0, 0.1, 1.0, 0, 0], [0, 0, 0.1, 1.0, 0, 0]):
        model.update(np.array(v, float), _relative(), 0.1)  # change 0
    T = transform_from_rpy_xyz(0, 0, 0.01, 0.2, 0, 0)
    source = EpochEstimate([], PlaneSet.from_planes([]), None, _relative(), T, [])
    own = se3_log(T) / 0.1
    np.testing.assert_allclose(model.refined(source, 0.1, own), [0.03, 0.5])
    kept = own + np.r_[0, 0, 0, 0.2, 0, 0]  # a velocity within the tolerance kept
    np.testing.assert_allclose(model.refined(source, 0.1, kept), [0.03, 0.7])


def test_the_odometry_passes_each_twist_with_its_own_sigma():
    """A wrong prediction is extracted with a larger sigma than the epoch's own twist
    refined after it, whose sigma covers its true error; ``twist_sigma: fixed`` leaves the
    extraction config as it is."""
    rng = np.random.default_rng(4)
    world = world_planes(rng, 10)
    poses = [transform_from_rpy_xyz(0, 0, 0.03 * k, 0.1 * k, 0.002 * k**2, 0) for k in range(6)]
    planes = [observe(world, T) for T in poses]
    for mode in ("always", "fixed"):
        calls = []

        def extractor(scan, cfg, twist=None):
            sig = (cfg.twist_rate_sigma_deg_s, cfg.twist_speed_sigma_mps)
            calls.append((int(scan.points[0, 0]), twist, sig))
            return planes[int(scan.points[0, 0])]

        cfg = PlanodomConfig.from_dict({"odometry": {"twist_sigma": mode, "pipeline": "wocsc"}})
        odo = PlaneOdometry(cfg, extractor=extractor)
        for k in range(6):
            # times centred on the epoch time: the planes do not move with the twist
            odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[-0.05, 0.05]), 0.1 * k)
            if k == 3:
                odo.twist = odo.twist + np.r_[0, 0, 0.05, 1.0, 0, 0]  # a wrong prediction
        if mode == "fixed":
            assert all(sig == (0.0, 0.0) for _, _, sig in calls)
            continue
        assert all(sig == (0.0, 0.0) for _, tw, sig in calls if tw is None)
        last = [c for c in calls if c[0] == 4]
        assert len(last) == 2  # the prediction, then the epoch's own twist
        predicted, refined = last[0][2], last[1][2]
        assert refined[0] < predicted[0] and refined[1] < predicted[1]
        true = se3_log(invert_transform(poses[3]) @ poses[4]) / 0.1
        err = last[1][1] - true
        assert np.degrees(np.linalg.norm(err[:3])) <= refined[0]
        assert np.linalg.norm(err[3:]) <= refined[1]
