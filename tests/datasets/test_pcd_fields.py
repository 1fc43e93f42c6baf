"""PCD headers whose fields cannot be read as written: a field given twice (ASCII bodies
read the last, binary ones the first), a type planodom does not read (named)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import read_scan
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
