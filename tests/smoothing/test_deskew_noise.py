"""The deskewing error's share of the factors' noise (planodom.smoothing.deskew_noise)."""

from __future__ import annotations

from dataclasses import replace

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.deskew_noise import (
    DeskewNoise,
    between_keys,
    deskew_frame_factor,
    plane_deskew_covariance,
)
from planodom.smoothing.noise import between_covariance, plane_covariance, plane_factor_covariance
from planodom.smoothing.synthetic import make_sequence
from planodom.smoothing.windowed import smooth_windowed
from planodom_factors.planes import plane_factor
from planodom_factors.pose5 import pose5_error


def _steps(motions: np.ndarray, sigma: float = 1e-9) -> list[RelativePose]:
    """delta = 1 relative poses with the given (rotation vector, translation) motions (K, 6):
    the motion into epoch k + 1 is ``motions[k]``."""
    out = []
    for k, m in enumerate(motions):
        T = np.eye(4)
        T[:3, :3] = Rotation.from_rotvec(m[:3]).as_matrix()
        T[:3, 3] = m[3:]
        cov = np.eye(5) * sigma**2
        out.append(RelativePose(T, cov, prev=k, curr=k + 1, z_observed=True, sigma_z=sigma))
    return out


def _random_walk_motions(rng: np.random.Generator, n: int, s: np.ndarray) -> np.ndarray:
    """Motions whose changes from one epoch to the next are N(0, s^2) per component."""
    base = np.array([0.0, 0.0, 0.05, 0.5, 0.0, 0.0])
    return base + np.cumsum(rng.normal(0.0, 1.0, (n, 6)) * s, axis=0)


def _fed(motions: np.ndarray) -> DeskewNoise:
    model = DeskewNoise()
    for rel in _steps(motions):
        model.add(rel)
    return model


def test_pose_covariance_is_a_third_of_the_motion_change_variance():
    rng = np.random.default_rng(3)
    s = np.array([0.004, 0.002, 0.001, 0.01, 0.005, 0.003])
    n = 3000
    model = _fed(_random_walk_motions(rng, n, s))
    epochs = range(10, n - 10)
    # Closed form: the twist is off by the change dxi ~ N(0, s^2); E[(t / dt)^2] = 1 / 3.
    expected = s**2 / 3.0
    pose = np.mean([np.diag(model.pose_covariance(k)) for k in epochs], axis=0)
    np.testing.assert_allclose(pose, expected, rtol=0.08)
    # A relative pose: dxi_k - dxi_{k-delta}, independent changes: twice that.
    for delta in (1, 3):
        rel = np.mean([np.diag(model.relative_covariance(k - delta, k)) for k in epochs], axis=0)
        np.testing.assert_allclose(rel, 2 * expected[:5], rtol=0.08)


def test_white_odometry_noise_is_counted_twice_per_change():
    rng = np.random.default_rng(4)
    sigma, n = 0.002, 3000
    motions = np.array([0.0, 0.0, 0.05, 0.5, 0.0, 0.0]) + rng.normal(0.0, sigma, (n, 6))
    model = _fed(motions)
    pose = np.mean([np.diag(model.pose_covariance(k)) for k in range(10, n - 10)], axis=0)
    np.testing.assert_allclose(pose, np.full(6, 2 * sigma**2 / 3), rtol=0.08)


def test_the_estimate_is_local_to_a_change_of_motion():
    motions = np.tile([0.0, 0.0, 0.0, 0.5, 0.0, 0.0], (100, 1))
    motions[50:, 2] = 0.03  # yaw rate changes once: motion into epoch 51 onwards
    model = _fed(motions)
    # The step into epoch k + 1 is motions[k]: the change dxi_k = m_{k+1} - m_k is nonzero
    # at k = 50 only; a window of 5 anchors holds it once around there.
    np.testing.assert_allclose(model.pose_covariance(50)[2, 2], 0.03**2 / 5 / 3)
    assert model.pose_covariance(47)[2, 2] == 0.0 and model.pose_covariance(53)[2, 2] == 0.0
    assert not np.any(model.pose_covariance(10)) and not np.any(model.pose_covariance(90))


def test_streaming_estimates_follow_new_steps():
    motions = _random_walk_motions(np.random.default_rng(5), 60, np.full(6, 0.01))
    rels = _steps(motions)
    streaming = DeskewNoise()
    for rel in rels[:40]:
        streaming.add(rel)
    early = streaming.pose_covariance(38), streaming.relative_covariance(36, 38)
    for rel in rels[40:]:
        streaming.add(rel)
    full = _fed(motions)
    np.testing.assert_array_equal(streaming.pose_covariance(38), full.pose_covariance(38))
    np.testing.assert_array_equal(
        streaming.relative_covariance(36, 38), full.relative_covariance(36, 38)
    )
    assert not np.array_equal(early[0], full.pose_covariance(38))
    assert not np.any(DeskewNoise().pose_covariance(3))


def _perturbed_plane_tangent(n: np.ndarray, d: float, xi: np.ndarray) -> np.ndarray:
    """Tangent (Unit3 basis of n (2), offset (1)) of the plane after its points moved by the
    rigid motion Exp(xi) (p -> R p + t): independent of the first-order formula."""
    R = Rotation.from_rotvec(xi[:3]).as_matrix()
    n2 = R @ n
    d2 = d - n2 @ xi[3:]
    dn = np.asarray(gtsam.Unit3(n).localCoordinates(gtsam.Unit3(n2)))
    return np.append(dn, d2 - d)


def test_plane_deskew_covariance_matches_finite_differences():
    rng = np.random.default_rng(6)
    n = rng.normal(size=3)
    n /= np.linalg.norm(n)
    d = -3.2
    A = rng.normal(size=(6, 6)) * 1e-3
    pose_cov = A @ A.T
    h = 1e-6
    J = np.stack([_perturbed_plane_tangent(n, d, h * e) / h for e in np.eye(6)], axis=1)  # (3, 6)
    np.testing.assert_allclose(
        plane_deskew_covariance(n, pose_cov), J @ pose_cov @ J.T, rtol=1e-4, atol=1e-14
    )


def test_between_covariance_adds_the_relative_term():
    cfg = PlanodomConfig().smoothing
    model = _fed(_random_walk_motions(np.random.default_rng(7), 50, np.full(6, 0.01)))
    rel = _steps(_random_walk_motions(np.random.default_rng(8), 12, np.full(6, 0.01)))[10]
    deskew = model.relative_covariance(rel.prev, rel.curr)
    added = between_covariance(rel, cfg, deskew) - between_covariance(rel, cfg)
    np.testing.assert_allclose(added, deskew, atol=1e-15)
    assert np.all(np.diag(added) > 0)


def test_a_gap_of_unmeasured_epochs_takes_the_run_wide_estimate():
    motions = _random_walk_motions(np.random.default_rng(9), 80, np.full(6, 0.01))
    rels = [r for r in _steps(motions) if not 30 <= r.curr < 50]  # epochs 30-49 unresolved
    model = DeskewNoise()
    for rel in rels:
        model.add(rel)
    m = {r.curr: motions[r.curr - 1] for r in rels}
    changes = np.array([m[k + 1] - m[k] for k in m if k + 1 in m])
    np.testing.assert_allclose(np.diag(model.pose_covariance(40)), np.mean(changes**2, 0) / 3)
    assert np.all(np.diag(model.pose_covariance(40)) > 0)


def test_the_graph_takes_the_term_in_batch_and_fixed_lag_smoothing():
    seq = make_sequence(30, seed=2, sigma_rotation=1e-3, sigma_translation=0.01,
                        sigma_normal=0.005, sigma_offset=0.01)  # fmt: skip
    base = SmoothingConfig(robust_kernel="none", deskew_noise="none")
    for mode in ("twist_change", "twist_change_frame", "twist_change_jacobian"):
        on = base.model_copy(update={"deskew_noise": mode})
        for smooth in (smooth_batch, smooth_windowed):
            off_cov = smooth(seq.planes, seq.relatives, base).covariances
            on_cov = smooth(seq.planes, seq.relatives, on).covariances
            assert off_cov is not None and on_cov is not None
            # More noise on every factor: the last pose can only be less certain.
            assert np.trace(on_cov[-1]) > np.trace(off_cov[-1])


def test_deskew_frame_factor_whitens_by_the_pose_covariance():
    rng = np.random.default_rng(11)
    sig = np.array([2e-3, 1e-3, 5e-4, 0.01, 0.02, 0.005])
    X = gtsam.Pose3(gtsam.Rot3.Rodrigues(*rng.normal(size=3)), rng.normal(size=3))
    xi = rng.normal(size=6) * sig
    values = gtsam.Values()
    values.insert(1, X)
    values.insert(2, X.compose(gtsam.Pose3.Expmap(xi)))
    factor = deskew_frame_factor(1, 2, np.diag(sig**2))
    assert factor is not None
    # Closed form: the frame is the pose perturbed by xi; error 0.5 * sum((xi / sigma)^2).
    np.testing.assert_allclose(factor.error(values), 0.5 * np.sum((xi / sig) ** 2), rtol=1e-6)
    assert deskew_frame_factor(1, 2, np.zeros((6, 6))) is None


def test_a_shared_frame_adds_the_perturbation_once_to_the_pose():
    """The epoch's planes are measured in its deskewed frame: the pose's marginal is the
    frame's (from the planes) plus the perturbation's covariance, however many planes
    there are (independent inflation would shrink it with their number)."""
    rng = np.random.default_rng(12)
    normals = rng.normal(size=(8, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    planes = [np.append(n, -rng.uniform(2.0, 6.0)) for n in normals]  # world = base frame
    pose_cov = np.diag([1e-5, 2e-5, 4e-6, 1e-4, 3e-4, 5e-5])
    plane_cov = gtsam.noiseModel.Isotropic.Sigma(3, 1e-3)
    tight = gtsam.noiseModel.Isotropic.Sigma(3, 1e-7)  # landmarks known (a fixed pose 50)

    def marginal(frame: bool) -> np.ndarray:
        graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
        values.insert(0, gtsam.Pose3())
        values.insert(50, gtsam.Pose3())
        graph.add(
            gtsam.PriorFactorPose3(50, gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-7))
        )
        key = 1 if frame else 0
        if frame:
            values.insert(1, gtsam.Pose3())
            graph.add(deskew_frame_factor(0, 1, pose_cov))
        for j, p in enumerate(planes):
            values.insert(100 + j, gtsam.OrientedPlane3(p))
            graph.add(plane_factor(50, 100 + j, p, tight))
            graph.add(plane_factor(key, 100 + j, p, plane_cov))
        return np.asarray(gtsam.Marginals(graph, values).marginalCovariance(0))

    np.testing.assert_allclose(marginal(True), marginal(False) + pose_cov, rtol=1e-4, atol=1e-11)


def test_relative_poses_between_deskewed_frames_take_no_separate_term():
    model = _fed(_random_walk_motions(np.random.default_rng(13), 30, np.full(6, 0.01)))
    model.frames.update({4, 5})
    X, F = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.F
    assert between_keys(model, 4, 5, X, F) == ((F(4), F(5)), None)
    keys, cov = between_keys(model, 5, 6, X, F)  # epoch 6 has no frame: the poses
    assert keys == (X(5), X(6))
    np.testing.assert_array_equal(cov, model.relative_covariance(5, 6))
    assert between_keys(None, 4, 5, X, F) == ((X(4), X(5)), None)


def test_epochs_taken_at_one_instant_have_no_deskewing_error():
    rng = np.random.default_rng(5)
    s = np.array([0.004, 0.002, 0.001, 0.01, 0.005, 0.003])
    motions = _random_walk_motions(rng, 200, s)
    spread, instant = DeskewNoise(), DeskewNoise()
    for rel in _steps(motions):
        spread.add(replace(rel, time_spread=True))
        instant.add(replace(rel, time_spread=False))
    # The same changes of motion: an error only where the points were spread in time.
    assert np.all(np.diag(spread.pose_covariance(100)) > 0)
    for k in (0, 100):  # epoch 0 (no relative pose into it) as every known epoch was
        assert not np.any(instant.pose_covariance(k))
    assert not np.any(instant.relative_covariance(99, 100))
    assert np.all(np.diag(spread.relative_covariance(99, 100)) > 0)
    # A mixed run: an epoch of unknown spread keeps the model.
    mixed = DeskewNoise()
    for k, rel in enumerate(_steps(motions)):
        mixed.add(replace(rel, time_spread=bool(k % 2)))
    assert mixed.instant(1) and not mixed.instant(2) and not mixed.instant(0)


def test_a_loop_factor_takes_the_deskewing_error_of_both_its_epochs():
    """Monte Carlo against the factor's Jacobians: both epochs' frames perturbed by their
    own independent deskewing errors, the 5-DoF error of the relative pose they give."""
    rng = np.random.default_rng(21)
    model = _fed(_random_walk_motions(rng, 300, np.array([3e-3, 2e-3, 1e-3, 0.01, 5e-3, 2e-3])))
    old, curr = 20, 260  # a lap apart: independent errors
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec([0.01, -0.02, 2.5]).as_matrix()
    T[:3, 3] = [3.0, -1.5, 0.1]
    P_old, P_curr = model.pose_covariance(old), model.pose_covariance(curr)
    assert np.all(np.diag(P_old) > 0) and np.all(np.diag(P_curr) > 0)
    errors = []
    for _ in range(20000):
        F_old = gtsam.Pose3.Expmap(rng.multivariate_normal(np.zeros(6), P_old)).matrix()
        F_curr = T @ gtsam.Pose3.Expmap(rng.multivariate_normal(np.zeros(6), P_curr)).matrix()
        measured = np.linalg.inv(F_old) @ F_curr  # the planes were seen in the frames
        errors.append(pose5_error(measured, np.eye(4), T)[0])
    sample = np.cov(np.array(errors).T)
    cov = model.loop_covariance(old, curr, T)
    np.testing.assert_allclose(np.sqrt(np.diag(cov)), np.sqrt(np.diag(sample)), rtol=0.03)
    np.testing.assert_allclose(cov, sample, atol=0.05 * np.max(np.diag(sample)))
    # Instant epochs: no deskewing error, and a loop between them none either.
    instant = DeskewNoise()
    for rel in _steps(_random_walk_motions(rng, 300, np.full(6, 0.01))):
        instant.add(replace(rel, time_spread=False))
    assert not np.any(instant.loop_covariance(old, curr, T))


def test_plane_motion_change_is_the_change_of_motion_itself():
    rng = np.random.default_rng(12)
    s = np.array([0.004, 0.002, 0.001, 0.01, 0.005, 0.003])
    n = 3000
    model = DeskewNoise(plane_jacobian=True)
    for rel in _steps(_random_walk_motions(rng, n, s)):
        model.add(rel)
    change = np.mean([np.diag(model.plane_motion_change(k)) for k in range(10, n - 10)], axis=0)
    # Closed form: the twist is off by the change dxi ~ N(0, s^2) (no 1/3: the planes'
    # own Jacobians weigh their points' times); the rigid share is then left out.
    np.testing.assert_allclose(change, s**2, rtol=0.08)
    assert not np.any(model.plane_pose_covariance(100))
    assert DeskewNoise().plane_motion_change(100) is None


def test_an_unmeasured_vertical_motion_takes_the_measured_ones_mean_square():
    rng = np.random.default_rng(13)
    motions = _random_walk_motions(rng, 60, np.full(6, 1e-4))
    motions[:, 5] = 0.02 + rng.normal(0.0, 1e-4, 60)  # climbing: steps that hardly change
    rels = _steps(motions)
    free = {r.curr for r in rels if r.curr % 3 == 0}
    model = DeskewNoise(plane_jacobian=True)
    for r in rels:
        model.add(replace(r, z_observed=r.curr not in free, sigma_z=1e-9))
    measured = np.array([r.T_prev_curr[2, 3] for r in rels if r.curr not in free])
    k = min(free - {0, 3, 57})
    assert np.isclose(model.plane_motion_change(k)[5, 5], np.mean(measured**2))
    assert model.plane_motion_change(k + 1)[5, 5] < 0.1 * np.mean(measured**2)


def test_a_planes_jacobian_carries_the_motion_change_into_its_covariance():
    cfg = SmoothingConfig(min_plane_normal_sigma_rad=1e-9, min_plane_offset_sigma_m=1e-9)
    n = np.array([0.0, 0.6, 0.8])
    J = np.zeros((4, 6))
    J[3, 5] = -0.5  # the offset moves by half a vertical velocity error
    J[:3, 0] = np.cross([1.0, 0.0, 0.0], n) * 2.0  # the normal turns about x by twice roll
    plane = Plane(n, -4.0, covariance=np.zeros((4, 4)), deskew_jacobian=J)
    change = np.diag([1e-4, 0, 0, 0, 0, 4e-4])
    added = plane_covariance(plane, cfg, None, change) - plane_covariance(plane, cfg)
    # closed form: offset variance 0.25 * 4e-4; the normal's tangent variance 4 * 1e-4 along
    # one direction of the Unit3 basis (whatever its orientation), nothing across
    np.testing.assert_allclose(added[2, 2], 1e-4, rtol=1e-9)
    np.testing.assert_allclose(np.trace(added[:2, :2]), 4e-4, rtol=1e-9)
    assert abs(np.linalg.det(added[:2, :2])) < 1e-20
    # without a Jacobian: the rigid model on a third of it
    rigid = replace(plane, deskew_jacobian=None)
    expected = plane_covariance(rigid, cfg, change / 3.0)
    np.testing.assert_allclose(plane_covariance(rigid, cfg, None, change), expected)
    model = DeskewNoise(plane_jacobian=True)
    assert np.allclose(
        plane_factor_covariance(plane, cfg, model, 0, False), plane_covariance(plane, cfg)
    )
