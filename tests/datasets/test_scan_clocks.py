"""Dataset folders whose PCD scans carry point times as drivers and converters write them:
absolute times on another clock than ``poses.tum``'s, offsets counted from the recording's
start, times under a name not read, one time for all the points. Each refused in one line
naming the file, or read and noted."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import load_dataset
from planodom.datasets.pcd import write_pcd
from planodom.errors import DatasetError

T0 = 1_700_000_000.0
PERIOD = 0.1


def _dataset(path: Path, fields: Callable[[np.ndarray, float], dict[str, np.ndarray]]) -> Path:
    """Four scans 0.1 s apart (``poses.tum`` on the Unix clock), each of 200 points whose
    true times ``t`` (s from the epoch's time, over the sweep) ``fields(t, epoch time)``
    stores beside ``x y z``."""
    rng = np.random.default_rng(7)
    (path / "scans").mkdir(parents=True)
    rows = []
    for k in range(4):
        epoch = T0 + k * PERIOD
        t = np.sort(rng.uniform(0.0, PERIOD, 200))
        xyz = rng.uniform(-5.0, 5.0, (200, 3)).astype(np.float32)
        write_pcd(
            path / "scans" / f"{k:06d}.pcd",
            {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], **fields(t, epoch)},
        )
        rows.append(f"{epoch:.9f} {k * 0.1} 0 0 0 0 0 1")
    (path / "poses.tum").write_text("\n".join(rows) + "\n")
    return path


def test_absolute_times_on_another_clock_are_refused(tmp_path: Path) -> None:
    """Read before: each scan deskewed by 0.5 s of motion, no word."""
    synced = load_dataset(_dataset(tmp_path / "synced", lambda t, e: {"timestamp": e + t}))
    rng = np.random.default_rng(7)
    t0 = np.sort(rng.uniform(0.0, PERIOD, 200))
    np.testing.assert_allclose(synced[0].t, t0, atol=1e-6)
    late = load_dataset(_dataset(tmp_path / "late", lambda t, e: {"timestamp": e + t + 0.5}))
    with pytest.raises(DatasetError) as exc:
        late[0]
    msg = str(exc.value)
    assert msg.startswith(str(tmp_path / "late" / "scans" / "000000.pcd"))
    assert "another clock than the epoch times'" in msg and "0.5 s of motion" in msg
    assert "\n" not in msg
    ignored = load_dataset(tmp_path / "late", time_field="none")[0]
    assert ignored.t is None or not ignored.t.any()


def test_offsets_from_the_recordings_start_are_refused(tmp_path: Path) -> None:
    """``time`` counted from the first epoch: the third scan's nearest point 0.2 s off."""
    ds = load_dataset(
        _dataset(tmp_path / "since", lambda t, e: {"time": (e - T0 + t).astype(np.float32)})
    )
    assert ds[1].t.min() >= 0.1 - 1e-6  # within two periods: read as it is
    with pytest.raises(DatasetError) as exc:
        ds[2]
    assert "000002.pcd: point times lie +0.2" in str(exc.value)


def test_times_under_another_name_are_noted(tmp_path: Path) -> None:
    path = _dataset(
        tmp_path / "named",
        lambda t, e: {"time_offset": np.round(t * 1e9).astype(np.uint32)},
    )
    ds = load_dataset(path)
    (note,) = ds.notes
    assert "000000.pcd: none of the time fields read" in note
    assert "'time_offset' (uint32)" in note and "--time-field time_offset" in note
    assert ds[0].t is None
    named = load_dataset(path, time_field="time_offset")
    assert named.notes == [] and np.ptp(named[0].t) > 0.09


def test_one_time_for_all_the_points_is_noted(tmp_path: Path) -> None:
    ds = load_dataset(
        _dataset(tmp_path / "flat", lambda t, e: {"time": np.zeros(len(t), np.float32)})
    )
    (note,) = ds.notes
    assert "time field 'time' (float32) holds one value for all its points" in note
