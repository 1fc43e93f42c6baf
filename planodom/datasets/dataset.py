"""A dataset directory: scan files, optional ground truth ``poses.tum``, optional epoch
``times.txt``, optional ``rig.yaml``."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from planodom.datasets.bag_clock import far_message
from planodom.datasets.bin_scan import check_bin_layout
from planodom.datasets.file_entries import (
    broken_link,
    check_file_entries,
    kitti_sequences_hint,
    optional_file,
    subfolders_hint,
)
from planodom.datasets.folder_ring_order import folder_ring_order, renumbered_rig, renumbered_rings
from planodom.datasets.pcd import viewpoint_note
from planodom.datasets.scan_io import SCAN_EXTENSIONS, check_time_field, read_scan, write_scan
from planodom.datasets.scan_names import check_numbering, kitti_raw_times, name_times
from planodom.datasets.scan_order import scan_order_key
from planodom.datasets.scan_time_notes import scan_time_notes
from planodom.datasets.scan_time_units import scan_time_unit
from planodom.datasets.time_wraps import CUT_PERIODS, WRAP_NS
from planodom.datasets.times_file import epoch_unit_note, read_times, unread_times, write_times
from planodom.datasets.tum import read_tum, write_tum
from planodom.errors import DatasetError
from planodom.mounts import check_mounts
from planodom.outputs import atomic_folder
from planodom.rig import RIG_KEYS, Rig, rig_mounts, unread_keys
from planodom.scan import Scan, ScanSequence
from planodom.yaml_files import read_yaml_file

SCANS_DIR = "scans"
POSES_FILE = "poses.tum"
RIG_FILE = "rig.yaml"
TIMES_FILE = "times.txt"
#: Epoch period (s) when neither poses.tum nor rig.yaml's ``epoch_rate`` gives the times.
DEFAULT_EPOCH_PERIOD = 0.1
#: Largest span of a scan's point times, in epoch periods (the longer of the gaps to its
#: neighbouring epochs). A scan is recorded between its neighbours' times, several sweeps
#: at most; a span of ten periods or more is a unit error (a sweep's 100 ms written as
#: 100 milliseconds read as seconds is a thousand), which deskewing would turn into
#: nonsense. Not from data: any factor between the sweep overlap (about 1) and a unit
#: step (1000) separates them.
MAX_TIME_SPAN_PERIODS = 10.0
#: Times spread over a sweep within 4.29 s of 0 but far from the epoch's time: a 32-bit field.
_CUT32 = f", or a clock's nanoseconds cut to 32 bits, which wrap every {WRAP_NS * 1e-9:.3g} s"


class Dataset:
    """A lazily loaded sequence of epochs: ``len(ds)``, ``ds[k] -> Scan``, ``for scan in ds``.

    Attributes:
        path: the dataset directory.
        scan_files: one file per epoch, in time order.
        times: (E,) float64 seconds, reference time of each epoch (see :func:`load_dataset`).
        gt_poses: (E, 4, 4) float64 ground truth ``T_world_base`` at ``times``, or None.
        rig: the typed ``rig.yaml`` (:class:`planodom.rig.Rig`; ``Rig()`` when there is none).
        bin_layout: how ``.bin`` scans are read: ``auto``, ``kitti``, ``nuscenes`` or ``xyz``
            (:mod:`planodom.datasets.bin_scan`).
        time_field: the scans' per-point time field: ``auto``, ``none`` (ignored) or a
            field name (:func:`planodom.datasets.scan_io.read_scan`).
        time_scale: seconds per unit of integer time offsets (None: nanoseconds), set by
            :func:`load_dataset` (:mod:`planodom.datasets.scan_time_units`).
        notes: one line each on how the scans are read that a user should check (a time
            unit other than the documented one); the CLI prints them as warnings.
        ring_renumber: ``(ids (k,), new ids (k,))`` given to the scans' rings when read, their
            ids in elevation order (:mod:`planodom.datasets.folder_ring_order`), or None.
    """

    def __init__(
        self,
        path: Path,
        scan_files: Sequence[Path],
        times: np.ndarray,
        gt_poses: np.ndarray | None = None,
        rig: Rig | None = None,
        bin_layout: str = "auto",
        time_field: str = "auto",
    ) -> None:
        self.path = Path(path)
        self.bin_layout = check_bin_layout(bin_layout)
        self.time_field = check_time_field(time_field)
        self.scan_files = list(scan_files)
        self.times = np.asarray(times, dtype=np.float64)
        self.gt_poses = gt_poses
        self.rig = rig if rig is not None else Rig()
        self.time_scale: float | None = None
        self.notes: list[str] = []
        self.ring_renumber: tuple[np.ndarray, np.ndarray] | None = None
        if len(self.times) != len(self.scan_files):
            raise DatasetError(
                f"{self.path}: {len(self.times)} epoch times for {len(self.scan_files)} scans"
            )

    def __len__(self) -> int:
        return len(self.scan_files)

    def __getitem__(self, index: int) -> Scan:
        """Read epoch ``index``'s scan from its file (negative indices count from the end)."""
        n = len(self.scan_files)
        if not -n <= index < n:
            raise IndexError(f"epoch {index} out of range for {n} epochs")
        file = self.scan_files[index]
        scan = read_scan(
            file, self.bin_layout, float(self.times[index]), self.time_field, self.time_scale
        )
        if self.ring_renumber is not None and scan.ring is not None:
            scan = replace(scan, ring=renumbered_rings(scan.ring, self.ring_renumber))
        origins = self.rig.sensor_origins
        if origins is not None and len(origins) > 1:  # per ring: the rings must index them
            rig_file = self.path / RIG_FILE
            if scan.ring is None:
                raise DatasetError(
                    f"{file}: no 'ring' field, but {rig_file} gives {len(origins)} "
                    "sensor_origins (one per ring)"
                )
            if len(scan) and (scan.ring.min() < 0 or scan.ring.max() >= len(origins)):
                raise DatasetError(
                    f"{file}: ring ids {scan.ring.min()}..{scan.ring.max()} do not index the "
                    f"{len(origins)} sensor_origins of {rig_file}"
                )
        self._check_time_span(index % n, scan)
        return scan

    def _check_time_span(self, index: int, scan: Scan) -> None:
        """Refuse point times spanning :data:`MAX_TIME_SPAN_PERIODS` epoch periods or more,
        or as far from the epoch's reference time (e.g. integer Unix seconds read as ns), or
        whose nearest point lies more than ``CUT_PERIODS`` periods from it (another clock,
        :mod:`planodom.datasets.bag_clock`)."""
        if scan.t is None or len(scan.t) == 0 or len(self.times) < 2:
            return
        gaps = np.diff(self.times[max(index - 1, 0) : index + 2])
        period = float(np.max(np.abs(gaps)))
        span = float(np.ptp(scan.t))
        far = float(np.max(np.abs(scan.t)))
        if period > 0 and far >= MAX_TIME_SPAN_PERIODS * period and span < far:
            raise DatasetError(
                f"{self.scan_files[index]}: point times ('t') reach {far:g} s from the epoch's "
                f"reference time, {far / period:.0f} epoch periods of {period:g} s: another "
                "clock or unit (integer Unix seconds read as nanoseconds"
                + (_CUT32 if 0 < span and far < WRAP_NS * 1e-9 else "")
                + "?; --time-field none ignores them)"
            )
        near = max(float(scan.t.min()), -float(scan.t.max()), 0.0)  # the nearest point
        if period > 0 and near > CUT_PERIODS * period:
            raise DatasetError(f"{self.scan_files[index]}: {far_message(scan.t, near, period)}")
        if period > 0 and span >= MAX_TIME_SPAN_PERIODS * period:
            raise DatasetError(
                f"{self.scan_files[index]}: point times ('t') span {span:g} s, "
                f"{span / period:.0f} epoch periods of {period:g} s: the time field is in "
                "another unit (milliseconds?); convert it to seconds (or --time-field none)"
            )

    def __iter__(self) -> Iterator[Scan]:
        for k in range(len(self)):
            yield self[k]

    def __repr__(self) -> str:
        gt = "with" if self.gt_poses is not None else "without"
        return f"Dataset({str(self.path)!r}, {len(self)} epochs, {gt} ground truth)"


def load_dataset(path: str | Path, bin_layout: str = "auto", time_field: str = "auto") -> Dataset:
    """Open a dataset directory; scans are read only when indexed.

    ``path`` is either a dataset (scan files in ``path/scans/``) or a directory of scan
    files itself (e.g. KITTI's ``velodyne/``). Files are sorted by name with digit runs
    compared as numbers (``-1.bin`` before ``2.bin`` before ``10.bin``,
    :mod:`planodom.datasets.scan_order`); hidden files are skipped. ``poses.tum``
    and ``rig.yaml`` are looked for in ``path``.

    Epoch times: from ``poses.tum`` when present, else from ``times.txt``, else from KITTI
    raw's ``timestamps.txt`` (its ``rig.platform`` then "vehicle", a car, unless
    ``rig.yaml`` states one) or the file names when they are the clouds' Unix stamps
    (:mod:`planodom.datasets.scan_names`, noted), else ``k / epoch_rate`` with
    ``epoch_rate`` (Hz) from ``rig.yaml``, else ``k * DEFAULT_EPOCH_PERIOD`` (0.1 s).
    ``bin_layout`` tells how ``.bin`` scans are read
    (:mod:`planodom.datasets.bin_scan`), ``time_field`` which field holds the point times
    (``auto``, ``none`` or a name, :func:`planodom.datasets.scan_io.read_scan`); integer
    time offsets in microseconds are told from nanoseconds by the first scans' spans
    against the epoch period (:mod:`planodom.datasets.scan_time_units`; ``notes`` says so).

    Raises:
        DatasetError: naming the file, when ``path`` is missing, there are no scan files,
            files have unknown or mixed extensions, ``poses.tum`` or ``times.txt`` is
            malformed or has a count different from the scan count, or ``rig.yaml`` is
            malformed.
    """
    root = Path(path)
    if not root.exists():
        raise DatasetError(f"dataset {root} does not exist")
    if not root.is_dir():
        raise DatasetError(f"dataset {root} is not a directory")
    scan_files = _scan_files(root)
    rig = read_rig(root / RIG_FILE) if optional_file(root / RIG_FILE) else Rig()
    gt_poses = None
    name_note = times_note = None
    if optional_file(root / POSES_FILE):
        times, gt_poses = read_tum(root / POSES_FILE)
        if len(times) != len(scan_files):
            raise DatasetError(
                f"{root / POSES_FILE}: {len(times)} poses for {len(scan_files)} scan files "
                f"in {scan_files[0].parent} (it holds the reference pose of each scan; a "
                "reference at its own rate is compared with `planodom eval` after the run)"
            )
        if optional_file(root / TIMES_FILE):  # not read: say so when it disagrees
            times_note = unread_times(root / TIMES_FILE, times, POSES_FILE)
    elif optional_file(root / TIMES_FILE):
        times = read_times(root / TIMES_FILE, len(scan_files))
    else:
        named, name_note = kitti_raw_times(scan_files)
        if named is not None and rig.platform is None:  # KITTI raw: a car
            rig = replace(rig, platform="vehicle")
        if named is None:
            named, name_note = name_times(scan_files)
        if named is None:
            check_numbering(scan_files, POSES_FILE)
        times = epoch_times(len(scan_files), rig) if named is None else named
    ds = Dataset(root, scan_files, times, gt_poses, rig, bin_layout, time_field)
    ds.notes = [unit_note] if (unit_note := epoch_unit_note(times, str(root))) else []
    unit = scan_time_unit(scan_files, times, time_field)
    if unit is not None:
        ds.time_scale = unit.scale
        ds.notes += [f"{root}: {unit.note}"] if unit.note else []
    if name_note:
        ds.notes.append(f"{scan_files[0].parent}: {name_note}")
    ds.notes += [times_note] if times_note else []
    ds.notes += scan_time_notes(scan_files, time_field)
    view = viewpoint_note(scan_files[0]) if scan_files[0].suffix.lower() == ".pcd" else None
    ds.notes += [view] if view else []
    ds.ring_renumber, ring_note = folder_ring_order(ds)
    if ds.ring_renumber is not None:
        ds.rig = renumbered_rig(ds.rig, ds.ring_renumber)
    ds.notes += [ring_note] if ring_note else []
    ds.notes += check_mounts(rig_mounts(rig, str(root / RIG_FILE)), "")
    unread = unread_keys(rig)
    if unread:
        ds.notes.append(
            f"{root / RIG_FILE}: {', '.join(map(repr, unread))} not read (planodom reads "
            f"{', '.join(RIG_KEYS)}; a typo?), kept as written"
        )
    return ds


def write_dataset(
    path: str | Path,
    scans: ScanSequence,
    times: np.ndarray,
    gt_poses: np.ndarray | None = None,
    rig: Rig | None = None,
    overwrite: bool = False,
    *,
    extension: str = ".ply",
    points_dtype: type[np.floating] = np.float64,
    inputs: Sequence[str | Path] = (),
) -> Dataset:
    """Write a dataset directory: ``scans/000000.ply``, ..., ``poses.tum`` or ``times.txt``,
    ``rig.yaml``.

    Args:
        path: dataset directory (created if needed).
        scans: E scans in time order (scans with zero points are fine).
        times: (E,) float64 seconds, strictly increasing: stored in ``poses.tum`` with
            ``gt_poses``, else in ``times.txt``.
        gt_poses: (E, 4, 4) ground truth ``T_world_base``, written to ``poses.tum``.
        rig: written to ``rig.yaml`` (None: no file; numpy values in ``rig.extra`` are
            stored as lists / numbers).
        overwrite: replace an existing dataset at ``path``. Without it a non-empty folder
            there is an :class:`OutputExistsError`; with it, a folder holding anything but
            ``scans/`` (of scan files), ``poses.tum`` and ``rig.yaml`` is an
            :class:`OutputError` (nothing is deleted). The new dataset is written beside it
            and swapped in when complete (:func:`planodom.outputs.atomic_folder`): a failure
            leaves the old one as it was.
        extension: ".ply" or ".pcd".
        points_dtype: np.float64 (exact) or np.float32 for the coordinates.
        inputs: files and folders ``scans`` are read from (a bag): ``path`` may not be,
            lie in or contain them (:class:`OutputError`, before anything is written).

    Returns:
        The written dataset, loaded back.
    """
    root = Path(path)
    times = np.asarray(times, dtype=np.float64).reshape(-1)
    if len(scans) == 0:
        raise DatasetError(f"{root}: no scans to write")
    if len(times) != len(scans):
        raise DatasetError(f"{root}: {len(times)} times for {len(scans)} scans")
    if not np.all(np.isfinite(times)) or np.any(np.diff(times) <= 0):
        raise DatasetError(f"{root}: epoch times must be finite and strictly increasing")
    if gt_poses is not None and np.shape(gt_poses) != (len(scans), 4, 4):
        raise DatasetError(
            f"{root}: gt_poses must have shape ({len(scans)}, 4, 4), got {np.shape(gt_poses)}"
        )
    if extension.lower() not in (".ply", ".pcd"):
        raise DatasetError(f"{root}: cannot write scans as '{extension}' (use .ply or .pcd)")

    with atomic_folder(
        root, overwrite=overwrite, inputs=inputs, owned=is_dataset_entry, what="a dataset"
    ) as tmp:
        scans_dir = tmp / SCANS_DIR
        scans_dir.mkdir()
        width = max(6, len(str(len(scans) - 1)))
        for k, scan in enumerate(scans):  # iteration: a bag streams its epochs in one pass
            write_scan(scans_dir / f"{k:0{width}d}{extension.lower()}", scan, points_dtype)
        if gt_poses is not None:
            write_tum(tmp / POSES_FILE, times, np.asarray(gt_poses, dtype=np.float64))
        else:
            write_times(tmp / TIMES_FILE, times)
        if rig is not None:
            write_rig(tmp / RIG_FILE, rig)
    return load_dataset(root)


def epoch_times(n_epochs: int, rig: Rig | None = None) -> np.ndarray:
    """(E,) seconds ``k / rig.epoch_rate_hz``, or ``k * DEFAULT_EPOCH_PERIOD`` without a rate."""
    k = np.arange(n_epochs, dtype=np.float64)
    rate = None if rig is None else rig.epoch_rate_hz
    return k * DEFAULT_EPOCH_PERIOD if rate is None else k / rate


def read_rig(path: str | Path) -> Rig:
    """The typed :class:`Rig` of a ``rig.yaml`` file (an empty file: ``Rig()``).

    Raises:
        DatasetError: naming the file (and the field) when it is not YAML, not a mapping,
            or a field fails :meth:`Rig.from_dict`'s checks.
    """
    path = Path(path)
    data = read_yaml_file(path, "rig", DatasetError)
    return Rig.from_dict(data, source=str(path))


def write_rig(path: str | Path, rig: Rig) -> None:
    """Write ``rig`` to ``path`` as YAML (numpy arrays as nested lists, floats exact)."""
    text = yaml.safe_dump(_plain(rig.to_dict()), sort_keys=False)
    Path(path).write_text(text, encoding="utf-8")


def _plain(value: Any) -> Any:
    """``value`` with numpy arrays / scalars and tuples turned into YAML-safe Python types."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray | np.generic):
        return value.tolist()
    return value


def is_dataset_entry(path: Path) -> bool:
    """Whether ``path`` (an entry of a dataset folder or of its ``scans/``) is one a
    dataset is made of."""
    if path.parent.name == SCANS_DIR and path.suffix.lower() in SCAN_EXTENSIONS:
        return path.is_file()
    if path.name in (POSES_FILE, RIG_FILE, TIMES_FILE):
        return path.is_file()
    if path.name != SCANS_DIR or not path.is_dir():
        return False
    return all(is_dataset_entry(f) for f in path.iterdir())


def _files(directory: Path, extensions: Sequence[str] | None = None) -> list[Path]:
    """Visible files in ``directory`` (optionally only with ``extensions``); [] if none."""
    if not directory.is_dir():
        return []
    entries = [f for f in directory.iterdir() if not f.name.startswith(".")]
    check_file_entries(entries, SCAN_EXTENSIONS)  # a broken link is no file: not skipped
    files = [f for f in entries if f.is_file()]
    if extensions is not None:
        files = [f for f in files if f.suffix.lower() in extensions]
    return files


#: Files of a results folder of ``planodom run`` / ``smooth`` that no dataset holds.
_RESULT_FILES = ("config.yaml", "covariances.npz", "epochs.csv", "metrics.json", "timing.json")


def _results_files(root: Path) -> list[str]:
    """The :data:`_RESULT_FILES` in ``root`` when two or more are there (a results folder,
    perhaps cut short or of an earlier release: without ``covariances.npz`` it read as a
    folder of "files with unknown extensions"), else []."""
    found = [name for name in _RESULT_FILES if (root / name).is_file()]
    return found if len(found) >= 2 else []


def _scan_files(root: Path) -> list[Path]:
    """The scan files of a dataset, checked for a single known extension and sorted."""
    scans_dir = root / SCANS_DIR
    if broken := broken_link(scans_dir):
        raise DatasetError(f"{scans_dir}: {broken}")
    if scans_dir.exists():
        if not scans_dir.is_dir():
            raise DatasetError(f"{scans_dir} is not a directory")
        files = _files(scans_dir)
        if not files:
            hint = subfolders_hint(scans_dir, SCAN_EXTENSIONS)
            raise DatasetError(f"{scans_dir} is empty: no scan files{hint}")
    else:
        files = [f for f in _files(root) if f.name not in (POSES_FILE, RIG_FILE, TIMES_FILE)]
        scans = [f for f in files if f.suffix.lower() in SCAN_EXTENSIONS]
        if not scans and (root / "velodyne").is_dir():  # a KITTI sequence but for calib.txt
            raise DatasetError(
                f"{root} has velodyne/ but no calib.txt: a KITTI sequence needs both (or give "
                "velodyne/ itself, a folder of scans, without the KITTI camera frame)"
            )
        if not scans and (results := _results_files(root)):
            inner = " (its dataset/ is the one it ran on)" if (root / "dataset").is_dir() else ""
            raise DatasetError(
                f"{root} is a results folder of planodom run or smooth ({', '.join(results[:2])})"
                f", not a recording: give the recording it ran on{inner}; `planodom eval` "
                f"reads its {POSES_FILE}"
            )
        if not files:
            hint = kitti_sequences_hint(root)
            raise DatasetError(f"{root} has no {SCANS_DIR}/ directory and no scan files{hint}")
    unknown = sorted(f.name for f in files if f.suffix.lower() not in SCAN_EXTENSIONS)
    if unknown:
        more = f" and {len(unknown) - 5} more" if len(unknown) > 5 else ""
        shown = ", ".join(unknown[:5]) + more
        raw = (root / "data").is_dir() and "timestamps.txt" in unknown
        raise DatasetError(
            f"{files[0].parent}: files with unknown extensions: {shown} "
            f"(scan files are {', '.join(SCAN_EXTENSIONS)})"
            + (f"; a KITTI raw folder: give its scans, {root / 'data'}" if raw else "")
        )
    suffixes = sorted({f.suffix.lower() for f in files})
    if len(suffixes) > 1:
        raise DatasetError(f"{files[0].parent}: scan files mix extensions {', '.join(suffixes)}")
    return sorted(files, key=scan_order_key)
