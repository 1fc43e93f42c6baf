"""planodom eval's reading and association: shifted and subsampled timestamps, KITTI files."""

from __future__ import annotations

import json

import numpy as np
import pytest
from cli_checks import fails
from plot_checks import assert_nontrivial_png
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import write_tum
from planodom.datasets.kitti import write_kitti_poses
from planodom.errors import DatasetError
from planodom.evaluation import Trajectory, associate, evaluate, read_trajectory
from planodom.geometry import transform_from_rpy_xyz

runner = CliRunner()
TIMES = 1.7e9 + np.arange(40) * 0.1
GT = np.stack(
    [transform_from_rpy_xyz(0, 0, 0.05 * k, 0.5 * k, np.sin(0.2 * k), 0) for k in range(40)]
)


def test_association_pairs_nearest_times_within_max_diff(tmp_path) -> None:
    # every other pose, 4 ms late, with a 0.2 m offset in y on pose 20 only
    est = GT[::2].copy()
    est[10, 1, 3] += 0.2
    write_tum(tmp_path / "gt.tum", TIMES, GT)
    write_tum(tmp_path / "est.tum", TIMES[::2] + 0.004, est)
    times, e, g = associate(
        read_trajectory(tmp_path / "est.tum"), read_trajectory(tmp_path / "gt.tum")
    )
    np.testing.assert_allclose(times, TIMES[::2])
    np.testing.assert_allclose(g, GT[::2], atol=1e-12)  # through quaternions
    m = evaluate(e, g, "none")
    assert m["ate_max_m"] == pytest.approx(0.2, abs=1e-9) and m["epochs"] == 20
    # 4 ms is beyond a 3 ms limit: nothing matches; --offset puts them back
    with pytest.raises(DatasetError, match="no pose within 0.003 s"):
        associate(
            read_trajectory(tmp_path / "est.tum"), read_trajectory(tmp_path / "gt.tum"), 0.003
        )
    times, _, _ = associate(
        read_trajectory(tmp_path / "est.tum"), read_trajectory(tmp_path / "gt.tum"), 0.003, -0.004
    )
    assert len(times) == 20


def test_kitti_files_pair_by_index(tmp_path) -> None:
    write_kitti_poses(tmp_path / "est.txt", GT)
    write_tum(tmp_path / "gt.tum", TIMES, GT)
    est = read_trajectory(tmp_path / "est.txt")
    assert est.times is None and len(est.poses) == 40
    times, e, g = associate(est, read_trajectory(tmp_path / "gt.tum"))
    np.testing.assert_array_equal(times, TIMES)
    short = Trajectory(tmp_path / "est.txt", GT[:5], None)
    with pytest.raises(DatasetError, match="same count"):
        associate(short, read_trajectory(tmp_path / "gt.tum"))
    (tmp_path / "bad.txt").write_text("1 2 3\n")
    with pytest.raises(DatasetError, match="bad.txt: not a TUM"):
        read_trajectory(tmp_path / "bad.txt")


def test_eval_command_aligns_and_writes_metrics_and_plots(tmp_path) -> None:
    # the estimate in another world frame (yawed 0.7 rad, shifted): se3 and 4dof undo it
    T = transform_from_rpy_xyz(0, 0, 0.7, 3.0, -2.0, 0.0)
    write_tum(tmp_path / "gt.tum", TIMES, GT)
    write_tum(tmp_path / "est.tum", TIMES + 0.002, T @ GT)
    for align, ate in (("none", None), ("se3", 0.0), ("4dof", 0.0)):
        out = tmp_path / align
        args = ["eval", tmp_path / "est.tum", tmp_path / "gt.tum", "--align", align, "--out", out]
        result = runner.invoke(app, [str(a) for a in args])
        assert result.exit_code == 0, result.output
        metrics = json.loads((out / "metrics.json").read_text())
        assert metrics["matched_poses"] == 40 and metrics["align"] == align
        if ate is None:
            assert metrics["ate_rmse_m"] > 1.0
        else:
            assert metrics["ate_rmse_m"] == pytest.approx(ate, abs=1e-9)
    assert_nontrivial_png(tmp_path / "se3" / "trajectory.png")
    assert_nontrivial_png(tmp_path / "se3" / "errors.png")
    bad = runner.invoke(
        app, ["eval", str(tmp_path / "est.tum"), str(tmp_path / "gt.tum"), "--align", "sim3"]
    )
    assert bad.exit_code == 2 and "--align" in bad.output


def test_eval_against_a_reference_over_part_of_the_run_says_so(tmp_path) -> None:
    """A reference for the first 15 of 40 poses gave errors over 15 poses, said only in the
    table's title and ``matched_poses``: a warning names the 25 without a reference."""
    write_tum(tmp_path / "gt.tum", TIMES[:15], GT[:15])
    write_tum(tmp_path / "est.tum", TIMES, GT)
    args = ["eval", tmp_path / "est.tum", tmp_path / "gt.tum", "--out", tmp_path / "e"]
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    assert result.stderr.startswith(
        f"warning: 25 of the 40 poses of {tmp_path / 'est.tum'} have no reference pose "
        "within 0.01 s (the reference spans part of the run?): the errors are over the 15 "
        "matched"
    )
    metrics = json.loads((tmp_path / "e" / "metrics.json").read_text())
    assert (metrics["matched_poses"], metrics["estimate_poses"]) == (15, 40)
    assert metrics["ate_rmse_m"] == pytest.approx(0.0, abs=1e-9)


def test_eval_pairs_no_two_poses_across_a_gap_in_the_reference(tmp_path) -> None:
    """A reference with a gap (poses 15-24 missing, a GNSS outage) paired pose 14 with 25 as
    one RPE step: an estimate whose steps are each about 1 cm too long had a 10-step error
    there. Only the pairs of consecutive estimated poses are compared now."""
    est = GT.copy()
    for k in range(40):  # pose k is k cm ahead in its own x: each step 1 cm too long
        est[k] = GT[k] @ transform_from_rpy_xyz(0, 0, 0, 0.01 * k, 0, 0)
    kept = np.r_[0:15, 25:40]
    write_tum(tmp_path / "gt.tum", TIMES[kept], GT[kept])
    write_tum(tmp_path / "est.tum", TIMES, est)
    args = ["eval", tmp_path / "est.tum", tmp_path / "gt.tum", "--out", tmp_path / "e"]
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code == 0, result.output
    metrics = json.loads((tmp_path / "e" / "metrics.json").read_text())
    assert metrics["matched_poses"] == 30
    # the error of step k -> k+1: inv(gt_k_k+1) @ est_k_k+1, by hand
    steps = [k for k in range(39) if k in kept and k + 1 in kept]
    assert len(steps) == 28
    errors = []
    for k in steps:
        gt_step = np.linalg.inv(GT[k]) @ GT[k + 1]
        est_step = np.linalg.inv(est[k]) @ est[k + 1]
        errors.append(np.linalg.norm((np.linalg.inv(gt_step) @ est_step)[:3, 3]))
    assert metrics["rpe_trans_max_m"] == pytest.approx(max(errors), abs=1e-9)
    assert metrics["rpe_trans_rmse_m"] == pytest.approx(np.sqrt(np.mean(np.square(errors))))
    across = np.linalg.inv(np.linalg.inv(GT[14]) @ GT[25]) @ np.linalg.inv(est[14]) @ est[25]
    assert np.linalg.norm(across[:3, 3]) > 3 * max(errors)  # the pair left out
    assert "no relative error pairs two poses across the unmatched ones" in result.stderr
    assert "the drift's distance takes the reference's straight line across a gap" in " ".join(
        result.stderr.split()
    )
    # the drift's distance: the reference's steps, and the straight line 14 -> 25 (said)
    length = sum(np.linalg.norm(GT[k + 1, :3, 3] - GT[k, :3, 3]) for k in steps)
    chord = np.linalg.norm(GT[25, :3, 3] - GT[14, :3, 3])
    assert metrics["distance_m"] == pytest.approx(length + chord, rel=1e-9)


def test_csv_euroc_and_empty_references_are_named(tmp_path) -> None:
    """Before: 'not a TUM (8 numbers per line) or KITTI (12 numbers) trajectory; the first
    line has 1 fields' for each."""
    path = tmp_path / "ref.csv"
    path.write_text("timestamp,tx,ty,tz,qx,qy,qz,qw\n0,0,0,0,0,0,0,1\n")
    with pytest.raises(DatasetError, match=r"ref.csv: values separated by commas \(8 per line"):
        read_trajectory(path)
    euroc = "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w []\n"
    path.write_text(euroc + "1403636579758555392," + ",".join(["0"] * 15) + ",1\n")
    with pytest.raises(DatasetError, match=r"ref.csv: a EuRoC ground-truth CSV .*evo_traj euroc"):
        read_trajectory(path)
    path.write_text("# timestamp tx ty tz qx qy qz qw\n\n")
    with pytest.raises(DatasetError, match=r"ref.csv: no poses in the trajectory file"):
        read_trajectory(path)


def test_a_reference_in_nanoseconds_is_named_by_its_span(tmp_path) -> None:
    times = np.arange(20) * 0.1
    poses = np.tile(np.eye(4), (20, 1, 1))
    poses[:, 0, 3] = times
    write_tum(tmp_path / "est.tum", times, poses)
    write_tum(tmp_path / "ref.tum", times * 1e9, poses)
    line = fails(["eval", tmp_path / "est.tum", tmp_path / "ref.tum"], "1 pose matched")
    assert "reference 0..1.9e+09 s; one lasts 1e+09 times the other: another time unit?" in line
