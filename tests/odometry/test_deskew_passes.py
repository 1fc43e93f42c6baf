"""The odometry on simulated scans deskewed through the poses of neighbouring epochs
(planodom.odometry.run.redeskewed_run) and at sigma = 0 in snapshot motion, against the truth."""

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform, se3_log
from planodom.odometry import RelativePose, Status, run_odometry
from planodom.odometry.run import OdometryRun, fit_nodes, redeskewed_run, step_variances
from planodom.simulation.rigs import rig_from_name
from planodom.simulation.simulate import simulate
from planodom.simulation.trajectory import paper_loop_trajectory
from planodom.simulation.worlds import scene_from_name


def _paper_loop(n_epochs: int, motion: str, start_time: float = 0.0):
    return simulate(scene_from_name("paper-loop"), paper_loop_trajectory(),
                    rig_from_name("isoclinal"), n_epochs=n_epochs, noise_sigma=0.0,
                    motion=motion, start_time=start_time)  # fmt: skip


def _errors(run, sim, skip=()):
    """Per resolved epoch: rotation (deg) and translation (m) error of its relative pose."""
    rot, tr = [], []
    for k, r in enumerate(run.results):
        if r is None or r.status is not Status.OK or k in skip:
            continue
        truth = invert_transform(sim.poses[r.prev]) @ sim.poses[k]
        err = invert_transform(truth) @ r.T_prev_curr
        rot.append(np.degrees(np.linalg.norm(se3_log(err)[:3])))
        tr.append(np.linalg.norm(err[:3, 3]))
    return np.array(rot), np.array(tr)


N_EPOCHS = 30


@pytest.fixture(scope="module")
def continuous():
    return _paper_loop(N_EPOCHS, "continuous")


def test_scans_deskewed_through_the_true_poses_give_the_true_motion(continuous):
    """sigma = 0, continuous motion: deskewed through the true poses, every resolved epoch
    is exact to 1e-3 deg and 0.1 mm (the cubic's interpolation error; the streaming
    pass's constant twist leaves ~0.03 deg); the last, extrapolated, is left out."""
    sim = continuous
    poses = invert_transform(sim.poses[0]) @ sim.poses
    run = redeskewed_run(sim, sim.times, poses, PlanodomConfig(), sim.rig)
    rot, tr = _errors(run, sim, skip=(N_EPOCHS - 1,))
    assert len(rot) == len(sim) - 2
    assert rot.max() < 1e-3 and tr.max() < 1e-4, (rot.max(), tr.max())
    streaming = run_odometry(sim, PlanodomConfig(), sim.rig)
    assert _errors(streaming, sim)[0].max() > 10 * rot.max()


def test_passes_to_the_epoch_middles_converge_to_the_true_motion(continuous):
    """sigma = 0, continuous motion, from the streaming pass's poses (~0.03 deg and up to
    16 cm off): three passes to the epoch middles and the last one bring every resolved
    epoch within 1e-3 deg and 0.1 mm of the truth. With the paper's single consensus
    candidate: the least-squares refinement over all associated planes (the default)
    takes every plane's deskewing residue in, and one epoch here ends 0.5 mm off."""
    sim = continuous
    cfg = PlanodomConfig().updated({"odometry.deskew_passes": 3, "odometry.refinement": "none"})
    run = run_odometry(sim, cfg, sim.rig)
    rot, tr = _errors(run, sim)
    assert len(rot) == len(sim) - 1
    assert rot.max() < 1e-3 and tr.max() < 1e-4, (rot.max(), tr.max())
    assert np.sqrt(np.mean(rot**2)) < 3e-4
    assert run.seconds["deskew"] > 0


def test_unmeasured_poses_keep_the_streaming_deskewing(continuous):
    """Where no pose around an epoch was measured, the passes deskew as the streaming
    pass does: with every pose unmeasured the run is the streaming run."""
    sim = continuous
    cfg = PlanodomConfig()
    streaming = run_odometry(sim, cfg, sim.rig)
    again = redeskewed_run(sim, streaming.times, streaming.poses,
                           cfg.updated({"odometry.deskew_passes": 0}), sim.rig,
                           measured=np.zeros(len(sim), bool))  # fmt: skip
    np.testing.assert_allclose(again.poses, streaming.poses, atol=1e-12)


def test_snapshot_motion_is_exact_where_every_sweep_repeats_a_corner_point():
    """sigma = 0, snapshot motion (the paper's simulator): every resolved epoch exact to
    1e-6. Around t = 47.3 s on the paper loop every sweep of a scanner puts its last beam
    of a wall on the next facade (5.6 mm off before the group refit trimmed ends)."""
    sim = _paper_loop(6, "snapshot", start_time=47.0)
    run = run_odometry(sim, PlanodomConfig(), sim.rig)
    rot, tr = _errors(run, sim)
    assert len(rot) == 5
    assert rot.max() < 1e-6 and tr.max() < 1e-6, (rot.max(), tr.max())


def test_a_deskewed_scan_without_planes_falls_back_to_the_streaming_deskewing(continuous):
    """register_epoch(scan, t, deskewed): a deskewed scan that finds no planes (here:
    two of its points) is replaced by the scan deskewed as the streaming pass does."""
    from planodom.odometry import PlaneOdometry
    from planodom.scan import Scan

    def two_points(scan: Scan) -> Scan:
        return Scan(scan.points[:2], ring=scan.ring[:2], t=np.zeros(2))

    sim = continuous
    streaming = run_odometry(sim, PlanodomConfig(), sim.rig)
    odo = PlaneOdometry(PlanodomConfig(), sensor_origins=sim.rig.sensor_origins)
    for k in range(4):
        odo.register_epoch(sim[k], float(sim.times[k]), two_points(sim[k]) if k else None)
    np.testing.assert_allclose(np.array(odo.poses), streaming.poses[:4], atol=1e-12)


def test_lidar_scans_deskewed_through_the_true_poses_keep_their_range_image():
    """A spinning lidar (sigma = 0, continuous motion) deskewed through the true poses:
    the scans keep their times, so the range image still has its columns (with the
    times zeroed it had none and RANSAC cut the walls into fragments), and every resolved
    epoch is exact to 2e-3 deg, well below the streaming pass's constant twist."""
    sim = simulate(scene_from_name("paper-loop"), paper_loop_trajectory(),
                   rig_from_name("lidar32"), n_epochs=12, noise_sigma=0.0,
                   motion="continuous")  # fmt: skip
    poses = invert_transform(sim.poses[0]) @ sim.poses
    run = redeskewed_run(sim, sim.times, poses, PlanodomConfig(), sim.rig)
    streaming = run_odometry(sim, PlanodomConfig(), sim.rig)
    assert np.all(run.n_planes <= streaming.n_planes + 2), (run.n_planes, streaming.n_planes)
    rot, _ = _errors(run, sim, skip=(len(sim) - 1,))
    assert len(rot) == len(sim) - 2 and rot.max() < 2e-3, rot
    assert _errors(streaming, sim)[0].max() > 3 * rot.max()


def test_passes_along_the_least_squares_curve_converge_to_the_true_motion(continuous):
    """sigma = 0, continuous motion: the passes along the degree-5 fit to the increments over
    0.8 s (9 nodes at 10 Hz) bring every resolved epoch within 1e-3 deg and 0.1 mm of the
    truth, as the interpolation does (the fit is exact for a polynomial motion)."""
    sim = continuous
    cfg = PlanodomConfig().updated({"odometry.deskew_passes": 3, "odometry.refinement": "none",
                                    "odometry.deskew_fit": "increments", "odometry.deskew_order": 5,
                                    "odometry.deskew_fit_span_s": 0.8})  # fmt: skip
    run = run_odometry(sim, cfg, sim.rig)
    rot, tr = _errors(run, sim)
    assert len(rot) == len(sim) - 1
    assert rot.max() < 1e-3 and tr.max() < 1e-4, (rot.max(), tr.max())


def test_fit_nodes_follow_the_span_and_the_epoch_period():
    times = np.arange(50) * 0.1
    cfg = PlanodomConfig().updated({"odometry.deskew_fit": "weighted"})
    assert fit_nodes(cfg, times) == 6  # 0.5 s at 10 Hz
    assert fit_nodes(cfg, times * 0.5) == 11  # 0.5 s at 20 Hz
    assert fit_nodes(cfg, times * 10) == 5  # at least deskew_order + 2
    assert fit_nodes(PlanodomConfig(), times) is None  # interpolation


def test_step_variances_come_from_the_steps_covariances():
    """The 5x5 (roll, pitch, yaw, x, y) diagonal per step, z the mean of x and y, infinite
    where unmeasured, the first epoch as the second."""
    cov = np.diag([1.0, 2.0, 3.0, 4.0, 6.0])
    results = [None] + [
        RelativePose(np.eye(4), cov * k, Status.OK, prev=k - 1, curr=k) for k in range(1, 4)
    ]
    run = OdometryRun(np.tile(np.eye(4), (4, 1, 1)), np.arange(4.0), results, np.zeros(4, int))
    v = step_variances(run, np.array([True, True, False, True]))
    np.testing.assert_allclose(v[1], [1, 2, 3, 4, 6, 5])
    np.testing.assert_allclose(v[0], v[1])
    assert np.all(np.isinf(v[2]))
    np.testing.assert_allclose(v[3], 3 * np.array([1, 2, 3, 4, 6, 5]))
