"""A message damaged inside its bytes (the storage intact) is named by its record time."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
from bag_factory import STATIC_TF, T_BASE, Sensor, write_bag

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError


def test_a_message_cut_inside_its_bytes_is_named_by_topic_and_record_time(
    tmp_path: Path,
) -> None:
    """The error named the bag and the topic only: which of its messages, not said."""
    bag = tmp_path / "rec"
    sensors = [Sensor("/points", "lidar", 0, "velodyne")]
    write_bag(bag, 2, sensors, STATIC_TF, T_BASE, storage="sqlite3", duration_s=0.6)
    (db,) = bag.glob("*.db3")
    with sqlite3.connect(db) as con:
        rows = con.execute(
            "select m.id, m.timestamp, m.data from messages m join topics t "
            "on m.topic_id = t.id where t.name = '/points' order by m.timestamp"
        ).fetchall()
        mid, stamp, data = rows[3]
        con.execute("update messages set data = ? where id = ?", (data[: len(data) // 2], mid))
    seconds = f"{stamp // 10**9}.{stamp % 10**9:09d}"
    with (
        pytest.raises(DatasetError, match=rf"topic '/points' recorded at {seconds} s \(trunc"),
        open_bag(bag, BagOptions(gt_topic="/odom")) as ds,
    ):
        list(ds)
