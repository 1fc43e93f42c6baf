"""Results folder writers: exact trajectory round trips through independent readers."""

from __future__ import annotations

import csv
import json

import numpy as np
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.datasets import read_tum
from planodom.geometry import make_transform
from planodom.results import (
    write_config,
    write_metrics,
    write_rows,
    write_trajectory,
)


def test_trajectory_files_round_trip(tmp_path) -> None:
    rng = np.random.default_rng(0)
    poses = np.stack(
        [
            make_transform(Rotation.random(random_state=rng).as_matrix(), rng.normal(size=3))
            for _ in range(5)
        ]
    )
    times = np.arange(5) * 0.1
    out = tmp_path
    write_trajectory(out, times, poses)
    t, P = read_tum(out / "poses.tum")
    np.testing.assert_array_equal(t, times)
    np.testing.assert_allclose(P, poses, atol=1e-14)
    kitti = np.loadtxt(out / "poses_kitti.txt").reshape(-1, 3, 4)
    np.testing.assert_array_equal(kitti, poses[:, :3, :4])


def test_rows_metrics_and_config(tmp_path) -> None:
    write_rows(tmp_path / "e.csv", [{"a": 1, "b": "ok"}, {"a": 2, "c": 0.5}])
    rows = list(csv.DictReader((tmp_path / "e.csv").open()))
    assert rows == [{"a": "1", "b": "ok", "c": ""}, {"a": "2", "b": "", "c": "0.5"}]
    write_metrics(tmp_path, {"x": float("nan"), "y": np.float64(2.0), "z": [np.inf]})
    assert json.loads((tmp_path / "metrics.json").read_text()) == {"x": None, "y": 2.0, "z": [None]}
    cfg = PlanodomConfig()
    write_config(tmp_path, cfg)
    assert PlanodomConfig.from_yaml(tmp_path / "config.yaml") == cfg


def test_clock_measurements_go_to_timing_json(tmp_path) -> None:
    """metrics.json held epochs_per_second, so two runs of one command differed in it."""
    import json

    from planodom.results import write_metrics

    metrics = {"ate_rmse_m": 0.5, "epochs_per_second": 3.0}
    metrics |= {"odometry": {"epochs_per_second": float("nan"), "epochs": 4.0}}
    write_metrics(tmp_path, metrics)
    assert json.loads((tmp_path / "metrics.json").read_text()) == {
        "ate_rmse_m": 0.5,
        "odometry": {"epochs": 4.0},
    }
    timing = json.loads((tmp_path / "timing.json").read_text())
    assert timing == {"epochs_per_second": 3.0, "odometry": {"epochs_per_second": None}}
    (tmp_path / "timing.json").unlink()
    write_metrics(tmp_path, {"ate_rmse_m": 0.5})
    assert not (tmp_path / "timing.json").exists()
