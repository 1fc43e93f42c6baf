"""The CLI on recorded data: a ROS 2 bag of the paper's rig (four LaserScan topics,
/tf_static, an /odom reference) and a KITTI sequence, checked against the truth."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from bag_factory import T0_NS
from kitti_factory import TR, make_sequence
from plot_checks import assert_nontrivial_png
from sim_bag_factory import simulated_run, write_simulated_bag
from typer.testing import CliRunner

from planodom.cli import app
from planodom.covariances import read_covariances
from planodom.datasets import load_dataset, read_tum
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.kitti import read_kitti_poses
from planodom.datasets.rosbag import open_bag
from planodom.smoothing.run import run_smoothing

runner = CliRunner()
PICTURES = ("trajectory.png", "errors.png", "planes.png")


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("bags") / "rig"
    write_simulated_bag(path, simulated_run(epochs=10))
    return path


def invoke(*args: object) -> None:
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output


def test_run_on_a_ros2_bag(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "run"
    invoke("run", bag, "--gt-topic", "/odom", "--out", out)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["unresolved_epochs"] == 0 and metrics["epochs"] >= 10
    assert metrics["ate_rmse_m_xy"] < 0.05  # 6 mm range noise, a few metres
    times, poses = read_tum(out / "poses.tum")
    assert abs(times[0] - T0_NS / 1e9) < 0.2  # the bag's own clock, not 0
    with open_bag(bag, BagOptions(gt_topic="/odom")) as ds:
        np.testing.assert_array_equal(times, ds.times)
    for name in PICTURES:
        assert_nontrivial_png(out / name)
    # covariances.npz: the relative covariances whose sigmas epochs.csv states
    cov = read_covariances(out / "covariances.npz")
    rows = list(csv.DictReader((out / "epochs.csv").open()))
    sigma_yaw = np.array([float(r["sigma_yaw"]) for r in rows[1:]])
    np.testing.assert_allclose(np.sqrt(cov["relative"][1:, 2, 2]), sigma_yaw, rtol=1e-12)
    np.testing.assert_array_equal(cov["times"], times)
    assert cov["relative_status"][0] == "first" and np.isnan(cov["relative"][0]).all()
    assert list(cov["relative_prev"][1:]) == list(range(len(times) - 1))


def test_smooth_on_a_bag_keeps_the_marginals(bag: Path, tmp_path: Path) -> None:
    out = tmp_path / "smooth"
    invoke("smooth", bag, "--gt-topic", "/odom", "--out", out, "--delta", "2")
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["smoothing_batch"]["ate_rmse_m_xy"] < 0.05
    cov = read_covariances(out / "covariances.npz")
    marginals = cov["smoothed_batch"]
    assert marginals.shape == (len(cov["times"]), 6, 6)
    assert np.all(np.linalg.eigvalsh(marginals[1:]) > 0)  # the first is fixed (the gauge)
    # the file holds what the library computes for the same recording, exactly
    with open_bag(bag, BagOptions(gt_topic="/odom")) as ds:
        sm = run_smoothing(ds, delta=2)
    np.testing.assert_array_equal(marginals, sm.result.covariances)
    np.testing.assert_allclose(read_tum(out / "poses.tum")[1], sm.poses, atol=1e-12)  # quaternions
    for name in PICTURES:
        assert_nontrivial_png(out / name)


def test_convert_then_run_keeps_the_bag_times(bag: Path, tmp_path: Path) -> None:
    invoke("convert", bag, tmp_path / "ds", "--topic", "/scan_0", "--topic", "/scan_1")
    ds = load_dataset(tmp_path / "ds")
    assert ds.gt_poses is None and (tmp_path / "ds" / "times.txt").is_file()
    assert abs(ds.times[0] - T0_NS / 1e9) < 0.2
    assert set(np.unique(ds[3].ring)) == {0, 1}  # two topics chosen: two rings
    bad = runner.invoke(app, ["run", str(tmp_path / "ds"), "--gt-topic", "/odom"])
    assert bad.exit_code == 2 and "apply to bags only" in bad.output


def test_run_on_a_kitti_sequence(tmp_path: Path) -> None:
    seq = make_sequence(tmp_path, poses_beside=False)
    out = tmp_path / "run"
    invoke("run", seq, "--out", out)
    _, poses = read_tum(out / "poses.tum")  # Velodyne frame
    camera = read_kitti_poses(out / "poses_kitti.txt")  # KITTI's camera convention
    np.testing.assert_allclose(camera, TR @ poses @ np.linalg.inv(TR), atol=1e-12)
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["epochs"] == 3 and "kitti_translation_pct" not in metrics  # < 100 m
    for name in PICTURES:
        assert (out / name).stat().st_size > 5_000


def test_scan_names_of_each_recording(bag: Path, tmp_path: Path) -> None:
    from planodom.cli.common import ScanEpochs
    from planodom.datasets.recording import open_recording

    seq = make_sequence(tmp_path, poses_beside=True)
    assert ScanEpochs(open_recording(seq)).scan_name(1).endswith("velodyne/000001.bin")
    epochs = ScanEpochs(open_recording(bag))
    assert epochs.scan_name(2).startswith(f"{bag} epoch 2 (t = 1700000000.")
    epochs.close()


def test_smooth_without_reference_reports_the_odometry(bag: Path, tmp_path: Path) -> None:
    """No reference: not a table of dashes but what the odometry under the smoothing did."""
    result = runner.invoke(app, ["smooth", str(bag), "--out", str(tmp_path / "s")])
    assert result.exit_code == 0, result.output
    words = " ".join(result.output.split())  # the title wraps with the folder's length
    assert "(no reference)" in words and "unresolved epochs" in words
    odometry = list(csv.DictReader((tmp_path / "s" / "epochs.csv").open()))
    epochs_row = next(line for line in result.output.splitlines() if "│ epochs " in line)
    assert epochs_row.split("│")[2].strip() == str(len(odometry))
