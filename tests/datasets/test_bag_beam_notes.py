"""A 2D scan topic's messages whose range limits are swapped, or whose beams carry no
times, are read as they are and said; read against the same rig's clean bag (the room of
:mod:`bag_factory`, three tilted scanners)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import bag_factory
import numpy as np
import pytest
from bag_factory import SCANNERS, STATIC_TF, T_BASE, write_bag

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag

OPTS = BagOptions(gt_topic="/odom")


def _rig_bag(path: Path, monkeypatch: pytest.MonkeyPatch, change: Callable[..., Any]) -> None:
    """Six epochs of the three scanners, each LaserScan passed through ``change(topic,
    msg)``."""
    clean = bag_factory.laser_scan

    def scan(bw: Any, truth: Any, topic: str, frame: str, stamp: int) -> Any:
        return change(topic, clean(bw, truth, topic, frame, stamp))

    with monkeypatch.context() as m:
        m.setattr(bag_factory, "laser_scan", scan)
        write_bag(path, 2, SCANNERS, STATIC_TF, T_BASE, duration_s=0.6)


def _swap(msg: Any) -> Any:
    return replace(msg, range_min=msg.range_max, range_max=msg.range_min)


def test_swapped_range_limits_are_said(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The front scanner's range_min and range_max swapped: no range lies within them, so
    the rig lost that scanner's every point without a word. Said now; the other two
    scanners' points are the clean bag's."""
    _rig_bag(tmp_path / "clean", monkeypatch, lambda topic, msg: msg)
    _rig_bag(tmp_path / "front", monkeypatch, lambda t, m: _swap(m) if t == "/scan_front" else m)
    _rig_bag(tmp_path / "all", monkeypatch, lambda topic, msg: _swap(msg))
    with open_bag(tmp_path / "front", OPTS) as ds, open_bag(tmp_path / "clean", OPTS) as clean:
        assert clean.notes == []
        assert ds.notes == [
            "topic '/scan_front': 6 of 6 messages have a range_min of 40 m above their "
            "range_max of 0.05 m (the limits swapped in the driver's settings?): no range "
            "lies within them, so they are read without a return"
        ]
        np.testing.assert_array_equal(ds.times, clean.times)
        for scan, other in zip(ds, clean, strict=True):
            assert 0 not in scan.ring
            np.testing.assert_array_equal(scan.points, other.points[other.ring != 0])
    with open_bag(tmp_path / "all", OPTS) as ds:
        assert [n.split(":")[0] for n in ds.notes] == [
            "topic '/scan_front'",
            "topic '/scan_left'",
            "topic '/scan_rear'",
        ]
        assert all("range_min of 40 m above their range_max" in n for n in ds.notes)
        assert sum(len(scan) for scan in ds) == 0


def test_a_scanner_without_any_return_is_said(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The left scanner blocked (every range infinite): one of the rig's three scanners
    gave nothing, without a word. Said now."""

    def blocked(topic: str, msg: Any) -> Any:
        if topic != "/scan_left":
            return msg
        return replace(msg, ranges=np.full_like(msg.ranges, np.inf))

    _rig_bag(tmp_path / "blocked", monkeypatch, blocked)
    with open_bag(tmp_path / "blocked", OPTS) as ds:
        assert ds.notes == [
            "topic '/scan_left': none of its 6 scans holds a return (the scanner blocked or "
            "off, or its range limits?): it adds no point to the epochs"
        ]
        assert all(1 not in scan.ring and len(scan) for scan in ds)


def test_beams_without_times_are_said(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A time_increment of 0 (pointcloud_to_laserscan writes one): every beam read at the
    stamp (points up to 8 cm off the room on this rig at 1.5 m/s and 23 deg/s), without a
    word. Said now; the points are the clean bag's, their times the stamp's."""
    _rig_bag(tmp_path / "clean", monkeypatch, lambda topic, msg: msg)
    untimed = lambda t, m: replace(m, time_increment=0.0) if t != "/scan_rear" else m  # noqa: E731
    _rig_bag(tmp_path / "untimed", monkeypatch, untimed)
    with open_bag(tmp_path / "untimed", OPTS) as ds, open_bag(tmp_path / "clean", OPTS) as clean:
        assert ds.notes == [
            f"topic '{topic}': 6 of 6 messages have a time_increment of 0 (scan_time 0.1 s): "
            "their beams are all read at the stamp, not deskewed (a driver or a converter "
            "such as pointcloud_to_laserscan that gives no beam times)"
            for topic in ("/scan_front", "/scan_left")
        ]
        for scan, other in zip(ds, clean, strict=True):
            np.testing.assert_array_equal(scan.points, other.points)
            np.testing.assert_array_equal(scan.t[scan.ring == 2], other.t[other.ring == 2])
            for ring in (0, 1):  # one time a sweep, where the clean sweep spans 40 ms
                assert np.ptp(scan.t[scan.ring == ring]) == 0.0
                assert np.ptp(other.t[other.ring == ring]) > 0.03
