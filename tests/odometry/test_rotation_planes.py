"""One scanner's widened planes are kept out of the rotation's LDA pairs."""

from __future__ import annotations

import numpy as np

from planodom.association import lenient_association
from planodom.config import ExtractionConfig
from planodom.geometry import Plane
from planodom.odometry.rotation_planes import rotation_pairs
from planodom.planes import PlaneSet


def _room(tilt_sigma_deg: float) -> PlaneSet:
    """Three walls and the ground, fit covariances of 0.1 deg; the last wall's normal
    known to ``tilt_sigma_deg`` (a widened one-scanner plane)."""
    normals = [[1.0, 0, 0], [0, 1.0, 0], [0.6, -0.8, 0], [0, 0, 1.0]]
    offsets = [4.0, 3.0, 6.0, 1.5]
    planes = []
    for k, (n, d) in enumerate(zip(normals, offsets, strict=True)):
        s = np.radians(tilt_sigma_deg if k == 2 else 0.1)
        cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-4])
        planes.append(Plane(np.array(n), d, cov, 0.9))
    return PlaneSet.from_planes(planes)


def test_pairs_with_a_plane_above_the_normal_bar_are_dropped_only_with_the_option() -> None:
    prev = curr = _room(5.0)  # 5 deg, above max_normal_sigma_deg (1 deg)
    lda = lenient_association(prev, curr)
    assert (lda.prev_pairs == 2).any()  # the widened wall pairs, without the option
    off = ExtractionConfig()
    assert rotation_pairs(prev, curr, lda, off) is lda
    on = ExtractionConfig(single_scanner_rate_sigma_deg_s=0.5)
    kept = rotation_pairs(prev, curr, lda, on)
    expected = ~((lda.prev_pairs == 2).any(axis=1) | (lda.curr_pairs == 2).any(axis=1))
    assert len(kept) == int(expected.sum()) > 0
    assert not (kept.prev_pairs == 2).any() and not (kept.curr_pairs == 2).any()
    sharp = _room(0.5)  # within the bar: nothing dropped
    assert len(rotation_pairs(sharp, sharp, lenient_association(sharp, sharp), on)) == len(
        lenient_association(sharp, sharp)
    )
