"""Smoothing end to end on the simulator, the comparison experiment and the benchmark."""

from __future__ import annotations

import numpy as np
import pytest
from experiment_scripts import load_script
from pose_checks import pose_error

from planodom.config import PlanodomConfig
from planodom.experiments.simulated import Simulation
from planodom.experiments.smoothing import run_smoothing_experiment
from planodom.geometry import invert_transform
from planodom.simulation import simulate_named
from planodom.smoothing.run import run_smoothing
from planodom.smoothing.synthetic import make_sequence


@pytest.fixture(scope="module")
def loop():
    return simulate_named("paper-loop", "isoclinal", noise=0.0, seed=1, n_epochs=20,
                          motion="snapshot")  # fmt: skip


@pytest.mark.parametrize("mode", ["batch", "windowed"])
def test_noise_free_loop_is_smoothed_to_the_truth(loop, mode: str) -> None:
    run = run_smoothing(loop, PlanodomConfig(), window=8, delta=3, mode=mode)
    gt = invert_transform(loop.poses[0])[None] @ loop.poses
    errors = np.array([pose_error(a, b) for a, b in zip(run.poses, gt, strict=True)])
    assert errors[:, 0].max() < 1e-5 and errors[:, 1].max() < 1e-3
    assert run.config.smoothing.window == 8 and run.config.smoothing.delta_max == 3
    # the loop declares a vehicle: the smoothing's config (written as config.yaml) and its
    # odometry's resolve the platform alike
    assert run.odometry.config is not None
    for cfg in (run.config, run.odometry.config):
        assert cfg.odometry.platform == "vehicle" and cfg.odometry.start_vehicle_twist
    assert {r.delta for r in run.relatives} == {1, 2, 3}
    assert run.result.stats.plane_factors > 0
    if mode == "batch":
        assert run.result.covariances is not None and run.result.covariances.shape == (20, 6, 6)


def test_smoothing_experiment_writes_its_figures_and_tables(tmp_path) -> None:
    res = run_smoothing_experiment(
        tmp_path, noise_levels=(0.0,), scenes=("paper-loop",), window=5, delta=2,
        simulation=Simulation(n_epochs=10),
    )  # fmt: skip
    assert [r["method"] for r in res.tables["summary"]] == [
        "odometry d=1", "odometry d=D", "windowed", "batch",
    ]  # fmt: skip
    assert len(res.tables["nees"]) == 1 and np.isfinite(res.tables["nees"][0]["mean_nees6"])
    for path in res.files.values():
        assert path.exists() and path.stat().st_size > 0
    assert "windowed" in (tmp_path / "summary.md").read_text()


def test_benchmark_script_runs_on_a_short_sequence() -> None:
    bench = load_script("bench_smoothing")
    seq = make_sequence(15, seed=3, sigma_rotation=1e-3, sigma_translation=0.01)
    rows = bench.bench(
        "synthetic", seq.planes, seq.relatives, seq.poses, PlanodomConfig().smoothing
    )
    assert [r["mode"] for r in rows] == ["batch", "windowed"]
    assert all(r["epochs_per_s"] > 0 for r in rows)
