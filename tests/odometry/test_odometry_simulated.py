"""End to end on the simulator: scans -> extraction -> odometry, against the truth."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.experiments.paper import run_paper_experiment
from planodom.experiments.simulated import Simulation
from planodom.metrics import per_epoch_errors, relative_motions
from planodom.odometry import epoch_rows, run_odometry
from planodom.simulation import simulate_named


@pytest.fixture(scope="module")
def loop():
    return simulate_named("paper-loop", "isoclinal", noise=0.0, seed=1, n_epochs=25,
                          motion="snapshot")  # fmt: skip


def test_noise_free_loop_is_recovered(loop):
    run = run_odometry(loop, PlanodomConfig(), loop.rig)
    assert run.poses.shape == (25, 4, 4) and run.n_unresolved == 0
    gt = np.linalg.inv(loop.poses[0]) @ loop.poses
    e = per_epoch_errors(relative_motions(run.poses), relative_motions(gt))
    ok = np.array([r.status == "ok" for r in run.results[1:]])
    worst = np.max(np.abs(np.column_stack(list(e.values()))), axis=1)[ok]
    # Every resolved epoch exact, but for rare extraction artefacts (a plane that is not
    # a wall); at least 90 % to 1e-6.
    assert np.mean(worst < 1e-6) >= 0.9
    assert np.median(worst) < 1e-9
    rows = epoch_rows(run)
    assert rows[0]["status"] == "first" and {"roll", "x", "sigma_y", "status"} <= set(rows[1])


def test_paper_experiment_writes_its_figures_and_tables(tmp_path):
    res = run_paper_experiment(
        tmp_path, noise_levels=(0.0, 0.02), simulation=Simulation(n_epochs=6)
    )
    assert {lr.method for lr in res.runs} == {"sda-mean", "wocsc", "planodom"}
    assert len(res.tables["precision"]) == 2 * 3 * 5 and len(res.tables["summary"]) == 6
    for path in res.files.values():
        assert path.exists() and path.stat().st_size > 0
    text = (tmp_path / "precision.md").read_text()
    assert "roll rate" in text and "sigma 20 mm" in text
    exact = [r for r in res.tables["summary"] if r["noise_m"] == 0.0]
    assert all(r["unresolved"] == 0 for r in exact)


def test_results_say_whether_their_epoch_was_spread_in_time(loop):
    # The simulator's truth: snapshot scans carry one time per epoch, continuous ones not.
    snap = run_odometry(loop, PlanodomConfig(), loop.rig)
    assert all(r.time_spread is False for r in snap.results[1:])
    moving = simulate_named("paper-loop", "isoclinal", noise=0.0, seed=1, n_epochs=4,
                            motion="continuous")  # fmt: skip
    cont = run_odometry(moving, PlanodomConfig(), moving.rig)
    assert all(r.time_spread is True for r in cont.results[1:])
