"""PCD files (PCL's point cloud format): a checked reader and a writer.

The header and the ``ascii`` and ``binary`` bodies are read here with numpy, not by
open3d (``o3d.t.io``, checked on 0.19 / 0.20), which guesses where it should refuse:

- an ASCII line with fewer values than the header's fields fills the rest of the point
  from uninitialised memory (a different cloud on every read), and a line ``foo bar baz``
  becomes (0, 0, 0);
- a header ``POINTS 100`` over a body of 10 000 points reads 100 points, and a short body
  is returned at full size, padded with garbage, with a log warning only;
- it reads and writes no zero-point PCD (an epoch that saw nothing is valid here).

So every count is checked here: ``WIDTH * HEIGHT`` against ``POINTS`` (``WIDTH 0``
and ``HEIGHT 0``, left unset by some writers, read as an unorganised cloud), the number of
ASCII lines and values per line, the binary body's size to the byte. Only
``binary_compressed`` (LZF) bodies are decoded by open3d, after the sizes stated in the
file are checked against the header, and its point count is checked again.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planodom.datasets.ply import parse_ascii_column
from planodom.errors import DatasetError

_TYPES = {("F", 4): "f4", ("F", 8): "f8", ("I", 1): "i1", ("I", 2): "i2", ("I", 4): "i4"}
_TYPES |= {("U", 1): "u1", ("U", 2): "u2", ("U", 4): "u4", ("I", 8): "i8", ("U", 8): "u8"}
_MODES = ("ascii", "binary", "binary_compressed")
_MAX_HEADER_LINES = 64
_PAGE_SIZES = (4096, 8192, 16384, 32768, 65536)


@dataclass(frozen=True)
class _Header:
    names: list[str]
    codes: list[str]  # numpy type codes
    counts: list[int]  # values per field
    n_points: int
    mode: str
    lines: int  # header lines, for the line numbers of ASCII points

    @property
    def dtype(self) -> np.dtype:
        """One point of a binary body (repeated names, such as PCL's ``_`` padding, renamed)."""
        fields = [
            (name if self.names.index(name) == i else f"{name}#{i}", "<" + code, (count,))
            for i, (name, code, count) in enumerate(
                zip(self.names, self.codes, self.counts, strict=True)
            )
        ]
        return np.dtype(fields)


def _header(path: Path, data: bytes) -> tuple[_Header, int]:
    """The checked header and the byte offset of the body."""
    entries: dict[str, list[str]] = {}
    pos, number = 0, 0
    while "DATA" not in entries:
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end  # a last line without a newline
        number += 1
        if pos >= len(data) or number > _MAX_HEADER_LINES:
            raise DatasetError(f"{path}: not a PCD file (no 'DATA' header line)")
        try:
            line = data[pos:end].decode("ascii").strip()
        except UnicodeDecodeError:
            raise DatasetError(f"{path}:{number}: not a PCD file (binary header line)") from None
        pos = end + 1
        if line and not line.startswith("#"):
            key, *values = line.split()
            entries[key.upper()] = values
    for key in ("FIELDS", "SIZE", "TYPE", "POINTS"):
        if key not in entries:
            raise DatasetError(f"{path}: PCD header has no {key} line")
    names = entries["FIELDS"]
    twice = sorted({n for n in names if n != "_" and names.count(n) > 1})  # "_": PCL's padding
    if twice:  # ASCII bodies read the last, binary ones the first (as PCL): refused
        raise DatasetError(
            f"{path}: PCD field '{twice[0]}' given twice in FIELDS: which one holds its values "
            "is unknown"
        )
    unread = [
        f"'{n}' (TYPE {t} SIZE {z})"
        for n, t, z in zip(names, entries.get("TYPE", []), entries.get("SIZE", []), strict=False)
        if z.isdigit() and (t, int(z)) not in _TYPES
    ]
    if unread:
        raise DatasetError(
            f"{path}: PCD field {unread[0]} is of a type planodom does not read (F 4 or 8, "
            "I or U 1, 2, 4 or 8)"
        )
    try:
        n = int(entries["POINTS"][0])
        sizes = [int(s) for s in entries["SIZE"]]
        counts = [int(c) for c in entries.get("COUNT", ["1"] * len(names))]
        codes = [_TYPES[(t, s)] for t, s in zip(entries["TYPE"], sizes, strict=True)]
        width, height = (int(entries.get(k, [v])[0]) for k, v in (("WIDTH", n), ("HEIGHT", 1)))
    except (ValueError, IndexError, KeyError):
        raise DatasetError(
            f"{path}: bad PCD header (POINTS / WIDTH / HEIGHT / SIZE / TYPE / COUNT)"
        ) from None
    if not len(names) == len(codes) == len(counts) or min(counts, default=0) < 1 or n < 0:
        raise DatasetError(f"{path}: PCD header FIELDS / SIZE / TYPE / COUNT do not match")
    if width == height == 0:  # a writer that left them unset (nebula's scans): unorganised
        width, height = n, 1
    if width * height != n:
        raise DatasetError(f"{path}: PCD header WIDTH {width} x HEIGHT {height} is not POINTS {n}")
    mode = entries["DATA"][0] if entries["DATA"] else ""
    if mode not in _MODES:
        raise DatasetError(f"{path}: unknown PCD DATA mode '{mode}'")
    return _Header(names, codes, counts, n, mode, number), pos


def read_pcd(path: Path) -> dict[str, np.ndarray]:
    """The fields of a PCD file by name, (N,) arrays (the first value of multi-count fields).

    Raises:
        DatasetError: naming ``path`` (and ``path:line`` for a bad ASCII line) when the
            header is malformed, or the body holds fewer or more points or values than the
            header states, or a value is not a number of its field's type.
    """
    data = Path(path).read_bytes()
    header, offset = _header(path, data)
    if header.mode == "ascii":
        columns = _ascii(path, data[offset:], header)
    elif header.mode == "binary":
        columns = _binary(path, data[offset:], header, offset)
    else:
        columns = _compressed(path, data[offset:], header)
    return {name: columns[name] for name in header.names if name in columns}


def _ascii(path: Path, body: bytes, header: _Header) -> dict[str, np.ndarray]:
    try:
        lines = body.decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: ASCII PCD body is not text") from None
    numbers = [header.lines + i + 1 for i, ln in enumerate(lines) if ln.strip()]
    rows = [ln.split() for ln in lines if ln.strip()]
    if len(rows) != header.n_points:
        where = f"{path}:{numbers[header.n_points]}" if len(rows) > header.n_points else path
        raise DatasetError(
            f"{where}: ASCII PCD has {len(rows)} point lines, its header POINTS {header.n_points}"
        )
    width = sum(header.counts)
    for i, row in enumerate(rows):
        if len(row) != width:
            raise DatasetError(
                f"{path}:{numbers[i]}: {len(row)} values, the header's fields need {width}"
            )
    starts = np.cumsum([0, *header.counts[:-1]])
    table = np.array(rows, dtype=str).reshape(len(rows), width)
    out = {}
    for name, code, j in zip(header.names, header.codes, starts, strict=True):
        out[name] = parse_ascii_column(path, table[:, j], code, numbers)
    return out


def _binary(path: Path, body: bytes, header: _Header, offset: int) -> dict[str, np.ndarray]:
    dtype = header.dtype
    need = header.n_points * dtype.itemsize
    if len(body) > need and _pcl_page_padding(offset, body[need:]):
        body = body[:need]
    if len(body) != need:
        problem = "truncated" if len(body) < need else "longer than its header states"
        raise DatasetError(
            f"{path}: binary PCD {problem}: POINTS {header.n_points} of {dtype.itemsize} bytes "
            f"need {need} bytes, the body has {len(body)}"
        )
    table = np.frombuffer(body, dtype=dtype, count=header.n_points)
    return {name: table[name][:, 0].astype(table[name].dtype) for name in set(header.names)}


def _pcl_page_padding(header_bytes: int, tail: bytes) -> bool:
    """Whether ``tail`` (after the points) is the zero padding of PCL's binary writer.

    PCL up to 1.8 sizes a binary PCD by seeking to ``page size + data size - 1`` before
    mapping it (``PCDWriter::writeBinary``), so the file is exactly one page longer than
    its points, the header included: the points are followed by ``page size - header size``
    zero bytes (seen in VLP-16 scans saved by PCL 1.7). Only that tail, all zeros, for a
    power-of-two page size of 4 to 64 KiB, is accepted; any other extra bytes stay an error.
    """
    page = header_bytes + len(tail)
    return page in _PAGE_SIZES and not any(tail)


def _compressed(path: Path, body: bytes, header: _Header) -> dict[str, np.ndarray]:
    """A ``binary_compressed`` body: sizes checked here, LZF decoded by open3d."""
    need = header.n_points * header.dtype.itemsize
    if len(body) < 8:
        raise DatasetError(f"{path}: truncated binary_compressed PCD (no size words)")
    packed, unpacked = (int(v) for v in np.frombuffer(body[:8], dtype="<u4"))
    if unpacked != need or len(body) < 8 + packed:
        raise DatasetError(
            f"{path}: binary_compressed PCD states {packed} -> {unpacked} bytes for "
            f"POINTS {header.n_points} ({need} bytes), with {len(body) - 8} present"
        )
    if header.n_points == 0:
        pairs = zip(header.names, header.codes, strict=True)
        return {name: np.zeros(0, code) for name, code in pairs}
    from planodom._open3d import o3d  # slow to import: only compressed PCD needs it

    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        cloud = o3d.t.io.read_point_cloud(str(path), remove_nan_points=False)
    if "positions" not in cloud.point or len(cloud.point["positions"]) != header.n_points:
        raise DatasetError(f"{path}: open3d could not decode this binary_compressed PCD")
    pos = cloud.point["positions"].numpy()
    out = {"x": pos[:, 0], "y": pos[:, 1], "z": pos[:, 2]}
    for name in header.names:
        if name not in out and name in cloud.point:
            out[name] = cloud.point[name].numpy().reshape(-1)
    return out


def viewpoint_note(path: Path) -> str | None:
    """A note when the PCD file's ``VIEWPOINT`` (``tx ty tz qw qx qy qz``: PCL's
    ``sensor_origin_`` and ``sensor_orientation_``, the sensor's pose in the points' frame)
    is not the identity: the points are then in another frame than the sensor's (a cloud
    registered into a map frame?), and planodom reads them as they are. None for the
    identity, no such line or one that is not seven numbers (not read, as before)."""
    with open(path, "rb") as f:
        head = f.read(16384)
    for line in head.split(b"\n")[:_MAX_HEADER_LINES]:
        words = line.decode("ascii", "replace").split()
        key = words[0].upper() if words else ""
        if key == "DATA":
            break
        if key == "VIEWPOINT":
            try:
                v = np.array([float(w) for w in words[1:]])
            except ValueError:
                return None
            if len(v) != 7 or (not np.any(v[:3]) and abs(v[3]) == 1.0 and not np.any(v[4:])):
                return None
            return (
                f"{path}: PCD VIEWPOINT {' '.join(words[1:])} is not the identity: its points "
                "are in another frame than the sensor's (a cloud registered into a map?); "
                "they are read as they are, as the base frame's"
            )
    return None


def write_pcd(path: Path, fields: dict[str, np.ndarray]) -> None:
    """Write ``{name: (N,) array}`` as a binary PCD (each array keeps its dtype); N may be 0."""
    arrays = {name: np.asarray(a).reshape(-1) for name, a in fields.items()}
    n = len(arrays["x"])
    names = list(arrays)
    for name, a in arrays.items():
        if (a.dtype.kind.upper(), a.dtype.itemsize) not in _TYPES or len(a) != n:
            raise DatasetError(f"{path}: PCD cannot store field '{name}' ({a.dtype}, {len(a)})")
    table = np.empty(n, dtype=[(k, "<" + arrays[k].dtype.str[1:]) for k in names])
    for name in names:
        table[name] = arrays[name]
    text = (
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n"
        f"FIELDS {' '.join(names)}\n"
        f"SIZE {' '.join(str(arrays[k].dtype.itemsize) for k in names)}\n"
        f"TYPE {' '.join(arrays[k].dtype.kind.upper() for k in names)}\n"
        f"COUNT {' '.join('1' for _ in names)}\n"
        f"WIDTH {n}\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {n}\nDATA binary\n"
    )
    Path(path).write_bytes(text.encode("ascii") + table.tobytes())
