"""Dataset format: exact round trips of scans and poses, interop with open3d / evo, bad input."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from evo.core.trajectory import PoseTrajectory3D
from evo.tools import file_interface
from scipy.spatial.transform import Rotation

from planodom._open3d import o3d
from planodom.datasets import (
    Dataset,
    load_dataset,
    read_rig,
    read_scan,
    read_tum,
    write_dataset,
    write_rig,
    write_scan,
    write_tum,
)
from planodom.datasets.ply import write_ply_vertices
from planodom.errors import DatasetError
from planodom.scan import Scan

ALL_FIELDS = ("ring", "t", "label")


def make_scan(rng: np.random.Generator, n: int = 50, fields=ALL_FIELDS) -> Scan:
    """Random scan with values that catch lossy storage (tiny, huge, -0.0, int32 extremes)."""
    pts = rng.normal(scale=20.0, size=(n, 3)) * 10.0 ** rng.integers(-8, 8, size=(n, 1))
    if n >= 3:
        pts[0, 0], pts[1, 1], pts[2, 2] = -0.0, 5e-324, 1e300
    label = rng.integers(-1, 40, n).astype(np.int32)
    if n >= 2:
        label[:2] = [np.iinfo(np.int32).min, np.iinfo(np.int32).max]
    extra = {
        "ring": rng.integers(0, 64, n).astype(np.int32),
        "t": rng.uniform(0.0, 0.1, n) + 1e-17,
        "label": label,
    }
    return Scan(pts, **{k: v for k, v in extra.items() if k in fields})


def float32_safe(scan: Scan) -> Scan:
    """``scan`` with coordinates clipped into float32 range."""
    return Scan(np.clip(scan.points, -1e30, 1e30), scan.ring, scan.t, scan.label)


def assert_same_scan(a: Scan, b: Scan) -> None:
    """Bit-exact equality of points and fields (also tells -0.0 from 0.0)."""
    assert a.points.dtype == b.points.dtype == np.float64
    assert a.points.shape == b.points.shape
    assert np.array_equal(a.points.view(np.uint64), b.points.view(np.uint64))
    for name in ALL_FIELDS:
        va, vb = getattr(a, name), getattr(b, name)
        assert (va is None) == (vb is None), name
        if va is not None:
            assert va.dtype == vb.dtype
            assert np.array_equal(va.view(np.uint8), vb.view(np.uint8)), name


def random_poses(rng: np.random.Generator, n: int) -> np.ndarray:
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, :3] = Rotation.random(n, random_state=rng).as_matrix()
    poses[:, :3, 3] = rng.normal(scale=100.0, size=(n, 3))
    return poses


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
    with pytest.raises(DatasetError, match="beyond float32 range"):  # it holds 1e300
        write_scan(tmp_path / f"a{ext}", scan, points_dtype=np.float32)
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
            "truncated",
        ),
        (
            "noxyz.ply",
            lambda p: b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n",
            "coordinates",
        ),
        ("garbage.pcd", lambda p: np.random.default_rng(1).bytes(500), "PCD"),
        ("truncated.pcd", lambda p: _good_pcd(p)[:-9], "truncated"),
        (
            "ascii.pcd",
            lambda p: (
                b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                b"COUNT 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n1 2 3\n4 5 6\n"
            ),
            "header says 3",
        ),
        ("truncated.bin", lambda p: np.zeros(10, np.float32).tobytes(), "multiple of 16"),
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


def test_missing_scan_file(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nothere.ply"):
        read_scan(tmp_path / "nothere.ply")


# --------------------------------------------------------------------------- poses


def test_tum_round_trip_exact_and_evo_compatible(tmp_path: Path) -> None:
    rng = np.random.default_rng(6)
    times = np.cumsum(rng.uniform(0.05, 0.15, 40)) + 1.6e9
    poses = random_poses(rng, 40)
    write_tum(tmp_path / "p.tum", times, poses)
    t_back, p_back = read_tum(tmp_path / "p.tum")
    assert np.array_equal(t_back, times)
    assert np.array_equal(p_back[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(p_back, poses, rtol=0, atol=1e-15 * 100)

    evo_traj = file_interface.read_tum_trajectory_file(str(tmp_path / "p.tum"))
    assert np.array_equal(evo_traj.timestamps, times)
    assert np.array_equal(evo_traj.positions_xyz, poses[:, :3, 3])
    np.testing.assert_allclose(np.array(evo_traj.poses_se3), poses, atol=1e-13)

    file_interface.write_tum_trajectory_file(
        str(tmp_path / "evo.tum"), PoseTrajectory3D(poses_se3=list(poses), timestamps=times)
    )
    t_evo, p_evo = read_tum(tmp_path / "evo.tum")
    assert np.array_equal(t_evo, times)
    assert np.array_equal(p_evo[:, :3, 3], poses[:, :3, 3])
    np.testing.assert_allclose(p_evo, poses, atol=1e-13)


@pytest.mark.parametrize(
    "line, message",
    [
        ("0.2 1 2 3 0 0 0", "expected 8 finite numbers"),
        ("0.2 1 2 3 0 0 0 1 5", "expected 8 finite numbers"),
        ("0.2 1 2 x 0 0 0 1", "expected 8 finite numbers"),
        ("0.2 1 2 nan 0 0 0 1", "expected 8 finite numbers"),
        ("0.2 1 2 3 0 0 0 0.9", "quaternion norm 0.9"),
        ("0.2 1 2 3 0 0 0 0", "quaternion norm 0"),
        ("0.1 1 2 3 0 0 0 1", "does not increase"),
    ],
)
def test_bad_tum_lines_name_file_and_line(tmp_path: Path, line: str, message: str) -> None:
    text = "# time tx ty tz qx qy qz qw\n0.1 0 0 0 0 0 0 1\n\n" + line + "\n0.3 0 0 0 0 0 0 1\n"
    (tmp_path / "poses.tum").write_text(text)
    with pytest.raises(DatasetError, match=message) as err:
        read_tum(tmp_path / "poses.tum")
    assert "poses.tum:4" in str(err.value)


def test_tum_empty_or_missing(tmp_path: Path) -> None:
    (tmp_path / "e.tum").write_text("# only a comment\n")
    with pytest.raises(DatasetError, match="e.tum: no poses"):
        read_tum(tmp_path / "e.tum")
    with pytest.raises(DatasetError, match="missing.tum"):
        read_tum(tmp_path / "missing.tum")


def test_tum_accepts_nearly_unit_quaternions(tmp_path: Path) -> None:
    q = Rotation.from_euler("z", 0.3).as_quat()
    (tmp_path / "p.tum").write_text("0 1 2 3 " + " ".join(f"{v:.6f}" for v in q) + "\n")
    _, poses = read_tum(tmp_path / "p.tum")
    np.testing.assert_allclose(
        poses[0, :3, :3], Rotation.from_euler("z", 0.3).as_matrix(), atol=2e-6
    )
    np.testing.assert_allclose(poses[0, :3, :3] @ poses[0, :3, :3].T, np.eye(3), atol=1e-15)


# --------------------------------------------------------------------------- datasets


def test_dataset_round_trip(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    scans = [make_scan(rng, n) for n in (30, 0, 12, 1)]
    scans[2] = Scan(scans[2].points)  # epochs with and without optional fields
    times = np.array([0.0, 0.1, 0.2, 0.35]) + 1234.5
    poses = random_poses(rng, 4)
    rig = {"T_base_scanner": np.eye(4)[:3], "fov_deg": 270.0, "scene": {"seed": np.int64(3)}}
    ds = write_dataset(tmp_path / "ds", scans, times, poses, rig)
    assert isinstance(ds, Dataset)

    ds = load_dataset(tmp_path / "ds")
    assert len(ds) == 4
    assert [f.name for f in ds.scan_files] == [f"00000{k}.ply" for k in range(4)]
    for k, scan in enumerate(scans):
        assert_same_scan(ds[k], scan)
    assert_same_scan(ds[-1], scans[-1])
    assert sum(1 for _ in ds) == 4
    with pytest.raises(IndexError):
        ds[4]
    assert np.array_equal(ds.times, times)
    np.testing.assert_allclose(ds.gt_poses, poses, atol=1e-13)
    assert ds.rig == {
        "T_base_scanner": np.eye(4)[:3].tolist(),
        "fov_deg": 270.0,
        "scene": {"seed": 3},
    }


def test_dataset_pcd_float32(tmp_path: Path) -> None:
    scans = [float32_safe(make_scan(np.random.default_rng(k), 10)) for k in range(3)]
    ds = write_dataset(tmp_path, scans, [0.0, 0.1, 0.2], extension=".pcd", points_dtype=np.float32)
    assert [f.suffix for f in ds.scan_files] == [".pcd"] * 3
    assert np.array_equal(ds[1].points, scans[1].points.astype(np.float32).astype(np.float64))
    assert np.array_equal(ds[1].t, scans[1].t) and ds.gt_poses is None and ds.rig is None


def test_epoch_times_without_poses(tmp_path: Path) -> None:
    scans = [Scan(np.zeros((1, 3)))] * 5
    ds = write_dataset(tmp_path / "a", scans, np.arange(5) * 0.1)
    np.testing.assert_array_equal(ds.times, np.arange(5) * 0.1)
    ds = write_dataset(tmp_path / "b", scans, np.arange(5) / 20.0, rig={"epoch_rate": 20})
    np.testing.assert_array_equal(ds.times, np.arange(5) / 20.0)
    with pytest.raises(DatasetError, match="epoch_rate"):
        write_dataset(tmp_path / "c", scans, np.arange(5) * 0.5)


def test_write_refuses_then_overwrites_without_stale_files(tmp_path: Path) -> None:
    rng = np.random.default_rng(8)
    write_dataset(
        tmp_path,
        [make_scan(rng, 5) for _ in range(5)],
        np.arange(5) * 0.1,
        random_poses(rng, 5),
        rig={"a": 1},
    )
    fewer = [make_scan(rng, 5) for _ in range(3)]
    with pytest.raises(DatasetError, match="already holds a dataset"):
        write_dataset(tmp_path, fewer, np.arange(3) * 0.1)
    ds = write_dataset(tmp_path, fewer, np.arange(3) * 0.1, overwrite=True)
    assert len(ds) == 3 and ds.gt_poses is None and ds.rig is None
    assert_same_scan(ds[2], fewer[2])


def test_files_sorted_naturally_and_directory_given_directly(tmp_path: Path) -> None:
    rng = np.random.default_rng(9)
    rows = {}
    for name in ("10", "2", "1", "0000003", "100"):
        rows[name] = rng.normal(size=(4, 4)).astype(np.float32)
        rows[name].tofile(tmp_path / f"{name}.bin")
    (tmp_path / ".hidden").write_text("ignored")
    ds = load_dataset(tmp_path)
    order = ["1", "2", "0000003", "10", "100"]
    assert [f.stem for f in ds.scan_files] == order
    for k, name in enumerate(order):
        assert np.array_equal(ds[k].points, rows[name][:, :3].astype(np.float64))
    np.testing.assert_allclose(ds.times, np.arange(5) * 0.1)

    # poses.tum and rig.yaml beside the scan files are part of the dataset, not scans.
    write_tum(tmp_path / "poses.tum", np.arange(5) + 0.5, random_poses(rng, 5))
    write_rig(tmp_path / "rig.yaml", {"epoch_rate": 10.0})
    ds = load_dataset(tmp_path)
    assert len(ds) == 5 and ds.rig == {"epoch_rate": 10.0}
    np.testing.assert_array_equal(ds.times, np.arange(5) + 0.5)


def _dataset(tmp_path: Path, n: int = 3) -> Path:
    rng = np.random.default_rng(10)
    write_dataset(
        tmp_path / "ds",
        [make_scan(rng, 4) for _ in range(n)],
        np.arange(n) * 0.1,
        random_poses(rng, n),
        rig={"epoch_rate": 10},
    )
    return tmp_path / "ds"


def test_bad_datasets(tmp_path: Path) -> None:
    with pytest.raises(DatasetError, match="nowhere does not exist"):
        load_dataset(tmp_path / "nowhere")

    (tmp_path / "empty").mkdir()
    with pytest.raises(DatasetError, match="empty has no scans/ directory"):
        load_dataset(tmp_path / "empty")
    (tmp_path / "empty" / "scans").mkdir()
    with pytest.raises(DatasetError, match=r"scans is empty"):
        load_dataset(tmp_path / "empty")

    root = _dataset(tmp_path)
    (root / "scans" / "notes.txt").write_text("x")
    (root / "scans" / "README").write_text("x")
    with pytest.raises(DatasetError, match="unknown extensions: README, notes.txt"):
        load_dataset(root)
    (root / "scans" / "notes.txt").unlink()
    (root / "scans" / "README").unlink()

    write_scan(root / "scans" / "000003.pcd", make_scan(np.random.default_rng(0), 3))
    with pytest.raises(DatasetError, match="scans: scan files mix extensions .pcd, .ply"):
        load_dataset(root)
    (root / "scans" / "000003.pcd").unlink()

    write_scan(root / "scans" / "000003.ply", make_scan(np.random.default_rng(0), 3))
    with pytest.raises(DatasetError, match="poses.tum: 3 poses for 4 scan files"):
        load_dataset(root)
    (root / "scans" / "000003.ply").unlink()
    load_dataset(root)  # repaired


@pytest.mark.parametrize(
    "text, message",
    [
        ("a: [1, 2\n", "cannot read rig file"),
        ("- 1\n- 2\n", "must hold a mapping"),
        ("epoch_rate: -5\n", "epoch_rate must be a positive number"),
        ("epoch_rate: fast\n", "epoch_rate must be a positive number"),
        ("epoch_rate: .inf\n", "epoch_rate must be finite"),
    ],
)
def test_bad_rig(tmp_path: Path, text: str, message: str) -> None:
    root = _dataset(tmp_path)
    (root / "rig.yaml").write_text(text)
    with pytest.raises(DatasetError, match=message) as err:
        load_dataset(root)
    assert "rig.yaml" in str(err.value)


def test_empty_rig_is_empty_dict(tmp_path: Path) -> None:
    (tmp_path / "rig.yaml").write_text("")
    assert read_rig(tmp_path / "rig.yaml") == {}


def test_bad_scan_in_dataset_names_file_when_read(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    data = (root / "scans" / "000001.ply").read_bytes()
    (root / "scans" / "000001.ply").write_bytes(data[:-3])
    ds = load_dataset(root)  # lazy: the scan is read only when indexed
    ds[0]
    with pytest.raises(DatasetError, match=r"000001\.ply: truncated"):
        ds[1]


def test_malformed_poses_in_dataset(tmp_path: Path) -> None:
    root = _dataset(tmp_path)
    lines = (root / "poses.tum").read_text().splitlines()
    lines[2] = "0.1 0 0 0 0 0 0"
    (root / "poses.tum").write_text("\n".join(lines) + "\n")
    with pytest.raises(DatasetError, match=r"poses\.tum:3: expected 8"):
        load_dataset(root)
