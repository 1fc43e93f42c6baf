"""A minimal PLY reader and writer for the vertex element of point-cloud files.

Why not open3d for PLY (checked on open3d 0.20, ``o3d.t.io``): it keeps ``int`` and
``double`` custom properties exactly, but

- it refuses to write a cloud with zero points (an epoch that saw nothing is valid here);
- a truncated binary file is returned as a full-size cloud partly filled with garbage, with
  only a log warning and no error to catch;
- it silently drops ``ushort`` / ``uint`` properties, the type many lidar drivers give
  ``ring``.

Reading the vertex element with numpy is a few lines, exact for every PLY scalar type, and
tells a truncated file from a complete one. Files written here are plain binary PLY that
open3d, CloudCompare and PCL read.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from planodom.errors import DatasetError

#: PLY scalar type names (both spellings) to numpy type codes.
_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}
#: numpy type codes to the PLY names written.
_PLY_NAMES = {
    "i1": "char",
    "u1": "uchar",
    "i2": "short",
    "u2": "ushort",
    "i4": "int",
    "u4": "uint",
    "f4": "float",
    "f8": "double",
}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
_MAX_HEADER = 1 << 16


@dataclass
class _Element:
    name: str
    count: int
    props: list[tuple[str, str]]  # (name, numpy code); list properties have code "list"

    @property
    def fixed_size(self) -> bool:
        return all(code != "list" for _, code in self.props)


def _parse_header(path: Path, data: bytes) -> tuple[str, list[_Element], int]:
    """Format, elements and the byte offset of the body."""
    if not (data.startswith(b"ply\n") or data.startswith(b"ply\r\n")):
        raise DatasetError(f"{path}: not a PLY file (no 'ply' magic line)")
    end = data.find(b"end_header", 0, _MAX_HEADER)
    newline = data.find(b"\n", end)
    if end < 0 or newline < 0:
        raise DatasetError(f"{path}: PLY header has no 'end_header' line")
    try:
        lines = data[:end].decode("ascii").splitlines()[1:]
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: PLY header is not ASCII text") from exc
    fmt = None
    elements: list[_Element] = []
    for line in lines:
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info"):
            continue
        try:
            if tok[0] == "format" and tok[1] in _FORMATS and len(tok) == 3:
                fmt = tok[1]
            elif tok[0] == "element" and len(tok) == 3:
                count = int(tok[2])
                if count < 0:
                    raise ValueError
                elements.append(_Element(tok[1], count, []))
            elif tok[0] == "property" and tok[1] == "list" and len(tok) == 5 and elements:
                elements[-1].props.append((tok[4], "list"))
            elif tok[0] == "property" and tok[1] in _PLY_TYPES and len(tok) == 3 and elements:
                elements[-1].props.append((tok[2], _PLY_TYPES[tok[1]]))
            else:
                raise ValueError
        except (ValueError, IndexError):
            raise DatasetError(f"{path}: bad PLY header line {line!r}") from None
    if fmt is None:
        raise DatasetError(f"{path}: PLY header has no valid 'format' line")
    return fmt, elements, newline + 1


def read_ply_vertices(path: Path) -> dict[str, np.ndarray]:
    """The vertex properties of a PLY file (ascii or binary), by name.

    Returns:
        ``{name: (N,) array}`` in the file's dtypes (native byte order), N may be 0.

    Raises:
        DatasetError: naming ``path``, when the file is not PLY, has no vertex element,
            has list properties in or before it (binary), or is truncated.
    """
    data = Path(path).read_bytes()
    fmt, elements, offset = _parse_header(path, data)
    names = [e.name for e in elements]
    if "vertex" not in names:
        raise DatasetError(f"{path}: PLY file has no 'vertex' element")
    index = names.index("vertex")
    vertex = elements[index]
    if not vertex.fixed_size:
        raise DatasetError(f"{path}: PLY vertex element has list properties (not a point cloud)")
    if fmt == "ascii":
        return _read_ascii(path, data, offset, elements, index)
    before = elements[:index]
    if not all(e.fixed_size for e in before):
        raise DatasetError(f"{path}: PLY elements with list properties precede 'vertex'")
    endian = _FORMATS[fmt]
    assert endian is not None  # ascii was read above
    try:
        dtype = np.dtype([(n, endian + c) for n, c in vertex.props])
    except (ValueError, TypeError) as exc:
        raise DatasetError(f"{path}: bad PLY vertex properties: {exc}") from None
    for e in before:
        offset += e.count * sum(np.dtype(c).itemsize for _, c in e.props)
    need = vertex.count * dtype.itemsize
    if len(data) - offset < need:
        raise DatasetError(
            f"{path}: truncated PLY file: {vertex.count} vertices need {need} bytes, "
            f"{max(len(data) - offset, 0)} present"
        )
    if all(e.fixed_size for e in elements):  # the body's size is known: check it exactly
        end = (
            offset
            + need
            + sum(
                e.count * sum(np.dtype(c).itemsize for _, c in e.props)
                for e in elements[index + 1 :]
            )
        )
        if len(data) > end:
            raise DatasetError(
                f"{path}: PLY file has {len(data) - end} bytes beyond its header's "
                f"{vertex.count} vertices (a wrong count, or not this format)"
            )
    table = np.frombuffer(data, dtype=dtype, count=vertex.count, offset=offset)
    return {n: table[n].astype(c) for n, c in vertex.props}


def _read_ascii(
    path: Path, data: bytes, offset: int, elements: list[_Element], index: int
) -> dict[str, np.ndarray]:
    """The vertex element of an ASCII body: one line per element item, checked line by line."""
    try:
        lines = data[offset:].decode("ascii").splitlines()
    except UnicodeDecodeError:
        raise DatasetError(f"{path}: ASCII PLY body is not text") from None
    first = data[:offset].count(b"\n") + 1  # line number of the body's first line
    numbers = [first + i for i, ln in enumerate(lines) if ln.strip()]
    rows = [ln.split() for ln in lines if ln.strip()]
    vertex = elements[index]
    start = sum(e.count for e in elements[:index])
    total = sum(e.count for e in elements)
    if len(rows) < total or (len(rows) > total and all(e.fixed_size for e in elements)):
        where = f"{path}:{numbers[total]}" if len(rows) > total else str(path)
        raise DatasetError(
            f"{where}: ASCII PLY has {len(rows)} data lines, its header's elements {total}"
        )
    n_props = len(vertex.props)
    for i in range(start, start + vertex.count):
        if len(rows[i]) != n_props:
            raise DatasetError(
                f"{path}:{numbers[i]}: {len(rows[i])} values, a vertex has {n_props}"
            )
    table = np.array(rows[start : start + vertex.count], dtype=str).reshape(-1, n_props)
    numbers = numbers[start : start + vertex.count]
    return {
        name: parse_ascii_column(path, table[:, j], code, numbers)
        for j, (name, code) in enumerate(vertex.props)
    }


def parse_ascii_column(path: Path, column: np.ndarray, code: str, numbers: list[int]) -> np.ndarray:
    """ASCII values (strings, one per line ``numbers[i]``) as numbers of numpy type
    ``code``; DatasetError ``path:line`` at the first that is not a number of that type."""
    wide = np.float64 if code[0] == "f" else np.int64
    try:
        values = column.astype(wide)
        fits = code[0] == "f" or len(values) == 0 or _fits(values.min(), values.max(), code)
    except (ValueError, OverflowError):
        fits = False
    if not fits:
        for i, text in enumerate(column):  # the first bad line, for the message
            try:
                value = wide(text)
                ok = code[0] == "f" or _fits(value, value, code)
            except (ValueError, OverflowError):
                ok = False
            if not ok:
                raise DatasetError(f"{path}:{numbers[i]}: '{text}' is not a {np.dtype(code)}")
    with np.errstate(over="ignore"):
        return values.astype(code)


def _fits(low: object, high: object, code: str) -> bool:
    info = np.iinfo(code)
    return bool(info.min <= low and high <= info.max)  # type: ignore[operator]


def write_ply_vertices(path: Path, fields: dict[str, np.ndarray]) -> None:
    """Write ``{name: (N,) array}`` as the vertex element of a binary little-endian PLY.

    Each array keeps its dtype (one of int8..uint32, float32, float64); N may be 0.
    """
    arrays = {name: np.asarray(a).reshape(-1) for name, a in fields.items()}
    counts = {len(a) for a in arrays.values()}
    if len(counts) != 1:
        raise DatasetError(f"{path}: PLY fields have different lengths {sorted(counts)}")
    n = counts.pop()
    dtype = np.dtype([(name, "<" + a.dtype.str[1:]) for name, a in arrays.items()])
    table = np.empty(n, dtype=dtype)
    header = ["ply", "format binary_little_endian 1.0", "comment planodom", f"element vertex {n}"]
    for name, a in arrays.items():
        code = a.dtype.str[1:]
        if code not in _PLY_NAMES:
            raise DatasetError(f"{path}: PLY cannot store field '{name}' of dtype {a.dtype}")
        header.append(f"property {_PLY_NAMES[code]} {name}")
        table[name] = a
    header.append("end_header\n")
    Path(path).write_bytes("\n".join(header).encode("ascii") + table.tobytes())
