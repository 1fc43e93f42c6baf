"""Fuzzing the PointCloud2 decoder over the field layouts drivers produce: field order,
types and names, padding, endianness, organised rows with row padding, no-return points,
and per-point times as float seconds or integer nanoseconds, offsets or absolute. The
decoder must return exactly the points written, their rings, and their times after the
stamp (to the float resolution of the stored field)."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
from fuzz_corruptions import fuzz
from hypothesis import given
from hypothesis import strategies as st

from planodom.datasets.bag_msgs import POINT_CLOUD2, decode_sweep

STAMP = 1_700_000_123 * 10**9 + 456_789_000
_CODES = {"i1": 1, "u1": 2, "i2": 3, "u2": 4, "i4": 5, "u4": 6, "f4": 7, "f8": 8}
#: time encodings: (numpy type, value from an offset in ns, tolerance in s)
_TIMES = {
    "float32 s offsets": ("f4", lambda ns: ns * 1e-9, 1e-8),
    "float64 s absolute": ("f8", lambda ns: (STAMP + ns) * 1e-9, 1e-6),
    "uint32 ns offsets": ("u4", lambda ns: ns, 0.0),
    "float64 ns absolute": ("f8", lambda ns: float(STAMP) + ns, 1e-6),
}


@st.composite
def layouts(draw: st.DrawFn) -> dict:
    coord = draw(st.sampled_from(["f4", "f8"]))
    fields = [("x", coord), ("y", coord), ("z", coord)]
    ring_name = draw(st.sampled_from([None, "ring", "line", "channel"]))
    if ring_name:
        fields.append((ring_name, draw(st.sampled_from(["u1", "u2", "i4"]))))
    time_kind = draw(st.sampled_from([None, *_TIMES]))
    time_name = draw(st.sampled_from(["t", "time", "timestamp", "offset_time", "time_stamp"]))
    if time_kind:
        fields.append((time_name, _TIMES[time_kind][0]))
    fields.append(("intensity", draw(st.sampled_from(["f4", "u1", "u2"]))))
    order = draw(st.permutations(range(len(fields))))
    pads = draw(st.lists(st.integers(0, 5), min_size=len(fields) + 1, max_size=len(fields) + 1))
    return {
        "fields": [fields[i] for i in order],
        "pads": pads,
        "big": draw(st.booleans()),
        "height": draw(st.sampled_from([1, 2, 4])),
        "row_pad": draw(st.integers(0, 7)),
        "ring_name": ring_name,
        "time_kind": time_kind,
        "time_name": time_name,
    }


def _message(layout: dict, rng: np.random.Generator, width: int) -> tuple[NS, dict]:
    end = ">" if layout["big"] else "<"
    names, formats, offsets, pos = [], [], [], layout["pads"][0]
    for (name, code), pad in zip(layout["fields"], layout["pads"][1:], strict=True):
        names.append(name)
        formats.append(end + code)
        offsets.append(pos)
        pos += np.dtype(code).itemsize + pad
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": pos})
    n = width * layout["height"]
    rows = np.zeros(n, dtype=dtype)
    xyz = rng.uniform(-50, 50, (n, 3))
    lost = rng.random(n) < 0.15  # no returns: NaN or all-zero
    xyz[lost] = np.where(rng.random((int(lost.sum()), 1)) < 0.5, np.nan, 0.0)
    for i, c in enumerate("xyz"):
        rows[c] = xyz[:, i]
    truth = {"xyz": np.column_stack([rows[c].astype(np.float64) for c in "xyz"]), "lost": lost}
    if layout["ring_name"]:
        rows[layout["ring_name"]] = rng.integers(0, 32, n)
        truth["ring"] = rows[layout["ring_name"]].astype(np.int64)
    if layout["time_kind"]:
        ns = rng.integers(0, 100_000_000, n)
        rows[layout["time_name"]] = _TIMES[layout["time_kind"]][1](ns)
        truth["dt"] = ns * 1e-9
    raw = rows.tobytes()
    row_bytes = width * pos
    data = b"".join(
        raw[r * row_bytes : (r + 1) * row_bytes] + bytes(layout["row_pad"])
        for r in range(layout["height"])
    )
    fields = [
        NS(name=name, offset=off, datatype=_CODES[code], count=1)
        for (name, code), off in zip(layout["fields"], offsets, strict=True)
    ]
    msg = NS(
        header=NS(stamp=NS(sec=STAMP // 10**9, nanosec=STAMP % 10**9), frame_id="lidar"),
        height=layout["height"], width=width, fields=fields, is_bigendian=layout["big"],
        point_step=pos, row_step=row_bytes + layout["row_pad"],
        data=np.frombuffer(data, dtype=np.uint8),
    )  # fmt: skip
    return msg, truth


@fuzz
@given(layout=layouts(), seed=st.integers(0, 2**16), width=st.integers(1, 40))
def test_every_layout_decodes_to_the_points_written(layout: dict, seed: int, width: int) -> None:
    msg, truth = _message(layout, np.random.default_rng(seed), width)
    points, ring, dt, rings = decode_sweep(msg, POINT_CLOUD2)
    kept = ~truth["lost"]
    assert np.array_equal(points, truth["xyz"][kept])
    if layout["ring_name"]:
        assert np.array_equal(ring, truth["ring"][kept])
        assert rings == (int(truth["ring"][kept].max()) + 1 if kept.any() else 0)
    else:
        assert ring is None and rings == 0
    if layout["time_kind"]:
        tolerance = _TIMES[layout["time_kind"]][2]
        assert np.allclose(dt, truth["dt"][kept], rtol=0, atol=tolerance)
    else:
        assert np.array_equal(dt, np.zeros(int(kept.sum())))
