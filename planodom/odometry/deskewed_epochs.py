"""Epochs deskewed along a curve through poses (the deskewing passes of
:func:`planodom.odometry.run.redeskewed_run`)."""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import Plane
from planodom.odometry.interpolate import deskew_with_poses
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.run import EpochSequence


@dataclass(frozen=True)
class Curve:
    """The deskewing curve's nodes (times (J,) s, poses (J, 4, 4)), their variances
    (J, 6) (None: interpolation), polynomial degree and fit window
    (:func:`planodom.odometry.interpolate.curve_poses`)."""

    times: np.ndarray
    poses: np.ndarray
    variances: np.ndarray | None
    order: int
    n_fit: int | None
    increments: bool = False


@dataclass(frozen=True)
class Deskewed:
    """An epoch's scan (times relative to the pass's reference time) and the same points
    deskewed along the curve (:meth:`PlaneOdometry.register_epoch`'s ``deskewed``); with
    ``planes``, the planes to take for ``deskewed`` instead of extracting it
    (``odometry.deskew_pass_skip``, :mod:`planodom.odometry.pass_skip`; ``deskewed`` is
    then a copy of ``scan``, its points not deskewed: they are not read)."""

    scan: Scan
    deskewed: Scan
    planes: list[Plane] | None = None


class DeskewedEpochs:
    """``source``'s epochs, each scan (epoch k at ``times[k]``) deskewed to
    ``reference[k]`` along ``curve`` where ``trusted[k]``, else with
    its times shifted to that reference (see :func:`redeskewed_run`); ``seconds`` adds up
    the time spent deskewing. ``given(k)``: planes of a deskewed epoch k to take instead
    of extracting it, or None (:mod:`planodom.odometry.pass_skip`)."""

    def __init__(
        self,
        source: EpochSequence,
        times: np.ndarray,
        reference: np.ndarray,
        curve: Curve,
        trusted: np.ndarray,
        given: Callable[[int], list[Plane] | None] | None = None,
    ) -> None:
        self.source, self.times, self.reference = source, times, reference
        self.curve, self.trusted, self.given = curve, trusted, given
        self.seconds = 0.0

    def __len__(self) -> int:
        return len(self.source)

    def __getitem__(self, k: int) -> Scan | Sequence[Plane] | Deskewed:
        item = self.source[k]
        if not isinstance(item, Scan):
            return item
        shift = float(self.reference[k] - self.times[k])
        raw = item if item.t is None or shift == 0 else replace(item, t=item.t - shift)
        if not self.trusted[k]:  # the streaming deskewing, to the reference time
            return raw
        planes = None if self.given is None else self.given(k)
        if planes is not None:  # not extracted: its points are not read (a copy: not raw)
            return Deskewed(raw, replace(raw), planes)
        c0 = _time.perf_counter()
        c = self.curve
        out = deskew_with_poses(
            item, c.times, c.poses, float(self.times[k]), c.order, float(self.reference[k]),
            c.variances, c.n_fit, c.increments,
        )  # fmt: skip
        self.seconds += _time.perf_counter() - c0
        # the times stay (extracted with a zero twist): a lidar's range image takes its
        # columns from them (with zeros it has none and falls back to RANSAC fragments)
        return Deskewed(raw, replace(out, t=raw.t))
