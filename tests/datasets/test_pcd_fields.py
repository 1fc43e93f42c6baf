"""PCD headers whose fields cannot be read as written: a field given twice (ASCII bodies
read the last, binary ones the first), a type planodom does not read (named); a
``VIEWPOINT`` other than the identity (noted)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import load_dataset, read_scan
from planodom.datasets.pcd import write_pcd
from planodom.errors import DatasetError

HEADER = "VERSION 0.7\nFIELDS {}\nSIZE {}\nTYPE {}\nCOUNT {}\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n"


def _pcd(path: Path, names: str, sizes: str, types: str, rows: list[list[float]]) -> Path:
    ones = " ".join("1" for _ in names.split())
    head = HEADER.format(names, sizes, types, ones)
    body = "\n".join(" ".join(str(v) for v in r) for r in rows)
    path.write_text(head + "DATA ascii\n" + body + "\n")
    return path


def _binary(path: Path, names: str, rows: list[list[float]]) -> Path:
    n = len(names.split())
    head = HEADER.format(names, " ".join(["4"] * n), " ".join(["F"] * n), " ".join(["1"] * n))
    path.write_bytes((head + "DATA binary\n").encode() + np.array(rows, "<f4").tobytes())
    return path


@pytest.mark.parametrize("mode", ["ascii", "binary"])
def test_a_field_given_twice_is_refused(tmp_path: Path, mode: str) -> None:
    # 'x y z x': ASCII read x = 9 (the last), binary x = 1 (the first), without a word
    rows = [[1.0, 2.0, 3.0, 9.0], [4.0, 5.0, 6.0, 9.0]]
    if mode == "ascii":
        path = _pcd(tmp_path / "twice.pcd", "x y z x", "4 4 4 4", "F F F F", rows)
    else:
        path = _binary(tmp_path / "twice.pcd", "x y z x", rows)
    with pytest.raises(DatasetError, match=r"twice\.pcd: PCD field 'x' given twice"):
        read_scan(path)


def test_pcl_padding_fields_may_repeat(tmp_path: Path) -> None:
    rows = [[1.0, 2.0, 3.0, 0.0, 0.0], [4.0, 5.0, 6.0, 0.0, 0.0]]
    path = _binary(tmp_path / "pad.pcd", "x y z _ _", rows)
    np.testing.assert_array_equal(read_scan(path).points, [[1, 2, 3], [4, 5, 6]])


def test_a_type_not_read_is_named(tmp_path: Path) -> None:
    path = _pcd(tmp_path / "half.pcd", "x y z", "2 2 2", "F F F", [[1, 2, 3], [4, 5, 6]])
    with pytest.raises(DatasetError, match=r"half\.pcd: PCD field 'x' \(TYPE F SIZE 2\)"):
        read_scan(path)


@pytest.mark.parametrize(
    "viewpoint, noted",
    [
        ("10 5 2 0.7071068 0 0 0.7071068", True),  # a cloud registered into a map frame
        ("0 0 0 0 0 0 1", True),  # turned 180 deg about z
        ("0 0 0 1 0 0 0", False),  # PCL's default, and what planodom writes
        ("0 0 0 -1 0 0 0", False),  # the identity too
        (None, False),  # no VIEWPOINT line
    ],
)
def test_a_viewpoint_other_than_the_identity_is_noted(
    tmp_path: Path, viewpoint: str | None, noted: bool
) -> None:
    # read as if in the sensor's frame without a word before
    (tmp_path / "scans").mkdir()
    write_pcd(tmp_path / "scans" / "000000.pcd", {c: np.ones(3, np.float32) for c in "xyz"})
    data = (tmp_path / "scans" / "000000.pcd").read_bytes()
    line = b"" if viewpoint is None else f"VIEWPOINT {viewpoint}\n".encode()
    data = data.replace(b"VIEWPOINT 0 0 0 1 0 0 0\n", line)
    (tmp_path / "scans" / "000000.pcd").write_bytes(data)
    notes = [n for n in load_dataset(tmp_path).notes if "VIEWPOINT" in n]
    assert len(notes) == noted
    if noted:
        assert f"000000.pcd: PCD VIEWPOINT {viewpoint} is not the identity" in notes[0]
