"""The command line end to end on small simulated datasets, checked against the truth."""

from __future__ import annotations

import json

import numpy as np
import yaml
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import load_dataset, read_tum
from planodom.metrics import relative_to_first

runner = CliRunner()


def test_simulate_writes_a_dataset(tmp_path) -> None:
    out = tmp_path / "sim"
    result = runner.invoke(app, ["simulate", "--out", str(out), "--epochs", "3", "--seed", "2"])
    assert result.exit_code == 0, result.output
    ds = load_dataset(out)
    assert len(ds) == 3 and ds.gt_poses is not None and ds.rig.extra["simulation"]["seed"] == 2
    # Existing dataset: a one-line error, no traceback, exit status 2.
    again = runner.invoke(app, ["simulate", "--out", str(out), "--epochs", "3"])
    assert again.exit_code == 2
    assert "already holds a dataset" in again.output and "Traceback" not in again.output


def test_run_noise_free_snapshot_recovers_the_truth(tmp_path) -> None:
    out = tmp_path / "run"
    args = ["run", "--scenario", "paper-loop", "--out", str(out), "--epochs", "12"]
    args += ["--noise", "0", "--motion", "snapshot"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    times, est = read_tum(out / "poses.tum")
    gt = relative_to_first(load_dataset(out / "dataset").gt_poses)
    np.testing.assert_allclose(est[0], np.eye(4), atol=1e-12)
    # z is unobserved by walls; the horizontal pose and the rotation are exact at sigma 0.
    np.testing.assert_allclose(est[:, :2, 3], gt[:, :2, 3], atol=1e-6)
    np.testing.assert_allclose(est[:, :3, :3], gt[:, :3, :3], atol=1e-6)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["unresolved_epochs"] == 0
    assert (out / "epochs.csv").read_text().count("\n") == 13
    assert (out / "config.yaml").exists() and (out / "poses_kitti.txt").exists()
    # the simulated dataset's rig.yaml declares a vehicle: the run's resolved config says so
    odometry = yaml.safe_load((out / "config.yaml").read_text())["odometry"]
    assert (odometry["platform"], odometry["start_vehicle_twist"]) == ("vehicle", True)


def test_run_reports_bad_input_in_one_line(tmp_path) -> None:
    missing = runner.invoke(app, ["run", str(tmp_path / "nope"), "--out", str(tmp_path / "o")])
    assert missing.exit_code == 2 and "nope" in missing.output
    neither = runner.invoke(app, ["run", "--out", str(tmp_path / "o")])
    assert neither.exit_code == 2 and "--scenario" in neither.output
    (tmp_path / "bad.yaml").write_text("odometry: {pipeline: magic}\n")
    args = ["run", "--scenario", "paper-loop", "--out", str(tmp_path / "o"), "--epochs", "2"]
    bad = runner.invoke(app, [*args, "--config", str(tmp_path / "bad.yaml")])
    assert bad.exit_code == 2 and "bad.yaml" in bad.output and "pipeline" in bad.output


def test_eval_against_truth(tmp_path) -> None:
    from planodom.datasets import write_tum
    from planodom.geometry import transform_from_rpy_xyz

    times = np.arange(5) * 0.1
    gt = np.stack([transform_from_rpy_xyz(0, 0, 0.1 * k, k, 0) for k in range(5)])
    est = gt.copy()
    est[:, 1, 3] += 0.5  # a constant 0.5 m offset, removed by the origin alignment
    est[4, 0, 3] += 0.3  # and one final error of 0.3 m
    write_tum(tmp_path / "gt.tum", times, gt)
    write_tum(tmp_path / "est.tum", times, est)
    args = ["eval", str(tmp_path / "est.tum"), str(tmp_path / "gt.tum")]
    result = runner.invoke(app, [*args, "--out", str(tmp_path / "e")])
    assert result.exit_code == 0, result.output
    line = next(x for x in result.output.splitlines() if "drift_m" in x)
    assert abs(float(line.split()[-2]) - 0.3) < 1e-9
    assert abs(json.loads((tmp_path / "e" / "metrics.json").read_text())["drift_m"] - 0.3) < 1e-9
    # times far from the reference's: nothing to associate, a one-line error
    write_tum(tmp_path / "late.tum", times + 5.0, gt)
    late = ["eval", str(tmp_path / "late.tum"), str(tmp_path / "gt.tum")]
    bad = runner.invoke(app, [*late, "--out", str(tmp_path / "f")])
    assert bad.exit_code == 2 and "late.tum" in bad.output and "--offset" in bad.output


def _error_line(result) -> str:
    """The one ``error:`` line of a refused command (exit status 2, nothing else)."""
    assert result.exit_code == 2 and result.exception is not None, result.output
    assert isinstance(result.exception, SystemExit), result.exception  # not a traceback
    lines = [x for x in result.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith("error: "), result.output
    return lines[0]


def test_eval_refuses_what_it_cannot_evaluate_in_one_line(tmp_path) -> None:
    """A non-finite --offset (inf leaked a numpy warning and blamed the files), one matched
    pose ('needs 1 <= delta < 1'), and se3 on poses along a line (evo's message naming
    neither file nor option)."""
    from planodom.datasets import write_tum
    from planodom.geometry import transform_from_rpy_xyz

    times = np.arange(5) * 0.1
    line = np.stack([transform_from_rpy_xyz(0, 0, 0, k, 0) for k in range(5)])
    write_tum(tmp_path / "gt.tum", times, line)
    write_tum(tmp_path / "one.tum", times[:1], line[:1])
    gt = str(tmp_path / "gt.tum")
    for value in ("nan", "inf"):
        args = ["eval", gt, gt, "--offset", value, "--out", str(tmp_path / "o")]
        message = _error_line(runner.invoke(app, args))
        assert message == f"error: --offset: expected a finite number of seconds, got {value}"
    args = ["eval", str(tmp_path / "one.tum"), gt, "--out", str(tmp_path / "o")]
    message = _error_line(runner.invoke(app, args))
    assert "one.tum: 1 pose matched with" in message and "2 or more" in message
    args = ["eval", gt, gt, "--align", "se3", "--out", str(tmp_path / "o")]
    message = _error_line(runner.invoke(app, args))
    assert message.startswith("error: --align se3: ") and "5 matched poses of" in message
    assert "gt.tum" in message
    assert not (tmp_path / "o").exists()


def test_zero_epochs_name_the_option_not_a_temporary_folder(tmp_path) -> None:
    """``run --scenario ... --epochs 0`` said '<out's hidden .partial folder>/dataset: no
    scans to write'; a trajectory file that is missing or binary quoted Python's error."""
    for command in (["run", "--scenario", "paper-loop"], ["simulate"]):
        args = [*command, "--epochs", "0", "--out", str(tmp_path / "o")]
        message = _error_line(runner.invoke(app, args))
        assert message == "error: --epochs 0: expected 1 or more (default: one lap)"
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "scan.bin").write_bytes(bytes(range(256)))
    for name, problem in (("missing.tum", "cannot read trajectory (No such file or directory)"),
                          ("scan.bin", "not a trajectory file (not UTF-8 text)")):  # fmt: skip
        path = tmp_path / name
        message = _error_line(runner.invoke(app, ["eval", str(path), str(path)]))
        assert message == f"error: {path}: {problem}"


def test_simulation_options_with_a_recording_and_infinite_noise_are_refused(tmp_path) -> None:
    """``run DATASET --epochs 3`` ran the whole recording, the option ignored without a word;
    ``simulate --noise inf`` wrote a dataset of NaN ranges."""
    data = tmp_path / "d"
    assert runner.invoke(app, ["simulate", "--out", str(data), "--epochs", "2"]).exit_code == 0
    for command in ("run", "smooth"):
        args = [
            command,
            str(data),
            "--epochs",
            "3",
            "--noise",
            "0.02",
            "--out",
            str(tmp_path / "o"),
        ]
        message = _error_line(runner.invoke(app, args))
        assert message == (
            "error: --noise, --epochs: options of --scenario (a simulation), not for a "
            "recording, which is read whole"
        )
    args = ["simulate", "--noise", "inf", "--epochs", "2", "--out", str(tmp_path / "s")]
    message = _error_line(runner.invoke(app, args))
    assert message == "error: noise sigma must be finite and >= 0 (m), got inf"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["d"]


def test_results_never_land_in_the_folder_of_a_ros2_bag_given_by_its_file(tmp_path) -> None:
    """``run BAG/data.db3 --out BAG/res`` wrote the results into the bag's folder (only
    the .db3 file counted as the input)."""
    from bag_factory import SCANNERS, STATIC_TF, T_BASE, write_bag

    write_bag(tmp_path / "bag", 2, SCANNERS[:1], STATIC_TF, T_BASE, duration_s=0.3)
    (data,) = [p for p in (tmp_path / "bag").iterdir() if p.suffix == ".db3"]
    for command in ("run", "smooth"):
        result = runner.invoke(app, [command, str(data), "--out", str(tmp_path / "bag" / "res")])
        assert "lies inside the input" in _error_line(result)
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.db3", "metadata.yaml"]


def test_smooth_noise_free_recovers_the_truth(tmp_path) -> None:
    out = tmp_path / "smooth"
    args = ["smooth", "--scenario", "paper-loop", "--out", str(out), "--epochs", "10"]
    args += ["--noise", "0", "--motion", "snapshot", "--delta", "2"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    _, est = read_tum(out / "poses.tum")
    _, odo = read_tum(out / "odometry.tum")
    gt = relative_to_first(load_dataset(out / "dataset").gt_poses)
    np.testing.assert_allclose(est[:, :2, 3], gt[:, :2, 3], atol=1e-5)
    np.testing.assert_allclose(est[:, :3, :3], gt[:, :3, :3], atol=1e-5)
    np.testing.assert_allclose(odo[:, :2, 3], gt[:, :2, 3], atol=1e-6)
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) == {"odometry", "smoothing_batch"}


def test_smooth_loop_closure_switches_the_mode_run(tmp_path) -> None:
    """--loop-closure sets batch loop closure in batch mode and fixed-lag loop closure with
    --mode windowed, never the other mode's (read back from the written config.yaml)."""
    import yaml

    base = ["smooth", "--scenario", "paper-loop", "--epochs", "6", "--noise", "0"]
    cases = (  # flags, (smoothing.loop_closure, smoothing.windowed_loop_closure)
        (["--no-loop-closure"], (False, False)),
        (["--window", "4", "--loop-closure"], (True, True)),
        (["--mode", "windowed", "--no-loop-closure"], (True, False)),
    )
    for i, (flags, expected) in enumerate(cases):
        out = tmp_path / f"s{i}"
        result = runner.invoke(app, [*base, "--out", str(out), *flags])
        assert result.exit_code == 0, result.output
        smoothing = yaml.safe_load((out / "config.yaml").read_text())["smoothing"]
        assert (smoothing["loop_closure"], smoothing["windowed_loop_closure"]) == expected, flags


def test_experiment_paper_small(tmp_path) -> None:
    import csv

    out = tmp_path / "paper"
    args = ["experiment", "paper", "--out", str(out), "--epochs", "6", "--levels", "0"]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    for name in ("trajectories.png", "precision.csv", "precision.md", "summary.csv"):
        assert (out / name).exists(), name
    rows = list(csv.DictReader((out / "summary.csv").open()))
    assert {r["method"] for r in rows} == {"sda-mean", "wocsc", "planodom"}
    # Noise-free: the per-epoch errors against the simulator's truth vanish.
    assert all(float(r["xy_rms_m"]) < 1e-6 and float(r["rot_rms_deg"]) < 1e-6 for r in rows)
    bad = runner.invoke(app, ["experiment", "paper", "--out", str(out), "--levels", "-1"])
    assert bad.exit_code == 2 and "--levels" in bad.output


def test_config_prints_defaults_that_load_back_unchanged(tmp_path) -> None:
    from planodom.config import PlanodomConfig

    result = runner.invoke(app, ["config"])
    assert result.exit_code == 0, result.output
    (tmp_path / "c.yaml").write_text(result.output)
    assert PlanodomConfig.from_yaml(tmp_path / "c.yaml") == PlanodomConfig()
    # a file over the defaults is resolved: its values, every other field as default
    (tmp_path / "d.yaml").write_text("odometry: {delta: 2}\n")
    again = runner.invoke(app, ["config", "--config", str(tmp_path / "d.yaml")])
    (tmp_path / "e.yaml").write_text(again.output)
    expected = PlanodomConfig().updated({"odometry.delta": 2})
    assert PlanodomConfig.from_yaml(tmp_path / "e.yaml") == expected != PlanodomConfig()


def test_version_and_shared_source_options() -> None:
    from importlib.metadata import version

    result = runner.invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"planodom {version('planodom')}"
    for command in ("run", "smooth"):  # one option set, both commands
        text = runner.invoke(app, [command, "--help"], terminal_width=200).output
        for option in ("--scenario", "--rig", "--noise", "--seed", "--epochs", "--motion"):
            assert option in text, (command, option)


def test_experiment_consistency_small(tmp_path) -> None:
    import csv

    from scipy.stats import chi2

    out = tmp_path / "consistency"
    args = ["experiment", "consistency", "--out", str(out), "--epochs", "20"]
    result = runner.invoke(app, [*args, "--levels", "0.006"])
    assert result.exit_code == 0, result.output
    rows = list(csv.DictReader((out / "odometry.csv").open()))
    assert [int(r["delta"]) for r in rows] == [1, 2, 3]
    # The reference value is chi2(5)'s median, not what the code wrote before.
    assert all(abs(float(r["chi2_median"]) - chi2.median(5)) < 1e-9 for r in rows)
    assert {"planes.csv", "smoothed.csv"} <= {p.name for p in out.iterdir()}
    bad = runner.invoke(app, [*args, "--levels", "x"])
    assert bad.exit_code == 2 and "--levels" in bad.output
