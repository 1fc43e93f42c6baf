"""Trajectory metrics against closed forms and independent numpy computations."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from planodom import geometry as g
from planodom import metrics as m
from planodom.errors import GeometryError


def random_trajectory(rng: np.random.Generator, n: int = 40) -> np.ndarray:
    """A wandering ground truth T_world_base (n, 4, 4), away from the world origin."""
    poses = np.empty((n, 4, 4))
    T = g.transform_from_rpy_xyz(0.05, -0.03, 1.0, 100.0, -50.0, 3.0)
    for k in range(n):
        poses[k] = T
        step = g.transform_from_rpy_xyz(
            *rng.normal(0, [0.02, 0.02, 0.1]), *rng.normal([1.0, 0, 0], 0.3)
        )
        T = T @ step
    return poses


def translate(poses: np.ndarray, offset) -> np.ndarray:
    out = poses.copy()
    out[:, :3, 3] += offset
    return out


def inv(T: np.ndarray) -> np.ndarray:
    return np.linalg.inv(T)


def test_relative_to_first_and_motions() -> None:
    gt = random_trajectory(np.random.default_rng(0), 10)
    rel = m.relative_to_first(gt)
    np.testing.assert_allclose(rel[0], np.eye(4), atol=1e-12)
    for k in range(10):
        np.testing.assert_allclose(rel[k], inv(gt[0]) @ gt[k], atol=1e-9)
    inc = m.relative_motions(gt)
    assert inc.shape == (9, 4, 4)
    for k in range(9):
        np.testing.assert_allclose(inc[k], inv(gt[k]) @ gt[k + 1], atol=1e-9)


def test_ate_constant_offset_without_alignment() -> None:
    gt = random_trajectory(np.random.default_rng(1))
    offset = np.array([0.3, -0.4, 1.2])  # |offset| = 1.3
    res = m.ate(translate(gt, offset), gt, align="none")
    for key in ("rmse", "mean", "median", "max"):
        assert res[key] == pytest.approx(1.3, abs=1e-9)
    # Origin alignment removes a constant offset entirely.
    assert m.ate(translate(gt, offset), gt)["max"] == pytest.approx(0.0, abs=1e-9)


def test_ate_odometry_frame_estimate() -> None:
    """An estimate starting at identity, off by a fixed vector from epoch 1 on."""
    gt = random_trajectory(np.random.default_rng(2), 20)
    est = m.relative_to_first(gt)
    assert m.ate(est, gt)["rmse"] == pytest.approx(0.0, abs=1e-9)
    est[1:, :3, 3] += [0.0, 0.6, 0.8]  # 1.0 m in the first epoch's frame
    res = m.ate(est, gt)
    errors = np.r_[0.0, np.ones(19)]
    assert res["rmse"] == pytest.approx(np.sqrt(np.mean(errors**2)))
    assert res["mean"] == pytest.approx(errors.mean())
    assert res["median"] == pytest.approx(1.0)
    assert res["max"] == pytest.approx(1.0)


def test_ate_xy_only_ignores_height() -> None:
    gt = random_trajectory(np.random.default_rng(3))
    est = m.relative_to_first(gt)
    est[:, 2, 3] = 0.0  # odometry that never moves vertically
    gt_rel = m.relative_to_first(gt)
    # In the world frame the height error of epoch k is the gt height change (tilted start
    # aside), so compare against positions expressed back in the world frame.
    est_world = gt[0] @ est
    expected_xy = np.linalg.norm(est_world[:, :2, 3] - gt[:, :2, 3], axis=1)
    expected_3d = np.linalg.norm(est[:, :3, 3] - gt_rel[:, :3, 3], axis=1)
    assert m.ate(est, gt, xy_only=True)["max"] == pytest.approx(expected_xy.max(), abs=1e-9)
    assert m.ate(est, gt)["max"] == pytest.approx(expected_3d.max(), abs=1e-9)


def _kabsch_rmse(p_est: np.ndarray, p_gt: np.ndarray) -> float:
    """Independent rigid least-squares alignment (Kabsch via SVD) and its RMSE."""
    a, b = p_est - p_est.mean(0), p_gt - p_gt.mean(0)
    U, _, Vt = np.linalg.svd(b.T @ a)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(U @ Vt))])
    R = U @ D @ Vt
    res = b - a @ R.T
    return float(np.sqrt(np.mean(np.sum(res**2, axis=1))))


def test_ate_se3_alignment_matches_kabsch() -> None:
    rng = np.random.default_rng(4)
    gt = random_trajectory(rng)
    A = g.make_transform(Rotation.random(random_state=rng).as_matrix(), [5.0, -7.0, 2.0])
    est = translate(A @ gt, rng.normal(0.0, 0.2, (len(gt), 3)))
    expected = _kabsch_rmse(est[:, :3, 3], gt[:, :3, 3])
    assert m.ate(est, gt, align="se3")["rmse"] == pytest.approx(expected, rel=1e-9)
    assert m.ate(A @ gt, gt, align="se3")["max"] == pytest.approx(0.0, abs=1e-6)


def test_ate_4dof_alignment() -> None:
    rng = np.random.default_rng(5)
    gt = random_trajectory(rng)
    yaw_shift = g.transform_from_rpy_xyz(0.0, 0.0, 0.7, 3.0, -2.0, 1.0)
    # Yaw and translation are absorbed entirely, even with a different starting pose.
    assert m.ate(yaw_shift @ gt, gt, align="4dof")["max"] == pytest.approx(0.0, abs=1e-9)
    # A tilt is not: compare with a brute-force minimisation over yaw.
    tilt = g.transform_from_rpy_xyz(0.05, 0.0, 0.3, 0.0, 0.0, 0.0)
    est = translate(tilt @ gt, rng.normal(0.0, 0.1, (len(gt), 3)))
    p_est = (gt[0] @ inv(est[0]) @ est)[:, :3, 3]  # origin alignment first
    p_gt = gt[:, :3, 3]

    def rmse(theta: float) -> float:
        R = Rotation.from_euler("z", theta).as_matrix()
        q = p_est @ R.T
        q += p_gt.mean(0) - q.mean(0)
        return float(np.sqrt(np.mean(np.sum((q - p_gt) ** 2, axis=1))))

    best = minimize_scalar(rmse, bounds=(-np.pi, np.pi), method="bounded", options={"xatol": 1e-10})
    assert m.ate(est, gt, align="4dof")["rmse"] == pytest.approx(best.fun, rel=1e-6)
    assert m.ate(est, gt, align="4dof")["rmse"] <= m.ate(est, gt, align="origin")["rmse"] + 1e-12


def _compose(increments: np.ndarray, start: np.ndarray) -> np.ndarray:
    poses = [start]
    for inc in increments:
        poses.append(poses[-1] @ inc)
    return np.array(poses)


def test_rpe_known_rotation_and_translation_errors() -> None:
    gt = random_trajectory(np.random.default_rng(6), 30)
    inc = np.array([inv(gt[k]) @ gt[k + 1] for k in range(29)])
    angle = np.radians(0.5)
    E_rot = g.make_transform(
        Rotation.from_rotvec(angle * np.array([0.6, 0.0, 0.8])).as_matrix(), np.zeros(3)
    )
    est = _compose(inc @ E_rot, np.eye(4))
    res = m.rpe(est, gt)
    for key in ("rmse", "mean", "median", "max"):
        assert res["rotation"][key] == pytest.approx(0.5, abs=1e-9)
        assert res["translation"][key] == pytest.approx(0.0, abs=1e-9)

    c = np.array([0.03, -0.04, 0.0])  # 5 cm per epoch
    est = _compose(inc @ g.make_transform(np.eye(3), c), np.eye(4))
    res = m.rpe(est, gt)
    assert res["translation"]["max"] == pytest.approx(0.05, abs=1e-12)
    assert res["rotation"]["max"] == pytest.approx(0.0, abs=1e-6)
    # Over two epochs: inv(G1 G2) G1 T(c) G2 T(c) has translation R2^T c + c.
    expected = np.array([np.linalg.norm(inc[k + 1][:3, :3].T @ c + c) for k in range(28)])
    res2 = m.rpe(est, gt, delta=2)  # a pair starting at every epoch
    assert res2["translation"]["mean"] == pytest.approx(expected.mean(), rel=1e-9)
    assert res2["translation"]["max"] == pytest.approx(expected.max(), rel=1e-9)
    res2 = m.rpe(est, gt, delta=2, all_pairs=False)  # pairs (0, 2), (2, 4), ...
    assert res2["translation"]["mean"] == pytest.approx(expected[::2].mean(), rel=1e-9)


def test_rpe_and_per_epoch_errors_take_no_pair_across_a_gap() -> None:
    """Epochs 10-14 without a reference are left out: the poses given are epochs 0-9 and
    15-29. No pair spans the gap; each run's pairs are those of the whole trajectory."""
    gt = random_trajectory(np.random.default_rng(7), 30)
    inc = np.array([inv(gt[k]) @ gt[k + 1] for k in range(29)])
    c = np.array([0.03, -0.04, 0.0])  # 5 cm per epoch
    est = _compose(inc @ g.make_transform(np.eye(3), c), np.eye(4))
    est[15:] = g.make_transform(np.eye(3), np.array([2.0, 0.0, 0.0])) @ est[15:]  # a jump
    index = np.r_[0:10, 15:30]
    with pytest.raises(GeometryError, match="increasing epoch numbers"):
        m.rpe(est[index], gt[index], index=index[::-1])
    res = m.rpe(est[index], gt[index], index=index)
    assert res["translation"]["max"] == pytest.approx(0.05, abs=1e-12)  # not the 2 m jump
    expected = np.array([np.linalg.norm(inc[k + 1][:3, :3].T @ c + c) for k in range(28)])
    pairs = [k for k in range(28) if k + 2 <= 9 or k >= 15]  # (k, k + 2) within a run
    res2 = m.rpe(est[index], gt[index], delta=2, index=index)
    assert res2["translation"]["mean"] == pytest.approx(expected[pairs].mean(), rel=1e-9)
    assert res2["translation"]["rmse"] == pytest.approx(
        np.sqrt(np.mean(expected[pairs] ** 2)), rel=1e-9
    )
    s = m.summarize(est[index], gt[index], align="none", index=index)
    steps = [k for k in range(29) if k + 1 <= 9 or k >= 15]  # the increment k -> k + 1
    x_errors = [(inc[k][:3, :3] @ c)[0] for k in steps]  # est_k_k+1 = inc_k T(c)
    assert s["x_err_mean_m"] == pytest.approx(np.mean(x_errors), abs=1e-9)
    assert s["x_err_std_m"] == pytest.approx(np.std(x_errors), abs=1e-9)
    # without the index the poses 9 and 15 were one step, the jump its error
    assert m.summarize(est[index], gt[index])["rpe_trans_max_m"] > 1.9


def test_drift() -> None:
    gt = random_trajectory(np.random.default_rng(7), 25)
    est = m.relative_to_first(gt)
    est[-1, :3, 3] += [2.0, 0.0, 0.0]
    d = m.drift(est, gt)
    distance = np.sum(np.linalg.norm(np.diff(gt[:, :3, 3], axis=0), axis=1))
    assert d["final_error"] == pytest.approx(2.0)
    assert d["distance"] == pytest.approx(distance)
    assert d["percent"] == pytest.approx(200.0 / distance)
    standing = np.tile(np.eye(4), (3, 1, 1))
    assert np.isnan(m.drift(standing, standing)["percent"])


def test_drift_distance_across_a_gap_is_the_straight_line() -> None:
    """Epochs 8-16 without a reference: the distance is the path's length over the steps
    within epochs 0-7 and 17-24 plus the straight line 7 -> 17 (a lower bound of the path
    there, tighter than leaving the gap out), the same with or without the index."""
    gt = random_trajectory(np.random.default_rng(7), 25)
    est = m.relative_to_first(gt)
    est[-1, :3, 3] += [0.0, 3.0, 0.0]
    index = np.r_[0:8, 17:25]
    within = [k for k in range(24) if k + 1 < 8 or k >= 17]  # the step k -> k + 1
    length = sum(float(np.linalg.norm(gt[k + 1, :3, 3] - gt[k, :3, 3])) for k in within)
    chord = float(np.linalg.norm(gt[17, :3, 3] - gt[7, :3, 3]))
    path = sum(float(np.linalg.norm(gt[k + 1, :3, 3] - gt[k, :3, 3])) for k in range(7, 17))
    s = m.summarize(est[index], gt[index], index=index)
    assert s["drift_m"] == pytest.approx(3.0)
    assert s["distance_m"] == pytest.approx(length + chord, rel=1e-12)
    assert s["drift_percent"] == pytest.approx(300.0 / (length + chord), rel=1e-12)
    assert length < length + chord <= length + path  # the whole path's is the smallest
    assert m.drift(est[index], gt[index])["distance"] == pytest.approx(length + chord)


def test_per_epoch_errors_known_biases_and_wrapping() -> None:
    rng = np.random.default_rng(8)
    params = rng.normal(0, [0.02, 0.02, 0.1, 1.0, 0.3, 0.05], (50, 6))
    params[0, 2] = np.pi - 0.01  # true yaw increment near +pi
    bias = np.array([0.001, -0.002, 0.03, 0.05, -0.01])  # roll, pitch, yaw (rad), x, y (m)
    gt_rel = np.array([g.transform_from_rpy_xyz(*p) for p in params])
    est_params = params.copy()
    est_params[:, :5] += bias
    est_rel = np.array([g.transform_from_rpy_xyz(*p) for p in est_params])
    errors = m.per_epoch_errors(est_rel, gt_rel)
    for j, name in enumerate(m.POSE5_NAMES):
        assert errors[name].shape == (50,)
        np.testing.assert_allclose(errors[name], bias[j], atol=1e-9)  # incl. the wrapped yaw


def test_pose_nees_closed_form() -> None:
    """The truth displaced from each estimate by a known twist: NEES = sum (xi_i / sigma_i)^2."""
    import gtsam

    rng = np.random.default_rng(9)
    est = random_trajectory(rng, 6)
    sigmas = np.array([0.01, 0.02, 0.03, 0.1, 0.2, 0.3])
    xi = rng.normal(size=(6, 6)) * sigmas
    gt = np.array([T @ gtsam.Pose3.Expmap(x).matrix() for T, x in zip(est, xi, strict=True)])
    P = np.broadcast_to(np.diag(sigmas**2), (6, 6, 6)).copy()
    np.testing.assert_allclose(m.pose_nees(est, P, gt), np.sum((xi / sigmas) ** 2, axis=1))
    five = m.pose_nees(est, P, gt, dofs=range(5))  # body z marginalised
    np.testing.assert_allclose(five, np.sum((xi[:, :5] / sigmas[:5]) ** 2, axis=1))
    P[2] = 0.0  # a singular covariance gives NaN, not an error
    assert np.isnan(m.pose_nees(est, P, gt)[2]) and np.isfinite(m.pose_nees(est, P, gt)[3])


def test_summarize() -> None:
    rng = np.random.default_rng(10)
    params = rng.normal(0, [0.02, 0.02, 0.1, 1.0, 0.3, 0.05], (14, 6))
    gt = _compose(np.array([g.transform_from_rpy_xyz(*p) for p in params]), np.eye(4))
    # Increments off by 0.2 deg in yaw and 0.1 m in x: inv(G) @ E is then a pure rotation of
    # 0.2 deg (Rx^T Ry^T Rz(0.2 deg) Ry Rx) with a translation of length 0.1 m.
    params[:, 2] += np.radians(0.2)
    params[:, 3] += 0.1
    est = _compose(np.array([g.transform_from_rpy_xyz(*p) for p in params]), np.eye(4))
    s = m.summarize(est, gt)
    assert all(isinstance(v, float) for v in s.values())
    assert s["epochs"] == 15.0
    assert s["yaw_err_mean_deg"] == pytest.approx(0.2, abs=1e-6)
    assert s["yaw_err_std_deg"] == pytest.approx(0.0, abs=1e-6)
    assert s["x_err_mean_m"] == pytest.approx(0.1, abs=1e-9)
    assert s["rpe_rot_mean_deg"] == pytest.approx(0.2, abs=1e-9)
    assert s["rpe_trans_max_m"] == pytest.approx(0.1, abs=1e-9)
    assert s["ate_rmse_m"] > 0 and s["drift_m"] > 0
    single = m.summarize(gt[:1], gt[:1])
    assert single["ate_max_m"] == 0.0 and np.isnan(single["rpe_rot_rmse_deg"])


def test_bad_input() -> None:
    gt = random_trajectory(np.random.default_rng(11), 5)
    with pytest.raises(GeometryError, match="differ in shape"):
        m.ate(gt[:4], gt)
    with pytest.raises(GeometryError, match=r"\(E, 4, 4\)"):
        m.ate(gt[:, :3], gt)
    bad = gt.copy()
    bad[2, 0, 3] = np.nan
    with pytest.raises(GeometryError, match="not finite"):
        m.rpe(bad, gt)
    with pytest.raises(GeometryError, match="delta"):
        m.rpe(gt, gt, delta=5)
    with pytest.raises(ValueError, match="unknown alignment"):
        m.ate(gt, gt, align="sim3")  # type: ignore[arg-type]


def test_inputs_are_not_modified() -> None:
    gt = random_trajectory(np.random.default_rng(12), 8)
    est = translate(gt, [1.0, 2.0, 3.0])
    gt0, est0 = gt.copy(), est.copy()
    for align in ("none", "origin", "se3", "4dof"):
        m.ate(est, gt, align=align, xy_only=True)
    m.summarize(est, gt)
    assert np.array_equal(gt, gt0) and np.array_equal(est, est0)


def test_errors_nees_over_chosen_components_against_a_direct_solve() -> None:
    rng = np.random.default_rng(4)
    errors = rng.normal(size=(5, 6))
    A = rng.normal(size=(5, 6, 6))
    cov = A @ A.transpose(0, 2, 1) + 0.1 * np.eye(6)
    dofs = (3, 4)
    expect = [
        e[[3, 4]] @ np.linalg.inv(P[3:5, 3:5]) @ e[[3, 4]] for e, P in zip(errors, cov, strict=True)
    ]
    np.testing.assert_allclose(m.errors_nees(errors, cov, dofs), expect, rtol=1e-10)
