"""Raw ``.bin`` scans: KITTI (x y z intensity) and nuScenes (x y z intensity ring) rows told
apart by their columns, also when the point count lets one layout divide into the other."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from planodom.cli import app
from planodom.datasets import load_dataset, read_scan
from planodom.datasets.recording import open_recording
from planodom.errors import DatasetError


def _sweep(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) float32 points of a 32-beam sweep around the sensor and their rings (n,)."""
    rng = np.random.default_rng(seed)
    ring = np.arange(n) % 32
    azimuth = np.linspace(-np.pi, np.pi, n, endpoint=False)
    rng_m = rng.uniform(2.0, 40.0, n)
    elev = np.deg2rad(-25.0 + 30.0 * ring / 31)
    pts = np.column_stack(
        [
            rng_m * np.cos(elev) * np.cos(azimuth),
            rng_m * np.cos(elev) * np.sin(azimuth),
            rng_m * np.sin(elev),
        ]
    )
    return pts.astype(np.float32), ring


def _nuscenes(path: Path, n: int) -> tuple[np.ndarray, np.ndarray]:
    pts, ring = _sweep(n)
    intensity = np.random.default_rng(1).integers(0, 256, n)  # nuScenes: 0..255 as floats
    np.column_stack([pts, intensity, ring]).astype(np.float32).tofile(path)
    return pts, ring


def _kitti(path: Path, n: int) -> np.ndarray:
    pts, _ = _sweep(n, seed=4)
    reflectance = np.random.default_rng(5).uniform(0, 1, n)  # KITTI: 0..1
    np.column_stack([pts, reflectance]).astype(np.float32).tofile(path)
    return pts


@pytest.mark.parametrize("n", [1000, 1003])  # 1000: also 16-byte rows; 1003: 20-byte only
def test_nuscenes_bin_read_with_its_rings(tmp_path: Path, n: int) -> None:
    pts, ring = _nuscenes(tmp_path / "a.bin", n)
    for layout in ("auto", "nuscenes"):
        scan = read_scan(tmp_path / "a.bin", layout)
        np.testing.assert_array_equal(scan.points, pts.astype(np.float64))
        np.testing.assert_array_equal(scan.ring, ring)


@pytest.mark.parametrize("n", [1000, 1001])  # 1000: also 20-byte rows; 1001: 16-byte only
def test_kitti_bin_not_read_as_nuscenes(tmp_path: Path, n: int) -> None:
    pts = _kitti(tmp_path / "a.bin", n)
    for layout in ("auto", "kitti"):
        scan = read_scan(tmp_path / "a.bin", layout)
        np.testing.assert_array_equal(scan.points, pts.astype(np.float64))
        assert scan.ring is None


def test_given_layout_is_obeyed_and_its_size_checked(tmp_path: Path) -> None:
    pts, _ = _nuscenes(tmp_path / "a.bin", 1000)
    as_kitti = read_scan(tmp_path / "a.bin", "kitti")  # the user's word: 1250 rows of 4
    assert len(as_kitti) == 1250 and as_kitti.ring is None
    _nuscenes(tmp_path / "b.bin", 1003)
    with pytest.raises(DatasetError, match=r"b\.bin: .*not a multiple of 16.*--bin-layout kitti"):
        read_scan(tmp_path / "b.bin", "kitti")
    with pytest.raises(DatasetError, match="auto, kitti, nuscenes or xyz"):
        read_scan(tmp_path / "a.bin", "velodyne")


def test_ambiguous_bin_asks_for_the_layout(tmp_path: Path) -> None:
    # whole, non-negative numbers everywhere: both layouts are plausible
    rows = np.random.default_rng(0).integers(0, 30, size=(1000, 4)).astype(np.float32)
    rows.tofile(tmp_path / "grid.bin")
    with pytest.raises(DatasetError, match=r"grid\.bin: cannot tell.*--bin-layout") as err:
        read_scan(tmp_path / "grid.bin")
    assert "\n" not in str(err.value)
    scan = read_scan(tmp_path / "grid.bin", "kitti")
    np.testing.assert_array_equal(scan.points, rows[:, :3])


def test_layout_reaches_datasets_and_the_cli(tmp_path: Path) -> None:
    scans = tmp_path / "ds" / "scans"
    scans.mkdir(parents=True)
    rows = np.random.default_rng(0).integers(0, 30, size=(1000, 4)).astype(np.float32)
    for k in range(3):
        rows.tofile(scans / f"{k:06d}.bin")
    ds = load_dataset(tmp_path / "ds", bin_layout="kitti")
    np.testing.assert_array_equal(ds[1].points, rows[:, :3])
    assert len(open_recording(tmp_path / "ds", bin_layout="nuscenes")[0]) == 800
    result = CliRunner().invoke(app, ["run", str(tmp_path / "ds"), "--out", str(tmp_path / "o")])
    assert result.exit_code == 2
    message = " ".join(result.output.split())
    assert "000000.bin: cannot tell the .bin layout" in message and "--bin-layout" in message
    assert "Traceback" not in result.output
    with pytest.raises(DatasetError, match="auto, kitti, nuscenes or xyz"):
        load_dataset(tmp_path / "ds", bin_layout="kiti")


def test_bin_layout_option_is_refused_where_it_means_nothing(tmp_path: Path) -> None:
    result = CliRunner().invoke(
        app, ["run", "--scenario", "paper-loop", "--bin-layout", "kitti", "--out", str(tmp_path)]
    )
    assert result.exit_code == 2 and "--bin-layout" in result.output
    assert "Traceback" not in result.output


def test_xyz_rows_are_not_read_as_kitti_rows(tmp_path: Path) -> None:
    # x y z float32 rows without intensity (numpy's tofile of an (N, 3) cloud), N a multiple
    # of 4: read as KITTI rows, a cloud of interleaved coordinates, without a word
    pts, _ = _sweep(400)
    pts.tofile(tmp_path / "xyz.bin")
    with pytest.raises(DatasetError, match=r"xyz.bin: cannot tell .*--bin-layout xyz"):
        read_scan(tmp_path / "xyz.bin")
    scan = read_scan(tmp_path / "xyz.bin", bin_layout="xyz")
    np.testing.assert_array_equal(scan.points, pts.astype(np.float64))
    pts[:399].tofile(tmp_path / "odd.bin")  # 4788 bytes: no layout fits; xyz is named
    with pytest.raises(DatasetError, match=r"odd.bin: .* truncated; or x y z rows"):
        read_scan(tmp_path / "odd.bin")


@pytest.mark.parametrize("widened", [True, False])
def test_float64_rows_are_named(tmp_path: Path, widened: bool) -> None:
    # float64 x y z intensity rows: read as float32 KITTI rows, garbage, finite and read
    # without a word when the values were float32 ones widened (their low halves zero), else
    # refused as "NaN or infinite coordinates"
    pts, _ = _sweep(100)
    rows = np.column_stack([pts, np.ones(100)]).astype("<f8")
    (rows if widened else rows * (1 + 1e-12)).tofile(tmp_path / "f64.bin")
    with pytest.raises(DatasetError, match=r"f64.bin: cannot tell .*float64 x y z intensity"):
        read_scan(tmp_path / "f64.bin")


def test_kitti_rows_with_negative_intensities_are_still_read(tmp_path: Path) -> None:
    # no other layout fits (101 points: neither 12-byte nor 32-byte rows divide the size)
    pts, _ = _sweep(101)
    rows = np.column_stack([pts, -np.ones(101, np.float32)])
    rows.tofile(tmp_path / "k.bin")
    np.testing.assert_array_equal(read_scan(tmp_path / "k.bin").points, pts.astype(np.float64))
