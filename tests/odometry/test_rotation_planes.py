"""One scanner's widened planes are kept out of the rotation's LDA pairs, and the deskewing
policy ranks an epoch's extractions by the planes that can take part in the rotation."""

from __future__ import annotations

import numpy as np

from planodom.association import lenient_association
from planodom.config import ExtractionConfig, PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.rotation_planes import rotation_pairs, rotation_planes
from planodom.odometry.surfaces import ranking
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


def _planes(tilt_sigmas_deg: list[float], yaws_deg: list[float]) -> list[Plane]:
    """The ground (sharp, 0.1 deg) and one wall per yaw (normal sigma per wall, deg)."""
    planes = [Plane(np.array([0.0, 0, 1.0]), 1.5, np.diag([1e-6] * 3 + [1e-4]), 0.9)]
    for s_deg, yaw in zip(tilt_sigmas_deg, yaws_deg, strict=True):
        a, s = np.radians(yaw), np.radians(s_deg)
        cov = np.diag([s**2 / 2, s**2 / 2, s**2 / 2, 1e-4])
        planes.append(Plane(np.array([np.cos(a), np.sin(a), 0.0]), -4.0 - yaw / 30, cov, 0.9))
    return planes


#: After an unresolved epoch, both extractions unresolved (a tie of statuses): without
#: deskewing the ground and two crossing walls, all within the 1 deg bar; with the held twist
#: the ground and five walls of one scanner, widened to 5 deg (world 178 at 2 cm, epoch 94).
SHARP = _planes([0.1, 0.1], [0.0, 90.0])
ONE_SCANNER = _planes([5.0] * 5, [0.0, 30.0, 60.0, 90.0, 120.0])
HELD = np.array([0.0, 0.0, 0.2, 2.0, -1.2, 0.0])


def _unresolved(twist: np.ndarray | None, source: object = None) -> EpochEstimate:
    planes = SHARP if twist is None else ONE_SCANNER
    rel = RelativePose(np.eye(4), None, Status.UNRESOLVED)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, np.eye(4), planes)


def test_counts_the_planes_within_the_normal_bar() -> None:
    on = ExtractionConfig(single_scanner_rate_sigma_deg_s=0.5)
    assert rotation_planes(SHARP, on) == 3 and rotation_planes(ONE_SCANNER, on) == 1
    assert rotation_planes([Plane(np.array([1.0, 0, 0]), 2.0)], on) == 1  # no covariance


def test_a_tie_of_statuses_keeps_the_extraction_that_can_seed_the_next_rotation() -> None:
    """Ranked by plane count, the six planes of one scanner win the tie and, kept as the
    reference, leave the next epoch (the same room, seen sharp) no rotation pair: the
    56-epoch gap. With the widening on, the three sharp planes win and pair with it."""
    nxt = PlaneSet.from_planes(_planes([0.1, 0.1, 0.1], [0.0, 90.0, 30.0]))
    kept = {}
    for name, widen in (("off", {}), ("on", {"single_scanner_rate_sigma_deg_s": 0.5})):
        cfg = PlanodomConfig.from_dict({"extraction": widen})
        best = register_deskewed(None, 0.1, _unresolved, lambda t: False, cfg.odometry, 3,
                                 held=HELD, rank=ranking(cfg))  # fmt: skip
        kept[name] = best
    on = ExtractionConfig(single_scanner_rate_sigma_deg_s=0.5)
    assert kept["off"].planes is ONE_SCANNER and kept["on"].planes is SHARP
    for name, n_pairs in (("off", 0), ("on", 1)):
        ref = kept[name].plane_set
        pairs = rotation_pairs(ref, nxt, lenient_association(ref, nxt), on)
        assert (len(pairs) >= 1) == bool(n_pairs), name
