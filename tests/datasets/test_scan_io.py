"""Scan files: exact round trips (.ply, .pcd, KITTI .bin), interop with open3d, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from dataset_factory import ALL_FIELDS, assert_same_scan, float32_safe, make_scan

from planodom._open3d import o3d
from planodom.datasets import read_scan, write_scan
from planodom.datasets.pcd import write_pcd
from planodom.datasets.ply import write_ply_vertices
from planodom.errors import DatasetError
from planodom.scan import Scan

# --------------------------------------------------------------------------- scans


@pytest.mark.parametrize("ext", [".ply", ".pcd"])
@pytest.mark.parametrize("fields", [ALL_FIELDS, (), ("ring",), ("t", "label")])
@pytest.mark.parametrize("n", [0, 1, 200])
def test_scan_round_trip_float64_exact(tmp_path: Path, ext: str, fields, n: int) -> None:
    scan = make_scan(np.random.default_rng(n), n, fields)
    write_scan(tmp_path / f"s{ext}", scan)
    assert_same_scan(read_scan(tmp_path / f"s{ext}"), scan)


@pytest.mark.parametrize("ext", [".ply", ".pcd"])
def test_scan_float32_storage_round_trips(tmp_path: Path, ext: str) -> None:
    scan = make_scan(np.random.default_rng(1), 100)
    huge = Scan(np.where(scan.points == scan.points.min(), 1e300, scan.points))
    with pytest.raises(DatasetError, match="beyond float32 range"):
        write_scan(tmp_path / f"a{ext}", huge, points_dtype=np.float32)
    scan = float32_safe(scan)
    write_scan(tmp_path / f"a{ext}", scan, points_dtype=np.float32)
    back = read_scan(tmp_path / f"a{ext}")
    assert np.array_equal(back.points, scan.points.astype(np.float32).astype(np.float64))
    # A float32 scan written again as float32 is the same file content, bit for bit.
    write_scan(tmp_path / f"b{ext}", back, points_dtype=np.float32)
    assert_same_scan(read_scan(tmp_path / f"b{ext}"), back)
    if ext == ".ply":
        assert (tmp_path / "a.ply").read_bytes() == (tmp_path / "b.ply").read_bytes()


def test_ply_from_and_to_open3d(tmp_path: Path) -> None:
    """Our PLY files read the same in open3d, and open3d's PLY files read the same here."""
    scan = float32_safe(make_scan(np.random.default_rng(2), 80))
    write_scan(tmp_path / "ours.ply", scan)
    cloud = o3d.t.io.read_point_cloud(str(tmp_path / "ours.ply"))
    assert np.array_equal(cloud.point["positions"].numpy(), scan.points)
    for name in ALL_FIELDS:
        assert np.array_equal(cloud.point[name].numpy().ravel(), getattr(scan, name))

    for dtype in (np.float64, np.float32):
        theirs = o3d.t.geometry.PointCloud()
        theirs.point["positions"] = o3d.core.Tensor(scan.points.astype(dtype))
        for name in ALL_FIELDS:
            theirs.point[name] = o3d.core.Tensor(getattr(scan, name)[:, None])
        assert o3d.t.io.write_point_cloud(str(tmp_path / "theirs.ply"), theirs)
        back = read_scan(tmp_path / "theirs.ply")
        expected = Scan(scan.points.astype(dtype), scan.ring, scan.t, scan.label)
        assert_same_scan(back, expected)


def test_ply_other_property_types_and_ascii(tmp_path: Path) -> None:
    """uint16 ring (lidar drivers), float32 t, extra properties ignored, ASCII PLY."""
    n = 4
    write_ply_vertices(
        tmp_path / "u.ply",
        {
            "x": np.arange(n, dtype=np.float32),
            "y": np.ones(n, np.float32),
            "z": np.zeros(n, np.float32),
            "intensity": np.full(n, 7.5, np.float32),
            "ring": np.array([0, 1, 65000, 3], np.uint16),
            "t": np.array([0.0, 0.25, 0.5, 0.75], np.float32),
        },
    )
    scan = read_scan(tmp_path / "u.ply")
    assert scan.ring.tolist() == [0, 1, 65000, 3] and scan.ring.dtype == np.int32
    assert scan.t.tolist() == [0.0, 0.25, 0.5, 0.75] and scan.label is None

    text = (
        "ply\nformat ascii 1.0\ncomment hand written\nelement vertex 2\n"
        "property double x\nproperty double y\nproperty double z\nproperty int label\n"
        "end_header\n0.1 -2.5 3e-7 4\n1 2 3 -1\n"
    )
    (tmp_path / "a.ply").write_text(text)
    scan = read_scan(tmp_path / "a.ply")
    assert np.array_equal(scan.points, [[0.1, -2.5, 3e-7], [1.0, 2.0, 3.0]])
    assert scan.label.tolist() == [4, -1]


def test_kitti_bin(tmp_path: Path) -> None:
    rows = np.random.default_rng(3).normal(size=(30, 4)).astype(np.float32)
    rows.tofile(tmp_path / "000000.bin")
    np.zeros((0, 4), np.float32).tofile(tmp_path / "000001.bin")
    scan = read_scan(tmp_path / "000000.bin")
    assert np.array_equal(scan.points, rows[:, :3].astype(np.float64))
    assert scan.ring is None and scan.t is None and scan.label is None
    assert len(read_scan(tmp_path / "000001.bin")) == 0


def test_pcd_with_uint16_ring_and_ascii_from_other_tools(tmp_path: Path) -> None:
    header = (
        "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z ring\nSIZE 4 4 4 2\nTYPE F F F U\n"
        "COUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n"
    )
    (tmp_path / "a.pcd").write_text(header + "DATA ascii\n1 2 3 4\n-1 0.5 2 60000\n")
    scan = read_scan(tmp_path / "a.pcd")
    assert np.array_equal(scan.points, [[1, 2, 3], [-1, 0.5, 2]])
    assert scan.ring.tolist() == [4, 60000]


# --------------------------------------------------------------------------- bad scans


def _good_ply(tmp_path: Path) -> bytes:
    write_scan(tmp_path / "good.ply", make_scan(np.random.default_rng(4), 20))
    return (tmp_path / "good.ply").read_bytes()


def _good_pcd(tmp_path: Path) -> bytes:
    write_scan(tmp_path / "good.pcd", make_scan(np.random.default_rng(5), 20))
    return (tmp_path / "good.pcd").read_bytes()


@pytest.mark.parametrize(
    "name, content, message",
    [
        ("garbage.ply", lambda p: np.random.default_rng(0).bytes(500), "not a PLY"),
        ("truncated.ply", lambda p: _good_ply(p)[:-9], "truncated"),
        ("noheader.ply", lambda p: b"ply\nformat ascii 1.0\nelement vertex 3\n", "end_header"),
        ("badtype.ply", lambda p: b"ply\nformat ascii 1.0\nproperty quad x\nend_header\n", "bad"),
        (
            "ascii.ply",
            lambda p: (
                b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                b"property float y\nproperty float z\nend_header\n1 2 3\n4 5\n"
            ),
            "ascii.ply:9: 2 values, a vertex has 3",
        ),
        (
            "noxyz.ply",
            lambda p: b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
            "coordinates",
        ),
        ("garbage.pcd", lambda p: np.random.default_rng(1).bytes(500), "PCD"),
        ("empty.pcd", lambda p: b"", r"empty.pcd: empty file \(0 bytes\), no PCD header"),
        ("empty.ply", lambda p: b"", r"empty.ply: empty file \(0 bytes\), no PLY header"),
        ("truncated.pcd", lambda p: _good_pcd(p)[:-9], "truncated"),
        (
            "ascii.pcd",
            lambda p: (
                b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                b"COUNT 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n"
            ),
            "2 point lines, its header POINTS 3",
        ),
        ("truncated.bin", lambda p: np.zeros(9, np.float32).tobytes(), "multiple of neither 16"),
        (
            "truncated5.bin",  # 2 rows of 5 values whose 'rings' are not whole numbers
            lambda p: np.random.default_rng(2).normal(size=10).astype(np.float32).tobytes(),
            "fit only nuScenes rows",
        ),
        ("scan.xyz", lambda p: b"1 2 3\n", "unknown scan file extension"),
    ],
)
def test_bad_scan_files(tmp_path: Path, name: str, content, message: str) -> None:
    (tmp_path / name).write_bytes(content(tmp_path))
    with pytest.raises(DatasetError, match=message) as err:
        read_scan(tmp_path / name)
    assert name in str(err.value)


@pytest.mark.parametrize("ext", [".ply", ".pcd", ".bin"])
def test_nan_points_are_rejected_with_count(tmp_path: Path, ext: str) -> None:
    pts = np.ones((10, 4), np.float32)
    pts[2, 0], pts[5, 1], pts[5, 2], pts[7, 2] = np.nan, np.inf, np.nan, -np.inf
    if ext == ".bin":
        pts.tofile(tmp_path / "nan.bin")
    elif ext == ".ply":
        write_ply_vertices(tmp_path / "nan.ply", {c: pts[:, i] for i, c in enumerate("xyz")})
    else:
        cloud = o3d.t.geometry.PointCloud()
        cloud.point["positions"] = o3d.core.Tensor(pts[:, :3].copy())
        o3d.t.io.write_point_cloud(str(tmp_path / "nan.pcd"), cloud)
    with pytest.raises(DatasetError, match=r"nan\.\w+: 3 of 10 points have NaN or infinite"):
        read_scan(tmp_path / f"nan{ext}")


@pytest.mark.parametrize("ext", [".ply", ".pcd"])
@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.int32])
def test_integer_coordinates_are_refused_naming_field_and_type(
    tmp_path: Path, ext: str, dtype: type
) -> None:
    """A ``uchar x`` (or millimetres as int32) was read as metres: a cloud of garbage
    that nothing refused."""
    xyz = {"x": np.arange(5, dtype=dtype), "y": np.ones(5, np.float32)}
    xyz["z"] = np.zeros(5, np.float32)
    (write_ply_vertices if ext == ".ply" else write_pcd)(tmp_path / f"i{ext}", xyz)
    expected = rf"i\{ext}: coordinate field 'x' is {np.dtype(dtype)}, not a float: "
    with pytest.raises(DatasetError, match=expected):
        read_scan(tmp_path / f"i{ext}")


def test_missing_scan_file(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nothere.ply"):
        read_scan(tmp_path / "nothere.ply")


# --------------------------------------------------------------------------- PCL's layouts


def _pcl17_binary_pcd(points: np.ndarray, ring: np.ndarray, page: int, tail: bytes | None) -> bytes:
    """A binary PCD as PCL 1.7 writes velodyne_pointcloud's PointXYZIR: ``_`` padding
    fields, and the file one page longer than its points (``tail`` replaces the zeros)."""
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        "FIELDS x y z _ intensity ring _\nSIZE 4 4 4 1 4 2 1\nTYPE F F F U F U U\n"
        f"COUNT 1 1 1 4 1 1 10\nWIDTH {len(points)}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
        f"POINTS {len(points)}\nDATA binary\n"
    ).encode()
    rows = np.zeros(
        len(points),
        dtype=[("xyz", "<f4", 3), ("_a", "u1", 4), ("i", "<f4"), ("ring", "<u2"), ("_b", "u1", 10)],
    )
    rows["xyz"], rows["i"], rows["ring"] = points, 7.0, ring
    rows["_a"], rows["_b"] = 0xAB, 0xCD  # padding bytes are not zero in the wild
    pad = bytes(page - len(header)) if tail is None else tail
    return header + rows.tobytes() + pad


@pytest.mark.parametrize("page", [4096, 16384])
def test_pcd_from_pcl17_with_page_padding_reads_the_points(tmp_path: Path, page: int) -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(-30, 30, (50, 3)).astype(np.float32)
    ring = rng.integers(0, 16, 50).astype(np.uint16)
    (tmp_path / "v.pcd").write_bytes(_pcl17_binary_pcd(pts, ring, page, None))
    scan = read_scan(tmp_path / "v.pcd")
    assert np.array_equal(scan.points, pts.astype(np.float64))
    assert np.array_equal(scan.ring, ring.astype(np.int32))


@pytest.mark.parametrize("tail", ["short zeros", "one page, not all zeros", "ones"])
def test_pcd_with_other_extra_bytes_is_still_refused(tmp_path: Path, tail: str) -> None:
    pts = np.ones((5, 3), np.float32)
    data = _pcl17_binary_pcd(pts, np.zeros(5, np.uint16), 4096, None)
    header_end = data.index(b"DATA binary\n") + len(b"DATA binary\n")
    page_tail = bytearray(4096 - header_end)
    page_tail[-3] = 1
    extra = {"short zeros": bytes(100), "one page, not all zeros": bytes(page_tail)}
    body_end = header_end + 5 * 32
    (tmp_path / "v.pcd").write_bytes(data[:body_end] + extra.get(tail, b"\x01" * 8))
    with pytest.raises(DatasetError, match=r"v\.pcd: binary PCD longer than its header"):
        read_scan(tmp_path / "v.pcd")


# ------------------------------------------------------------ fields as lidar drivers name them


def _driver_fields(layout: str, n: int, rng: np.random.Generator) -> tuple[dict, np.ndarray | None]:
    """Fields as a driver's cloud saved to a file has them, and the true times (s)."""
    xyz = rng.uniform(-20, 20, (n, 3)).astype(np.float32)
    t_true = np.sort(rng.uniform(0, 0.1, n))
    fields = {"x": xyz[:, 0], "y": xyz[:, 1], "z": xyz[:, 2]}
    fields["intensity"] = rng.uniform(0, 255, n).astype(np.float32)
    if layout == "velodyne":  # ring uint16, time float32 s
        fields["ring"] = rng.integers(0, 16, n).astype(np.uint16)
        fields["time"] = t_true.astype(np.float32)
        t_true = fields["time"].astype(np.float64)
    elif layout == "ouster":  # t uint32 ns, ring uint16 (listed after t)
        fields["t"] = np.round(t_true * 1e9).astype(np.uint32)
        fields["ring"] = rng.integers(0, 128, n).astype(np.uint16)
        t_true = fields["t"] * 1e-9
    elif layout == "nebula":  # channel uint16; time_stamp absolute float64 Unix seconds
        fields["channel"] = rng.integers(0, 32, n).astype(np.uint16)
        fields["time_stamp"] = 1.5e9 + t_true
        t_true = t_true - t_true[0]  # no epoch time given: from the first point
    else:  # livox: line uint8, offset_time uint32 ns
        fields["line"] = rng.integers(0, 6, n).astype(np.uint8)
        fields["offset_time"] = np.round(t_true * 1e9).astype(np.uint32)
        t_true = fields["offset_time"] * 1e-9
    return fields, t_true


@pytest.mark.parametrize("ext", [".pcd", ".ply"])
@pytest.mark.parametrize("layout", ["velodyne", "ouster", "livox", "nebula"])
def test_time_and_ring_fields_named_as_drivers_do(tmp_path: Path, ext: str, layout: str) -> None:
    fields, t_true = _driver_fields(layout, 40, np.random.default_rng(8))
    file = tmp_path / f"scan{ext}"
    write = write_pcd if ext == ".pcd" else write_ply_vertices
    write(file, fields)
    scan = read_scan(file)
    ring = next(fields[n] for n in ("ring", "line", "channel") if n in fields)
    assert np.array_equal(scan.ring, ring.astype(np.int32))
    if t_true is None:
        assert scan.t is None
    else:  # float64 Unix seconds resolve 0.24 us
        assert scan.t == pytest.approx(t_true, abs=1e-6 if layout == "nebula" else 1e-12)
    assert np.array_equal(scan.points[:, 0], fields["x"].astype(np.float64))


@pytest.mark.parametrize("marker", [np.nan, 0.0])
def test_all_nan_points_of_an_organised_cloud_are_no_returns(tmp_path: Path, marker) -> None:
    """PCL marks a no return all NaN, Ouster's driver (0, 0, 0): the latter were kept, a
    cluster at the sensor's origin (KITTI raw 0005's PCD scans hold one a scan)."""
    fields, t_true = _driver_fields("velodyne", 30, np.random.default_rng(9))
    no_return = np.zeros(30, bool)
    no_return[[0, 7, 29]] = True
    for c in "xyz":
        fields[c][no_return] = marker
    fields["x"][3] = 0.0  # one coordinate 0 is a return
    write_pcd(tmp_path / "org.pcd", fields)
    scan = read_scan(tmp_path / "org.pcd")
    assert len(scan) == 27
    assert np.array_equal(scan.points[:, 1], fields["y"][~no_return].astype(np.float64))
    assert np.array_equal(scan.ring, fields["ring"][~no_return].astype(np.int32))
    assert scan.t == pytest.approx(t_true[~no_return], abs=0)


def test_times_in_another_unit_name_field_and_unit(tmp_path: Path) -> None:
    fields, _ = _driver_fields("velodyne", 10, np.random.default_rng(2))
    fields["time"] = fields["time"] * np.float32(1e6)  # microseconds in a float field
    write_pcd(tmp_path / "us.pcd", fields)
    with pytest.raises(DatasetError, match=r"us\.pcd: \d+ of 10 point times 'time' \(read as s\)"):
        read_scan(tmp_path / "us.pcd")


def test_pcd_with_width_and_height_left_unset_is_unorganised(tmp_path: Path) -> None:
    """nebula (TIER IV's lidar drivers) saves scans with ``WIDTH 0`` / ``HEIGHT 0``."""
    write_pcd(
        tmp_path / "a.pcd", {c: np.arange(4, dtype=np.float32) + i for i, c in enumerate("xyz")}
    )
    data = (tmp_path / "a.pcd").read_bytes()
    unset = data.replace(b"WIDTH 4\nHEIGHT 1\n", b"WIDTH 0\nHEIGHT 0\n")
    assert unset != data
    (tmp_path / "b.pcd").write_bytes(unset)
    assert np.array_equal(
        read_scan(tmp_path / "b.pcd").points, read_scan(tmp_path / "a.pcd").points
    )
    (tmp_path / "c.pcd").write_bytes(data.replace(b"WIDTH 4\nHEIGHT 1\n", b"WIDTH 0\nHEIGHT 1\n"))
    with pytest.raises(
        DatasetError, match=r"c\.pcd: PCD header WIDTH 0 x HEIGHT 1 is not POINTS 4"
    ):
        read_scan(tmp_path / "c.pcd")


@pytest.mark.parametrize(
    ("value", "later"),
    [("1700000000", "1700000000.0512345"), ("1.7e+18", "1.7000000000512345e+18")],
)
def test_absolute_times_rounded_to_whole_seconds_are_refused(
    tmp_path: Path, value: str, later: str
) -> None:
    """open3d writes an ASCII PCD's floats with 10 significant digits: a Hesai, Robosense
    (Unix seconds) or livox_ros_driver2 (Unix nanoseconds) ``timestamp`` becomes one whole
    second for every point. Main read the sweep as one instant, without a word (the points'
    true times span 0.1 s); now refused naming the file and the field."""
    rows = "\n".join(f"{x:.3f} 2.0 0.5 {value}" for x in np.linspace(1, 5, 20))
    path = tmp_path / "hesai.pcd"
    path.write_text(
        "VERSION 0.7\nFIELDS x y z timestamp\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 1\n"
        f"WIDTH 20\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 20\nDATA ascii\n{rows}\n"
    )
    with pytest.raises(DatasetError) as exc:
        read_scan(path)
    assert str(exc.value).startswith(
        f"{path}: absolute point times 'timestamp' are all whole seconds: stored with too few"
    )
    assert len(read_scan(path, time_field="none")) == 20
    full = path.read_text().replace(f" {value}\n", f" {later}\n", 1)
    path.write_text(full)  # one point off the whole second (and the 10 ms grid): times kept
    t = read_scan(path).t
    assert t is not None and np.isclose(t.max(), 0.0512345) and np.count_nonzero(t) == 1


def _timestamp_pcd(path: Path, stamps: list[str]) -> Path:
    """An ASCII PCD, one point a row at x = 1 m, 2 m, ..., its ``timestamp`` (f64) given."""
    rows = "\n".join(f"{k + 1}.0 2.0 0.5 {v}" for k, v in enumerate(stamps))
    n = len(stamps)
    path.write_text(
        "VERSION 0.7\nFIELDS x y z timestamp\nSIZE 4 4 4 8\nTYPE F F F F\nCOUNT 1 1 1 1\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA ascii\n{rows}\n"
    )
    return path


@pytest.mark.parametrize("unit", ["s", "ns"])
def test_per_sweep_absolute_times_on_an_exact_clock_are_kept(tmp_path: Path, unit: str) -> None:
    """A simulated 2D rig's five sweeps an epoch stamped on an exact 50 Hz clock (Unix s, or
    ns as livox_ros_driver2 writes them): five values, all multiples of 0.01 s, the same
    pattern as times rounded to 0.01 s: kept, each point at its sweep's time to 1 us (a
    refusal here would refuse good data; times rounded that way are not caught)."""
    sweep = np.repeat(np.arange(5) * 0.02, 40)
    seconds = 1700000000.0 + sweep
    stamps = [f"{v:.2f}" if unit == "s" else f"{v * 1e9:.12e}" for v in seconds]
    t = read_scan(_timestamp_pcd(tmp_path / "rig.pcd", stamps)).t
    assert t is not None
    np.testing.assert_allclose(t, sweep, atol=1e-6)


@pytest.mark.parametrize("packets", [75, 10])
def test_per_packet_absolute_times_are_kept(tmp_path: Path, packets: int) -> None:
    """Per-packet times (a Velodyne's 75 packets a 10 Hz sweep, 1.33 ms apart; or 10,
    10 ms apart, off the clock's 10 ms grid): few values, evenly spread, not rounded: kept,
    to the microsecond."""
    per_packet = 0.0377 + np.floor(np.arange(200) * packets / 200) * 0.1 / packets
    path = _timestamp_pcd(tmp_path / "vlp.pcd", [f"{1700000000 + v:.7f}" for v in per_packet])
    t = read_scan(path).t
    assert t is not None and len(np.unique(t)) == packets
    np.testing.assert_allclose(t, per_packet - per_packet[0], atol=1e-6)


def test_float_times_in_nanoseconds_are_named_so(tmp_path: Path) -> None:
    """A float64 't' of relative nanoseconds: refused before as times neither near the
    epoch nor Unix times, with nothing saying they were nanoseconds."""
    from planodom.datasets.pcd import write_pcd

    rng = np.random.default_rng(2)
    points = rng.uniform(-10, 10, (200, 3))
    t = np.sort(rng.uniform(0, 0.1, 200))
    fields = {"x": points[:, 0], "y": points[:, 1], "z": points[:, 2], "t": t * 1e9}
    write_pcd(tmp_path / "a.pcd", fields)
    with pytest.raises(DatasetError, match=r"a sweep of 0.0\d+ s in nanoseconds: a float time"):
        read_scan(tmp_path / "a.pcd", reference_time=0.0)
    write_pcd(tmp_path / "b.pcd", fields | {"t": t * 1e6})
    with pytest.raises(DatasetError, match=r"a sweep of 0.0\d+ s in microseconds"):
        read_scan(tmp_path / "b.pcd", reference_time=0.0)
    write_pcd(tmp_path / "c.pcd", fields | {"t": t})  # seconds: read
    assert np.array_equal(read_scan(tmp_path / "c.pcd", reference_time=0.0).t, t)
