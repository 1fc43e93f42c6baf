"""A refinement that merges split walls, tried again against its reference extracted again.

Where a turn's rate changes, the twist an epoch is first deskewed with (the step before's)
lags its points and splits a wall into one plane per sweep (docs/RESULTS.md, DEGEN166 and
TURNLAG). The deskewing policy's refinement (:mod:`planodom.odometry.deskew`, step 2)
extracts the epoch again with its own step's twist and may then find each surface once;
but its reference epoch, deskewed with a lagging twist as well, keeps its split walls, the
pair's step turns degenerate, and a refinement of a worse status is dropped (2D-rig world
166 at 6 mm, epoch 74: 13 planes of 4 true surfaces first, 6 of 6 refined, dropped).

The refinement's twist is the mean over the step from the reference epoch to this one,
centred half a step after the reference's time: about the middle of the reference's own
points (a sweep of the 2D rig's epoch follows its reference time), where the twist the
reference was deskewed with was centred a step and a half earlier. So with
``odometry.split_reference: split`` (pairwise pipelines), when a refinement

- has a worse status than the estimate it was refined from,
- splits fewer walls than it (fewer planes beyond its distinct surfaces,
  :func:`.surfaces.distinct_surfaces`: the association's margins, never the simulator's
  labels), and
- was estimated against a reference whose walls are split (fewer distinct surfaces than
  planes),

the reference epoch is extracted again with the refinement's twist and the epoch estimated
again against it (``split``; ``any``: every refinement of a worse status, the second and
third conditions dropped). The new pair is kept when it is better than the estimate refined from
by status, then distinct surfaces; else the reference's planes (and twist) come back and
the refinement is dropped as before. The reference's pose is not changed; its own result,
made against its old planes, is marked superseded.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from planodom.odometry.deskew import EpochEstimate, Estimator
from planodom.odometry.surfaces import distinct_surfaces

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry


def split_reference(odometry: PlaneOdometry, estimate: Estimator) -> Estimator:
    """``estimate`` (an :data:`.deskew.Estimator` of ``odometry``'s epoch being registered)
    with its refinements tried again against a reference extracted again with their twist
    (module docstring) when ``odometry.split_reference`` is not ``off`` and the pipeline
    is pairwise; ``estimate`` itself otherwise."""
    mode = odometry.config.odometry.split_reference
    if mode == "off" or not odometry.pairwise:
        return estimate
    association = odometry.config.association
    tol = association.normal_tol_deg, association.offset_tol_m

    def fragments(planes: list) -> int:
        """Planes beyond the distinct surfaces they hold: a wall's extra fragments."""
        return len(planes) - distinct_surfaces(planes, *tol)

    def rank(e: EpochEstimate) -> tuple[int, int]:
        return e.relative.status.rank, distinct_surfaces(e.planes, *tol)

    def refined(twist: np.ndarray | None, source: EpochEstimate | None = None) -> EpochEstimate:
        again = estimate(twist) if source is None else estimate(twist, source)
        if source is None or twist is None:
            return again
        if again.relative.status.rank >= source.relative.status.rank:
            return again
        if mode == "split" and fragments(again.planes) >= fragments(source.planes):
            return again
        if mode == "split" and not fragments(again.reference_planes):
            return again
        undo = _refresh(odometry, twist)
        if undo is None:
            return again
        pair = estimate(twist, source)
        if rank(pair) > rank(source):
            return pair
        undo()
        return again

    return refined


def _refresh(odometry: PlaneOdometry, twist: np.ndarray) -> Callable[[], None] | None:
    """Extract ``odometry``'s reference epoch again with ``twist`` (rad/s, m/s, (6,)), its
    pose unchanged, and return what brings its planes, twist and bookkeeping back; None
    (nothing changed) when it has no scan, was deskewed with ``twist`` already, or would
    lose its non-parallel pair."""
    ref = odometry._reference()
    if ref.scan is None or (ref.twist is not None and np.array_equal(ref.twist, twist)):
        return None
    before = (ref.planes, ref.plane_set, ref.twist)
    was_superseded = ref.index in odometry.superseded
    last_usable = odometry._last_usable
    planes, used = odometry._extract(ref.scan, twist, prior=odometry.twist_uncertainty.predicted())
    odometry._set_planes(ref, planes, used)
    if not ref.has_pair(odometry.config.association):
        odometry._set_planes(ref, before[0], before[2], before[1])
        return None  # a reference without a pair is no reference (:meth:`_reference`)
    if odometry.results[ref.index] is not None:
        odometry.superseded.add(ref.index)
    last = odometry._last_usable
    if last is None or last.index <= ref.index:
        odometry._last_usable = ref

    def undo() -> None:
        odometry._set_planes(ref, before[0], before[2], before[1])
        odometry._last_usable = last_usable
        if not was_superseded:
            odometry.superseded.discard(ref.index)

    return undo
