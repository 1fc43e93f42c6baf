"""Absolute per-point times in scan files (Unix seconds or nanoseconds, as some drivers write
them) made relative to the epoch's reference time; what is neither offsets nor Unix times
refused naming the field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import load_dataset, read_scan
from planodom.datasets.dataset import write_times
from planodom.datasets.pcd import write_pcd
from planodom.errors import DatasetError

T0 = 1_700_000_123.25  # an epoch's Unix time, s
OFFSETS = np.linspace(0.0, 0.0999, 50)  # the sweep's points after the epoch's time, s


def _pcd(path: Path, times: np.ndarray, name: str = "timestamp") -> None:
    rng = np.random.default_rng(0)
    xyz = rng.uniform(-10, 10, (len(times), 3))
    write_pcd(path, {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], name: times})


def _dataset(root: Path, stamps: list[np.ndarray], epoch_times: list[float] | None) -> None:
    (root / "scans").mkdir(parents=True)
    for k, times in enumerate(stamps):
        _pcd(root / "scans" / f"{k:06d}.pcd", times)
    if epoch_times is not None:
        write_times(root / "times.txt", np.array(epoch_times))


@pytest.mark.parametrize(
    "stamps",
    [
        lambda t0: t0 + OFFSETS,  # float64 Unix seconds
        lambda t0: (np.int64(round(t0 * 1e9)) + np.round(OFFSETS * 1e9)).astype(np.uint64),
        lambda t0: t0 * 1e9 + OFFSETS * 1e9,  # float64 Unix nanoseconds (livox driver2)
    ],
    ids=["float64 s", "uint64 ns", "float64 ns"],
)
def test_absolute_times_relative_to_the_epoch_time(tmp_path: Path, stamps) -> None:
    epoch_times = [T0, T0 + 0.1]
    # the second sweep starts 20 ms after its epoch's time
    _dataset(tmp_path, [stamps(T0), stamps(T0 + 0.12)], epoch_times)
    ds = load_dataset(tmp_path)
    np.testing.assert_allclose(ds[0].t, OFFSETS, atol=1e-6)  # float64 s: 0.24 us ulp
    np.testing.assert_allclose(ds[1].t, OFFSETS + 0.02, atol=1e-6)


def test_absolute_times_without_absolute_epoch_times_start_at_the_first_point(
    tmp_path: Path,
) -> None:
    _dataset(tmp_path, [T0 + 0.03 + OFFSETS, T0 + 0.13 + OFFSETS], None)  # epochs 0, 0.1 s
    ds = load_dataset(tmp_path)
    for k in range(2):
        np.testing.assert_allclose(ds[k].t, OFFSETS, atol=1e-6)
    scan = read_scan(tmp_path / "scans" / "000000.pcd")  # no epoch time at all
    np.testing.assert_allclose(scan.t, OFFSETS, atol=1e-6)


def test_relative_times_unchanged(tmp_path: Path) -> None:
    _pcd(tmp_path / "a.pcd", OFFSETS - 0.05, name="time")
    np.testing.assert_array_equal(
        read_scan(tmp_path / "a.pcd", reference_time=T0).t, OFFSETS - 0.05
    )


@pytest.mark.parametrize(
    ("times", "message"),
    [
        ((T0 + OFFSETS).astype(np.float32), r"'timestamp' are absolute \(Unix\) times in float32"),
        (5000.0 + OFFSETS, r"'timestamp' \(read as s\) are NaN, infinite, or neither"),
        (T0 * 1e6 + OFFSETS * 1e6, r"'timestamp' \(read as s\) are NaN"),  # microseconds
    ],
    ids=["float32 unix", "5000 s", "unix us"],
)
def test_neither_offsets_nor_unix_times_refused(tmp_path: Path, times, message: str) -> None:
    _pcd(tmp_path / "a.pcd", times)
    with pytest.raises(DatasetError, match=r"a\.pcd: .*" + message):
        read_scan(tmp_path / "a.pcd", reference_time=0.0)


def test_absolute_times_on_another_clock_refused(tmp_path: Path) -> None:
    _dataset(tmp_path, [T0 + 3600 + OFFSETS, T0 + 3600.1 + OFFSETS], [T0, T0 + 0.1])
    with pytest.raises(
        DatasetError,
        match=r"000000\.pcd: absolute point times 'timestamp'.*"
        "different clocks",
    ):
        load_dataset(tmp_path)[0]


def test_integer_unix_seconds_read_as_nanoseconds_refused(tmp_path: Path) -> None:
    # uint32 Unix seconds are ~1.7 s as nanoseconds: 17 epoch periods from the epoch's time
    _dataset(tmp_path, [np.full(50, int(T0), np.uint32)] * 2, None)
    with pytest.raises(DatasetError, match=r"000000\.pcd: point times .*another clock or unit"):
        load_dataset(tmp_path)[0]


def test_time_field_none_ignores_refused_times(tmp_path: Path) -> None:
    # the times of another clock are refused by default; --time-field none reads the points
    # (the same coordinates as the file) without them
    _dataset(tmp_path, [T0 + 3600 + OFFSETS, T0 + 3600.1 + OFFSETS], [T0, T0 + 0.1])
    with pytest.raises(DatasetError, match=r"--time-field none ignores them"):
        load_dataset(tmp_path)[0]
    scan = load_dataset(tmp_path, time_field="none")[0]
    assert scan.t is None
    expected = np.random.default_rng(0).uniform(-10, 10, (len(OFFSETS), 3))  # as _pcd drew
    np.testing.assert_array_equal(scan.points, expected)


def test_time_field_by_name(tmp_path: Path) -> None:
    # two time-like fields: auto takes the first of TIME_FIELDS ('t'), a name picks the other
    rng = np.random.default_rng(1)
    xyz = rng.uniform(-10, 10, (len(OFFSETS), 3))
    fields = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "t": OFFSETS, "stamp_rel": -OFFSETS}
    write_pcd(tmp_path / "a.pcd", fields)
    np.testing.assert_array_equal(read_scan(tmp_path / "a.pcd").t, OFFSETS)
    np.testing.assert_array_equal(read_scan(tmp_path / "a.pcd", time_field="stamp_rel").t, -OFFSETS)
    with pytest.raises(DatasetError, match=r"a\.pcd: no time field 'offset'.*fields: x, y, z"):
        read_scan(tmp_path / "a.pcd", time_field="offset")
    with pytest.raises(DatasetError, match="time field must be auto, none or a field name"):
        read_scan(tmp_path / "a.pcd", time_field=" ")


@pytest.mark.parametrize("per_unit_ns", [1, 1000], ids=["ns", "us"])
def test_integer_offsets_in_us_are_told_from_ns_by_the_epoch_period(
    tmp_path: Path, per_unit_ns: int
) -> None:
    """Integer microseconds were read as nanoseconds: a 0.1 s sweep taken as 0.1 ms."""
    offsets_ns = np.arange(0, 100_000_000, 400_000)  # a 0.1 s sweep, 250 points
    _dataset(tmp_path, [(offsets_ns // per_unit_ns).astype(np.uint32)] * 3, [0.0, 0.1, 0.2])
    ds = load_dataset(tmp_path)
    np.testing.assert_allclose(ds[1].t, offsets_ns * 1e-9, rtol=0, atol=1e-12)
    if per_unit_ns == 1:
        assert ds.notes == []
    else:
        assert len(ds.notes) == 1
        assert "time field 'timestamp' (uint32) read as microseconds" in ds.notes[0]
        assert "100 ms between epochs" in ds.notes[0]
