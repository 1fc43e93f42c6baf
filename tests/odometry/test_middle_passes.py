"""The deskewing passes registered at the sweeps' middles (planodom.odometry.middle_passes,
``planemap.pass_reference_time: middle``), on a simulated spinning lidar against the truth."""

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform
from planodom.metrics import per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.odometry.middle_passes import middle_redeskewed_run
from planodom.odometry.run import OdometryRun
from planodom.simulation import simulate_named

N_EPOCHS = 12
MIDDLE = {"planemap.pass_reference_time": "middle"}


@pytest.fixture(scope="module")
def lidar():
    return simulate_named("urban-canyon", "lidar32", noise=0.0, seed=1, n_epochs=N_EPOCHS,
                          motion="continuous")  # fmt: skip


def _rotation_deg(run, sim) -> np.ndarray:
    """(N - 1,) rotation error per step, deg."""
    gt = invert_transform(sim.poses[0])[None] @ sim.poses
    err = per_epoch_errors(relative_motions(run.poses), relative_motions(gt))
    return np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))


def test_passes_through_the_true_middle_poses_give_the_true_motion(lidar):
    """sigma = 0, continuous motion: one pass deskewed along the cubic through the true
    poses at the sweeps' middles, registered there and brought to the epoch times, is
    within 1e-3 deg of the truth at every step (the cubic's error; the last step's pose
    extrapolated half a sweep past the last middle), 1e-4 deg in median, several times
    below the streaming pass (one constant twist a sweep). The first epoch is registered
    at its epoch time: extrapolated from the middles (``planemap.first_pose``) its step
    was 0.02 deg off."""
    sim = lidar
    cfg = PlanodomConfig().updated(MIDDLE | {"odometry.deskew_passes": 1,
                                             "odometry.deskew_pass_guard": "off"})  # fmt: skip
    streaming = run_odometry(sim.scans, PlanodomConfig(), sim.rig, times=sim.times)
    middles = np.array([t + 0.5 * (s.t.min() + s.t.max())
                        for t, s in zip(sim.times, sim.scans, strict=True)])  # fmt: skip
    truth = OdometryRun(sim.trajectory.poses(middles), middles, [None] * N_EPOCHS,
                        np.zeros(N_EPOCHS, int))  # fmt: skip
    run = middle_redeskewed_run(sim.scans, truth, streaming, cfg, sim.rig)
    assert np.allclose(run.times, sim.times)
    assert run.statuses[1:] == ["ok"] * (N_EPOCHS - 1)
    rot = _rotation_deg(run, sim)
    assert rot.max() < 1e-3, rot
    assert np.median(rot) < 1e-4, rot
    rms = np.sqrt(np.mean(rot**2))
    assert np.sqrt(np.mean(_rotation_deg(streaming, sim) ** 2)) > 3 * rms


def test_middle_passes_from_the_streaming_poses_get_closer_to_the_truth(lidar):
    """From the streaming pass's own poses, two passes at the middles take the rotation
    rms per step below half the streaming pass's (sigma = 0, continuous motion)."""
    sim = lidar
    streaming = run_odometry(sim.scans, PlanodomConfig(), sim.rig, times=sim.times)
    cfg = PlanodomConfig().updated(MIDDLE | {"odometry.deskew_passes": 2})
    run = run_odometry(sim.scans, cfg, sim.rig, times=sim.times)
    assert run.statuses[1:] == ["ok"] * (N_EPOCHS - 1)
    before = np.sqrt(np.mean(_rotation_deg(streaming, sim) ** 2))
    after = np.sqrt(np.mean(_rotation_deg(run, sim) ** 2))
    assert after < 0.5 * before, (after, before)
    assert run.seconds["deskew"] > 0


def test_a_bad_pass_reference_time_is_one_line_naming_the_field():
    from planodom.errors import ConfigError

    with pytest.raises(ConfigError, match="pass_reference_time") as info:
        PlanodomConfig().updated({"planemap.pass_reference_time": "start"})
    assert "\n" not in str(info.value)
