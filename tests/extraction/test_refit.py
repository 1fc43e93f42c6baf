"""extraction.pipeline.refit: an extraction's planes fit again with another twist."""

from __future__ import annotations

import numpy as np

from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.pipeline import refit

from .synth_scans import default_scene, planes_in_base, scan_rig

XI = np.array([0.05, -0.04, 0.6, 3.0, 0.4, 0.1])  # rad/s, m/s: a brisk turn
OFF = np.array([0.0, 0.0, np.radians(1.0), 0.1, 0.0, 0.0])


def _errors(planes, truth):
    ang = off = 0.0
    for p in planes:
        n, d = truth[p.truth_id]
        s = np.sign(p.normal @ n)
        ang = max(ang, float(np.arccos(min(1.0, abs(p.normal @ n)))))
        off = max(off, abs(s * p.offset - d))
    return ang, off


def test_refit_with_the_true_twist_gives_the_true_planes_on_the_same_inliers():
    scene = default_scene()
    scan = scan_rig(scene, twist=XI)
    wrong = extract(scan, twist=XI + OFF)
    assert len(wrong.planes) >= 3
    assert max(_errors(wrong.planes, planes_in_base(scene))) > 1e-4
    again = refit(wrong, scan, ExtractionConfig(), XI)
    assert sorted(map(len, again.inliers)) == sorted(map(len, wrong.inliers))
    ang, off = _errors(again.planes, planes_in_base(scene))
    assert ang < 1e-9 and off < 1e-9
    # the same planes as an extraction with the true twist would build from these inliers
    exact = extract(scan, twist=XI)
    np.testing.assert_allclose(again.points, exact.points)


def test_refit_without_times_or_planes_returns_the_extraction():
    scan = scan_rig(default_scene(), twist=XI)
    found = extract(scan, twist=XI)
    assert refit(found, scan.__class__(scan.points, scan.ring), ExtractionConfig(), XI) is found
