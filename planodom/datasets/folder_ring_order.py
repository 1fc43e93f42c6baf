"""A dataset folder's ring ids out of its lidar's beam elevations: renumbered, noted.

As a bag's lidar topic (:mod:`planodom.datasets.bag_ring_order`, whose
:class:`RingElevations` and :func:`ring_renumbering` this reuses): a folder's ``ring``
field holding laser ids in firing order (a VLP-16's ids 0, 1, 2, ... at -15, +1, -13, ...
deg) put the range image's rows 16 degrees apart (a simulated 16-beam lidar's 30 epochs:
ATE 0.003 m -> 9.3 m, no word). A folder's points are in the base frame: the elevations
are measured in the lidar's frame, ``rig.yaml``'s one ``T_base_sensor`` (several sensors
with different extrinsics: left alone, their rings need not be one lidar's), over the
first :data:`SAMPLE_SCANS` scans (a scan that cannot be read is left to the run, which
names it; rings of a few points, :data:`MIN_RING_POINTS`, are not looked at). Renumbered
ids hold for the whole run (one lidar, one numbering), noted once. Without extrinsics the
points' own frame is tried and an order found is only noted: the lidar's frame is not
known, so neither is whether it is one lidar.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from planodom.datasets.bag_ring_order import RingElevations, ring_order_note, ring_renumbering
from planodom.datasets.scan_io import read_scan
from planodom.errors import DatasetError
from planodom.rig import Rig

if TYPE_CHECKING:
    from planodom.datasets.dataset import Dataset

#: Scans read for the rings' elevations: a lidar's ring is a cone in every scan, a few give
#: each ring thousands of points (the first few, as the time unit's sample).
SAMPLE_SCANS = 3
#: Fewer points than this in the median ring of the sample: no spinning lidar's scans (whose
#: rings hold hundreds of points a sweep), where a ring of a point or two would pass for a
#: cone of no spread (a test's few random points); a judgement, not fitted.
MIN_RING_POINTS = 10
_NO_FRAME = "rig.yaml gives no lidar extrinsics (T_base_sensor) to measure them in"


def folder_ring_order(ds: Dataset) -> tuple[tuple[np.ndarray, np.ndarray] | None, str | None]:
    """``(renumbering, note)`` of a dataset's scans: ``(ids (k,), new ids (k,))`` when its
    ring ids are to be given to its rings in elevation order (else None), and the note on
    ids out of elevation order (else None). Reads up to :data:`SAMPLE_SCANS` scans."""
    extrinsics = ds.rig.extrinsics
    if extrinsics and any(not np.allclose(T, extrinsics[0]) for T in extrinsics[1:]):
        return None, None  # several sensors: their rings are not one lidar's beams
    T_sensor_base = np.linalg.inv(extrinsics[0]) if extrinsics else np.eye(4)
    rings = RingElevations()
    for k, file in enumerate(ds.scan_files[:SAMPLE_SCANS]):
        try:
            scan = read_scan(file, ds.bin_layout, float(ds.times[k]), ds.time_field, ds.time_scale)
        except DatasetError:  # raised again, naming the file, when the run reads it
            return None, None
        if scan.ring is None:
            return None, None
        rings.add(scan.points @ T_sensor_base[:3, :3].T + T_sensor_base[:3, 3], scan.ring)
    if not rings.sums or np.median([c for c, _, _ in rings.sums.values()]) < MIN_RING_POINTS:
        return None, None
    folder = str(ds.scan_files[0].parent) if ds.scan_files else str(ds.path)
    note = ring_order_note(folder, rings, None, "scans in", "" if extrinsics else _NO_FRAME)
    renumber = ring_renumbering(rings) if extrinsics else None
    return renumber, note or None


def renumbered_rig(rig: Rig, renumber: tuple[np.ndarray, np.ndarray]) -> Rig:
    """``rig`` with its per-ring ``sensor_origins`` (S, 3) rows moved to the rings' new ids
    (row ``new[j]`` is the old row ``ids[j]``), as read when there are enough of them."""
    origins = rig.sensor_origins
    ids, new = renumber
    if origins is None or len(origins) <= int(max(ids.max(), new.max())):
        return rig
    moved = np.array(origins, dtype=np.float64, copy=True)
    moved[new] = np.asarray(origins)[ids]
    return replace(rig, sensor_origins=moved)


def renumbered_rings(ring: np.ndarray, renumber: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Ring ids ``ring`` (n,) with those of ``ids`` (k,, sorted) replaced by ``new``
    (a permutation of ``ids``; others kept, so no two rings meet), int32."""
    ids, new = renumber
    at = np.clip(np.searchsorted(ids, ring), 0, len(ids) - 1)
    return np.where(ids[at] == ring, new[at], ring).astype(np.int32)


__all__ = ["SAMPLE_SCANS", "folder_ring_order", "renumbered_rig", "renumbered_rings"]
