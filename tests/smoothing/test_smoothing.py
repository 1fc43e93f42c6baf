"""Smoothing: landmark tracks, noiseless recovery, consistency (NEES), flips, windows."""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np
import pytest
from pose_checks import pose_error
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError, GeometryError
from planodom.geometry import Plane, make_transform
from planodom.odometry import Status
from planodom.smoothing import LandmarkTracker, WindowedSmoother, smooth_batch, smooth_windowed
from planodom.smoothing.noise import rpy_to_rotation_vector
from planodom.smoothing.run import rotation_determined
from planodom.smoothing.synthetic import SyntheticSequence, make_sequence

GAUSSIAN = SmoothingConfig(robust_kernel="none")
NOISE = dict(sigma_rotation=1e-3, sigma_translation=0.01, sigma_normal=0.005, sigma_offset=0.01)


def max_pose_errors(estimate: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Largest rotation (rad) and translation (m) error over a trajectory (E, 4, 4)."""
    errors = np.array([pose_error(a, b) for a, b in zip(estimate, truth, strict=True)])
    return float(errors[:, 0].max()), float(errors[:, 1].max())


# --------------------------------------------------------------------------- landmarks


def test_tracker_chains_and_needs_two_epochs() -> None:
    tracker = LandmarkTracker(min_epochs=2)
    roots0 = tracker.add_epoch(0, 3, {})
    assert all(tracker.landmark(r) is None for r in roots0)  # seen once: no landmark
    roots1 = tracker.add_epoch(1, 2, {1: np.array([[0, 1], [2, 0]])})
    roots2 = tracker.add_epoch(2, 1, {1: np.array([[1, 0]]), 2: np.array([[0, 0]])})
    assert tracker.find(roots2[0]) == tracker.find(roots1[1]) == tracker.find(roots0[0])
    assert tracker.take_pending(tracker.find(roots2[0])) == [(0, 0), (1, 1), (2, 0)]
    assert tracker.take_pending(tracker.find(roots2[0])) == []
    ids = {tracker.landmark(tracker.find(r)) for r in (roots0[0], roots0[2])}
    assert ids == {0, 1}
    assert tracker.landmark(tracker.find(roots0[1])) is None  # plane 1 of epoch 0: once
    assert tracker.conflicts == 0


def test_tracker_refuses_two_planes_of_one_epoch_in_a_track() -> None:
    tracker = LandmarkTracker()
    tracker.add_epoch(0, 2, {})
    # Epoch 1's plane 0 matches both planes of epoch 0 (delta 1) -> second join refused.
    roots = tracker.add_epoch(1, 1, {1: np.array([[0, 0], [1, 0]])})
    assert tracker.conflicts == 1
    assert [e for e, _ in tracker.take_pending(roots[0])] == [0, 1]


# --------------------------------------------------------------------------- batch / windowed


@pytest.mark.parametrize("plane_factor", ["anchored", "global"])
def test_noiseless_graph_optimises_to_the_truth(plane_factor: str) -> None:
    seq = make_sequence(30, seed=2, vertical_sigma=0.0)
    config = replace_config(GAUSSIAN, plane_factor=plane_factor, batch_initial="odometry")
    result = smooth_batch(seq.planes, seq.relatives, config)
    rot, trans = max_pose_errors(result.poses, seq.poses)
    assert rot < 1e-9 and trans < 1e-8
    # The initial guess (odometry chained, z unobserved) was not the truth.
    assert max_pose_errors(result.initial_poses, seq.poses)[1] > 1e-3
    assert result.stats.flipped == 0 and not result.stats.unresolved_epochs
    for j, plane in result.landmarks.items():
        assert min(np.abs(plane - seq.walls).sum(axis=1)) < 1e-8, j


def replace_config(config: SmoothingConfig, **changes: object) -> SmoothingConfig:
    return SmoothingConfig.model_validate({**config.model_dump(), **changes})


def test_far_from_the_origin_anchored_landmarks_recover_the_truth() -> None:
    origin = np.array([3000.0, -2000.0, 50.0])
    seq = make_sequence(30, seed=3, vertical_sigma=0.0, origin=origin)
    result = smooth_batch(seq.planes, seq.relatives, GAUSSIAN, T_world_first=seq.poses[0])
    assert result.stats.global_landmarks == 0  # auto mode: all anchored out here
    rot, trans = max_pose_errors(result.poses, seq.poses)
    assert rot < 1e-9 and trans < 1e-7


@pytest.mark.parametrize("plane_factor", ["anchored", "global"])
def test_noisy_batch_is_consistent_with_its_covariance(plane_factor: str) -> None:
    """NEES of the last pose over independent seeds against chi-square bounds (6 DoF).

    The synthetic plane noise has normal-offset correlations: with the anchored factor
    (full covariance) a wrong sign of those correlations pushes the sum to ~200.
    """
    seeds = range(24)
    nees = []
    # The synthetic epochs are instants with white noise about a constant twist: no
    # deskewing error to model (the deskew term would count the noise of the measured
    # motion changes once more, smoothing.deskew_noise).
    config = replace_config(GAUSSIAN, plane_factor=plane_factor, deskew_noise="none")
    for seed in seeds:
        seq = make_sequence(25, seed=seed, **NOISE)
        result = smooth_batch(seq.planes, seq.relatives, config)
        k = len(seq.poses) - 1
        xi = gtsam.Pose3(result.poses[k]).localCoordinates(gtsam.Pose3(seq.poses[k]))
        nees.append(xi @ np.linalg.solve(result.covariances[k], xi))
    dof = 6 * len(seeds)
    lo, hi = chi2.ppf([0.005, 0.995], dof)
    assert lo < np.sum(nees) < hi, (np.sum(nees), lo, hi)


def test_smoothing_beats_chained_odometry_under_noise() -> None:
    seq = make_sequence(60, seed=5, **NOISE)
    config = replace_config(GAUSSIAN, batch_initial="odometry")  # against the chained odometry
    result = smooth_batch(seq.planes, seq.relatives, config)
    final_initial = pose_error(result.initial_poses[-1], seq.poses[-1])[1]
    final_smoothed = pose_error(result.poses[-1], seq.poses[-1])[1]
    assert final_smoothed < 0.5 * final_initial


def test_windowed_agrees_with_batch_when_the_window_covers_the_sequence() -> None:
    seq = make_sequence(20, seed=4, **NOISE)
    # Without the deskew noise: batch estimates it from the whole run, the fixed-lag
    # smoother from the epochs so far (smoothing.deskew_noise).
    config = replace_config(GAUSSIAN, window=25, relinearize_threshold=1e-4, deskew_noise="none")
    batch = smooth_batch(seq.planes, seq.relatives, config)
    windowed = smooth_windowed(seq.planes, seq.relatives, config)
    rot, trans = max_pose_errors(windowed.poses, batch.poses)
    assert rot < 1e-5 and trans < 1e-4
    assert windowed.stats.plane_factors == batch.stats.plane_factors
    for backend_result in (
        smooth_windowed(
            seq.planes, seq.relatives, replace_config(config, windowed_backend="batch")
        ),
    ):
        assert max_pose_errors(backend_result.poses, batch.poses)[1] < 1e-4


@pytest.mark.parametrize("seed", [4, 5, 6])
def test_plane_relinearisation_threshold_takes_the_window_to_the_batch_minimum(seed: int) -> None:
    # Poses at the default 0.01, the plane landmarks' own threshold far below it: the
    # window covering the sequence reaches the batch's minimum (poses < 0.1 mm apart);
    # with the planes at 0.01 too it stops 0.19-0.51 mm short (seeds 4-6).
    seq = make_sequence(20, seed=seed, **NOISE)
    config = replace_config(GAUSSIAN, window=25, deskew_noise="none")
    batch = smooth_batch(seq.planes, seq.relatives, config)
    planes = replace_config(config, relinearize_threshold_planes=1e-6)
    assert (
        max_pose_errors(smooth_windowed(seq.planes, seq.relatives, planes).poses, batch.poses)[1]
        < 1e-4
    )
    default = smooth_windowed(seq.planes, seq.relatives, config)
    assert max_pose_errors(default.poses, batch.poses)[1] > 1.5e-4


def test_marginalised_separators_keep_their_linearisation_point() -> None:
    """gtsam's fixed-lag smoother holds every variable of a marginal's separator at its
    linearisation point (iSAM2's fixed variables: first-estimate Jacobians) until it
    leaves: a plane landmark there is not relinearised, whatever its own threshold, though
    its estimate moves (why ``relinearize_threshold_planes`` reaches only the landmarks no
    marginal holds yet; docs/RESULTS.md, FEJLAG)."""
    seq = make_sequence(30, seed=6, **NOISE)
    config = replace_config(
        GAUSSIAN, window=5, delta_max=3, deskew_noise="none", relinearize_threshold_planes=1e-12
    )
    smoother = WindowedSmoother(config)
    by_curr: dict[int, list] = {}
    for rel in seq.relatives:
        by_curr.setdefault(rel.curr, []).append(rel)
    held: dict[int, np.ndarray] = {}  # plane key -> its linearisation point when first held
    checked = moved = 0
    for k, planes in enumerate(seq.planes):
        smoother.add_epoch(planes, by_curr.get(k, []))
        isam = smoother.smoother.getISAM2()  # type: ignore[attr-defined]
        point, estimate = isam.getLinearizationPoint(), isam.calculateEstimate()
        fixed = {key for key in isam.getFixedVariables() if gtsam.Symbol(key).chr() == ord("l")}
        for key in fixed:
            now = point.atOrientedPlane3(key).planeCoefficients()
            if key in held:
                np.testing.assert_array_equal(now, held[key])
                checked += 1
                step = point.atOrientedPlane3(key).localCoordinates(estimate.atOrientedPlane3(key))
                moved += bool(np.max(np.abs(step)) > 1e-9)
            else:
                held[key] = now
    assert checked > 20 and moved > 10  # held while their estimates moved


def test_short_window_runs_online_and_stays_close() -> None:
    seq = make_sequence(50, seed=6, **NOISE)
    config = replace_config(GAUSSIAN, window=6, delta_max=3)
    smoother = WindowedSmoother(config)
    by_curr: dict[int, list] = {}
    for rel in seq.relatives:
        by_curr.setdefault(rel.curr, []).append(rel)
    for k, planes in enumerate(seq.planes):
        T = smoother.add_epoch(planes, by_curr.get(k, []))
        assert pose_error(T, seq.poses[k])[1] < 0.5
        poses_kept = [
            key for key in smoother.smoother.timestamps() if gtsam.Symbol(key).chr() == ord("x")
        ]
        assert len(poses_kept) == min(k + 1, config.window)
    windowed = smoother.result()
    assert windowed.online_poses is not None and len(windowed.poses) == 50
    batch = smooth_batch(seq.planes, seq.relatives, config)
    # Loose: a 6-epoch window drifts more than the batch, but not wildly.
    assert max_pose_errors(windowed.poses, seq.poses)[1] < 10 * max(
        max_pose_errors(batch.poses, seq.poses)[1], 0.05
    )


# --------------------------------------------------------------------------- guards


def _with_flipped_observation(seq: SyntheticSequence, epoch: int, index: int) -> list[list[Plane]]:
    planes = [list(p) for p in seq.planes]
    planes[epoch][index] = planes[epoch][index].flipped()
    return planes


@pytest.mark.parametrize("policy", ["flip", "reject"])
def test_flipped_normal_is_caught(policy: str) -> None:
    seq = make_sequence(20, seed=7, vertical_sigma=0.0)
    planes = _with_flipped_observation(seq, 10, 2)
    config = replace_config(GAUSSIAN, flipped_normals=policy)
    result = smooth_batch(planes, seq.relatives, config)
    if policy == "flip":
        assert result.stats.flipped == 1 and result.stats.rejected_flips == 0
    else:
        assert result.stats.rejected_flips == 1 and result.stats.flipped == 0
    rot, trans = max_pose_errors(result.poses, seq.poses)
    assert rot < 1e-9 and trans < 1e-8
    # Without the guard the flipped plane would pull the pose along its normal.
    clean = smooth_batch(seq.planes, seq.relatives, config)
    assert clean.stats.plane_factors == result.stats.plane_factors + (policy == "reject")


def test_plane_seen_once_stays_out_of_the_graph() -> None:
    seq = make_sequence(12, seed=8, vertical_sigma=0.0)
    planes = [list(p) for p in seq.planes]
    planes[5].append(Plane(np.array([0.0, 1.0, 0.0]), 7.0, confidence=0.5))  # no association
    builder_stats = smooth_batch(planes, seq.relatives, GAUSSIAN).stats
    reference = smooth_batch(seq.planes, seq.relatives, GAUSSIAN).stats
    assert builder_stats.plane_factors == reference.plane_factors
    assert (
        builder_stats.anchored_landmarks + builder_stats.global_landmarks
        == reference.anchored_landmarks + reference.global_landmarks
    )
    # Every landmark's track has at least two observations in the graph.
    seq_tracks: dict[int, set[int]] = {}
    for k, ps in enumerate(seq.planes):
        for p in ps:
            seq_tracks.setdefault(p.truth_id, set()).add(k)
    assert reference.plane_factors == sum(len(v) for v in seq_tracks.values() if len(v) >= 2)


def test_unresolved_epoch_gets_a_fallback_and_planes_bridge_it() -> None:
    seq = make_sequence(20, seed=9, vertical_sigma=0.0)
    relatives = [replace(r, status=Status.UNRESOLVED) if r.curr == 10 else r for r in seq.relatives]
    # The synthetic planes carry no deskewing error: without the term (a deskewed frame
    # would let the fallback factor pull the pose off its planes by its sigmas).
    result = smooth_batch(seq.planes, relatives, replace_config(GAUSSIAN, deskew_noise="none"))
    assert result.stats.unresolved_epochs == [10] and result.stats.fallback == 1
    rot, trans = max_pose_errors(result.poses, seq.poses)
    assert rot < 1e-6 and trans < 1e-5


def test_robust_kernel_limits_an_outlier_relative_pose() -> None:
    seq = make_sequence(30, seed=10, **NOISE)
    bad = make_transform(np.eye(3), [2.0, -1.5, 0.0])
    relatives = [
        replace(r, T_prev_curr=r.T_prev_curr @ bad) if (r.prev, r.curr) == (14, 15) else r
        for r in seq.relatives
    ]
    gaussian = smooth_batch(seq.planes, relatives, GAUSSIAN)
    huber = smooth_batch(seq.planes, relatives, replace_config(GAUSSIAN, robust_kernel="huber"))
    cauchy = smooth_batch(seq.planes, relatives, replace_config(GAUSSIAN, robust_kernel="cauchy"))
    err = {
        name: max_pose_errors(r.poses, seq.poses)[1]
        for name, r in (("gaussian", gaussian), ("huber", huber), ("cauchy", cauchy))
    }
    assert err["huber"] < err["gaussian"] and err["cauchy"] < err["gaussian"], err


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("robust_kernel", "tukey"),
        ("windowed_backend", "isam"),
        ("plane_factor", "local"),
        ("between_factors", "some"),
        ("flipped_normals", "keep"),
        ("gate_normal_deg", float("nan")),
        ("prior_sigma", 0.0),
        ("vertical_sigma_m", float("inf")),
        ("covariance_inlier_quantile", 1.5),
        ("min_landmark_epochs", 1),
        ("relative_error_tol", 1.0),
    ],
)
def test_wrong_values_fail_at_load_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ConfigError, match=f"smoothing.{field}") as info:
        PlanodomConfig.from_dict({"smoothing": {field: value}})
    assert "\n" not in str(info.value)


def test_config_validation() -> None:
    with pytest.raises(ConfigError, match="smoothing.window"):
        PlanodomConfig.from_dict({"smoothing": {"window": 3, "delta_max": 3}})
    with pytest.raises(ConfigError, match="smoothing.plane_factor"):
        PlanodomConfig.from_dict({"smoothing": {"plane_factor": "global"}})
    with pytest.raises(ConfigError, match="smoothing.window"):
        PlanodomConfig().updated({"smoothing.window": 1})
    assert SmoothingConfig(plane_factor="global", robust_planes=False).plane_factor == "global"
    assert PlanodomConfig.from_dict({"smoothing": {"delta_max": 2}}).smoothing.delta_max == 2


def test_rpy_covariance_maps_to_the_rotation_error_tangent() -> None:
    rng = np.random.default_rng(11)
    for _ in range(5):
        rpy = rng.uniform(-0.6, 0.6, 3)
        R = Rotation.from_euler("ZYX", rpy[::-1]).as_matrix()
        J = rpy_to_rotation_vector(rpy)
        d = rng.normal(scale=1e-6, size=3)
        R2 = Rotation.from_euler("ZYX", (rpy + d)[::-1]).as_matrix()
        e = gtsam.Rot3.Logmap(gtsam.Rot3(R.T @ R2))
        np.testing.assert_allclose(e, J @ d, atol=1e-11)


def test_wrong_association_is_gated() -> None:
    seq = make_sequence(15, seed=12, vertical_sigma=0.0)
    planes = [list(p) for p in seq.planes]
    # Epoch 8's plane 1 replaced by a wall turned by 40 degrees: still "associated".
    wrong = planes[8][1]
    turned = Rotation.from_euler("z", 40, degrees=True).as_matrix() @ wrong.normal
    planes[8][1] = Plane(turned, wrong.offset, covariance=wrong.covariance)
    result = smooth_batch(planes, seq.relatives, GAUSSIAN)
    assert result.stats.gated == 1
    rot, trans = max_pose_errors(result.poses, seq.poses)
    assert rot < 1e-9 and trans < 1e-8


def test_rotation_needs_two_non_parallel_associated_planes() -> None:
    ground = Plane(np.array([0.0, 0.0, 1.0]), 1.5)
    wall = Plane(np.array([1.0, 0.0, 0.0]), 4.0)
    parallel = Plane(np.array([-1.0, 0.0, 0.0]), 3.0)
    assert rotation_determined([ground, wall], np.array([[0, 0], [1, 1]]))
    assert not rotation_determined([ground, wall], np.array([[0, 0]]))
    assert not rotation_determined([wall, parallel], np.array([[0, 0], [1, 1]]))
    assert not rotation_determined([ground], np.array([[0, 0], [1, 5]]))  # index out of range


def test_smoothing_reuses_the_odometry_results_and_estimates_the_rest() -> None:
    from planodom.odometry import run_odometry
    from planodom.smoothing.run import smoothing_relatives

    seq = make_sequence(12, seed=1, step_m=0.5)
    cfg = PlanodomConfig()
    odo = run_odometry(seq.planes, cfg, times=0.1 * np.arange(12))
    assert odo.superseded == [] and all(r.measured for r in odo.results[1:])
    relatives = smoothing_relatives(odo, cfg)
    pairs = [(r.prev, r.curr) for r in relatives]
    assert len(pairs) == len(set(pairs)) == 11 + 10 + 9  # delta = 1, 2, 3, once each
    for k in range(1, 12):
        assert relatives[k - 1] is odo.results[k]  # the streaming estimate itself
    truth = [np.linalg.inv(seq.poses[r.prev]) @ seq.poses[r.curr] for r in relatives]
    for r, T in zip(relatives, truth, strict=True):
        np.testing.assert_allclose(r.T_prev_curr[:3, :3], T[:3, :3], atol=1e-9)
        np.testing.assert_allclose(r.T_prev_curr[:2, 3], T[:2, 3], atol=1e-8)


def test_every_relative_pose_knows_whether_its_epoch_was_spread_in_time() -> None:
    """The streaming odometry's flag reaches the relative poses estimated from its planes
    (delta > 1), and planes given with their scans' flags label them likewise."""
    from dataclasses import replace

    from planodom.odometry import run_odometry
    from planodom.smoothing.run import relative_poses, smoothing_relatives

    seq = make_sequence(12, seed=1, step_m=0.5)
    cfg = PlanodomConfig()
    odo = run_odometry(seq.planes, cfg, times=0.1 * np.arange(12))
    flags = [k % 3 != 0 for k in range(12)]  # as if the odometry had seen these scans
    odo.results = [None] + [replace(r, time_spread=flags[r.curr]) for r in odo.results[1:]]
    relatives = smoothing_relatives(odo, cfg)
    assert {r.delta for r in relatives} == {1, 2, 3}
    assert all(r.time_spread is flags[r.curr] for r in relatives)
    given = relative_poses(seq.planes, cfg, [2], odo.poses, time_spread=flags)
    assert given and all(r.time_spread is flags[r.curr] for r in given)
    assert all(r.time_spread is None for r in relative_poses(seq.planes, cfg, [2], odo.poses))


def test_smooth_batch_refuses_no_epochs_and_epochs_that_are_no_plane_lists() -> None:
    """No epochs ended in numpy's 'need at least one array to stack'; an (E, 3) array
    given as the epochs' planes was smoothed as planes of floats, without a word."""
    with pytest.raises(GeometryError, match=r"^smooth_batch: no epochs to smooth$"):
        smooth_batch([], [])
    with pytest.raises(GeometryError, match=r"^smooth_batch: epoch 0 holds a float64, not "):
        smooth_batch(np.zeros((3, 3)), [])


def test_smooth_windowed_refuses_no_epochs() -> None:
    """smooth_windowed([], []) ended in numpy's 'need at least one array to stack'."""
    with pytest.raises(GeometryError, match=r"^smooth_windowed: no epochs to smooth$"):
        smooth_windowed([], [])


@pytest.mark.parametrize(
    ("T", "problem"),
    [
        (np.eye(3), r"shape \(3, 3\)"),  # a traceback from matmul before
        (np.full((4, 4), np.nan), "not finite"),  # 'plane normal must be 3 finite numbers'
        (np.diag([2.0, 2.0, 2.0, 1.0]), "column norms 2, 2, 2"),  # a traceback before
    ],
)
def test_smooth_batch_refuses_a_first_pose_that_is_no_rigid_transform(T, problem) -> None:
    with pytest.raises(GeometryError, match=rf"^smooth_batch: T_world_first .*{problem}"):
        smooth_batch([[], []], [], T_world_first=T)


@pytest.mark.parametrize("smoother", [smooth_batch, smooth_windowed])
@pytest.mark.parametrize(("prev", "curr"), [(-1, -1), (2, 1), (1, 1)])
def test_smoothers_refuse_relative_poses_whose_epochs_are_not_ordered(smoother, prev, curr):
    """An unset (-1) or reversed relative pose was left out of the graph without a word."""
    seq = make_sequence(n_epochs=4, seed=3)
    rel = replace(seq.relatives[0], prev=prev, curr=curr)
    with pytest.raises(GeometryError, match=rf"relative pose 0 links epoch {prev} to epoch {curr}"):
        smoother(seq.planes, [rel, *seq.relatives[1:]])


def test_stated_steps_restate_the_odometrys_steps_only_when_it_ran_without_the_option():
    """:func:`planodom.smoothing.run.stated_steps`: the relative poses estimated from the
    planes always get the term; the odometry's own only when its run did not state it."""
    from dataclasses import replace as _replace

    from planodom.config import PlanodomConfig
    from planodom.geometry import transform_planes
    from planodom.odometry.relative import RelativePose, Status
    from planodom.odometry.run import OdometryRun
    from planodom.odometry.stated_deskew import (
        epoch_deskew_covariances,
        run_twist_change,
        shared_term,
    )
    from planodom.se3 import se3_exp
    from planodom.smoothing.run import stated_steps

    rng = np.random.default_rng(2)
    T = se3_exp(np.array([0.0, 0.0, 0.05, 1.0, 0.1, 0.0]))
    normals = rng.normal(size=(5, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    offsets = rng.uniform(2.0, 8.0, 5)
    planes = []
    for k in range(3):
        n, d = transform_planes(np.linalg.inv(np.linalg.matrix_power(T, k)), normals, offsets)
        planes.append([Plane(m, float(e), np.diag([1e-6, 1e-6, 1e-6, 1e-4]),
                             deskew_jacobian=rng.normal(size=(4, 6)) * 0.1)
                       for m, e in zip(n, d, strict=True)])  # fmt: skip
    pairs = np.column_stack([np.arange(5), np.arange(5)])
    steps = [RelativePose(se3_exp(np.array([0, 0, 0.05 * k, 1.0 + 0.1 * k, 0.1, 0])),
                          np.eye(5) * 1e-6, Status.OK, pairs, prev=k - 1, curr=k,
                          deskew_twist=np.ones(6), deskew_times=(0.0, 0.1))
             for k in (1, 2)]  # fmt: skip
    far = RelativePose(T @ T, np.eye(5) * 1e-6, Status.OK, pairs, prev=0, curr=2)
    run = OdometryRun(np.stack([np.eye(4)] * 3), np.array([0.0, 0.1, 0.2]), [None, *steps],
                      np.full(3, 5), planes, config=PlanodomConfig())  # fmt: skip
    Q = epoch_deskew_covariances(run.results, run_twist_change(run.results, run.times))
    assert np.any(Q[1]) and not np.any(Q[0])
    out = stated_steps(run, steps, [far])
    for r, s in zip(steps + [far], out, strict=True):
        term = shared_term(r, planes[r.prev], planes[r.curr], Q[r.prev], Q[r.curr])
        assert np.any(term)
        np.testing.assert_allclose(s.covariance, r.covariance + term)
    ran = _replace(run, config=PlanodomConfig().updated({"odometry.stated_deskew_noise": "shared"}))
    out = stated_steps(ran, steps, [far])
    assert out[0] is steps[0] and out[1] is steps[1] and out[2] is not far
