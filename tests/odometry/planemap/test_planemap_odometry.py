"""PlaneMapOdometry on exact synthetic planes, and as a pipeline of PlaneOdometry."""

from __future__ import annotations

import numpy as np
import pytest
from planemap_factory import planes_of, pose, scene_points

from planodom.config import PlanodomConfig
from planodom.odometry import Status, run_odometry
from planodom.odometry.planemap import PlaneMapOdometry


def _scans(poses, seed=10):
    """Fresh samples of the scene's surfaces seen from each pose (scan frame)."""
    out = []
    for k, T in enumerate(poses):
        inv = np.linalg.inv(T)
        sets = scene_points(np.random.default_rng(seed + k))
        out.append(planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets]))
    return out


def test_known_motion_is_recovered_exactly_without_noise():
    T_true = pose([0.5, -1.0, 6.0], [0.8, 0.2, 0.05])
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.laser_bias_m": 0.0}))
    for planes in _scans([np.eye(4), T_true]):
        est = odo.estimate(planes)
        odo.commit(est)
    rel = est.relative
    assert rel.status is Status.OK and rel.z_observed
    np.testing.assert_allclose(rel.T_prev_curr, T_true, atol=1e-9)
    assert np.all(np.isfinite(rel.covariance)) and np.all(np.linalg.eigvalsh(rel.covariance) > 0)
    # Every plane of the second scan associates with its plane of the first.
    np.testing.assert_array_equal(np.sort(rel.associations[:, 0]), np.arange(8))


def test_estimate_does_not_change_the_state():
    scans = _scans([np.eye(4), pose([0, 0, 3], [0.5, 0, 0])])
    odo = PlaneMapOdometry()
    odo.commit(odo.estimate(scans[0]))
    a = odo.estimate(scans[1])
    b = odo.estimate(scans[1])
    np.testing.assert_array_equal(a.T, b.T)
    assert odo.frame == 0


def test_a_street_of_parallel_walls_is_degenerate_along_it():
    """Ground and two parallel facades: nothing observes the motion along the street."""
    rng = np.random.default_rng(5)
    from planemap_factory import plane_points

    def street(T):
        inv = np.linalg.inv(T)
        # Ground and facade pieces along x (parallel walls, house after house).
        sets = [plane_points(rng, [0, 0, 1.0], 1.8, [x, 0, -1.8], 8, 600) for x in (-10, 0, 10)]
        sets += [plane_points(rng, [0, 1.0, 0], 6.0, [x, -6, 0], 8, 400) for x in (-12, 0, 12)]
        sets += [plane_points(rng, [0, -1.0, 0], 7.0, [x, 7, 0], 8, 400) for x in (-6, 6)]
        return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])

    odo = PlaneMapOdometry()
    results = []
    for k in range(4):
        est = odo.estimate(street(pose([0, 0, 0], [0.5 * k, 0, 0])))
        odo.commit(est)
        results.append(est.relative)
    assert all(r.status is Status.DEGENERATE for r in results[1:])
    assert results[-1].sigmas5[3] > 0.1 > results[-1].sigmas5[4]


def test_pipeline_map_runs_in_plane_odometry_on_plane_lists():
    poses = [pose([0, 0, 2 * k], [0.4 * k, 0.05 * k, 0]) for k in range(4)]
    cfg = PlanodomConfig().updated({"odometry.pipeline": "map"})
    run = run_odometry(_scans(poses), cfg)
    assert run.statuses == ["first", "ok", "ok", "ok"]
    np.testing.assert_allclose(run.poses, np.array(poses), atol=1e-6)
    assert all(r.diagnostics.pipeline.startswith("map") for r in run.results[1:])
    # "auto" on plane lists (no scans) is the paper's pipeline.
    auto = run_odometry(_scans(poses), PlanodomConfig())
    assert all(r.diagnostics.pipeline == "wocsc" for r in auto.results[1:])


def test_an_estimate_made_before_the_first_scan_is_seeded_again_commits_on_the_new_map():
    """The streaming loop may seed the first scan again (deskewed) after estimating the
    second one and still keep that estimate: its associations index the old map."""
    T_true = pose([0.5, -1.0, 6.0], [0.8, 0.2, 0.05])
    scans = _scans([np.eye(4), T_true])
    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.laser_bias_m": 0.0}))
    odo.commit(odo.estimate(scans[0]))
    stale = odo.estimate(scans[1])
    odo.reseed(scans[0][:7])  # a smaller map: the stale associations point past its end
    odo.commit(stale)
    np.testing.assert_allclose(odo.pose, T_true, atol=1e-9)
    assert odo.frame == 1 and len(odo.map) == 8


def test_five_planes_that_fix_every_direction_resolve_the_step_with_min_inliers_4():
    """A corridor seen by a sparse lidar: floor, ceiling, the two long walls and one end
    wall. Each plane fixes up to three of the six degrees of freedom, so five planes with
    normals in all three directions determine the step (``min_inliers: 4``); with 6 (the
    default, one plane per degree of freedom) the epoch is left unresolved."""
    rng = np.random.default_rng(3)
    from planemap_factory import plane_points

    def corridor(T):
        inv = np.linalg.inv(T)
        sets = [
            plane_points(rng, [0, 0, 1.0], 1.8, [0, 0, -1.8], 16, 600),  # floor
            plane_points(rng, [0, 0, -1.0], 2.0, [0, 0, 2.0], 16, 600),  # ceiling
            plane_points(rng, [0, 1.0, 0], 2.3, [0, -2.3, 0], 16, 500),  # walls
            plane_points(rng, [0, -1.0, 0], 2.3, [0, 2.3, 0], 16, 500),
            plane_points(rng, [-1.0, 0, 0], 15.0, [15, 0, 0], 3, 150),  # end wall
        ]
        return planes_of([S @ inv[:3, :3].T + inv[:3, 3] for S in sets])

    T_true = pose([0.3, -0.2, 2.0], [0.9, 0.05, 0.01])
    for min_inliers, status in ((4, Status.OK), (6, Status.UNRESOLVED)):
        cfg = PlanodomConfig().updated(
            {"planemap.laser_bias_m": 0.0, "planemap.min_inliers": min_inliers}
        )
        odo = PlaneMapOdometry(cfg)
        odo.commit(odo.estimate(corridor(np.eye(4))))
        rel = odo.estimate(corridor(T_true)).relative
        assert rel.status is status
        if status is Status.OK:
            np.testing.assert_allclose(rel.T_prev_curr, T_true, atol=1e-9)
    np.testing.assert_allclose(rel.T_prev_curr, np.eye(4), atol=1e-12)  # the prediction


@pytest.mark.parametrize("kept", ["reported", "registration"])
def test_the_pose_kept_is_the_one_reported_when_the_vertical_is_the_predictions(kept):
    """World 75 (6 mm): a ground plane tied to a stale 25-point ground landmark left the
    vertical nearly unobserved; the relative pose took the prediction's vertical, but the
    pose kept (map update, next prediction) kept Gauss-Newton's 0.36 m drift along it,
    and the next steps went 10 m off vertically, 5 cm horizontally."""
    from planodom.odometry.planemap.register import Registration

    odo = PlaneMapOdometry(PlanodomConfig().updated({"planemap.kept_pose": kept}))
    odo.frame = 3
    odo.pose = pose([0.0, 0.0, 0.3], [4.0, 1.0, 0.2])
    odo.velocity = pose([0.0, 0.0, 0.01], [0.4, 0.0, 0.002])
    T_pred = odo.pose @ odo.velocity
    drifted = T_pred.copy()
    drifted[:3, 3] += [0.002, -0.001, 0.36]  # the vertical drifted, the horizontal measured
    H = np.diag([1e8, 1e8, 1e8, 1e6, 1e6, 1e-2])  # the vertical (world z) observed by nothing
    empty = np.zeros(0, dtype=np.intp)
    reg = Registration(drifted, H, empty, empty, np.zeros(0), "map")
    rel, T = odo._result(reg, True, T_pred, None, empty)  # type: ignore[arg-type]
    assert rel.status is Status.OK and not rel.z_observed
    np.testing.assert_allclose(rel.T_prev_curr[2, 3], odo.velocity[2, 3], atol=1e-9)
    if kept == "registration":  # the registration's drift kept (before the option)
        np.testing.assert_allclose(T, drifted, atol=1e-12)
        return
    np.testing.assert_allclose(T, odo.pose @ rel.T_prev_curr, atol=1e-12)
    # the vertical is the prediction's, the measured horizontal the registration's
    np.testing.assert_allclose(T[2, 3], T_pred[2, 3], atol=1e-9)
    np.testing.assert_allclose(T[:2, 3], drifted[:2, 3], atol=1e-9)
