"""Point times in a 32-bit integer field that are a clock's nanoseconds cut to 32 bits
(:mod:`planodom.datasets.time_wraps`): refused in one line, in scan files and in bags;
offsets in the same types still read exactly."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from bag_factory import (
    T0_NS,
    T_BASE,
    BagWriter,
    Truth,
    lidar_cloud,
    write_rig_and_odometry,
)

from planodom.datasets import load_dataset, read_scan
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.dataset import write_times
from planodom.datasets.pcd import write_pcd
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

OFFSETS_NS = np.linspace(0, 99_900_000, 50).astype(np.int64)  # a 0.1 s sweep


def _pcd(path: Path, t: np.ndarray) -> None:
    xyz = np.random.default_rng(0).uniform(-10, 10, (len(t), 3))
    write_pcd(path, {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2], "t": t})


@pytest.mark.parametrize("dtype", [np.uint32, np.int32])
def test_a_sweep_whose_32_bit_clock_wraps_inside_it_is_refused(tmp_path: Path, dtype) -> None:
    # the lowest 32 bits of a clock 50 ms before it wraps: values near the top of the
    # type's range, then near its bottom; the span check called it milliseconds
    start = 2**32 - 50_000_000 if dtype == np.uint32 else 2**31 - 50_000_000
    wrapped = ((start + OFFSETS_NS) % 2**32).astype(np.uint32).view(dtype)
    _pcd(tmp_path / "a.pcd", wrapped)
    with pytest.raises(DatasetError, match=r"a\.pcd: point times 't' .*wrap round 2\^32.*32 bits"):
        read_scan(tmp_path / "a.pcd")


@pytest.mark.parametrize(
    "values",
    [OFFSETS_NS.astype(np.uint32), (OFFSETS_NS - 50_000_000).astype(np.int32)],
    ids=["uint32 from 0", "int32 either side"],
)
def test_32_bit_offsets_are_read_exactly(tmp_path: Path, values: np.ndarray) -> None:
    _pcd(tmp_path / "a.pcd", values)
    np.testing.assert_array_equal(read_scan(tmp_path / "a.pcd").t, values * 1e-9)


def test_a_cut_clock_that_does_not_wrap_in_the_sweep_is_named(tmp_path: Path) -> None:
    (tmp_path / "scans").mkdir()
    for k in range(2):
        cut = (2**31 + k * 100_000_000 + OFFSETS_NS).astype(np.uint32)  # 2.1 s from 0
        _pcd(tmp_path / "scans" / f"{k:06d}.pcd", cut)
    write_times(tmp_path / "times.txt", np.array([0.0, 0.1]))
    with pytest.raises(DatasetError, match=r"another clock or unit.*cut to 32 bits"):
        load_dataset(tmp_path)[0]


def _bag(path: Path, ros: int, cut: bool, clock_ns: int = 0) -> None:
    """Six Ouster sweeps (``t`` uint32 at byte 16 of 24, rows padded by 8 bytes) whose ``t``
    holds, if ``cut``, the stamp's clock (plus ``clock_ns``) cut to 32 bits instead of the
    offsets."""
    truth = Truth(T_base_sensor=T_BASE)
    with BagWriter(path, ros) as bw:
        write_rig_and_odometry(bw, 8)
        for k in range(6):
            stamp = T0_NS + k * 100_000_000
            msg = lidar_cloud(bw, truth, "/points", "lidar", stamp, "ouster")
            if cut:
                rows = np.frombuffer(msg.data, np.uint8).reshape(msg.height, msg.row_step).copy()
                t = rows[:, : msg.width * 24].reshape(msg.height, msg.width, 24)[..., 16:20]
                offsets = t.copy().view("<u4").astype(np.int64)
                t[...] = ((stamp + clock_ns + offsets) % 2**32).astype("<u4").view(np.uint8)
                msg.data = rows.reshape(-1)
            bw.write("/points", msg, stamp + 2_000_000)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_bag_whose_time_field_is_its_stamps_cut_to_32_bits_is_refused(
    tmp_path: Path, ros: int
) -> None:
    # read as offsets they put points up to 4.29 s from the stamp (within the 10 s
    # allowed): the sweeps deskewed along metres of the trajectory, without a word
    path = tmp_path / ("cut.bag" if ros == 1 else "cut")
    _bag(path, ros, cut=True)
    with pytest.raises(DatasetError, match=r"topic '/points'.*'t' \(uint32\).*lowest 32 bits"):
        open_bag(path, BagOptions(gt_topic="/odom"))
    ok = tmp_path / ("ok.bag" if ros == 1 else "ok")
    _bag(ok, ros, cut=False)
    with open_bag(ok, BagOptions(gt_topic="/odom")) as ds:
        assert len(ds) == 6 and 0.09 < np.ptp(ds[3].t) < 0.1


def test_a_bag_sweep_whose_32_bit_clock_wraps_inside_it_is_refused(tmp_path: Path) -> None:
    # another clock than the stamps' (so not their lowest bits), wrapping 50 ms into the
    # first sweep: read as offsets from 0 to 4.29 s, without a word
    clock = (2**32 - 50_000_000 - T0_NS) % 2**32
    _bag(tmp_path / "wrap", 2, cut=True, clock_ns=clock)
    with pytest.raises(DatasetError, match=r"topic '/points'.*'t' \(uint32\) wrap round 2\^32"):
        open_bag(tmp_path / "wrap", BagOptions(gt_topic="/odom"))
