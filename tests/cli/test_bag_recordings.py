"""The CLI on bags as other drivers and recorders leave them: per-point times in another
unit, several point-cloud topics, unfinished recordings, a bag where a trajectory belongs.
Each case a warning naming the topic and field, or one error line naming the way out."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest
from bag_factory import STATIC_TF, T_BASE, Sensor, write_bag
from cli_checks import fails
from typer.testing import CliRunner

from planodom.cli import app

runner = CliRunner()


@pytest.fixture(scope="module")
def us_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A ROS 1 bag of an Ouster-like cloud whose uint32 ``t`` is in microseconds."""
    path = tmp_path_factory.mktemp("bags") / "us.bag"
    write_bag(path, 1, [Sensor("/points", "lidar", 0, "ouster_us")], STATIC_TF, T_BASE)
    return path


def test_run_and_convert_say_the_time_unit_chosen(us_bag: Path, tmp_path: Path) -> None:
    """Integer microseconds were read as nanoseconds without a word."""
    result = runner.invoke(app, ["run", str(us_bag), "--out", str(tmp_path / "run")])
    assert result.exit_code == 0, result.output
    warning = [line for line in result.stderr.splitlines() if "time field" in line]
    assert len(warning) == 1, result.stderr
    assert warning[0].startswith("warning: topic '/points': time field 't' (uint32) read as ")
    assert "microseconds, not nanoseconds" in warning[0]
    notes = json.loads((tmp_path / "run" / "metrics.json").read_text())["recording_notes"]
    assert notes == [warning[0].removeprefix("warning: ")]
    result = runner.invoke(app, ["convert", str(us_bag), str(tmp_path / "ds")])
    assert result.exit_code == 0, result.output
    assert "read as microseconds" in result.stderr


def test_unfinished_recordings_name_the_reindex(us_bag: Path, tmp_path: Path) -> None:
    """A .bag.active file was 'not a directory'; ROS 2 storage without metadata.yaml
    'files with unknown extensions'; a ROS 1 bag cut short a damaged index, no way out.
    (A complete storage file given by itself is read alone: test_bag_recorders.)"""
    active = tmp_path / "rec.bag.active"
    shutil.copy(us_bag, active)
    fails(["run", active, "--out", tmp_path / "o"], "unfinished ROS 1", "rosbag reindex")
    fails(["convert", active, tmp_path / "o"], "unfinished ROS 1", "rosbag reindex")
    ros2 = tmp_path / "ros2"
    write_bag(ros2, 2, [Sensor("/points", "lidar", 0, "velodyne")], STATIC_TF, T_BASE)
    (ros2 / "metadata.yaml").unlink()
    (db3,) = ros2.glob("*.db3")
    fails(["run", ros2, "--out", tmp_path / "o"], "no metadata.yaml", "ros2 bag reindex")
    shutil.copy(db3, ros2 / "part_1.db3")  # two storage files: the folder names no file
    fails(["run", ros2, "--out", tmp_path / "o"], "ros2 bag reindex", absent=("itself",))
    result = runner.invoke(app, ["run", str(db3), "--out", str(tmp_path / "alone")])
    assert result.exit_code == 0, result.output
    assert "warning: part_1.db3 beside " in result.stderr
    assert (tmp_path / "alone" / "poses.tum").is_file()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(us_bag.read_bytes()[:5000])
    fails(["run", cut, "--out", tmp_path / "o"], "cut.bag: cannot read bag", "rosbag reindex")
    assert not (tmp_path / "o").exists()


def test_eval_against_a_bag_names_the_conversion(us_bag: Path, tmp_path: Path) -> None:
    """A bag as the reference was 'not a trajectory file (not UTF-8 text)'."""
    est = tmp_path / "est.tum"
    est.write_text("0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n")
    fails(["eval", est, us_bag], "us.bag is a ROS bag", "convert BAG OUT --gt-topic")
    packed = tmp_path / "rec_0.mcap.zstd"  # a storage file compressed whole: not UTF-8 text
    packed.write_bytes(bytes([0x28, 0xB5, 0x2F, 0xFD]) + bytes(60))
    fails(["eval", est, packed], "rec_0.mcap.zstd is a ROS bag")


def test_run_on_a_reference_over_part_of_the_run_estimates_every_epoch(tmp_path: Path) -> None:
    """``run`` with a reference recorded for the first 0.25 s of a 0.6 s lidar bag wrote the
    poses of the 3 epochs it spans only. Every epoch is estimated, as without a reference
    (the same poses.tum to the byte); the metrics are over those 3 and say so."""
    from bag_factory import T0_NS, true_pose

    from planodom.datasets.tum import read_tum
    from planodom.metrics import summarize

    def odom(bw) -> None:
        for k in range(71):  # 200 Hz from 0.1 s before the first sweep to 0.25 s after it
            stamp = T0_NS - 100_000_000 + k * 5_000_000
            bw.write("/odom", bw.odometry(stamp, true_pose(stamp / 1e9)), stamp)

    bag = tmp_path / "half.bag"
    lidar = [Sensor("/points", "lidar", 0, "velodyne")]
    write_bag(bag, 1, lidar, STATIC_TF, T_BASE, duration_s=0.6, odom=False, extra=odom)
    for name, more in (("half", ["--gt-topic", "/odom"]), ("none", [])):
        result = runner.invoke(app, ["run", str(bag), "--out", str(tmp_path / name), *more])
        assert result.exit_code == 0, result.output
    poses = (tmp_path / "half" / "poses.tum").read_bytes()
    assert poses == (tmp_path / "none" / "poses.tum").read_bytes()
    times, est = read_tum(tmp_path / "half" / "poses.tum")
    assert len(times) == 6
    metrics = json.loads((tmp_path / "half" / "metrics.json").read_text())
    assert (metrics["epochs"], metrics["evaluated_epochs"]) == (6, 3)
    truth = summarize(est[:3], true_pose(times[:3]))  # the epochs at 0, 0.1, 0.2 s
    for key in ("ate_rmse_m", "rpe_trans_rmse_m", "drift_m"):
        assert metrics[key] == pytest.approx(truth[key], abs=1e-4)
    assert "spans 3 of the 6 epochs" in metrics["recording_notes"][0]


def test_skip_bad_scans_reads_a_split_recording_without_its_broken_part(tmp_path: Path) -> None:
    """A ROS 2 split recording's middle part lost: refused naming the part (and the flag);
    with --skip-bad-scans run reads the others, warns of the part and its time span, and
    reports the epochs after the gap, as for dropped scans. The bag is left as it was."""
    from bag_factory import T0_NS, split_ros2_bag

    whole, rec = tmp_path / "whole", tmp_path / "rec"
    write_bag(whole, 2, [Sensor("/points", "lidar", 0, "velodyne")], STATIC_TF, T_BASE)
    split_ros2_bag(whole, rec, [T0_NS + 350_000_000, T0_NS + 750_000_000])
    (rec / "rec_1.db3").unlink()
    args = ["run", str(rec), "--gt-topic", "/odom", "--out"]
    fails(
        [*args, tmp_path / "refused"],
        "rec_1.db3, part 2 of the 3 metadata.yaml lists, is missing; --skip-bad-scans",
    )
    result = runner.invoke(app, [*args, str(tmp_path / "run"), "--skip-bad-scans"])
    assert result.exit_code == 0, result.output
    (warning,) = [w for w in result.stderr.splitlines() if "rec_1.db3" in w]
    metrics = json.loads((tmp_path / "run" / "metrics.json").read_text())
    assert warning.removeprefix("warning: ") in metrics["recording_notes"]
    assert "a gap between epoch 3" in warning and metrics["epochs_after_gaps"] == [4]
    assert metrics["epochs"] == 8  # of the whole bag's 12
    result = runner.invoke(app, ["convert", str(rec), str(tmp_path / "ds"), "--skip-bad-scans"])
    assert result.exit_code == 0 and "a gap between epoch 3" in " ".join(result.stderr.split())
    assert len(list((tmp_path / "ds" / "scans").iterdir())) == 8
    assert sorted(p.name for p in rec.iterdir()) == ["metadata.yaml", "rec_0.db3", "rec_2.db3"]
