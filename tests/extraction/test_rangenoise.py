"""The 2D rig's range-noise estimate (:mod:`planodom.extraction.rig2d.rangenoise`)."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import ExtractionConfig
from planodom.extraction.rig2d.segments import split_scan_lines

from .synth_scans import default_rig, default_scene, scan_rig

SIGMA = 0.02  # m, the range noise simulated (Gaussian along each beam)


def _origins() -> np.ndarray:
    """(4, 3) each scanner's origin in the base frame (ring k is scanner k)."""
    return np.array([T[:3, 3] for T in default_rig()])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_range_estimate_recovers_the_simulated_range_noise(seed):
    """On a standing rig's epoch (no motion left to deskew) whose surfaces are seen at
    every incidence, the estimate along the rays is the simulated range sigma to 10 %,
    where the across-line estimate sees only its oblique share (below 0.85 sigma): the
    bias a plane seen head-on then fails its RMS test by."""
    scan = scan_rig(default_scene(), sigma=SIGMA, seed=seed)
    low = 0.001  # the configured noise, below both estimates: the estimate decides
    across = ExtractionConfig(range_noise_m=low)
    along = ExtractionConfig(range_noise_m=low, noise_estimate="range")
    _, s_across = split_scan_lines(scan.points, scan.ring, scan.t, across, _origins())
    _, s_range = split_scan_lines(scan.points, scan.ring, scan.t, along, _origins())
    assert abs(s_range / SIGMA - 1.0) < 0.10
    assert s_across < 0.85 * SIGMA


def test_range_estimate_is_the_across_one_without_origins_or_by_default():
    """Without origins (or with the default ``across``) the estimate is the across-line
    one, bit for bit: the option changes nothing it cannot compute."""
    scan = scan_rig(default_scene(), sigma=SIGMA, seed=4)
    base = ExtractionConfig(range_noise_m=0.001)
    along = ExtractionConfig(range_noise_m=0.001, noise_estimate="range")
    _, ref = split_scan_lines(scan.points, scan.ring, scan.t, base)
    _, without = split_scan_lines(scan.points, scan.ring, scan.t, along)
    _, default = split_scan_lines(scan.points, scan.ring, scan.t, base, _origins())
    assert ref == without == default


def test_one_origin_for_every_ring_is_used_for_all():
    """A (1, 3) origin array serves every ring (a lidar-like single sensor): on a scan
    whose four scanners all sit at one point the estimate equals the per-ring one."""
    rig = default_rig()
    for T in rig:
        T[:3, 3] = rig[0][:3, 3]
    scan = scan_rig(default_scene(), sigma=SIGMA, seed=5, rig=rig)
    along = ExtractionConfig(range_noise_m=0.001, noise_estimate="range")
    per_ring = np.repeat(rig[0][None, :3, 3], 4, axis=0)
    _, one = split_scan_lines(scan.points, scan.ring, scan.t, along, rig[0][None, :3, 3].copy())
    _, four = split_scan_lines(scan.points, scan.ring, scan.t, along, per_ring)
    assert one == four and abs(one / SIGMA - 1.0) < 0.10
