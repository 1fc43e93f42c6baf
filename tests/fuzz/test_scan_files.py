"""Fuzzing the scan readers: corrupted PLY, PCD and KITTI .bin files either fail with one
line naming the file, or read as the clean file does (or as the part of it the corruption
cannot be told from: a cut inside the last ASCII number, whole rows of a KITTI file)."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from dataset_factory import assert_same_scan
from fuzz_corruptions import (
    BAD_TOKENS,
    bit_flipped,
    fuzz,
    outcome,
    replace_line_token,
    truncated,
)
from hypothesis import given
from hypothesis import strategies as st

from planodom.datasets import read_scan, write_scan
from planodom.datasets.ply import write_ply_vertices
from planodom.scan import Scan

N = 8


def clean_scan(kitti: bool = False) -> Scan:
    rng = np.random.default_rng(3)
    points = rng.normal(scale=5.0, size=(N, 3))
    if kitti:
        return Scan(points.astype(np.float32).astype(np.float64))
    t = np.linspace(0.0, 0.09, N)
    return Scan(points, ring=np.arange(N) % 4, t=t, label=np.arange(N) - 1)


def _ascii_rows(scan: Scan) -> str:
    cols = [scan.points[:, 0], scan.points[:, 1], scan.points[:, 2], scan.ring, scan.t, scan.label]
    return "".join(" ".join(repr(c[i].item()) for c in cols) + "\n" for i in range(N))


def ply_ascii(scan: Scan) -> bytes:
    props = "".join(
        f"property {t} {n}\n"
        for t, n in [("double", "x"), ("double", "y"), ("double", "z"), ("int", "ring")]
        + [("double", "t"), ("int", "label")]
    )
    header = f"ply\nformat ascii 1.0\nelement vertex {N}\n{props}end_header\n"
    return (header + _ascii_rows(scan)).encode()


def pcd_ascii(scan: Scan) -> bytes:
    header = (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z ring t label\nSIZE 8 8 8 4 8 4\n"
        f"TYPE F F F I F I\nCOUNT 1 1 1 1 1 1\nWIDTH {N}\nHEIGHT 1\n"
        f"VIEWPOINT 0 0 0 1 0 0 0\nPOINTS {N}\nDATA ascii\n"
    )
    return (header + _ascii_rows(scan)).encode()


def _written(ext: str):
    def make(scan: Scan) -> bytes:
        import tempfile

        with tempfile.TemporaryDirectory() as tmp:
            write_scan(Path(tmp) / f"s{ext}", scan)
            return (Path(tmp) / f"s{ext}").read_bytes()

    return make


def kitti(scan: Scan) -> bytes:
    rows = np.column_stack([scan.points, np.ones(len(scan))]).astype("<f4")
    return rows.tobytes()


#: format -> (extension, writer, ASCII?)
FORMATS = {
    "ply-binary": (".ply", _written(".ply"), False),
    "ply-ascii": (".ply", ply_ascii, True),
    "pcd-binary": (".pcd", _written(".pcd"), False),
    "pcd-ascii": (".pcd", pcd_ascii, True),
    "kitti": (".bin", kitti, False),
}
CLEAN = {name: f(clean_scan(name == "kitti")) for name, (_, f, _) in FORMATS.items()}


def _read(tmp: Path, fmt: str, data: bytes) -> Scan | None:
    path = tmp / f"scan{FORMATS[fmt][0]}"
    path.write_bytes(data)
    return outcome(read_scan, path)


def _same_but_last(a: Scan, b: Scan) -> bool:
    """Equal in every point and field but the last point (a cut inside the last number)."""
    if len(a) != len(b):
        return False
    try:
        assert_same_scan(a.subset(slice(0, -1)), b.subset(slice(0, -1)))
    except AssertionError:
        return False
    return True


def _prefix(a: Scan, b: Scan) -> bool:
    """``a`` is ``b``'s first rows (KITTI has no count to check a cut against)."""
    return len(a) <= len(b) and np.array_equal(a.points, b.points[: len(a)])


def assert_valid(scan: Scan) -> None:
    """What the reader promises of any scan it returns."""
    assert scan.points.shape == (len(scan), 3) and scan.points.dtype == np.float64
    assert np.all(np.abs(scan.points) <= 1e6)
    if scan.t is not None:
        assert np.all(np.abs(scan.t) <= 3600)
    if scan.ring is not None:
        assert scan.ring.dtype == np.int32 and np.all(scan.ring >= 0)


@pytest.mark.parametrize("fmt", FORMATS)
@fuzz
@given(data=st.data())
def test_truncated_files(tmp_path: Path, fmt: str, data: st.DataObject) -> None:
    cut, _ = data.draw(truncated(CLEAN[fmt]))
    clean = clean_scan(fmt == "kitti")
    scan = _read(tmp_path, fmt, cut)
    if scan is None:
        return
    if fmt == "kitti":
        assert _prefix(scan, clean)
    elif FORMATS[fmt][2]:  # ASCII: only a cut inside the last number goes unnoticed
        assert _same_but_last(scan, clean)
    else:
        pytest.fail(f"a truncated binary {fmt} file was read ({len(scan)} points)")


@pytest.mark.parametrize("fmt", FORMATS)
@fuzz
@given(data=st.data())
def test_bit_flips(tmp_path: Path, fmt: str, data: st.DataObject) -> None:
    flipped = data.draw(bit_flipped(CLEAN[fmt]))
    scan = _read(tmp_path, fmt, flipped)
    if scan is not None:
        assert_valid(scan)
        assert_same_scan(scan, _read(tmp_path, fmt, flipped))  # the same on every read


@pytest.mark.parametrize("fmt", FORMATS)
@fuzz
@given(extra=st.binary(min_size=1, max_size=64))
def test_appended_bytes(tmp_path: Path, fmt: str, extra: bytes) -> None:
    scan = _read(tmp_path, fmt, CLEAN[fmt] + extra)
    clean = clean_scan(fmt == "kitti")
    if scan is None:
        return
    if fmt == "kitti":
        assert _prefix(clean, scan)
    else:
        assert_same_scan(scan, clean)  # only blank space may follow the points


_COUNT = {"ply": rb"(element vertex )(\d+)", "pcd": rb"(POINTS )(\d+)"}


@pytest.mark.parametrize("fmt", [f for f in FORMATS if f != "kitti"])
@fuzz
@given(count=st.integers(0, 10**12).filter(lambda m: m != N), with_width=st.booleans())
def test_wrong_point_counts(tmp_path: Path, fmt: str, count: int, with_width: bool) -> None:
    data = re.sub(_COUNT[fmt[:3]], rb"\g<1>" + str(count).encode(), CLEAN[fmt], count=1)
    if fmt.startswith("pcd") and with_width:  # a consistent header over the wrong body
        data = data.replace(f"WIDTH {N}\n".encode(), f"WIDTH {count}\n".encode())
    assert _read(tmp_path, fmt, data) is None


@pytest.mark.parametrize("fmt", ["ply-ascii", "pcd-ascii"])
@fuzz
@given(
    line=st.integers(0, N - 1),
    token=st.integers(0, 6),
    new=st.sampled_from([*BAD_TOKENS, None]),
)
def test_bad_ascii_values(tmp_path: Path, fmt: str, line: int, token: int, new: str | None) -> None:
    text = CLEAN[fmt].decode()
    marker = "end_header\n" if fmt == "ply-ascii" else "DATA ascii\n"
    body = text.index(marker) + len(marker)
    header_lines = text[:body].count("\n")
    bad = replace_line_token(text, header_lines + line, token, new)
    assert _read(tmp_path, fmt, bad.encode()) is None


@pytest.mark.parametrize("ext", [".ply", ".pcd"])
@pytest.mark.parametrize(
    "field, value",
    [("x", np.nan), ("y", np.inf), ("z", 1e30), ("t", np.nan), ("t", 1.7e9), ("t", -1e300)]
    + [("ring", -1), ("ring", 2**31 + 5), ("label", 2**32 - 1)],
)
def test_bad_values_in_binary_files(tmp_path: Path, ext: str, field: str, value: float) -> None:
    scan = clean_scan()
    fields = {c: scan.points[:, i].copy() for i, c in enumerate("xyz")}
    fields |= {"ring": scan.ring.copy(), "t": scan.t.copy(), "label": scan.label.copy()}
    if field in ("ring", "label") and value > 0:
        fields[field] = fields[field].astype(np.uint32)  # as lidar drivers store ring
    fields[field][3] = value
    path = tmp_path / f"bad{ext}"
    if ext == ".ply":
        write_ply_vertices(path, fields)
    else:
        _write_binary_pcd(path, fields)
    assert outcome(read_scan, path) is None


def _write_binary_pcd(path: Path, fields: dict[str, np.ndarray]) -> None:
    """A binary PCD written by hand (PCL's layout), whatever the values."""
    table = np.empty(N, dtype=[(k, "<" + a.dtype.str[1:]) for k, a in fields.items()])
    for name, a in fields.items():
        table[name] = a
    kinds = " ".join(a.dtype.kind.upper() for a in fields.values())
    sizes = " ".join(str(a.dtype.itemsize) for a in fields.values())
    header = (
        f"VERSION 0.7\nFIELDS {' '.join(fields)}\nSIZE {sizes}\nTYPE {kinds}\n"
        f"COUNT {' '.join('1' for _ in fields)}\nWIDTH {N}\nHEIGHT 1\nPOINTS {N}\nDATA binary\n"
    )
    path.write_bytes(header.encode() + table.tobytes())


def test_kitti_bit_patterns(tmp_path: Path) -> None:
    """NaN, inf and 1e30 as float32 in a KITTI row."""
    for value in (np.nan, np.inf, 1e30):
        rows = np.ones((4, 4), "<f4")
        rows[2, 1] = value
        (tmp_path / "k.bin").write_bytes(rows.tobytes())
        assert outcome(read_scan, tmp_path / "k.bin") is None
