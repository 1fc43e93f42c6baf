"""A dataset folder whose ring ids are a lidar's laser ids in firing order: renumbered by
the beams' elevations in the lidar's frame (rig.yaml's extrinsics), noted once."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import write_dataset
from planodom.datasets.folder_ring_order import renumbered_rig
from planodom.rig import Rig
from planodom.scan import Scan
from planodom.simulation import simulate_named
from planodom.simulation.simulate import SimulatedRun


@pytest.fixture(scope="module")
def run() -> SimulatedRun:
    """A 16-beam lidar 0.8 m above the base (rings 0..15 from the lowest beam up)."""
    return simulate_named("urban-canyon", "lidar16", noise=0.0, seed=2, n_epochs=4,
                          motion="snapshot")  # fmt: skip


def _firing_order(r: np.ndarray) -> np.ndarray:
    """Elevation ranks ``r`` (n,) as a VLP-16's laser ids in firing order (ids 0, 2, ..., 14
    the lower half from the bottom, 1, 3, ..., 15 the upper)."""
    r = r.astype(np.int64)
    return np.where(r < 8, 2 * r, 2 * (r - 8) + 1)


def _firing(run: SimulatedRun, shift: np.ndarray | None = None) -> list[Scan]:
    """The run's scans with firing-order ring ids (points moved by ``shift`` (3,) m)."""
    move = np.zeros(3) if shift is None else shift
    return [replace(s, points=s.points + move, ring=_firing_order(s.ring)) for s in run.scans]


def test_firing_order_rings_of_a_folder_are_renumbered_by_elevation(
    tmp_path: Path, run: SimulatedRun
) -> None:
    """Read before in id order (the range image's neighbouring rows 16 deg apart: ATE
    0.003 m -> 9.3 m on 30 epochs, no word); now each point's ring is its beam's elevation
    rank, the truth's ring, and the folder is noted once."""
    ds = write_dataset(tmp_path / "firing", _firing(run), run.times, run.poses, run.rig)
    for truth, scan in zip(run.scans, ds, strict=True):
        np.testing.assert_array_equal(scan.ring, truth.ring)
    (note,) = [n for n in ds.notes if "ring ids" in n]
    assert "its ring ids do not follow its beams' elevations (ring 0: -15.0, 1: +1.0, 2: -13.0" in (
        note
    )
    assert "the same ids are given to its rings in elevation order" in note
    same = write_dataset(tmp_path / "elevation", run.scans, run.times, run.poses, run.rig)
    assert same.ring_renumber is None and not [n for n in same.notes if "ring ids" in n]


def test_firing_order_rings_without_extrinsics_are_only_noted(
    tmp_path: Path, run: SimulatedRun
) -> None:
    """No lidar frame in rig.yaml: the points' own frame is tried (here the lidar's: the
    points moved 0.8 m down), the order noted, the ids read as they are."""
    lift = run.rig.extrinsics[0][:3, 3]
    scans = _firing(run, -lift)
    ds = write_dataset(tmp_path / "f", scans, run.times, run.poses, Rig(epoch_rate_hz=10.0))
    assert ds.ring_renumber is None
    np.testing.assert_array_equal(ds[0].ring, scans[0].ring)
    (note,) = [n for n in ds.notes if "ring ids" in n]
    assert "read in id order: rig.yaml gives no lidar extrinsics" in note


def test_per_ring_sensor_origins_follow_the_renumbering() -> None:
    """Row ``new[j]`` of the origins is the old row ``ids[j]``: origin z = the old id."""
    ids = np.arange(4)
    new = np.array([0, 2, 1, 3])
    origins = np.column_stack([np.zeros((4, 2)), ids.astype(np.float64)])
    moved = renumbered_rig(Rig(sensor_origins=origins), (ids, new)).sensor_origins
    assert moved is not None
    np.testing.assert_array_equal(moved[:, 2], [0.0, 2.0, 1.0, 3.0])
