"""The order of scan files: numbers in names compared as numbers, a leading minus a sign
(:mod:`planodom.datasets.scan_order`), in a dataset folder and a KITTI sequence. Each
scan holds one point whose x is its epoch number, so the order read is checked by hand."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from kitti_factory import make_sequence

from planodom.datasets import load_dataset
from planodom.datasets.dataset import write_times
from planodom.datasets.kitti import load_kitti_sequence
from planodom.datasets.pcd import write_pcd


def _scans(folder: Path, names: list[str], numbers: list[int]) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for name, k in zip(names, numbers, strict=True):
        write_pcd(folder / name, {"x": np.array([k + 0.5]), "y": np.ones(1), "z": np.zeros(1)})


def _order(ds) -> list[float]:
    return [float(ds[k].points[0, 0]) - 0.5 for k in range(len(ds))]


@pytest.mark.parametrize("times", [True, False])
@pytest.mark.parametrize("form", ["{}.pcd", "scan_{}.pcd"])
def test_negative_frame_numbers_come_first(tmp_path: Path, times: bool, form: str) -> None:
    # frames counted from an event: -2, -1, 0, 1, 2 were read 0, 1, 2, -1, -2 (with
    # times.txt, silently; without, refused as "numbers out of order")
    numbers = [2, -1, 0, -2, 1]  # written in no order
    _scans(tmp_path / "scans", [form.format(k) for k in numbers], numbers)
    if times:
        write_times(tmp_path / "times.txt", 0.1 * np.arange(5))
    assert _order(load_dataset(tmp_path)) == [-2, -1, 0, 1, 2]


@pytest.mark.parametrize("form", ["frame-{}.pcd", "2011-09-26-{}.pcd"])
def test_a_dash_after_a_letter_or_digit_is_a_separator(tmp_path: Path, form: str) -> None:
    numbers = [10, 2, 1, 11, 3]
    _scans(tmp_path / "scans", [form.format(k) for k in numbers], numbers)
    write_times(tmp_path / "times.txt", 0.1 * np.arange(5))
    assert _order(load_dataset(tmp_path)) == [1, 2, 3, 10, 11]


def _kitti(tmp_path: Path, names: list[str]) -> Path:
    seq = make_sequence(tmp_path, poses_beside=True)
    for f in (seq / "velodyne").iterdir():
        f.unlink()
    (seq / "poses.txt").unlink()
    for k, name in enumerate(names):
        np.array([[k + 0.5, 1.0, 0.0, 0.0]], np.float32).tofile(seq / "velodyne" / name)
    (seq / "times.txt").write_text("".join(f"{0.1 * k:.1f}\n" for k in range(len(names))))
    return seq


def test_a_kitti_sequence_with_unpadded_names_is_read_in_numeric_order(tmp_path: Path) -> None:
    # sorted as text: 0, 1, 10, 11, 2, ... with times.txt giving 0.0, 0.1, ...: the
    # scans out of order, no word
    seq = _kitti(tmp_path, [f"{k}.bin" for k in range(12)])
    assert _order(load_kitti_sequence(seq)) == list(range(12))


def test_a_kitti_sequence_skips_hidden_files(tmp_path: Path) -> None:
    # a Mac's AppleDouble file beside each scan (copied to an exFAT drive): read as a scan
    # ("4 times for ..."), as a dataset folder skips it
    seq = _kitti(tmp_path, [f"{k:06d}.bin" for k in range(3)])
    (seq / "velodyne" / "._000001.bin").write_bytes(b"\x00\x05\x16\x07" + bytes(4092))
    assert _order(load_kitti_sequence(seq)) == [0, 1, 2]
