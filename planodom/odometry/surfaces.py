"""How the deskewing policy ranks two extractions of one epoch (``odometry.deskew_rank``).

:func:`planodom.odometry.deskew.register_deskewed` keeps the best of several extractions of
an epoch, each deskewed with another twist. ``planes`` (the default) ranks them by status,
then plane count, and drops a refinement only when its status is worse. A twist off the
truth splits a wall into one plane per sweep: fragments count as planes, so a wrong twist
wins a tie of statuses, and a refinement that loses surfaces but splits others is kept.
``surfaces`` ranks by status, then the number of *distinct surfaces*: planes whose normals
agree within ``association.normal_tol_deg`` and whose offsets agree within
``association.offset_tol_m`` (the margins within which the association cannot tell two
planes apart) count once; a refinement is dropped when this rank is worse.
``surfaces_first`` ranks the first extractions (predicted, held, none) so and refinements
as ``planes`` does. With the one-scanner widening on
(``extraction.single_scanner_rate_sigma_deg_s`` or ``..._speed_sigma_mps``), unresolved
extractions rank by the planes that can take part in the rotation
(:func:`planodom.odometry.rotation_planes.rotation_planes`) before their count: one is kept
only as the next epoch's reference, and a reference of one scanner's planes pairs with none.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

from planodom.config import PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry.relative import Status
from planodom.odometry.rotation_planes import rotation_planes, widened

if TYPE_CHECKING:
    from planodom.odometry.deskew import EpochEstimate

#: ``rank(estimate) -> (status rank, [rotation planes,] count)``: higher is better.
Ranking = Callable[["EpochEstimate"], tuple[int, ...]]


def distinct_surfaces(planes: Sequence[Plane], normal_tol_deg: float, offset_tol_m: float) -> int:
    """How many distinct surfaces ``planes`` hold: planes ``n . p + d = 0`` (same frame) whose
    unit normals are within ``normal_tol_deg`` degrees of each other and whose offsets ``d``
    are within ``offset_tol_m`` metres are one surface, and so is every chain of such
    pairs (connected components). Normals point towards the sensor, so a plane and its
    opposite (a thin wall's two sides) stay two."""
    if len(planes) < 2:
        return len(planes)
    normals = np.array([p.normal for p in planes])  # (P, 3)
    offsets = np.array([p.offset for p in planes])  # (P,)
    close = normals @ normals.T >= np.cos(np.radians(normal_tol_deg))
    close &= np.abs(offsets[:, None] - offsets[None, :]) <= offset_tol_m
    n, _ = connected_components(csr_array(close), directed=False)
    return int(n)


def by_planes(estimate: EpochEstimate) -> tuple[int, int]:
    """An extraction's status, then its plane count (``odometry.deskew_rank: planes``)."""
    return estimate.relative.status.rank, len(estimate.planes)


def ranking(config: PlanodomConfig, pairwise: bool = False) -> Ranking:
    """The key an extraction of an epoch is ranked by (higher is better) under ``config``'s
    ``odometry.deskew_rank``: its status, then its plane count (``planes``) or its
    distinct surfaces within ``association.normal_tol_deg`` and ``offset_tol_m``
    (``surfaces``); with the one-scanner widening on, an unresolved extraction's planes
    that can take part in the rotation come between (module docstring). With
    ``odometry.deskew_tie: deskewed`` on a ``pairwise`` pipeline, last whether it was
    deskewed with a twist (:func:`deskewed_last`)."""
    key = _ranking(config)
    if pairwise and config.odometry.deskew_tie == "deskewed":
        return deskewed_last(key)
    return key


def deskewed_last(key: Ranking) -> Ranking:
    """``key`` with, last, whether the extraction was deskewed with a twist: of two that
    rank alike by ``key``, the deskewed one ranks higher (``odometry.deskew_tie``)."""
    return lambda e: (*key(e), int(e.twist is not None))


def _ranking(config: PlanodomConfig) -> Ranking:
    """:func:`ranking` without ``odometry.deskew_tie``."""
    tol_deg, tol_m = config.association.normal_tol_deg, config.association.offset_tol_m
    ext = config.extraction

    def count(e: EpochEstimate) -> int:
        if config.odometry.deskew_rank == "planes":
            return len(e.planes)
        return distinct_surfaces(e.planes, tol_deg, tol_m)

    def seeds(e: EpochEstimate) -> int:
        """An unresolved extraction is kept only as the next epoch's reference: its planes
        that can take part in the rotation; 0 (no say) for a measured one."""
        lost = e.relative.status is Status.UNRESOLVED
        return rotation_planes(e.planes, ext) if lost else 0

    if widened(ext):
        return lambda e: (e.relative.status.rank, seeds(e), count(e))
    if config.odometry.deskew_rank == "planes":
        return by_planes
    return lambda e: (e.relative.status.rank, count(e))


def fragment_count(config: PlanodomConfig) -> Callable[[EpochEstimate], int] | None:
    """With ``odometry.twist_sigma_fragments``, an estimate's distinct surfaces within
    ``association.normal_tol_deg`` and ``offset_tol_m`` (:func:`distinct_surfaces`), which
    :func:`planodom.odometry.twist_sigma.widened_if_lost` compares with its plane count;
    None when off."""
    if not config.odometry.twist_sigma_fragments:
        return None
    tol_deg, tol_m = config.association.normal_tol_deg, config.association.offset_tol_m
    return lambda e: distinct_surfaces(e.planes, tol_deg, tol_m)
