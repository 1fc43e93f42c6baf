"""covariances.npz: what a run computes, written and read back unchanged."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest

from planodom.covariances import (
    chained_covariances,
    odometry_covariances,
    read_covariances,
    write_covariances,
)
from planodom.errors import DatasetError
from planodom.odometry import OdometryRun, RelativePose, Status


def test_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(4, 5, 5))
    covs = A @ A.transpose(0, 2, 1)
    results = [None] + [
        RelativePose(np.eye(4), covs[k], Status.OK if k else Status.DEGENERATE).between(k, k + 1)
        for k in range(3)
    ]
    results.append(RelativePose(np.eye(4), None, Status.UNRESOLVED).between(2, 4))
    run = OdometryRun(
        np.tile(np.eye(4), (5, 1, 1)), 1.7e9 + np.arange(5) * 0.1, results, np.zeros(5)
    )
    arrays = odometry_covariances(run)
    marginals = rng.normal(size=(5, 6, 6))
    write_covariances(tmp_path / "c.npz", arrays | {"smoothed_batch": marginals, "x": None})
    back = read_covariances(tmp_path / "c.npz")
    assert set(back) == {
        "times", "relative", "relative_prev", "relative_status", "chained", "smoothed_batch"
    }  # fmt: skip
    np.testing.assert_array_equal(back["relative"][1:4], covs[:3])
    assert np.isnan(back["relative"][[0, 4]]).all()
    np.testing.assert_array_equal(back["relative_prev"], [-1, 0, 1, 2, 2])
    assert back["relative_status"].tolist() == ["first", "degenerate", "ok", "ok", "unresolved"]
    np.testing.assert_array_equal(back["times"], run.times)
    np.testing.assert_array_equal(back["smoothed_batch"], marginals)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    with pytest.raises(DatasetError, match="bad.npz: not a covariances archive"):
        read_covariances(tmp_path / "bad.npz")


def _relative(poses, status, s_bridged, s_measured, directions):
    """(E, 5, 5) step covariances: rotation 1 mrad, the translation s_bridged (bridged
    steps) along ``directions[k]`` (unit (2,), previous frame) and s_measured across it;
    s_measured both ways on measured steps."""
    n = len(poses)
    rel = np.full((n, 5, 5), np.nan)
    for k in range(1, n):
        d = directions[k]
        V = np.array([[d[0], -d[1]], [d[1], d[0]]])
        s = s_bridged if status[k] != "ok" else s_measured
        rel[k] = 0.0
        rel[k, :3, :3] = np.eye(3) * 1e-6
        rel[k, 3:, 3:] = V @ np.diag([s**2, s_measured**2]) @ V.T
    return rel


def test_chained_straight_bridge_closed_form() -> None:
    """Translation only along x (no rotation error): the pose is the sum of its steps,
    steps = true + v_err dt (bridged, one v_err per run) + noise u, so
    var_x(k) = sum of the steps' var(u) + per run (sigma(v_err) * elapsed time in it)^2."""
    status = ["first", "ok", "ok"] + ["degenerate"] * 5 + ["ok"] * 2 + ["unresolved"] * 3 + ["ok"]
    n, dt, s_ok, s_cv = len(status), 0.1, 0.01, 0.2
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, 0, 3] = 0.7 * np.arange(n)
    times = dt * np.arange(n)
    prev = np.arange(n) - 1
    rel = _relative(poses, status, s_cv, s_ok, [np.array([1.0, 0.0])] * n)
    rel[:, :3, :3] = 0.0  # no rotation error: the translation errors simply add

    def expected(v_sigma, own):  # own: the bridged steps' own variance
        out, run, done = np.zeros(n), 0.0, 0.0
        for k in range(1, n):
            if status[k] == "ok":
                done, run = done + run**2 + s_ok**2, 0.0
            else:
                run, done = run + v_sigma * dt, done + own
            out[k] = done + run**2
        return out

    # measured: v_err is the last ok step's error over its interval, on top of s_cv
    cov = chained_covariances(poses, times, rel, prev, status, 0.03)
    np.testing.assert_allclose(cov[:, 3, 3], expected(s_ok / dt, s_cv**2), rtol=1e-12)
    np.testing.assert_allclose(cov[:, 4, 4], s_ok**2 * np.arange(n), rtol=1e-12)
    assert cov[7, 3, 3] == pytest.approx(2 * s_ok**2 + 5 * s_cv**2 + (5 * s_ok) ** 2)
    # stated: the bridged steps' sigma is v_err dt itself, instead of independent terms
    cov = chained_covariances(poses, times, rel, prev, status, 0.03, velocity="stated")
    np.testing.assert_allclose(cov[:, 3, 3], expected(s_cv / dt, 0.0), rtol=1e-12)
    independent = chained_covariances(poses, times, rel, prev, status, 0.03, velocity="none")
    np.testing.assert_allclose(independent[:, 3, 3], expected(0.0, s_cv**2), rtol=1e-12)
    # one bridged step alone: stated and independent the same
    np.testing.assert_allclose(cov[:4], independent[:4], rtol=1e-12)


@pytest.mark.parametrize("velocity", ["stated", "measured"])
def test_chained_turning_matches_stacked_linear_model(velocity) -> None:
    """With rotations and a skipped reference epoch: the covariance of the stacked linear
    model x_k = sum_i J_ik w_i, J_ik = Ad(T_ik^-1) from gtsam, w_i = L_i z_run + u_i
    (measured: L_i = dt_i P_i R_ji^T B_j, the last ok step j's velocity error B_j z; pure
    yaw so that the horizontal block turns exactly)."""
    rng = np.random.default_rng(7)
    status = ["first", "ok", "degenerate", "degenerate", "unresolved", "ok", "ok"]
    status += ["degenerate"] * 4 + ["ok"]
    n = len(status)
    prev = np.arange(n) - 1
    prev[6] = 4  # epoch 6 referenced to epoch 4 (epoch 5 had too few planes)
    steps = [np.eye(4)]
    tilt = (0.01, -0.02) if velocity == "stated" else (0.0, 0.0)
    times = np.cumsum(rng.uniform(0.05, 0.15, n))
    for _ in range(1, n):
        steps.append(
            gtsam.Pose3(gtsam.Rot3.Ypr(rng.normal(0, 0.2), *tilt), rng.normal(0, 1, 3))
            .matrix()
        )  # fmt: skip
    poses = [np.eye(4)]
    for k in range(1, n):
        poses.append(poses[prev[k]] @ steps[k])
    poses_a = np.array(poses)
    dirs = [np.array([np.cos(a), np.sin(a)]) for a in rng.uniform(0, np.pi, n)]
    s_b, s_m = 0.2, 0.005
    rel = _relative(poses_a, status, s_b, s_m, dirs)
    cov = chained_covariances(poses_a, times, rel, prev, status, 0.03, velocity=velocity)

    def jac(i, k):  # pose i's tangent error into pose k's, along the chain of k
        T = np.linalg.inv(poses_a[i]) @ poses_a[k]
        return gtsam.Pose3(np.linalg.inv(T)).AdjointMap()

    def parts(k):  # step k's error in its end frame: independent Q, shared L
        R = steps[k][:3, :3]
        Q = np.zeros((6, 6))
        Q[:3, :3] = rel[k, :3, :3]
        d, L = dirs[k], np.zeros((6, 6))
        across = np.array([-d[1], d[0]])
        if status[k] == "ok":
            Q[3:5, 3:5] = rel[k, 3:, 3:]
        elif velocity == "stated":
            Q[3:5, 3:5] = s_m**2 * np.outer(across, across)
            L[3:5, 3:5] = s_b * np.outer(d, d)
        else:
            Q[3:5, 3:5] = rel[k, 3:, 3:]
            j = k
            while status[j] != "ok" and j > 0:
                j = prev[j]
            if j > 0:  # the velocity error of step j, in its end frame, then in k's start
                lam, V = np.linalg.eigh(rel[j, 3:, 3:])
                B = steps[j][:2, :2].T @ V @ np.diag(np.sqrt(lam)) @ V.T
                B = B / (times[j] - times[prev[j]])
                R_jp = (np.linalg.inv(poses_a[j]) @ poses_a[prev[k]])[:2, :2]
                dt = times[k] - times[prev[k]]
                L[3:5, 3:5] = dt * np.outer(d, d) @ R_jp.T @ B
        Q[5, 5] = 0.5 * (rel[k, 3, 3] + rel[k, 4, 4])
        J = np.eye(6)
        J[3:, 3:] = R.T
        return J @ Q @ J.T, J @ L @ J.T

    for k in range(1, n):
        chain, i = [], k
        while i > 0:
            chain.append(i)
            i = prev[i]
        expected = np.zeros((6, 6))
        runs: dict[int, np.ndarray] = {}
        for i in chain:
            Q, L = parts(i)
            J = jac(i, k)
            expected += J @ Q @ J.T
            if L.any():  # the run a bridged step belongs to: its first bridged epoch
                first = i
                while status[first - 1] != "ok" and first - 1 > 0:
                    first -= 1
                runs[first] = runs.get(first, np.zeros((6, 6))) + J @ L
        for G in runs.values():
            expected += G @ G.T
        np.testing.assert_allclose(cov[k], expected, rtol=1e-9, atol=1e-15)


def test_chained_unknown_covariance_is_nan() -> None:
    poses = np.tile(np.eye(4), (3, 1, 1))
    rel = np.full((3, 5, 5), np.nan)
    rel[2] = np.eye(5) * 1e-4
    status = ["first", "unresolved", "ok"]
    cov = chained_covariances(poses, np.arange(3.0), rel, np.array([-1, 0, 1]), status, 0.03)
    np.testing.assert_array_equal(cov[0], 0.0)
    assert np.isnan(cov[1:]).all()
