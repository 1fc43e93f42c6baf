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
        return _read_ascii(path, data[offset:], elements[:index], vertex)
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
    table = np.frombuffer(data, dtype=dtype, count=vertex.count, offset=offset)
    return {n: table[n].astype(c) for n, c in vertex.props}


def _read_ascii(
    path: Path, body: bytes, before: list[_Element], vertex: _Element
) -> dict[str, np.ndarray]:
    try:
        lines = body.decode("ascii").splitlines()
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: ASCII PLY body is not text") from exc
    start = sum(e.count for e in before)
    rows = lines[start : start + vertex.count]
    n_props = len(vertex.props)
    tokens = " ".join(rows).split()
    if len(rows) < vertex.count or len(tokens) != vertex.count * n_props:
        raise DatasetError(
            f"{path}: truncated or malformed ASCII PLY: expected {vertex.count} vertex "
            f"lines of {n_props} values"
        )
    table = np.array(tokens, dtype=str).reshape(vertex.count, n_props)
    out = {}
    try:
        for j, (name, code) in enumerate(vertex.props):
            wide = np.float64 if code[0] == "f" else np.int64
            out[name] = table[:, j].astype(wide).astype(code)
    except ValueError as exc:
        raise DatasetError(f"{path}: bad number in ASCII PLY: {exc}") from None
    return out


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
