"""The whole streaming run (:mod:`planodom.odometry.run`): the pairwise pipelines'
scans registered at their middles (``odometry.pairwise_reference_time``)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import invert_transform
from planodom.metrics import per_epoch_errors, relative_motions
from planodom.odometry import run_odometry
from planodom.simulation.random_world import random_world, simulate_world
from planodom.simulation.rigs import rig_from_name
from planodom.simulation.simulate import simulate
from planodom.simulation.trajectory import paper_loop_trajectory
from planodom.simulation.worlds import scene_from_name


def _rotation_errors_deg(poses: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """(E-1,) rotation error of each step against the truth, degrees."""
    err = per_epoch_errors(relative_motions(poses), relative_motions(truth))
    return np.degrees(np.sqrt(err["roll"] ** 2 + err["pitch"] ** 2 + err["yaw"] ** 2))


def test_middle_reference_on_a_rolling_2d_rig_is_closer_to_the_truth():
    # generalisation world 46: a 2D rig rolling up to 1 deg per 0.2 s epoch, back and
    # forth every 1.6 s; the twist from the step before lags each epoch's sweeps
    world = random_world(46, rig="rig2d")
    sim = simulate_world(world, 0.0, n_epochs=16)
    truth = invert_transform(sim.poses[0])[None] @ sim.poses
    # the reference time alone: with ``refine_unmeasured: prediction`` (the default) the
    # degenerate first step's velocity is kept, not pulled by the noise-free planes' weak
    # information, and epochs 3-6 err 0.1-0.8 deg either way (rms middle 0.136 -> 0.313)
    runs = {}
    for when in ("epoch", "middle"):
        change = {"odometry.pairwise_reference_time": when, "odometry.refine_unmeasured": "prior"}
        cfg = PlanodomConfig().updated(change)
        runs[when] = run_odometry(sim, cfg)
        assert np.allclose(runs[when].times, sim.times)  # poses at the epoch times
    start, middle = (_rotation_errors_deg(runs[w].poses, truth)[2:] for w in ("epoch", "middle"))
    assert np.sqrt(np.mean(middle**2)) < 0.5 * np.sqrt(np.mean(start**2))
    assert runs["middle"].statuses[7:] == ["ok"] * 9
    assert np.max(middle[5:]) < 0.06  # sigma 0: what is left is the curve's, not a lag


def test_moments_kept_to_the_deskewing_passes_leave_the_streaming_pass_the_defaults():
    """``moment_passes: deskew_passes`` without passes: the streaming pass refines the
    translation, so the run is the default config's, epoch for epoch (the moments in
    every pass give another run)."""
    sim = simulate(scene_from_name("paper-loop"), paper_loop_trajectory(),
                   rig_from_name("isoclinal"), n_epochs=8, noise_sigma=0.006,
                   motion="continuous")  # fmt: skip
    kept = PlanodomConfig().updated(
        {"odometry.refinement": "moments", "odometry.moment_passes": "deskew_passes"}, source="t"
    )
    default = run_odometry(sim, PlanodomConfig(), sim.rig).poses
    assert np.array_equal(run_odometry(sim, kept, sim.rig).poses, default)
    everywhere = kept.updated({"odometry.moment_passes": "all"}, source="t")
    assert not np.array_equal(run_odometry(sim, everywhere, sim.rig).poses, default)
