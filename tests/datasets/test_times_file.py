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


def _times_only(tmp_path: Path, times: np.ndarray) -> Path:
    """A dataset whose epoch times come from ``times.txt`` alone (no poses.tum)."""
    rng = np.random.default_rng(3)
    scans = [make_scan(rng, 20, ()) for _ in range(len(times))]
    write_dataset(tmp_path / "ds", scans, 0.1 * np.arange(len(times)))
    (tmp_path / "ds" / "poses.tum").unlink(missing_ok=True)
    (tmp_path / "ds" / "times.txt").write_text("".join(f"{t:.0f}\n" for t in times))
    return tmp_path / "ds"


def test_epoch_times_in_milliseconds_from_the_start_are_noted(tmp_path: Path) -> None:
    """0, 100, 200 ... ms read as seconds: epochs 100 s apart, read without a word (the
    simulated paper loop's poses 1.7 m off)."""
    ds = _times_only(tmp_path, 100.0 * np.arange(4))
    notes = [n for n in load_dataset(ds).notes if "apart (median)" in n]
    assert len(notes) == 1
    assert notes[0].startswith(f"{ds}: the epochs lie 100 s apart (median), where a scanner")
    assert "milliseconds? the epoch times are read as seconds" in notes[0]
    ns = load_dataset(_times_only(tmp_path / "ns", 1e8 * np.arange(4))).notes
    assert any("1e+08 s apart (median)" in n and "nanoseconds?" in n for n in ns)
    seconds = load_dataset(_times_only(tmp_path / "s", np.arange(4))).notes
    assert not [n for n in seconds if "apart (median)" in n]  # 1 s apart: a slow sweep


def test_unix_milliseconds_are_named_as_such(tmp_path: Path) -> None:
    import pytest

    from planodom.errors import DatasetError

    ds = _times_only(tmp_path, 1.7e12 + 100.0 * np.arange(4))
    with pytest.raises(DatasetError, match=r"times.txt:1: time 1.7e\+12 s .*\(milliseconds\? the"):
        load_dataset(ds)
