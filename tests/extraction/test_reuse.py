"""A ringed scan's segmentation reused when it is extracted again with a nearby twist
(planodom.extraction.lidar.reuse, ``extraction.segmentation_reuse``): the planes then take
the new twist (against the scene's truth), and nothing is reused beyond the bound."""

from __future__ import annotations

import numpy as np
import pytest

import planodom.extraction.lidar.path as lidar_path
from planodom.config import ExtractionConfig
from planodom.extraction import extract
from planodom.extraction.epoch import Epoch
from planodom.extraction.lidar import reuse
from planodom.scan import Scan

from .synth_scans import default_scene, plane_errors, planes_in_base, scan_lidar

#: The true twist of the scans: 1.5 m/s ahead, 10 deg/s of yaw.
TWIST = np.array([0.0, 0.0, np.radians(10.0), 1.5, 0.0, 0.0])


@pytest.fixture
def segmentations(monkeypatch):
    """Counts the scans segmented anew (calls of the candidate search)."""
    calls = [0]
    search = lidar_path.lidar_candidates

    def counted(*args, **kwargs):
        calls[0] += 1
        return search(*args, **kwargs)

    monkeypatch.setattr(lidar_path, "lidar_candidates", counted)
    monkeypatch.setattr(reuse, "_LAST", [None])
    return calls


def _scan() -> Scan:
    return scan_lidar(default_scene(), twist=TWIST, sigma=0.006, seed=2, n_beams=32)


def _config(mode: str) -> ExtractionConfig:
    return ExtractionConfig(range_noise_m=0.006, estimate_noise=False, segmentation_reuse=mode)


def _fingerprint(found) -> list[tuple]:
    return [
        (p.normal.tobytes(), p.offset, p.covariance.tobytes(), i.tobytes())
        for p, i in zip(found.planes, found.inliers, strict=True)
    ]


def test_default_is_off_and_segments_every_extraction(segmentations):
    assert ExtractionConfig().segmentation_reuse == "off"
    scan = _scan()
    extract(scan, _config("off"), twist=TWIST)
    extract(scan, _config("off"), twist=TWIST)
    assert segmentations[0] == 2


def test_reused_planes_take_the_new_twist(segmentations):
    """Extracted first with a twist 0.18 m/s off (points moved by up to 18 mm, under the
    2 cm member tolerance), then with the true one: the second extraction reuses the
    first's segmentation, and its planes are as near the truth as a fresh extraction with
    the true twist (within 0.5 mm and 0.01 deg of its errors), where the first's planes
    are off by the wrong twist's smear (over 2 mm)."""
    truth = planes_in_base(default_scene())
    scan = _scan()
    off = TWIST + np.array([0.0, 0.0, 0.0, 0.18, 0.0, 0.0])
    wrong = extract(scan, _config("near_twist"), twist=off)
    again = extract(scan, _config("near_twist"), twist=TWIST)
    assert segmentations[0] == 1
    fresh = extract(scan, _config("off"), twist=TWIST)
    assert segmentations[0] == 2
    assert {p.truth_id for p in again.planes} == {p.truth_id for p in fresh.planes}
    assert len(again.planes) >= 4
    ang_w, off_w = plane_errors(wrong.planes, truth)
    ang_a, off_a = plane_errors(again.planes, truth)
    ang_f, off_f = plane_errors(fresh.planes, truth)
    assert off_w > 0.002
    assert off_a <= off_f + 0.0005 and ang_a <= ang_f + np.radians(0.01)
    # the planes are fitted to the newly deskewed points, not the first extraction's
    assert np.array_equal(again.points, fresh.points)


def test_same_twist_reuses_exactly_and_far_twist_segments_anew(segmentations):
    """With the same twist a reused segmentation gives the planes a fresh extraction
    gives, bit for bit; a twist that moves points by more than the member tolerance
    (0.3 m/s over 0.1 s: 3 cm), another scan with equal points, or another config is
    segmented anew."""
    scan = _scan()
    first = extract(scan, _config("near_twist"), twist=TWIST)
    same = extract(scan, _config("near_twist"), twist=TWIST)
    assert segmentations[0] == 1
    assert _fingerprint(same) == _fingerprint(first)
    assert _fingerprint(first) == _fingerprint(extract(scan, _config("off"), twist=TWIST))
    assert segmentations[0] == 2  # "off" neither reuses nor replaces the kept one
    far = TWIST + np.array([0.0, 0.0, 0.0, 0.3, 0.0, 0.0])
    extract(scan, _config("near_twist"), twist=far)
    assert segmentations[0] == 3
    other = Scan(scan.points.copy(), scan.ring.copy(), scan.t.copy(), scan.label)
    extract(other, _config("near_twist"), twist=TWIST)
    assert segmentations[0] == 4
    extract(other, _config("near_twist").model_copy(update={"tolerance_floor_m": 0.03}), TWIST)
    assert segmentations[0] == 5


def test_bound_is_the_first_order_point_motion():
    """The reuse bound: ``max |t| (|dw| max |p| + |dv|)`` against half the member
    tolerance, computed from the raw scan (an independent count here)."""
    scan = _scan()
    t_max = float(np.max(np.abs(scan.t)))
    p_max = float(np.max(np.linalg.norm(scan.points, axis=1)))
    tol = 0.02  # max(3 * 6 mm, 2 cm)
    assert reuse.REUSE_SHARE == 1.0
    dw = 0.9 * reuse.REUSE_SHARE * tol / (t_max * p_max)  # rad/s: just inside
    for scale, reused in ((1.0, True), (1.2, False)):
        reuse._LAST[0] = None
        extract(scan, _config("near_twist"), twist=TWIST)
        twist = TWIST + np.array([0.0, 0.0, scale * dw, 0.0, 0.0, 0.0])
        epoch = Epoch(scan, scan.points, None, twist)
        view = np.array([0.0, 0.0, _config("near_twist").viewpoint_height_m])
        got = reuse.reused(epoch, scan.ring, view, _config("near_twist"))
        assert (got is not None) is reused
