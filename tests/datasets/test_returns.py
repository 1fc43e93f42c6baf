"""Dual-return clouds: one point per beam firing (the last return), so that planes are not
counted twice and a ring stays one run of azimuth; single-return clouds untouched."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from planodom.datasets import read_scan
from planodom.datasets.pcd import write_pcd
from planodom.datasets.returns import _firings, last_returns

RINGS, COLUMNS = 16, 90


def _single() -> dict[str, np.ndarray]:
    """A 16-beam sweep inside a 10 m x 10 m box of walls (ring-major order), single return."""
    azimuth = np.linspace(-np.pi, np.pi, COLUMNS, endpoint=False)
    elev = np.deg2rad(np.linspace(-15, 15, RINGS))
    az, el = np.meshgrid(azimuth, elev)  # (RINGS, COLUMNS)
    d = np.column_stack(
        [(np.cos(el) * np.cos(az)).ravel(), (np.cos(el) * np.sin(az)).ravel(), np.sin(el).ravel()]
    )
    rng_m = 5.0 / np.max(np.abs(d[:, :2]), axis=1)  # walls at x = +-5 and y = +-5
    pts = d * rng_m[:, None]
    ring = np.repeat(np.arange(RINGS), COLUMNS).astype(np.uint16)
    t = (np.tile(np.arange(COLUMNS), RINGS) * 1e-3 + ring * 2e-6).astype(np.float32)
    return {"x": pts[:, 0], "y": pts[:, 1], "z": pts[:, 2], "ring": ring, "time": t}


def _dual(single: dict[str, np.ndarray], labelled: bool) -> tuple[dict, np.ndarray]:
    """Each firing twice, strongest then last; a third of the firings' first returns hit a
    nearer object at 60 % of the range (foliage). Returns the fields and the last returns'
    indices into the single cloud's points."""
    n = len(single["x"])
    near = np.arange(n) % 3 == 0
    first = {k: v.copy() for k, v in single.items()}
    for c in "xyz":
        first[c] = np.where(near, 0.6 * single[c], single[c])
    out = {k: np.column_stack([first[k], single[k]]).ravel() for k in single}  # interleaved
    if labelled:
        out["return_type"] = np.tile(np.array([3, 1], np.uint8), n)  # STRONGEST, LAST
    return out, np.arange(n)


@pytest.mark.parametrize("labelled", [True, False])
def test_dual_return_pcd_keeps_the_last_return(tmp_path: Path, labelled: bool) -> None:
    single = _single()
    fields, _ = _dual(single, labelled)
    write_pcd(tmp_path / "dual.pcd", fields)
    scan = read_scan(tmp_path / "dual.pcd")
    # exactly the single-return cloud: every firing once, the wall behind, in ring order
    expected = np.column_stack([single[c] for c in "xyz"])
    np.testing.assert_array_equal(scan.points, expected)
    np.testing.assert_array_equal(scan.ring, single["ring"])
    np.testing.assert_array_equal(scan.t, single["time"].astype(np.float64))


def test_single_return_and_packet_times_untouched(tmp_path: Path) -> None:
    single = _single()
    write_pcd(tmp_path / "single.pcd", single)
    assert len(read_scan(tmp_path / "single.pcd")) == RINGS * COLUMNS
    coarse = dict(single, time=np.zeros(RINGS * COLUMNS, np.float32))  # one time a packet
    write_pcd(tmp_path / "coarse.pcd", coarse)
    assert len(read_scan(tmp_path / "coarse.pcd")) == RINGS * COLUMNS


def test_returns_that_cannot_be_paired_are_all_kept() -> None:
    """Without ring and time no firing pairs its returns: no return value is dropped (a
    driver's value may mean "both returns coincide", the bulk of a scan)."""
    pts = np.array([[1.0, 0, 0], [3.0, 0, 0], [0, 2.0, 0], [0, 4.0, 0]])
    returns = np.array([2, 1, 2, 1])  # FIRST, LAST
    assert last_returns(pts, None, None, returns) is None
    own_times = np.array([0.0, 1e-6, 2e-6, 3e-6])  # each return its own time (nebula Hesai)
    assert last_returns(pts, np.array([0, 0, 1, 1]), own_times, returns) is None
    assert last_returns(pts, None, None, np.ones(4)) is None
    assert last_returns(pts, None, None, None) is None
    few = np.array([[1.0, 0, 0], [3.0, 0, 0], [0, 2.0, 0], [0, 4.0, 0]])  # 2 points a ring
    assert last_returns(few, np.array([0, 0, 1, 1]), np.zeros(4), None) is None  # snapshot


def test_two_firings_with_one_time_stamp_are_not_returns_of_one_pulse() -> None:
    """Points that share ring and time but not a ray (a driver stamping two firings of a
    beam with one time, 1.2 deg apart) are different firings: all kept."""
    az = np.deg2rad([0.0, 1.2, 10.0, 11.2])
    pts = np.column_stack([np.cos(az), np.sin(az), np.zeros(4)]) * np.array(
        [[2.0], [6.0], [3], [3]]
    )
    ring, t = np.zeros(4), np.array([0.0, 0.0, 1e-3, 1e-3])
    assert last_returns(pts, ring, t, None) is None
    same_ray = pts.copy()
    same_ray[1] = pts[0] * 3.0  # now the far return of the first firing's pulse
    same_ray[3] = pts[2] * 1.5
    np.testing.assert_array_equal(last_returns(same_ray, ring, t, None), [1, 3])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_firings_are_numpy_unique_of_the_ring_and_time_pairs(seed: int) -> None:
    # the firings were np.unique(axis=0) of (ring, t): 39 s of a 10M-point cloud's
    # reading; the two-key sort must number them alike (ties, -0.0 and 0.0 included)
    rng = np.random.default_rng(seed)
    n = 20_000
    ring = rng.integers(0, 16, n).astype(np.float64)
    t = rng.integers(-20, 20, n) * 1e-4
    t[rng.random(n) < 0.05] = -0.0
    _, inverse, counts = np.unique(
        np.column_stack([ring, t]), axis=0, return_inverse=True, return_counts=True
    )
    firing, firing_counts = _firings(ring, t)
    np.testing.assert_array_equal(firing, inverse.reshape(-1))
    np.testing.assert_array_equal(firing_counts, counts)
