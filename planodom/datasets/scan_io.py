"""One scan file to and from a :class:`~planodom.scan.Scan`: ``.ply``, ``.pcd``, KITTI ``.bin``.

Stored per point: ``x y z`` (float32 or float64, metres), optional ``ring`` (int32),
``t`` (float64, seconds from the epoch's reference time) and ``label`` (int32). Other
properties (intensity, colour, ...) are ignored on reading. KITTI ``.bin`` files hold
float32 ``x y z intensity`` rows and carry no optional field; points are taken as they are
(in the scanner frame, which for KITTI is the base frame used here).

- PLY goes through :mod:`planodom.datasets.ply` (see there why not open3d).
- PCD goes through ``open3d.t.io``, which keeps int32 / float64 custom fields and uint16
  ``ring`` exactly. A PCD header is still parsed here first: open3d neither reads nor
  writes a zero-point PCD, and returns uninitialised points without any error for a
  truncated ASCII PCD.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from planodom.datasets.ply import read_ply_vertices, write_ply_vertices
from planodom.errors import DatasetError
from planodom.scan import Scan

#: File extensions of scan files that can be read.
SCAN_EXTENSIONS = (".ply", ".pcd", ".bin")
#: File extensions of scan files that can be written.
WRITABLE_EXTENSIONS = (".ply", ".pcd")
#: Optional per-point fields and their dtypes in a :class:`Scan`.
OPTIONAL_FIELDS = {"ring": np.int32, "t": np.float64, "label": np.int32}


def read_scan(file: str | Path) -> Scan:
    """Read one scan file (``.ply``, ``.pcd`` or KITTI ``.bin``).

    Returns:
        A :class:`Scan`: points (N, 3) float64 (float32 files widened exactly), with
        ``ring`` / ``t`` / ``label`` when the file has them. N may be 0.

    Raises:
        DatasetError: naming the file, when it is missing, has an unknown extension,
            does not parse, is truncated or has NaN / infinite coordinates or times.
    """
    path = Path(file)
    suffix = _suffix(path, SCAN_EXTENSIONS, "unknown scan file extension")
    if not path.is_file():
        raise DatasetError(f"{path}: scan file does not exist")
    if suffix == ".ply":
        fields = read_ply_vertices(path)
    elif suffix == ".pcd":
        fields = _read_pcd(path)
    else:
        fields = _read_kitti_bin(path)
    return _scan_from_fields(path, fields)


def write_scan(file: str | Path, scan: Scan, points_dtype: type[np.floating] = np.float64) -> None:
    """Write ``scan`` to a ``.ply`` or ``.pcd`` file, losslessly.

    Args:
        file: destination; its extension picks the format.
        scan: the scan; its optional fields are written when not None.
        points_dtype: np.float64 (exact) or np.float32 (half the size; reading widens it back
            exactly, so a float32 file round-trips bit for bit).
    """
    path = Path(file)
    suffix = _suffix(path, WRITABLE_EXTENSIONS, "cannot write scans as")
    if np.dtype(points_dtype) not in (np.dtype(np.float32), np.dtype(np.float64)):
        raise DatasetError(f"{path}: points_dtype must be float32 or float64, not {points_dtype}")
    with np.errstate(over="ignore"):
        pts = scan.points.astype(points_dtype)
    if not np.all(np.isfinite(pts)):
        raise DatasetError(
            f"{path}: cannot write non-finite coordinates "
            f"(or beyond {np.dtype(points_dtype)} range)"
        )
    fields = {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2]}
    for name in OPTIONAL_FIELDS:
        value = getattr(scan, name)
        if value is not None:
            fields[name] = value
    if suffix == ".ply":
        write_ply_vertices(path, fields)
    else:
        _write_pcd(path, fields)


def _suffix(path: Path, allowed: tuple[str, ...], problem: str) -> str:
    """The lower-case extension of ``path``, or DatasetError ``path: problem '.ext'``."""
    suffix = path.suffix.lower()
    if suffix not in allowed:
        raise DatasetError(
            f"{path}: {problem} '{path.suffix}' (expected one of {', '.join(allowed)})"
        )
    return suffix


def _scan_from_fields(path: Path, fields: dict[str, np.ndarray]) -> Scan:
    missing = [c for c in "xyz" if c not in fields]
    if missing:
        raise DatasetError(f"{path}: no '{' '.join(missing)}' coordinates in the file")
    points = np.column_stack([fields[c].astype(np.float64) for c in "xyz"]).reshape(-1, 3)
    bad = int(np.count_nonzero(~np.isfinite(points).all(axis=1)))
    if bad:
        raise DatasetError(
            f"{path}: {bad} of {len(points)} points have NaN or infinite coordinates"
        )
    extra = {n: fields[n].astype(dt) for n, dt in OPTIONAL_FIELDS.items() if n in fields}
    if "t" in extra and not np.all(np.isfinite(extra["t"])):
        bad = int(np.count_nonzero(~np.isfinite(extra["t"])))
        raise DatasetError(f"{path}: {bad} of {len(points)} point times 't' are NaN or infinite")
    return Scan(points, **extra)


def _read_kitti_bin(path: Path) -> dict[str, np.ndarray]:
    raw = path.read_bytes()
    if len(raw) % 16:
        raise DatasetError(
            f"{path}: KITTI .bin size {len(raw)} bytes is not a multiple of 16 "
            "(float32 x y z intensity rows); truncated or not a KITTI scan"
        )
    rows = np.frombuffer(raw, dtype="<f4").reshape(-1, 4)
    return {"x": rows[:, 0], "y": rows[:, 1], "z": rows[:, 2]}


# --------------------------------------------------------------------------- PCD

_PCD_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4"}
_PCD_TYPES |= {("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("I", 8): "i8", ("U", 8): "u8"}


def _pcd_header(path: Path, data: bytes) -> tuple[dict[str, list[str]], int]:
    """Header entries (key -> values) and the byte offset of the data."""
    header: dict[str, list[str]] = {}
    pos = 0
    while "DATA" not in header:
        end = data.find(b"\n", pos)
        if end < 0 or pos > 4096:
            raise DatasetError(f"{path}: not a PCD file (no 'DATA' header line)")
        try:
            line = data[pos:end].decode("ascii").strip()
        except UnicodeDecodeError:
            raise DatasetError(f"{path}: not a PCD file (binary bytes in the header)") from None
        pos = end + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            header[key.upper()] = values
    for key in ("FIELDS", "SIZE", "TYPE", "POINTS"):
        if key not in header:
            raise DatasetError(f"{path}: PCD header has no {key} line")
    return header, pos


def _read_pcd(path: Path) -> dict[str, np.ndarray]:
    data = path.read_bytes()
    header, offset = _pcd_header(path, data)
    names, mode = header["FIELDS"], header["DATA"][0] if header["DATA"] else ""
    try:
        n = int(header["POINTS"][0])
        sizes = [int(s) for s in header["SIZE"]]
        counts = [int(c) for c in header.get("COUNT", ["1"] * len(names))]
        codes = [_PCD_TYPES[(t, s)] for t, s in zip(header["TYPE"], sizes, strict=True)]
    except (ValueError, IndexError, KeyError):
        raise DatasetError(f"{path}: bad PCD header (POINTS / SIZE / TYPE / COUNT)") from None
    if not len(names) == len(sizes) == len(codes) == len(counts):
        raise DatasetError(f"{path}: PCD header FIELDS / SIZE / TYPE / COUNT lengths differ")
    if not {"x", "y", "z"} <= set(names):
        raise DatasetError(f"{path}: PCD file has no 'x y z' fields (has {' '.join(names)})")
    if mode not in ("ascii", "binary", "binary_compressed"):
        raise DatasetError(f"{path}: unknown PCD DATA mode '{mode}'")
    if n == 0:  # open3d cannot read a zero-point PCD
        return {name: np.zeros(0, code) for name, code in zip(names, codes, strict=True)}
    if mode == "ascii":
        lines = [ln for ln in data[offset:].splitlines() if ln.strip()]
        if len(lines) != n:
            raise DatasetError(f"{path}: ASCII PCD has {len(lines)} point lines, header says {n}")
    elif mode == "binary" and len(data) - offset < n * sum(np.multiply(sizes, counts)):
        raise DatasetError(f"{path}: truncated binary PCD ({n} points in the header)")

    from planodom._open3d import o3d  # imported here: open3d is slow to load, only PCD needs it

    # Failures are reported below as a DatasetError; keep open3d's own log quiet.
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        cloud = o3d.t.io.read_point_cloud(str(path), remove_nan_points=False)
    if "positions" not in cloud.point or len(cloud.point["positions"]) != n:
        raise DatasetError(f"{path}: open3d could not parse this PCD file ({n} points expected)")
    pos = cloud.point["positions"].numpy()
    out = {"x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}
    for name in OPTIONAL_FIELDS:
        if name in cloud.point:
            out[name] = cloud.point[name].numpy().reshape(-1)
    return out


def _write_pcd(path: Path, fields: dict[str, np.ndarray]) -> None:
    n = len(fields["x"])
    if n == 0:
        # open3d refuses to write an empty cloud: write the header of a zero-point PCD.
        names = list(fields)
        sizes = [fields[k].dtype.itemsize for k in names]
        types = [fields[k].dtype.kind.upper() for k in names]
        text = (
            "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
            f"FIELDS {' '.join(names)}\nSIZE {' '.join(map(str, sizes))}\n"
            f"TYPE {' '.join(types)}\nCOUNT {' '.join('1' for _ in names)}\n"
            "WIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\nDATA binary\n"
        )
        path.write_text(text, encoding="ascii")
        return

    from planodom._open3d import o3d

    cloud = o3d.t.geometry.PointCloud()
    xyz = np.column_stack([fields["x"], fields["y"], fields["z"]])
    cloud.point["positions"] = o3d.core.Tensor(np.ascontiguousarray(xyz))
    for name in OPTIONAL_FIELDS:
        if name in fields:
            cloud.point[name] = o3d.core.Tensor(np.ascontiguousarray(fields[name][:, None]))
    if not o3d.t.io.write_point_cloud(str(path), cloud, write_ascii=False, compressed=False):
        raise DatasetError(f"{path}: open3d failed to write the PCD file")
