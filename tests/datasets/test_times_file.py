"""A ``times.txt`` beside ``poses.tum``: not read (``poses.tum`` gives the epoch times), and
said so when the two disagree."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from dataset_factory import make_scan, random_poses

from planodom.datasets import load_dataset
from planodom.datasets.dataset import write_dataset, write_times


def _dataset(tmp_path: Path) -> Path:
    rng = np.random.default_rng(2)
    scans = [make_scan(rng, 20, ()) for _ in range(3)]
    write_dataset(tmp_path / "ds", scans, 0.1 * np.arange(3), random_poses(rng, 3))
    return tmp_path / "ds"


def test_times_txt_that_disagrees_with_poses_tum_is_noted(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    write_times(root / "times.txt", 0.2 * np.arange(3))  # ignored without a word before
    ds = load_dataset(root)
    np.testing.assert_array_equal(ds.times, 0.1 * np.arange(3))  # poses.tum's, as before
    (note,) = [n for n in ds.notes if "times.txt" in n]
    assert "not read, poses.tum beside it gives the epoch times" in note
    assert "differ by up to 0.2 s" in note
    (root / "times.txt").write_text("0\n0.1\n")  # two times for three scans
    (note,) = [n for n in load_dataset(root).notes if "times.txt" in n]
    assert "2 times for 3 scan files" in note


def test_times_txt_that_agrees_is_not_noted(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    write_times(root / "times.txt", 0.1 * np.arange(3))
    assert not [n for n in load_dataset(root).notes if "times.txt" in n]
