"""The epochs at the start of a run that no measured velocity deskewed, deskewed once a
step measures the motion (``odometry.start_refresh``).

The deskewing policy (:mod:`planodom.odometry.deskew`) extracts the first epoch before
any twist is known, and extracts a reference epoch again only with the twist of the step
right after it. When the first steps are degenerate (rotation only: no velocity is
measured) or unresolved, the epochs before the first measured step keep their planes as
first extracted: not deskewed, or deskewed with a prediction whose velocity is a
degenerate step's prior (standing still before any motion is known); only the last of
them is extracted again. The first epoch, whose pose is the frame of the whole run, then
keeps planes off by the motion over its points' times (the 2D-rig world 18 at 6 mm, its
first two steps degenerate: a deskewing error of 14 cm along track, which turns the
whole smoothed lap about 2 mrad against the truth), and the degenerate steps' unmeasured
direction is the prediction's: standing still (world 18: 0.74 m off after one step).

Here, once an epoch's step is measured (status OK, its planes deskewed with a twist),
every epoch of the start before it that was not extracted again while it was registered
(the policy's refresh of its reference used the measured twist) is extracted again
deskewed with that epoch's final twist (the constant velocity the odometry would have
predicted, had it known it), its angular rate replaced by that of the degenerate step
into the epoch where there is one (the extraction widens its tolerances by the predicted
twist's uncertainty, as for the policy's refresh). An extraction with far fewer planes
(under half, or under two, as the policy judges one) is not kept. Each step that joins a new
extraction is estimated again against the new planes with the constant-velocity
prediction of that twist as its prior (a degenerate step's unmeasured direction is then
the measured velocity's). A step estimated again is kept when its status is no worse;
otherwise the old one stays and its epoch is marked superseded (its result indexes
planes that are gone; the batch estimates it again from the planes); a degenerate one
is then estimated again on the planes it had, with that prior (:func:`_primed_again`).
The poses are then chained again through the steps. Only the pairwise pipelines (the
map holds its planes), scans with point times, no gap in the epoch times up to the
measured step, and a start of at most :data:`MAX_EPOCHS` epochs, or more while their scans
hold at most :data:`MAX_BYTES`.

With ``start_twist_search`` and ``start_search_speed: measured``, when the search gave
a step of the start (:attr:`StartEpochs.searched`), every epoch of the start is taken
as stale, whether or not it was extracted again: the search's candidate, and the
predictions its steps then gave, deskewed those epochs with a guessed speed that their
degenerate steps' unmeasured direction kept (2D-rig world 356 at 2 cm; docs/RESULTS.md,
START356).

The odometry's outputs are then not causal for those first epochs: their poses change
when the measured step arrives (the run's poses are those after it). The twist the first
epoch's planes were extracted with at last is kept (:attr:`StartEpochs.first_twist`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import Plane, orthonormalised, se3_log, twist_step
from planodom.odometry.deskew import EpochEstimate, time_spread, with_deskew
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.odometry.relative import RelativePose, Status, replaced
from planodom.odometry.solver import estimate_relative_pose
from planodom.odometry.start_search import searched_start
from planodom.odometry.vehicle_start import vehicle_started
from planodom.planes import PlaneSet
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry
    from planodom.odometry.start_converged import ConvergedStart


#: The start's epochs held at most (their scans are kept), unless their scans fit in
#: :data:`MAX_BYTES`: a run whose first epochs measure no motion for longer is not
#: deskewed at its start (a bound on the memory held).
MAX_EPOCHS = 20

#: The bytes the start's scans may hold beyond :data:`MAX_EPOCHS` epochs. A 2D-rig epoch
#: holds 0.07 MB (240 epochs), a simulated 16-beam lidar's 0.24 MB (66), a 64-beam one's
#: 2.5 MB (20 epochs: the bound as it was for scans of over 0.8 MB).
MAX_BYTES = 16_000_000


@dataclass
class StartEpochs:
    """The run's first epochs while none of them was deskewed (``enabled``: the option).

    Attributes:
        epochs: the epochs from the first on until the first whose step is measured
            (status OK): none of them was deskewed with a measured velocity.
        first_twist: (6,) the twist the first epoch's planes were extracted with at last
            (rad/s, m/s), None while not deskewed (kept by the odometry's own refresh too).
    """

    enabled: bool
    epochs: list[KeptEpoch] = field(default_factory=list)
    open: bool = True
    searched: bool = False  # the search (start_search) gave a step of the start
    converged: ConvergedStart | None = None  # odometry.start_redeskew
    _twists: list[np.ndarray | None] = field(default_factory=list)  # before the last epoch

    def appended(self, odo: PlaneOdometry, epoch: KeptEpoch) -> None:
        """Note ``epoch``, just appended to ``odo``; when its step is the first measured
        one, deskew the start's epochs with its twist (module docstring); then, with
        ``start_redeskew: converged``, :class:`.start_converged.ConvergedStart`'s turn."""
        self._appended(odo, epoch)
        if odo.config.odometry.start_redeskew == "converged":
            if self.converged is None:
                from planodom.odometry.start_converged import ConvergedStart

                self.converged = ConvergedStart()
            self.converged.appended(odo, epoch)

    def _appended(self, odo: PlaneOdometry, epoch: KeptEpoch) -> None:
        if not (self.enabled and self.open):
            return
        result = odo.results[epoch.index]
        if result is None or result.status is not Status.OK:
            if len(self.epochs) < MAX_EPOCHS or _held(self.epochs, epoch) <= MAX_BYTES:
                self.epochs.append(epoch)
                self._twists = [e.twist for e in self.epochs]
            else:  # too long a start: left as it is, its scans let go
                self.open, self.epochs, self._twists = False, [], []
            return
        self.open = False
        gaps = any(0 < k <= epoch.index for k in odo._gaps)
        if epoch.twist is None or odo._map is not None or gaps:
            return
        twist = np.asarray(epoch.twist, dtype=float)
        known = {e.index: e for e in [*self.epochs, epoch]}
        if self.searched and odo.config.odometry.start_search_speed == "measured":
            measured_start(odo, [*self.epochs, epoch], known, epoch.index)
            return
        # not extracted again while this epoch was (the policy's refresh of its reference
        # gave that one a measured twist), and not with this twist already
        stale = [
            e for e, was in zip(self.epochs, self._twists, strict=True)
            if e.scan is not None and time_spread(e.scan) and e.twist is was
            and (e.twist is None or not np.array_equal(e.twist, twist))
        ]  # fmt: skip
        if stale:
            refresh_start(odo, stale, known, twist, epoch.index)

    def vehicle(
        self, odo: PlaneOdometry, scan: Scan, t: float, best: EpochEstimate
    ) -> EpochEstimate:
        """``best`` or the start's epoch deskewed with a vehicle's twist
        (:func:`.vehicle_start.vehicle_started`, ``odometry.start_vehicle_twist``; for an
        unresolved step, :func:`.start_search.searched_start`, ``start_twist_search``)."""
        started = vehicle_started(odo, scan, t, best)
        searched = searched_start(odo, scan, t, started)
        self.searched = self.searched or searched is not started
        return searched

    @property
    def first_twist(self) -> np.ndarray | None:
        """(6,) the twist of the first epoch's planes when this module deskewed them."""
        if not self.epochs or self.epochs[0].index != 0 or self.epochs[0].twist is None:
            return None
        return np.array(self.epochs[0].twist, dtype=float)


def measured_twist(odo: PlaneOdometry, result: RelativePose) -> np.ndarray:
    """(6,) the own twist (rad/s, m/s) of the measured step ``result`` of ``odo``: its
    motion over its interval, not the twist its epoch was deskewed with (after a search,
    the guessed speed its degenerate predecessors carried)."""
    dt = odo.times[result.curr] - odo.times[result.prev]
    return se3_log(result.T_prev_curr) / dt


def measured_start(
    odo: PlaneOdometry, epochs: list[KeptEpoch], known: dict[int, KeptEpoch], last: int
) -> None:
    """``start_search_speed: measured``: every epoch of a searched start, ``epochs`` up to
    the measured one ``last`` included, extracted again with the measured step's own
    twist, its steps estimated again (:func:`refresh_start`), and again with the own
    twist of the measured step so estimated, ``deskew_iterations`` rounds at most (at
    least one) while it changes. The own twist of a step whose two epochs were deskewed
    with different velocities is off by their difference times the points' time offset
    over the interval (a reference deskewed with the guessed speed, its epoch with the
    prediction), so one round gives a speed between the guess and the truth; a round on
    epochs deskewed alike measures it. The run's next prediction takes the last round's
    velocity (the step's own velocity, as the odometry's prediction would)."""
    twist = measured_twist(odo, odo.results[last])  # type: ignore[arg-type]
    for _ in range(max(odo.config.odometry.deskew_iterations, 2)):
        stale = [
            e for e in epochs
            if e.scan is not None and time_spread(e.scan)
            and (e.twist is None or not np.array_equal(e.twist, twist))
        ]  # fmt: skip
        if not stale:
            break
        refresh_start(odo, stale, known, twist, last)
        result = odo.results[last]
        if result is None or result.status is not Status.OK:
            break
        new = measured_twist(odo, result)
        if np.array_equal(new, twist):
            break
        twist = new
    if odo._velocities and odo.twist is not None:  # the run's velocity: this step's
        odo._velocities[-1] = np.array(twist[3:])
        odo.twist = np.r_[odo.twist[:3], twist[3:]]


def _held(epochs: list[KeptEpoch], epoch: KeptEpoch) -> int:
    """The bytes the scans of ``epochs`` and ``epoch`` hold (their arrays)."""
    scans = [e.scan for e in [*epochs, epoch] if e.scan is not None]
    return sum(a.nbytes for s in scans for a in (s.points, s.ring, s.t, s.label) if a is not None)


def refresh_start(
    odo: PlaneOdometry, stale: list[KeptEpoch], known: dict[int, KeptEpoch],
    twist: np.ndarray, last: int,
) -> None:  # fmt: skip
    """Extract the ``stale`` epochs of ``odo`` again with ``twist`` (6,), estimate again
    every step up to epoch ``last`` (the measured one) that joins a new extraction
    (``known``: the epochs by index, their scans and twists), and chain the poses again
    (module docstring)."""
    was: dict[int, list[Plane]] = {}  # the planes of the epochs extracted again, as they were
    sigma = odo._twist_sigma.predicted()
    twists = {k: epoch_twist(odo, k, twist) for k in range(last + 1)}
    for epoch in stale:
        assert epoch.scan is not None
        planes, used = odo._extract(epoch.scan, twists[epoch.index], prior=sigma)
        if len(planes) < max(2.0, 0.5 * len(epoch.planes)):
            continue  # far fewer planes (as the policy judges an extraction): kept as it was
        was[epoch.index] = odo.planes[epoch.index]
        odo._set_planes(epoch, planes, used)
    for k in range(1, last + 1):
        old = odo.results[k]
        if old is None or not ({old.prev, k} & was.keys()):
            continue
        new = _solved(odo, old, twists[k], known.get(k))
        if new is None or new.status.rank < old.status.rank:
            odo.superseded.add(k)
            new = _primed_again(odo, old, twists[k], was)
            if new is None:
                continue
        else:
            odo.superseded.discard(k)
        commit_step(odo, k, new)
    rechain_poses(odo)


def epoch_twist(odo: PlaneOdometry, k: int, twist: np.ndarray) -> np.ndarray:
    """(6,) the twist to deskew epoch ``k`` of the start with: ``twist`` (6,), the measured
    one, with the angular rate of the step into the epoch (out of it for the first) where
    that step is degenerate (its rotation measured: the rate over the start, where the
    measured step's may be seconds later)."""
    j = max(k, 1)
    result = odo.results[j]
    dt = odo.times[j] - odo.times[j - 1]
    if result is None or result.status is not Status.DEGENERATE or result.prev != j - 1 or dt <= 0:
        return twist
    return np.r_[se3_log(odo._steps[j])[:3] / dt, twist[3:]]


def _primed_again(
    odo: PlaneOdometry, old: RelativePose, twist: np.ndarray, was: dict[int, list[Plane]]
) -> RelativePose | None:
    """A degenerate step ``old`` kept over its estimate on the new planes (a worse
    status): estimated again on the planes it was estimated on (``was``: those of the
    epochs extracted again, as they were) with the measured ``twist`` (6,)'s prior, so
    that its unmeasured direction is the measured velocity's, not the prediction it had
    (standing still, or a velocity an earlier such step gave). None (``old`` kept as it
    is) for other statuses, or when that estimate's status is not ``old``'s.

    (The 2D-rig world 180 at 6 mm: its first measured step is epoch 14; the steps into
    epochs 2 and 6-11 were degenerate, estimated again unresolved, and kept, each 37 cm
    off along the one wall it saw: horizontal ATE 2.38 m, the oracle's 0.019 m.)"""
    if old.status is not Status.DEGENERATE:
        return None
    planes = (was.get(old.prev, odo.planes[old.prev]), was.get(old.curr, odo.planes[old.curr]))
    again = _solved(odo, old, twist, None, planes)  # None: old's deskewing, as it was
    return again if again is not None and again.status is old.status else None


def _solved(
    odo: PlaneOdometry, old: RelativePose, twist: np.ndarray, epoch: KeptEpoch | None,
    planes: tuple[list[Plane], list[Plane]] | None = None,
) -> RelativePose | None:  # fmt: skip
    """The step ``old`` (``prev`` .. ``curr``) estimated again on the current planes (or
    ``planes``: the reference's and the epoch's) with the constant-velocity prediction of
    ``twist`` (6,) as prior; None without a positive interval."""
    prev, curr = old.prev, old.curr
    ref_planes, planes_now = planes or (odo.planes[prev], odo.planes[curr])
    dt = odo.times[curr] - odo.times[prev]
    if dt <= 0:
        return None
    prior = twist_step(twist, dt)
    sigma = odo._twist_sigma.predicted()[1] * dt
    config = odo._config_for_gap(curr - prev)
    rel = estimate_relative_pose(
        PlaneSet.from_planes(ref_planes), PlaneSet.from_planes(planes_now), config,
        prior if config.odometry.use_motion_prior else None, sigma, step=True,
    )  # fmt: skip
    if rel.status is Status.UNRESOLVED:  # bridged by constant velocity
        rel = replaced(rel, T_prev_curr=np.array(prior))
    rel = rel.between(prev, curr)
    scan = None if epoch is None else epoch.scan
    used = None if epoch is None else epoch.twist
    if scan is None:
        return replaced(rel, time_spread=old.time_spread, deskew_twist=old.deskew_twist,
                        deskew_times=old.deskew_times, interval_s=old.interval_s)  # fmt: skip
    return with_deskew(rel, scan, used, dt)


def commit_step(odo: PlaneOdometry, k: int, new: RelativePose) -> None:
    """Make ``new`` epoch ``k``'s result and its step T_{k-1}_{k}, taking out the steps
    between its reference and epoch k - 1 (a reference gap)."""
    odo.results[k] = new
    T_ref_last = np.eye(4)  # T_{prev}_{k-1}
    for step in odo._steps[new.prev + 1 : k]:
        T_ref_last = T_ref_last @ step
    odo._steps[k] = orthonormalised(np.linalg.inv(T_ref_last) @ new.T_prev_curr)


def rechain_poses(odo: PlaneOdometry) -> None:
    """The poses chained again from the (changed) steps, epoch 0 kept."""
    for k in range(1, len(odo.poses)):
        odo.poses[k] = orthonormalised(odo.poses[k - 1] @ odo._steps[k])
