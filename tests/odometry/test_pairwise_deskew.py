"""The candidate deskewing refinement on the pairwise pipelines only
(``odometry.pairwise_deskew``, :mod:`planodom.odometry.pairwise_deskew`)."""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.odometry import run_odometry
from planodom.odometry.pairwise_deskew import PASSES_OPTIONS, with_pairwise_deskew
from planodom.simulation import simulate_named

ON = {"odometry.pairwise_deskew": "passes_moments"}


def test_a_2d_rig_takes_the_candidates_fields_unless_set():
    """On a 2D rig's scans every field of the candidate takes its value; one the config
    sets explicitly keeps the user's; ``streaming`` changes nothing."""
    sim = simulate_named("paper-loop", "isoclinal", noise=0.006, seed=0, n_epochs=2,
                         motion="continuous")  # fmt: skip
    on = PlanodomConfig().updated(ON, source="t")
    odo = with_pairwise_deskew(on, sim.scans).odometry
    assert {k: getattr(odo, k) for k in PASSES_OPTIONS} == PASSES_OPTIONS
    mine = on.updated({"odometry.deskew_passes": 2}, source="t")
    odo = with_pairwise_deskew(mine, sim.scans).odometry
    assert odo.deskew_passes == 2 and odo.refinement == "moments"
    default = PlanodomConfig()
    assert with_pairwise_deskew(default, sim.scans) is default
    assert with_pairwise_deskew(on, []).odometry.deskew_passes == 1  # planes: pairwise


def test_the_2d_rig_run_is_the_candidates():
    """A 2D-rig run with the value is the run with the candidate's fields set one by one
    (the same poses to the bit)."""
    sim = simulate_named("paper-loop", "isoclinal", noise=0.006, seed=0, n_epochs=6,
                         motion="continuous")  # fmt: skip
    fields = {f"odometry.{k}": v for k, v in PASSES_OPTIONS.items()}
    by_hand = run_odometry(sim, PlanodomConfig().updated(fields, source="t"), sim.rig).poses
    resolved = run_odometry(sim, PlanodomConfig().updated(ON, source="t"), sim.rig).poses
    assert np.array_equal(resolved, by_hand)
    assert not np.array_equal(resolved, run_odometry(sim, PlanodomConfig(), sim.rig).poses)


def test_the_lidar_path_is_unchanged():
    """A spinning lidar (the plane map) runs as without the value, to the bit, though the
    candidate's passes would change it."""
    sim = simulate_named("urban-canyon", "lidar32", noise=0.006, seed=1, n_epochs=5,
                         motion="continuous")  # fmt: skip
    on = PlanodomConfig().updated(ON, source="t")
    assert with_pairwise_deskew(on, sim.scans) is on
    default = run_odometry(sim, PlanodomConfig(), sim.rig).poses
    assert np.array_equal(run_odometry(sim, on, sim.rig).poses, default)
    passes = PlanodomConfig().updated({"odometry.deskew_passes": 1}, source="t")
    assert not np.array_equal(run_odometry(sim, passes, sim.rig).poses, default)
