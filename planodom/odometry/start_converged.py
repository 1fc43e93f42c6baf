"""The start's epochs deskewed again once the measured velocity has converged
(``odometry.start_redeskew: converged``).

The first epoch is extracted before any twist is known and again with the first measured
step's twist; the next epochs are deskewed with the prediction, the median of the few
steps measured so far. Each of those steps carries its own noise (a step's velocity is
its translation, a few centimetres of plane offsets, over one interval), so the start's
epochs are deskewed with a velocity that the following steps correct: on 2D-rig lap 342
at 6 mm the first step measured 3.27 m/s for a true 3.45 and epoch 0's planes are 4.3 cm
off (docs/RESULTS.md, LOOPNEES). Epoch 0 is the frame of the run and the epoch every loop
factor of a lap closes on, so its planes' error is counted by every loop factor.

Here the own velocities (x, y) of the first measured steps are averaged, weighed by the
inverse of their covariances (the solver's 5-DoF covariance's x, y block over the
interval squared), while they agree with the running mean (a step beyond the chi-square
99 % bound of their difference ends the average before it: the motion changed, the mean
of the steps before is kept). The mean has converged once a step moves it by less than
its own standard error (Mahalanobis distance under the mean's covariance below 1): the
steps' own covariances decide, not a count. Then every epoch of the start up to that
step is extracted again deskewed with the mean velocity (the step's own angular rate and
vertical velocity: the rotation is measured far better than the speed) and the steps
between them are estimated again with that twist's constant-velocity prior
(:func:`.start_epochs._solved`); repeated with the mean of the steps so estimated
(``deskew_iterations`` rounds, at least two) while it changes, since the first steps
were measured on epochs deskewed with the first step's own error (lap 342: a mean of
3.40 m/s, then 3.44, for a true 3.45). A step estimated again is kept only when its
status is no worse than the first estimate's and its rotation agrees with that one
within the sum of their covariances (chi-square 95 %, 3 DoF): a degenerate start step
estimated again on planes extracted anew can be wrong in rotation by degrees (2D-rig
world 378 at 2 cm: one step 16 deg off in pitch, docs/RESULTS.md, START356). A step
not kept keeps its old estimate, marked superseded (it indexes planes that are gone).
The poses are chained again. Only the pairwise pipelines, scans with point times, no
gap in the epoch times, and a start of at most :data:`.start_epochs.MAX_EPOCHS` epochs;
otherwise nothing.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation
from scipy.stats import chi2

from planodom.geometry import se3_log
from planodom.odometry.deskew import time_spread
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.start_epochs import MAX_EPOCHS, _solved, commit_step, rechain_poses

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry

#: chi-square 99 % quantile, 2 DoF: a step's velocity against the running mean (a change).
CHI2_99_2 = float(chi2.ppf(0.99, 2))
#: chi-square 95 % quantile, 2 DoF: the mean's correction against its own covariance.
CHI2_95_2 = float(chi2.ppf(0.95, 2))
#: chi-square 95 % quantile, 3 DoF: a step's rotation estimated again against the old one.
CHI2_95_3 = float(chi2.ppf(0.95, 3))
#: ``start_redeskew_test: information``: the mean's information over the first step's,
#: in every direction, before the mean may count as converged (:func:`informed`).
INFORMATION_GAIN = 4.0


@dataclass
class ConvergedStart:
    """The start's epochs held until the measured velocity converges (module docstring).

    Attributes:
        epochs: the run's epochs from the first on, while open.
        mean, information: the weighed mean (2,) of the averaged steps' own x, y
            velocities (m/s) and its information (2, 2); None before the first.
        converged_at: the epoch whose step ended the average (None while open or when
            the start was left as it was); ``velocity``: the mean it was deskewed with.
    """

    epochs: list[KeptEpoch] = field(default_factory=list)
    open: bool = True
    mean: np.ndarray | None = None
    information: np.ndarray | None = None
    first: np.ndarray | None = None  # the first averaged step's information (2, 2)
    steps: list[int] = field(default_factory=list)  # the averaged steps' epochs
    converged_at: int | None = None
    velocity: np.ndarray | None = None

    def appended(self, odo: PlaneOdometry, epoch: KeptEpoch) -> None:
        """Note ``epoch``, just appended to ``odo``; deskew the start again when its step
        makes the mean converge (module docstring)."""
        if not self.open:
            return
        if odo._map is not None or epoch.index in odo._gaps or len(self.epochs) >= MAX_EPOCHS:
            self._close()
            return
        self.epochs.append(epoch)
        result = odo.results[epoch.index]
        if result is None:
            return
        own = _own_velocity(odo, result)
        if own is None and self.mean is None:
            return  # no step measured yet (the start's own refresh, start_refresh)
        if own is None:  # not measured: the average ends here
            self._finish(odo, self.epochs[-2].index if len(self.epochs) > 1 else 0)
            return
        v, info = own
        if self.mean is None or self.information is None:
            self.mean, self.information, self.steps = v, info, [epoch.index]
            self.first = info
            return
        d = v - self.mean
        S = np.linalg.inv(info) + np.linalg.inv(self.information)
        if float(d @ np.linalg.solve(S, d)) > CHI2_99_2:  # the motion changed
            self._finish(odo, self.steps[-1])
            return
        information = self.information + info
        mean = np.linalg.solve(information, self.information @ self.mean + info @ v)
        moved = mean - self.mean
        self.mean, self.information = mean, information
        self.steps.append(epoch.index)
        if float(moved @ information @ moved) < 1.0 and self._informed(odo):
            self._finish(odo, epoch.index)

    def _informed(self, odo: PlaneOdometry) -> bool:
        """``start_redeskew_test``: ``move``, always; ``information``, :func:`informed`."""
        if odo.config.odometry.start_redeskew_test == "move":
            return True
        assert self.first is not None and self.information is not None
        return informed(self.information, self.first)

    def _significant(self, odo: PlaneOdometry, epochs: list[KeptEpoch]) -> bool:
        """``start_redeskew_test: significant``: whether the mean differs from the x, y
        velocity epoch 0 (the run's frame) was deskewed with beyond the mean's own
        covariance (chi-square 95 %, 2 DoF). Why: extracting the start anew changes its
        planes by more than the deskewing does when the correction is within the mean's
        noise (2D-rig world 422 at 2 cm: a correction of (-0.006, +0.010) m/s, 0.4 mm over
        the sweep, and the ATE 0.054 -> 0.061 m); a correction the mean resolves is the
        error the start carries (lap 342: 3.27 -> 3.44 m/s, nine standard errors)."""
        if odo.config.odometry.start_redeskew_test != "significant":
            return True
        twist = epochs[0].twist if epochs else None
        if twist is None or self.mean is None or self.information is None:
            return True  # epoch 0 not deskewed: any measured velocity is a correction
        d = self.mean - np.asarray(twist, dtype=float)[3:5]
        return float(d @ self.information @ d) > CHI2_95_2

    def _close(self) -> None:
        self.open, self.epochs = False, []

    def _finish(self, odo: PlaneOdometry, last: int) -> None:
        """Deskew epochs 0 .. ``last`` again with the mean (two averaged steps at least),
        ``deskew_iterations`` rounds at most (at least two) while the mean of the steps
        estimated again changes: the first steps were measured on epochs deskewed with
        their own noisy velocity, so the mean over them is pulled by that error too."""
        epochs = [e for e in self.epochs if e.index <= last]
        # a change or a step not measured ends the average too: the same test applies
        informed_ = self._informed(odo) and self._significant(odo, epochs)
        if len(self.steps) >= 2 and self.mean is not None and last >= 1 and informed_:
            originals = {k: odo.results[k] for k in range(1, last + 1)}
            velocity, kept = np.array(self.mean), None
            whole = odo.config.odometry.start_redeskew_guard == "all"
            for _ in range(max(odo.config.odometry.deskew_iterations, 2)):
                saved = _saved(odo, epochs, last) if whole else None
                if not redeskew_start(odo, epochs, velocity, last, originals) and saved:
                    _restore(odo, epochs, saved)  # a step refused: the round undone
                    break
                kept = velocity
                again = _mean(odo, self.steps)
                if again is None or np.allclose(again, velocity, rtol=0, atol=1e-6):
                    break
                velocity = again
            if kept is not None:
                self.converged_at, self.velocity = last, kept
        self._close()


def informed(information: np.ndarray, first: np.ndarray) -> bool:
    """Whether the mean's ``information`` (2, 2) is at least :data:`INFORMATION_GAIN`
    times the first averaged step's ``first`` in every direction (``information - 4
    first`` positive semi-definite).

    Why: the start's epochs are deskewed with the first step's velocity, so the
    deskewing error they carry over an epoch's sweep (the velocity error times the
    points' time offsets) has the first step's covariance; deskewed again with the mean,
    the mean's. Doing it is worth its risk (every plane of the start extracted anew)
    only when that error's standard deviation is at most half the first step's in every
    direction, i.e. the mean's covariance at most a quarter of the first step's. The
    test the mean passes besides ("the last step moved it by less than its standard
    error") is a coin toss with two steps: for steps of equal noise the n-th step's move
    is 1 / (n - 1) of the mean's variance in expectation, so two steps whose noise
    agrees pass it (2D-rig world 382 at 6 mm: two steps' lateral velocities -0.14 and
    +0.08 m/s, sd 0.04 and 0.12, a mean of -0.11 for a true 0.00). With this test the
    two steps' information is 1.1x the first's laterally; four steps of equal noise are
    needed, more where the later steps are noisier. A noisy first step (a large
    covariance) is soon outweighed, a precise one needs more steps to improve on, as it
    should: it is the count weighed by the steps' own covariances."""
    return bool(np.linalg.eigvalsh(information - INFORMATION_GAIN * first).min() >= 0.0)


def velocity_agrees(old: RelativePose, new: RelativePose, dt: float) -> bool:
    """Whether ``new``'s own x, y velocity (its translation over ``dt``) is ``old``'s
    within the sum of their covariances (chi-square 99 %, 2 DoF; without both
    covariances: not judged, agrees). The start's steps estimated again move in
    translation by design (their epochs deskewed with a better velocity: the move is the
    deskewing change over the sweep, tens of millimetres per second at most), but a step
    whose translation jumps beyond both estimates' covariances was re-solved on planes
    that changed more than the velocity explains (2D-rig world 398 at 6 mm: the step into
    epoch 2 estimated again at 2.43 m/s for a first 1.97 and a true 2.0)."""
    if old.covariance is None or new.covariance is None or dt <= 0:
        return True
    d = (se3_log(new.T_prev_curr)[3:5] - se3_log(old.T_prev_curr)[3:5]) / dt
    S = (old.covariance[3:5, 3:5] + new.covariance[3:5, 3:5]) / dt**2
    if not np.all(np.isfinite(S)) or np.linalg.det(S) <= 0:
        return True
    return float(d @ np.linalg.solve(S, d)) <= CHI2_99_2


def _saved(odo: PlaneOdometry, epochs: list[KeptEpoch], last: int) -> tuple:
    """What a round of :func:`redeskew_start` changes, to undo it (``start_redeskew_guard:
    all``): the epochs' planes and twists, the results, steps, poses, superseded set."""
    planes = [(e.planes, e.plane_set, e.twist) for e in epochs]
    return planes, list(odo.results), list(odo._steps), list(odo.poses), set(odo.superseded)


def _restore(odo: PlaneOdometry, epochs: list[KeptEpoch], saved: tuple) -> None:
    """Undo a round of :func:`redeskew_start` (:func:`_saved`)."""
    planes, results, steps, poses, superseded = saved
    for epoch, (p, plane_set, twist) in zip(epochs, planes, strict=True):
        odo._set_planes(epoch, p, twist, plane_set)
    odo.results[:], odo._steps[:], odo.poses[:] = results, steps, poses
    odo.superseded.clear()
    odo.superseded.update(superseded)


def _mean(odo: PlaneOdometry, steps: list[int]) -> np.ndarray | None:
    """(2,) the weighed mean of the own x, y velocities of ``steps`` as they are now; None
    when one of them is no longer measured."""
    own = [_own_velocity(odo, odo.results[k]) for k in steps]  # type: ignore[arg-type]
    if any(o is None for o in own):
        return None
    information = sum(o[1] for o in own if o is not None)
    weighed = sum(o[1] @ o[0] for o in own if o is not None)
    return np.linalg.solve(information, weighed)


def _own_velocity(odo: PlaneOdometry, result: RelativePose) -> tuple[np.ndarray, np.ndarray] | None:
    """The own x, y velocity (2,) of an OK step into the previous epoch, m/s, and its
    information (2, 2); None for other steps or without a usable covariance."""
    if result.status is not Status.OK or result.prev != result.curr - 1:
        return None
    dt = odo.times[result.curr] - odo.times[result.prev]
    C = result.covariance
    if dt <= 0 or C is None or not np.all(np.isfinite(C[3:5, 3:5])):
        return None
    cov = C[3:5, 3:5] / dt**2
    if np.linalg.det(cov) <= 0:
        return None
    return se3_log(result.T_prev_curr)[3:5] / dt, np.linalg.inv(cov)


def epoch_twist(
    odo: PlaneOdometry, k: int, velocity: np.ndarray, epoch: KeptEpoch | None = None
) -> np.ndarray:
    """(6,) the twist to deskew epoch ``k`` of the start with: the x, y velocity
    ``velocity`` (2,), the vertical velocity of the step into it (out of it for the
    first), and the angular rate of that step (``start_redeskew_rate: step``) or the one
    ``epoch`` was last extracted with (``kept``; the step's where it was not deskewed)."""
    j = max(k, 1)
    dt = odo.times[j] - odo.times[j - 1]
    own = se3_log(odo._steps[j]) / dt if dt > 0 else np.zeros(6)
    rate = own[:3]
    if odo.config.odometry.start_redeskew_rate == "kept" and epoch is not None:
        rate = rate if epoch.twist is None else np.asarray(epoch.twist, dtype=float)[:3]
    return np.r_[rate, velocity, own[5]]


def rotation_agrees(old: RelativePose, new: RelativePose) -> bool:
    """Whether ``new``'s rotation is ``old``'s within the sum of their covariances (chi-
    square 95 %, 3 DoF; without both covariances: not judged, agrees)."""
    if old.covariance is None or new.covariance is None:
        return True
    d = Rotation.from_matrix(old.T_prev_curr[:3, :3].T @ new.T_prev_curr[:3, :3]).as_rotvec()
    S = old.covariance[:3, :3] + new.covariance[:3, :3]
    if not np.all(np.isfinite(S)) or np.linalg.det(S) <= 0:
        return True
    return float(d @ np.linalg.solve(S, d)) <= CHI2_95_3


def redeskew_start(
    odo: PlaneOdometry, epochs: list[KeptEpoch], velocity: np.ndarray, last: int,
    originals: dict[int, RelativePose | None],
) -> bool:  # fmt: skip
    """Extract ``epochs`` (0 .. ``last``) of ``odo`` again with the mean ``velocity`` (2,),
    estimate their steps again (kept by their status and :func:`rotation_agrees` against
    the step as first estimated, ``originals``), and chain the poses again (module
    docstring). Returns whether every step estimated again was kept."""
    sigma = odo._twist_sigma.predicted()
    every = True
    known = {e.index: e for e in epochs}
    twists = {k: epoch_twist(odo, k, velocity, known.get(k)) for k in range(last + 1)}
    was: set[int] = set()
    for epoch in epochs:
        if epoch.scan is None or not time_spread(epoch.scan):
            continue
        planes, used = odo._extract(epoch.scan, twists[epoch.index], prior=sigma)
        if len(planes) < max(2.0, 0.5 * len(epoch.planes)):
            continue  # far fewer planes (as the policy judges an extraction): kept as it was
        was.add(epoch.index)
        odo._set_planes(epoch, planes, used)
    for k in range(1, last + 1):
        old = odo.results[k]
        if old is None or not ({old.prev, k} & was):
            continue
        new = _solved(odo, old, twists[k], known.get(k))
        first = originals.get(k) or old
        moved = (
            odo.config.odometry.start_redeskew_translation_guard
            and new is not None
            and not velocity_agrees(first, new, odo.times[k] - odo.times[first.prev])
        )
        if (
            new is None
            or new.status.rank < first.status.rank
            or not rotation_agrees(first, new)
            or moved
        ):
            odo.superseded.add(k)
            every = False
            continue
        odo.superseded.discard(k)
        commit_step(odo, k, new)
    rechain_poses(odo)
    return every
