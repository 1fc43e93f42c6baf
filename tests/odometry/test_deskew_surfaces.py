"""``odometry.deskew_rank: surfaces`` (:mod:`planodom.odometry.surfaces`): fragments of one
wall, which a wrong twist makes, count once when the deskewing policy ranks extractions."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.config import OdometryConfig, PlanodomConfig
from planodom.errors import ConfigError
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
