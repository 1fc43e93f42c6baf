"""Consecutive scans holding the same points (a frozen driver) are found; scans that differ
by one bit, are empty, or are not consecutive are not."""

from __future__ import annotations

import numpy as np

from planodom.datasets.repeated_scans import RepeatedScans
from planodom.scan import Scan


def _scan(seed: int, n: int = 30) -> Scan:
    rng = np.random.default_rng(seed)
    return Scan(rng.uniform(-10, 10, (n, 3)), np.zeros(n, np.int32), np.zeros(n))


def test_repeats_of_the_scan_before_are_found_in_order() -> None:
    a, b, c = _scan(1), _scan(2), _scan(3)
    again = Scan(b.points.copy(), b.ring, b.t + 0.1)  # other times: the same frame re-sent
    repeats = RepeatedScans()
    for k, scan in enumerate([a, b, again, again, c, c]):
        repeats.check(k, f"s{k}", scan)
    assert repeats.found == {"s2": "s1", "s3": "s2", "s5": "s4"}
    assert repeats.note().startswith(
        "3 scan(s) repeat the scan before them point for point (first: s2, as s1): "
    )


def test_near_copies_empty_scans_and_other_epochs_are_no_repeats() -> None:
    b = _scan(2)
    nudged = b.points.copy()
    nudged[7, 2] = np.nextafter(nudged[7, 2], np.inf)  # one bit: a real sensor's noise is more
    empty = Scan(np.zeros((0, 3)))
    repeats = RepeatedScans()
    for k, scan in [(0, b), (1, Scan(nudged)), (2, empty), (3, empty), (5, Scan(nudged))]:
        repeats.check(k, f"s{k}", scan)  # epoch 4 not read: 5 is compared with nothing
    reversed_order = Scan(b.points[::-1].copy())
    repeats.check(6, "s6", reversed_order)
    repeats.check(7, "s7", Scan(b.points[:-1].copy()))
    assert repeats.found == {}
    repeats.check(6, "s6 again", b)  # the odometry reads an epoch again: compared with 5
    assert repeats.found == {}
