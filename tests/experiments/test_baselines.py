"""``planodom experiment baselines`` at tiny size (KISS-ICP skipped with a note if absent)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from planodom.errors import DatasetError
from planodom.experiments.baselines import MethodRun, errors, row_of, run_baselines_experiment
from planodom.geometry import transform_from_rpy_xyz
from planodom.simulation import simulate_named
from planodom.simulation.export import write_simulated_dataset


def test_baselines_table_plot_and_peers(tmp_path):
    sim = simulate_named("urban-canyon", "lidar16", noise=0.0, seed=2, n_epochs=5,
                         motion="snapshot")  # fmt: skip
    write_simulated_dataset(sim, tmp_path / "street")
    res = run_baselines_experiment([tmp_path / "street"], tmp_path / "out", limit=4)
    rows = {r["method"]: r for r in res.tables["baselines"]}
    have_kiss = importlib.util.find_spec("kiss_icp") is not None
    expected = {"planodom", "open3d-icp"} | ({"kiss-icp"} if have_kiss else set())
    assert set(rows) == expected
    assert rows["planodom"]["bad_epochs"] == "0/3"
    assert rows["planodom"]["rot_rms_deg"] < 0.01 and rows["planodom"]["trans_rms_cm"] < 0.1
    assert all(np.isfinite(r["epochs_per_s"]) for r in rows.values())
    text = res.files["baselines_md"].read_text()
    assert "| street | planodom |" in text
    assert have_kiss or "kiss-icp skipped" in text
    assert res.files["trajectories"].stat().st_size > 0


def test_errors_are_those_of_the_relative_error_transform():
    ref = np.array([transform_from_rpy_xyz(0, 0, 0.1, 1, 0)])
    est = ref @ transform_from_rpy_xyz(0, 0, np.radians(2), 0.03, 0.04)
    r, t = errors(est, ref)
    np.testing.assert_allclose(r, [2.0], atol=1e-9)
    np.testing.assert_allclose(t, [0.05], atol=1e-12)


def test_a_still_reference_has_no_drift_percentage_but_an_end_error():
    ref = np.tile(np.eye(4), (3, 1, 1))
    step = transform_from_rpy_xyz(0, 0, 0, 0.03, 0.04)
    row = row_of(MethodRun("d", "m", np.array([step, step, np.eye(4)]), 1.0, None, (0, 0)), ref)
    assert np.isnan(row["drift_pct"])
    assert row["end_cm"] == pytest.approx(10.0)  # two steps of 5 cm, straight


def test_a_recording_without_reference_is_compared_against_kiss_icp(tmp_path):
    sim = simulate_named("urban-canyon", "lidar16", noise=0.0, seed=2, n_epochs=4,
                         motion="snapshot")  # fmt: skip
    write_simulated_dataset(sim, tmp_path / "street")
    (tmp_path / "street" / "poses.tum").unlink()
    if importlib.util.find_spec("kiss_icp") is None:
        with pytest.raises(DatasetError, match="KISS-ICP"):
            run_baselines_experiment([tmp_path / "street"], tmp_path / "out")
        return
    res = run_baselines_experiment([tmp_path / "street"], tmp_path / "out")
    rows = {r["method"]: r for r in res.tables["baselines"]}
    assert set(rows) == {"planodom", "kiss-icp", "open3d-icp"}
    assert rows["kiss-icp"]["rot_rms_deg"] < 1e-6 and rows["kiss-icp"]["trans_rms_cm"] < 1e-6
    assert "errors against KISS-ICP's trajectory" in res.files["baselines_md"].read_text()
