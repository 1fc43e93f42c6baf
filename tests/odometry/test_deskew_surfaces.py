"""``odometry.deskew_rank: surfaces`` (:mod:`planodom.odometry.surfaces`): fragments of one
wall, which a wrong twist makes, count once when the deskewing policy ranks extractions."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
from planodom.extraction.deskew import deskew_points
from planodom.geometry import Plane
from planodom.odometry.deskew import EpochEstimate, register_deskewed
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.surfaces import distinct_surfaces, ranking
from planodom.planes import PlaneSet

DT = 0.1
HELD = np.array([0.0, 0.0, 0.2, 2.0, -1.2, 0.0])  # a held twist, rad/s and m/s


def _wall(yaw_deg: float, offset: float) -> Plane:
    a = np.radians(yaw_deg)
    return Plane(np.array([np.cos(a), np.sin(a), 0.0]), offset)


GROUND = Plane(np.array([0.0, 0.0, 1.0]), 1.0)
#: Three true surfaces: the ground and two walls at right angles.
TRUE_SURFACES = [GROUND, _wall(0.0, -5.0), _wall(90.0, -3.0)]
#: A wrong twist splits the wall at x = 5 into one plane per sweep (yaw 0.8 deg and 4 cm
#: apart, within the association's margins of 5 deg and 0.2 m) and loses the other.
FRAGMENTS = [GROUND] + [_wall(0.8 * i, -5.0 - 0.04 * i) for i in range(4)]


def _estimate(planes: list[Plane], twist: np.ndarray | None, status: Status) -> EpochEstimate:
    step = np.eye(4)
    rel = RelativePose(step, None, status)
    return EpochEstimate(planes, PlaneSet.from_planes(planes), twist, rel, step, planes)


def test_fragments_of_one_wall_count_once_and_distinct_surfaces_do_not_merge():
    assert distinct_surfaces(FRAGMENTS, 5.0, 0.2) == 2  # the ground and one wall
    assert distinct_surfaces(TRUE_SURFACES, 5.0, 0.2) == 3
    # parallel walls 0.5 m apart, and a wall seen from its two sides, stay two
    assert distinct_surfaces([_wall(0.0, -5.0), _wall(0.0, -5.5)], 5.0, 0.2) == 2
    assert distinct_surfaces([_wall(0.0, -5.0), _wall(180.0, 5.0)], 5.0, 0.2) == 2
    # a chain of fragments, each within the margins of the next, is one surface
    chain = [_wall(3.0 * i, -5.0) for i in range(5)]  # 12 deg from end to end
    assert distinct_surfaces(chain, 5.0, 0.2) == 1
    assert distinct_surfaces([], 5.0, 0.2) == 0


def _held_model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
    """After an unresolved epoch: without a twist the epoch gives the three true surfaces,
    with the held twist one wall split into four fragments; both unresolved (a tie)."""
    if twist is None:
        return _estimate(TRUE_SURFACES, None, Status.UNRESOLVED)
    return _estimate(FRAGMENTS, twist, Status.UNRESOLVED)


def test_fragments_of_a_held_twist_do_not_win_a_tie_of_statuses():
    """Ranked by plane count, the five fragments beat the three surfaces (the GAPS case of
    world 140, epochs 18-26); ranked by distinct surfaces, they are two."""
    rank = ranking(PlanodomConfig())
    planes = register_deskewed(None, DT, _held_model, lambda t: False, OdometryConfig(), 3,
                               held=HELD, rank=rank)  # fmt: skip
    assert planes.twist is not None and len(planes.planes) == 5
    config = OdometryConfig(deskew_rank="surfaces")
    rank = ranking(PlanodomConfig.from_dict({"odometry": {"deskew_rank": "surfaces"}}))
    surfaces = register_deskewed(None, DT, _held_model, lambda t: False, config, 3,
                                 held=HELD, rank=rank)  # fmt: skip
    assert surfaces.twist is None and len(surfaces.planes) == 3
    config = OdometryConfig(deskew_rank="surfaces_first")
    rank = ranking(PlanodomConfig.from_dict({"odometry": {"deskew_rank": "surfaces_first"}}))
    first = register_deskewed(None, DT, _held_model, lambda t: False, config, 3,
                              held=HELD, rank=rank)  # fmt: skip
    assert first.twist is None and len(first.planes) == 3


def test_a_refinement_that_loses_surfaces_is_dropped():
    """A refinement whose status is as good but which keeps fewer distinct surfaces (world
    172's epoch 6: 5 planes, then 3, then 7 of which 4 distinct) is dropped with
    ``surfaces``; with ``planes`` only a worse status drops it."""
    first = np.array([0.0, 0.0, 0.05, 2.0, 0.0, 0.0])

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        if source is None:  # the prediction: the three true surfaces
            return _estimate(TRUE_SURFACES, twist, Status.OK)
        return _estimate(FRAGMENTS, twist, Status.OK)  # its own twist: splits a wall

    def step_model(twist: np.ndarray | None, source: EpochEstimate | None = None):
        est = model(twist, source)
        own = first + np.array([0.0, 0.0, 0.1, 0.0, 0.6, 0.0])  # far from the one used
        step = np.eye(4)
        step[:3, 3] = own[3:] * DT
        c, s = np.cos(own[2] * DT), np.sin(own[2] * DT)
        step[:2, :2] = [[c, -s], [s, c]]
        return EpochEstimate(est.planes, est.plane_set, twist, est.relative, step, est.planes)

    cfg = OdometryConfig(deskew_iterations=1)
    planes = register_deskewed(first, DT, step_model, lambda t: False, cfg, 3)
    assert len(planes.planes) == 5  # the refinement, kept on its status
    cfg = OdometryConfig(deskew_iterations=1, deskew_rank="surfaces")
    rank = ranking(PlanodomConfig.from_dict({"odometry": cfg.model_dump()}))
    surfaces = register_deskewed(first, DT, step_model, lambda t: False, cfg, 3, rank=rank)
    assert len(surfaces.planes) == 3 and np.array_equal(surfaces.twist, first)
    cfg = OdometryConfig(deskew_iterations=1, deskew_rank="surfaces_first")
    rank = ranking(PlanodomConfig.from_dict({"odometry": cfg.model_dump()}))
    only_first = register_deskewed(first, DT, step_model, lambda t: False, cfg, 3, rank=rank)
    assert len(only_first.planes) == 5  # refinements ranked as with ``planes``


def test_a_bad_rank_names_its_key():
    with pytest.raises(ConfigError, match="deskew_rank"):
        PlanodomConfig.from_dict({"odometry": {"deskew_rank": "walls"}})


def _wall_seen_while_turning(rate: float, twist: np.ndarray | None) -> Plane:
    """The wall x = 5 (normal (-1, 0, 0) towards the sensor) as a sensor at the origin
    sees it over the 0.1 s before the epoch time while yawing at ``rate`` rad/s, its
    points deskewed with ``twist`` (None: as they are), fitted by least squares (σ = 0)."""
    t = np.linspace(-0.1, 0.0, 41)
    y, z = np.linspace(-3.0, 3.0, 41), np.tile([-0.5, 0.5, 1.5], 14)[:41]  # three lines
    world = np.column_stack([np.full(41, 5.0), y, z])
    c, s = np.cos(rate * t), np.sin(rate * t)  # the body frame at t: yawed by rate t
    seen = np.column_stack([c * world[:, 0] + s * world[:, 1],
                            -s * world[:, 0] + c * world[:, 1], world[:, 2]])  # fmt: skip
    points = seen if twist is None else deskew_points(seen, t, twist)
    centre = points.mean(axis=0)
    normal = np.linalg.svd(points - centre)[2][-1]
    normal = -normal if normal[0] > 0 else normal
    return Plane(normal, -float(normal @ centre))


def test_a_tie_keeps_the_deskewed_extraction_whose_wall_is_the_true_one():
    """After an unresolved epoch, the extraction without a twist and the one with the held
    twist (here the true one) both give the ground and one wall, degenerate: a tie
    (SIGMA0B, random-outdoor epoch 240). ``first`` keeps the undeskewed one, whose wall is
    turned by the sweep's motion; ``deskewed`` keeps the held one, whose wall is the true
    wall at σ = 0."""
    rate = np.radians(8.0)
    held = np.array([0.0, 0.0, rate, 0.0, 0.0, 0.0])

    def model(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        return _estimate([GROUND, _wall_seen_while_turning(rate, twist)], twist,
                         Status.DEGENERATE)  # fmt: skip

    def wall_error_deg(est: EpochEstimate) -> float:
        n = est.planes[1].normal
        return float(np.degrees(np.arccos(np.clip(-n[0], -1.0, 1.0))))

    for tie, deskewed in (("first", False), ("deskewed", True)):
        odo = {"deskew_tie": tie, "deskew_iterations": 0}  # the first extractions only
        cfg = PlanodomConfig.from_dict({"odometry": odo})
        rank = ranking(cfg, pairwise=True)
        kept = register_deskewed(None, DT, model, lambda t: False, cfg.odometry, 2,
                                 held=held, rank=rank)  # fmt: skip
        assert (kept.twist is not None) is deskewed
        if deskewed:
            assert wall_error_deg(kept) < 1e-9  # the true wall
        else:  # turned by the rate times the points' mean time, 8 deg/s x 0.05 s
            assert wall_error_deg(kept) == pytest.approx(0.4, rel=0.05)
    # the plane-map pipeline is not changed: the tie stays with the first
    cfg = PlanodomConfig.from_dict({"odometry": {"deskew_tie": "deskewed", "deskew_iterations": 0}})
    kept = register_deskewed(None, DT, model, lambda t: False, cfg.odometry, 2, held=held,
                             rank=ranking(cfg, pairwise=False))  # fmt: skip
    assert kept.twist is None


def test_a_bad_tie_names_its_key():
    with pytest.raises(ConfigError, match="deskew_tie"):
        PlanodomConfig.from_dict({"odometry": {"deskew_tie": "last"}})
