"""The generalisation experiment at CI size: every method on a 2D-rig and a lidar world."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from planodom.cli import app
from planodom.experiments.generalisation import (
    longest_run,
    run_generalisation_experiment,
    world_for,
)
from planodom.experiments.peers import kiss_available


@pytest.fixture
def seen(monkeypatch):
    """The keyword arguments the CLI passes to the experiment (which is not run)."""
    import planodom.experiments.generalisation as generalisation
    from planodom.experiments.tables import ExperimentResult

    kwargs_seen: dict = {}

    def fake(out, **kwargs):
        kwargs_seen.update(kwargs)
        return ExperimentResult([], {}, {})

    monkeypatch.setattr(generalisation, "run_generalisation_experiment", fake)
    return kwargs_seen


def test_longest_run():
    assert longest_run(np.array([0, 1, 1, 0, 1, 1, 1, 0], bool)) == 3
    assert longest_run(np.zeros(4, bool)) == 0


def test_worlds_cover_both_kinds_of_rig():
    families = [world_for(i).description["family"] for i in range(6)]
    assert families == ["rig2d", "lidar16", "rig2d", "lidar32", "rig2d", "lidar64"]


def test_quick_experiment(tmp_path):
    res = run_generalisation_experiment(tmp_path, n_worlds=2, noise_levels=[0.006], n_epochs=10)
    methods = {"planodom", "planodom-wocsc", "oracle", "open3d-icp"}
    methods |= {"kiss-icp"} if kiss_available() else set()
    assert {r.method for r in res.runs} == methods and len(res.runs) == 2 * len(methods)
    for r in res.runs:
        assert r.poses.shape == (10, 4, 4) and np.isfinite(r.metrics["ate_xy_m"])
        if r.method == "oracle":  # noise only: far below any estimator's error
            assert r.metrics["rot_rms_deg"] < 0.05 and r.metrics["xy_rms_m"] < 0.02
    oracle_rows = [row for row in res.tables["summary"] if row["method"] == "oracle"]
    assert all(row["ate_x_oracle_median"] == 1.0 for row in oracle_rows)
    for name in ("summary.md", "summary.csv", "runs.csv", "worst_world.png", "config.yaml"):
        assert (tmp_path / name).is_file()


def test_cli_simulates_a_random_world(tmp_path):
    out = tmp_path / "sim"
    args = ["simulate", "--out", str(out), "--scene", "random", "--seed", "4", "--epochs", "2"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "random-" in result.output
    bad = CliRunner().invoke(app, ["simulate", "--out", str(tmp_path / "x"), "--scene",
                                   "random", "--rig", "sonar"])  # fmt: skip
    assert bad.exit_code == 2 and "unknown rig" in bad.output


def test_cli_takes_noise_levels_as_in_the_issue(tmp_path, seen):
    """``--noise 0 0.006 0.02 0.1`` (space-separated) reaches the experiment as four levels."""
    args = ["experiment", "generalisation", "--worlds", "3", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, [*args, "--noise", "0", "0.006", "0.02", "0.1"])
    assert result.exit_code == 0, result.output
    assert seen["noise_levels"] == [0.0, 0.006, 0.02, 0.1] and seen["n_worlds"] == 3
    bad = CliRunner().invoke(app, [*args, "bogus"])
    assert bad.exit_code == 2 and "unexpected arguments bogus" in bad.output


def test_one_rig_class_runs_only_its_worlds():
    res = run_generalisation_experiment(
        None, n_worlds=4, noise_levels=[0.0], n_epochs=3, methods=("oracle",), rigs=("lidar",)
    )
    assert sorted({r.world for r in res.runs}) == [1, 3]
    assert {r.family for r in res.runs} <= {"lidar16", "lidar32", "lidar64"}


def test_held_out_worlds_start_at_first_world(tmp_path, seen):
    """``first_world`` shifts the span: worlds 20 and 22 run as worlds (not seeds 0, 2)."""
    res = run_generalisation_experiment(
        None, n_worlds=4, noise_levels=[0.0], n_epochs=2, methods=("oracle",),
        rigs=("rig2d",), first_world=20,
    )  # fmt: skip
    assert sorted({r.world for r in res.runs}) == [20, 22]
    with pytest.raises(ValueError, match="first_world"):
        run_generalisation_experiment(None, n_worlds=1, methods=("oracle",), first_world=-1)
    args = ["experiment", "generalisation", "--worlds", "2", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, [*args, "--first-world", "30"])
    assert result.exit_code == 0, result.output
    assert seen["first_world"] == 30


def test_cli_chooses_methods(tmp_path, seen):
    """``--methods`` reaches the experiment as a list; an unknown name is one line, exit 2."""
    args = ["experiment", "generalisation", "--worlds", "2", "--out", str(tmp_path)]
    result = CliRunner().invoke(app, [*args, "--methods", "oracle, planodom-offline"])
    assert result.exit_code == 0, result.output
    assert seen["methods"] == ["oracle", "planodom-offline"]
    bad = CliRunner().invoke(app, [*args, "--methods", "oracle,icp"])
    assert bad.exit_code == 2 and "unknown icp" in bad.output


def test_offline_method_runs_the_deskewing_passes(monkeypatch):
    """planodom-offline is the configuration given with odometry.deskew_passes = 2; the
    default planodom row keeps the configuration as given."""
    import planodom.experiments.generalisation as generalisation

    passes = {}
    real = generalisation.run_odometry

    def spy(run, cfg):
        passes.setdefault(cfg.odometry.deskew_passes, 0)
        passes[cfg.odometry.deskew_passes] += 1
        return real(run, cfg)

    monkeypatch.setattr(generalisation, "run_odometry", spy)
    res = run_generalisation_experiment(
        None, n_worlds=2, noise_levels=[0.0], n_epochs=4,
        methods=("planodom", "planodom-offline"), rigs=("lidar",),
    )  # fmt: skip
    assert (
        set(passes) == {0, 2}
        and passes[0] == passes[2]
        and {r.method for r in res.runs}
        == {
            "planodom",
            "planodom-offline",
        }
    )
    with pytest.raises(ValueError, match="icp"):
        run_generalisation_experiment(None, n_worlds=1, methods=("icp",))
