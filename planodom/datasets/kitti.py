"""KITTI odometry sequences (``.../sequences/NN``) as planodom datasets.

Layout::

    dataset/sequences/00/velodyne/000000.bin, ...   float32 x y z reflectance per point
    dataset/sequences/00/calib.txt                  P0..P3 and Tr: 12 numbers each
    dataset/sequences/00/times.txt                  one time (s from the sequence start) per scan
    dataset/sequences/00/poses.txt  or  dataset/poses/00.txt   ground truth (optional)

The base frame is the Velodyne frame. KITTI's ground truth is camera 0's pose
``P_k = T_cam0start_cam0k`` (3x4 rows); with ``Tr = T_cam0_velo`` from ``calib.txt`` the
Velodyne's pose in the world frame of the first Velodyne pose is
``T_world_velo_k = Tr^-1 @ P_k @ Tr``. :func:`write_kitti_camera_poses` writes an estimate
back in the camera convention (``P_k = Tr @ T_k @ Tr^-1``) for ``evo_ape kitti`` and the
devkit. The scans carry no ``ring`` (the .bin files hold none) and no ``t`` (KITTI gives
one time per scan).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planodom.datasets.bin_scan import check_bin_layout
from planodom.datasets.dataset import TIMES_FILE, read_times
from planodom.datasets.file_entries import optional_file
from planodom.datasets.scan_io import check_time_field, read_scan
from planodom.datasets.scan_names import check_numbering
from planodom.datasets.scan_order import scan_order_key
from planodom.datasets.times_file import epoch_unit_note
from planodom.errors import DatasetError
from planodom.geometry import first_non_rotation, rotation_problem
from planodom.mounts import check_mounts
from planodom.rig import Rig
from planodom.scan import Scan

#: KITTI's Velodyne HDL-64E turns at 10 Hz.
KITTI_RATE_HZ = 10.0


def is_kitti_sequence(path: str | Path) -> bool:
    """True for a folder with ``velodyne/`` and ``calib.txt`` (a KITTI odometry sequence)."""
    path = Path(path)
    return path.is_dir() and (path / "velodyne").is_dir() and (path / "calib.txt").is_file()


def read_kitti_calib(path: str | Path) -> np.ndarray:
    """``Tr = T_cam0_velo`` (4, 4) from a KITTI ``calib.txt`` (line ``Tr: 12 numbers``).

    Raises:
        DatasetError: naming the file when it is unreadable or has no valid ``Tr`` line.
    """
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read calibration: {exc}") from None
    for number, line in enumerate(lines, start=1):
        key, _, rest = line.partition(":")
        if key.strip() != "Tr":
            continue
        try:
            values = np.array([float(v) for v in rest.split()], dtype=np.float64)
        except ValueError:
            values = np.zeros(0)
        if len(values) != 12 or not np.all(np.isfinite(values)):
            raise DatasetError(f"{path}:{number}: 'Tr' must hold 12 finite numbers")
        Tr = _homogeneous(values.reshape(3, 4))
        problem = rotation_problem(Tr[:3, :3])
        if problem is not None:
            raise DatasetError(f"{path}:{number}: 'Tr' is not a rigid transform ({problem})")
        check_mounts([(f"{path}:{number}: 'Tr'", Tr[:3, 3])], "")  # millimetres: refused
        return Tr
    keys = [k.strip() for k, sep, _ in (x.partition(":") for x in lines) if sep and k.strip()]
    found = f"; its keys: {', '.join(keys[:8])}" if keys else "; it holds no 'KEY: numbers' line"
    raise DatasetError(
        f"{path}: no 'Tr:' line (the Velodyne-to-camera transform of KITTI odometry's "
        f"calib.txt){found}"
    )


def read_kitti_poses(path: str | Path) -> np.ndarray:
    """Poses (E, 4, 4) from a KITTI pose file (12 numbers, a 3x4 row-major matrix, per line).

    Raises:
        DatasetError: naming ``path:line`` for a line that is not 12 finite numbers.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise DatasetError(f"{path}: cannot read poses: {exc}") from None
    rows, numbers = [], []
    for number, line in enumerate(text.splitlines(), start=1):
        if not line.strip():
            continue
        numbers.append(number)
        try:
            values = [float(v) for v in line.split()]
        except ValueError:
            values = []
        if len(values) != 12 or not np.all(np.isfinite(values)):
            raise DatasetError(f"{path}:{number}: expected 12 finite numbers (a 3x4 pose)")
        rows.append(values)
    if not rows:
        raise DatasetError(f"{path}: no poses")
    poses = _homogeneous(np.array(rows).reshape(-1, 3, 4))
    bad = first_non_rotation(poses[:, :3, :3])
    if bad is not None:
        k, problem, count = bad
        raise DatasetError(f"{path}:{numbers[k]}: not a rigid pose ({problem}; {count} such lines)")
    return poses


def write_kitti_poses(path: str | Path, poses: np.ndarray) -> None:
    """Write poses (E, 4, 4) as KITTI rows: the top 3x4 block, row-major, exact decimals."""
    poses = np.asarray(poses, dtype=np.float64)
    if poses.ndim != 3 or poses.shape[1:] != (4, 4):
        raise DatasetError(f"{path}: poses must have shape (E, 4, 4), got {poses.shape}")
    lines = [" ".join(repr(float(v)) for v in T[:3].reshape(-1)) for T in poses]
    Path(path).write_text("\n".join(lines) + "\n", encoding="utf-8")


def write_kitti_camera_poses(path: str | Path, T_world_velo: np.ndarray, Tr: np.ndarray) -> None:
    """Write Velodyne-frame poses (E, 4, 4) in KITTI's camera convention.

    ``P_k = Tr @ T_world_velo_k @ Tr^-1`` with ``Tr = T_cam0_velo`` (4, 4), so that
    ``evo_ape kitti`` and the KITTI devkit compare the file with ``poses/NN.txt``.
    """
    T = np.asarray(T_world_velo, dtype=np.float64)
    write_kitti_poses(path, Tr @ T @ np.linalg.inv(Tr))


def velo_poses_from_camera(P: np.ndarray, Tr: np.ndarray) -> np.ndarray:
    """``T_world_velo_k = Tr^-1 @ P_k @ Tr`` (E, 4, 4) from camera poses ``P`` (E, 4, 4)."""
    return np.linalg.inv(Tr) @ np.asarray(P, dtype=np.float64) @ Tr


class KittiSequence:
    """A KITTI odometry sequence read lazily: ``len(ds)``, ``ds[k] -> Scan`` (Velodyne frame).

    Attributes:
        path: the sequence folder.
        scan_files: the ``velodyne/*.bin`` files, in order.
        times: (E,) float64 seconds from ``times.txt`` (from the sequence start).
        gt_poses: (E, 4, 4) ``T_world_velo`` or None without a pose file.
        gt_file: the pose file read, or None.
        Tr: ``T_cam0_velo`` (4, 4) from ``calib.txt`` (for :func:`write_kitti_camera_poses`).
        rig: rate 10 Hz, the Velodyne at the base frame's origin, platform "vehicle" (a
            car; ``odometry.platform`` in the config overrides it).
        notes: what a user should check (no ``times.txt``: the scans taken 0.1 s apart).
    """

    def __init__(
        self,
        path: Path,
        scan_files: list[Path],
        times: np.ndarray,
        Tr: np.ndarray,
        gt_poses: np.ndarray | None,
        gt_file: Path | None,
        bin_layout: str = "kitti",
        time_field: str = "auto",
    ) -> None:
        self.path = path
        self.bin_layout = check_bin_layout(bin_layout)
        self.time_field = check_time_field(time_field)
        self.scan_files = scan_files
        self.times = times
        self.Tr = Tr
        self.gt_poses = gt_poses
        self.gt_file = gt_file
        self.notes: list[str] = []  # how the sequence was read, warned of by the CLI
        self.rig = Rig(
            epoch_rate_hz=KITTI_RATE_HZ,
            sensor_origins=np.zeros((1, 3)),
            extrinsics=(np.eye(4),),
            extra={"source": "kitti", "sequence": str(path), "T_cam0_velo": Tr.tolist()},
            platform="vehicle",
        )

    def __len__(self) -> int:
        return len(self.scan_files)

    def __getitem__(self, index: int) -> Scan:
        n = len(self)
        if not -n <= index < n:
            raise IndexError(f"epoch {index} out of range for {n} epochs")
        return read_scan(self.scan_files[index], self.bin_layout, time_field=self.time_field)

    def __repr__(self) -> str:
        gt = "with" if self.gt_poses is not None else "without"
        return f"KittiSequence({str(self.path)!r}, {len(self)} scans, {gt} ground truth)"


def kitti_pose_file(path: str | Path) -> Path | None:
    """The ground-truth file of a sequence: ``poses.txt`` beside it or ``../../poses/NN.txt``."""
    path = Path(path)
    for candidate in (path / "poses.txt", path.parent.parent / "poses" / f"{path.name}.txt"):
        if optional_file(candidate):  # a broken link is refused, not read as no file
            return candidate
    return None


def load_kitti_sequence(
    path: str | Path, bin_layout: str = "kitti", time_field: str = "auto"
) -> KittiSequence:
    """Open a KITTI odometry sequence folder (see the module docstring).

    ``bin_layout``: how its ``.bin`` scans are read; KITTI's own layout unless told
    otherwise (``auto`` or ``nuscenes``, :mod:`planodom.datasets.bin_scan`); ``time_field``:
    the scans' point time field (:func:`planodom.datasets.scan_io.read_scan`).

    Raises:
        DatasetError: naming the file: no ``velodyne/*.bin`` files, a bad ``calib.txt``,
            ``times.txt`` or pose file, or counts that differ from the scan count.
    """
    path = Path(path)
    if not is_kitti_sequence(path):
        raise DatasetError(f"{path} is not a KITTI sequence (needs velodyne/ and calib.txt)")
    # hidden files skipped (a Mac's ._000000.bin beside each scan), as in a dataset; the
    # names' numbers compared as numbers (unpadded names were read 0, 1, 10, 11, 2, ...)
    scans = (f for f in (path / "velodyne").glob("*.bin") if not f.name.startswith("."))
    files = sorted(scans, key=scan_order_key)
    if not files:
        raise DatasetError(f"{path / 'velodyne'}: no .bin scan files")
    Tr = read_kitti_calib(path / "calib.txt")
    times_file = path / TIMES_FILE
    notes = []
    if optional_file(times_file):
        # the dataset format's reader: a NaN, a second column or a time going back was
        # read as is by np.loadtxt (NaN compares false, two columns made (E, 2) times)
        times = read_times(times_file, len(files))
    else:
        check_numbering(files, TIMES_FILE)
        times = np.arange(len(files)) / KITTI_RATE_HZ
        notes.append(f"{path}: no {TIMES_FILE}; the scans taken 0.1 s apart (KITTI's 10 Hz)")
    notes += [unit] if (unit := epoch_unit_note(times, str(path))) else []
    gt_file = kitti_pose_file(path)
    gt = None
    if gt_file is not None:
        P = read_kitti_poses(gt_file)
        if len(P) != len(files):
            raise DatasetError(f"{gt_file}: {len(P)} poses for {len(files)} scans")
        gt = velo_poses_from_camera(P, Tr)
    seq = KittiSequence(path, files, times, Tr, gt, gt_file, bin_layout, time_field)
    seq.notes = notes
    return seq


def _homogeneous(M: np.ndarray) -> np.ndarray:
    """(…, 3, 4) -> (…, 4, 4) with a last row 0 0 0 1."""
    out = np.zeros(M.shape[:-2] + (4, 4))
    out[..., :3, :] = M
    out[..., 3, 3] = 1.0
    return out
