"""The first epoch extracted again once its motion is known (``odometry.first_epoch_reextract``).

The streaming odometry extracts the first epoch before any twist is known: not deskewed
(the 2D rig's path then extrapolates each wall seen in several time windows to the epoch
time). On a run that starts while moving its planes are smeared by the motion within the
epoch, and every later pose is chained to them (loop closures tie back to them too). The
deskewing policy (:mod:`planodom.odometry.deskew`, step 2) extracts it again once, with the
twist of the first step, which was itself measured on the smeared planes.

Here, once the second epoch's estimate is final, ``rounds`` times: the first epoch is
extracted again deskewed with the own twist of the step between them
(:meth:`~planodom.odometry.deskew.EpochEstimate.own_twist`; a degenerate step measures the
angular rate only: its velocity is the one the first epoch was deskewed with, and without
one nothing is done, as the policy never deskews with a velocity nobody measured), and
the second epoch's step estimated again against the new planes. A round is kept while the
step stays measured and its status no worse; otherwise the first epoch's planes before it
are brought back and the rounds end. They end too when the twist no longer changes.

What one step can tell: a plane of an epoch deskewed with a twist off by ``e`` sits where
the pose off by ``-e tm`` puts it (``tm`` the mean point time, :func:`.deskew.twist_offset`),
so with both epochs deskewed with the same twist ``w`` the step's twist is, to first order,
``v0 + (tm / dt) (v1 - v0)`` whatever ``w`` is (``v0``, ``v1``: the true twists over the
two epochs' points): the rounds converge at once to the twist the deskewing policy's own
refresh already used, off the first epoch's own by the change of the motion times
``tm / dt`` (about half), and a second epoch's twist is not known before the third
epoch. What they change is the extraction's answer to a twist a little different (on the
2D rig's first epoch, extracted without a twist, each wall is extrapolated from its own
time windows). On the simulated paper loop at sigma = 0, 2D rig at 8 m/s, the first
epoch's planes were 0.5 mm off the true surfaces (median) after the policy's refresh and
3.0 mm after three rounds (the yaw rate ended 0.0034 rad/s off the first step's, the
change from it to the second's times 0.46); with 16 beams 5.0 -> 4.7 mm.

The step is reported once, after the rounds (the outputs stay causal). With the plane-map
odometry the map, which then holds only the first epoch, is seeded again with the new
planes; with ``planemap.reference_time: middle`` the epochs' times and the step are those
of the sweeps' middles, so the twist is the one over the sweeps. The extraction widens
its tolerances by the extraction's declared twist uncertainty
(``extraction.twist_*_sigma_*``), as :func:`planodom.smoothing.redeskew.
refresh_first_epoch`; with ``odometry.deskew_twist: coplanar`` the twist is the prior of
the coplanar fit (:mod:`.coplanar`), of the sigma of a twist refined from the step.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Protocol

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.deskew import EpochEstimate, time_spread
from planodom.odometry.relative import Status
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry

#: ``round(twist, best) -> (again, undo)``: extract the first epoch again deskewed with
#: ``twist`` (6,), estimate the second epoch's step again against the new planes
#: (``again``); ``undo()`` brings the first epoch's planes before the round back.
Round = Callable[[np.ndarray, EpochEstimate], tuple[EpochEstimate, Callable[[], None]]]


class FirstEpoch(Protocol):
    """The first epoch as the odometry keeps it: its scan (None: given as planes) and the
    twist its current planes were deskewed with (None: not deskewed)."""

    scan: Scan | None
    twist: np.ndarray | None


def first_twist(best: EpochEstimate, dt: float, used: np.ndarray | None) -> np.ndarray | None:
    """(6,) the twist (rad/s, m/s) to extract the first epoch again with, from ``best``,
    the second epoch's estimate over ``dt`` s, the first epoch having been deskewed with
    ``used`` (None: not deskewed): the step's own twist when OK; its angular rate with
    ``used``'s velocity when degenerate; None when unresolved, degenerate without a
    ``used`` velocity, or ``dt`` not positive."""
    status = best.relative.status
    if dt <= 0 or status is Status.UNRESOLVED:
        return None
    own = best.own_twist(dt)
    if status is Status.OK:
        return own
    return None if used is None else np.r_[own[:3], used[3:]]


def reextracted_first(
    best: EpochEstimate,
    dt: float,
    config: OdometryConfig,
    first: FirstEpoch,
    round_: Round,
) -> EpochEstimate:
    """The second epoch's estimate after up to ``config.first_epoch_reextract`` rounds
    (module docstring); ``best`` as it is when the first epoch has no scan with point times.

    Args:
        best: the second epoch's estimate against the first epoch (``relative.prev`` 0).
        dt: seconds between the two epochs.
        config: ``first_epoch_reextract``.
        first: the first epoch (its ``twist`` follows the rounds).
        round_: see :data:`Round`.
    """
    if first.scan is None or not time_spread(first.scan):
        return best
    for _ in range(config.first_epoch_reextract):
        if best.relative.prev != 0:
            break
        used = first.twist
        twist = first_twist(best, dt, used)
        if twist is None or (used is not None and np.array_equal(twist, used)):
            break
        again, undo = round_(twist, best)
        if again.relative.status.rank < best.relative.status.rank or not again.relative.measured:
            undo()
            break
        best = again
    return best


def first_round(
    odo: PlaneOdometry, scan: Scan, t: float, twist: np.ndarray, best: EpochEstimate
) -> tuple[EpochEstimate, Callable[[], None]]:
    """:data:`Round` for the streaming odometry ``odo``'s second epoch (``scan`` at ``t``,
    estimated as ``best``): its first epoch extracted again with ``twist`` (6,)."""
    first, last = odo._history[0], odo._last_usable
    old = (first.planes, first.twist, first.plane_set)
    assert first.scan is not None and first.index == 0
    prior = odo._twist_sigma.refined(best, t - odo.times[-1], twist)
    odo._set_planes(first, *odo._extract(first.scan, twist, prior=prior))
    odo._last_usable = first if first.has_pair(odo.config.association) else None

    def undo() -> None:
        odo._set_planes(first, *old)
        odo._last_usable = last

    return odo._estimate_scan(scan, t, twist, source=best), undo
