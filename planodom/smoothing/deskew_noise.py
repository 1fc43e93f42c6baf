"""The deskewing error's share of the factors' noise, from the run's own changes of motion.

An epoch's points are acquired over its time span and deskewed with a constant twist:
the epoch's own relative pose from the epoch before (the deskewing policy,
:mod:`planodom.odometry.deskew`), i.e. the mean twist of the *previous* interval, while the
points were acquired during the *next* one. The twist they were deskewed with is off by
about the change of the twist from one interval to the next, ``dxi_k = xi_{k+1} - xi_k``
(body frame, per epoch: a relative pose's rotation vector and translation, so the epoch's
duration cancels), and a point acquired ``t`` after the reference time (epoch start)
moves by ``(t / dt) dxi_k``. A plane fitted to the epoch's points is then displaced by
about that rigid perturbation at the points' times: with times spread uniformly over the
epoch, ``E[(t / dt)^2] = 1 / 3``, so the epoch's frame is perturbed with covariance
``Cov(dxi) / 3``. (A reference time in the middle of the epoch would give 1 / 12: one
third is the bound.) The fit's covariance misses this (it sees only the range noise):
on the procedural worlds with suspension sway (roll and pitch rates changing by
0.02-0.04 rad/s from one 0.2 s epoch to the next on a 2D rig) the ground planes' normals
were 1 mrad off against fit sigmas of 0.03 mrad, and the relative poses' roll 18 of its
sigmas (``experiments.consistency``).

``Cov(dxi_k)`` is estimated from the run's delta = 1 relative poses, locally: the mean
square of the changes at the epochs within ``half_window`` of k, per component. Local,
not one figure per run: the changes are sparse and heavy-tailed (turns, bumps), and on a
lidar world the planes' NEES per epoch followed the epoch's change of yaw rate
(correlation 0.76 of log NEES); a run-wide median missed the turns. The measured changes
also hold the odometry's own noise (twice per change); it is not subtracted, because the
odometry's declared covariances are not good enough to subtract (measured on the
procedural worlds: the plane-map odometry's roll sigma 25 times its error on a lidar, the
2D rig's ten times too small): the term errs on the cautious side, by two thirds of the
odometry's error variance for a plane and 4 / 3 to 2 times it for a relative pose.
Nothing here is fitted to a world: it is the measured non-constancy of the motion, and
it vanishes for a constant twist or a scan acquired at one instant. In a fixed-lag
smoother the changes after the newest epoch are not known yet: the window holds the ones
that are. The half window (2 epochs) only averages a few changes; it is no tuned figure.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from planodom.odometry.relative import RelativePose
from planodom_factors.pose5 import pose5_error

if TYPE_CHECKING:
    from planodom.smoothing.graph import GraphUpdate

#: ``E[(t / dt)^2]`` for times spread uniformly over the epoch from its reference time.
TIME_SPREAD = 1.0 / 3.0


class DeskewNoise:
    """Local estimates of the covariance of an epoch's deskewing perturbation.

    Its tangent is (rotation vector (rad), translation (m)), body frame. Feed it every
    measured delta = 1 relative pose (:meth:`add`, any order of epochs); read
    :meth:`pose_covariance` (a plane's epoch) and :meth:`relative_covariance`.

    Args:
        half_window: epochs on each side of an epoch whose changes of motion are averaged.
        net: less the variance the odometry's covariances declare for the changes.
        plane_rotation: whether :meth:`plane_pose_covariance` holds the perturbation's
            rotation (the planes' normals) or its translation only (their offsets).
        shared_frame: the perturbation is one nuisance frame per epoch in the graph
            (:func:`deskew_frame_factor`), none of it in the plane factors' covariances.
        plane_jacobian: each plane factor's covariance holds the epoch's change of motion
            through the plane's own ``deskew_jacobian`` (:meth:`plane_motion_change`)
            instead of a rigid perturbation of the epoch's frame.
    """

    def __init__(
        self,
        half_window: int = 2,
        net: bool = False,
        plane_rotation: bool = True,
        shared_frame: bool = False,
        plane_jacobian: bool = False,
    ) -> None:
        self.half_window = half_window
        self.net = net
        self.plane_rotation = plane_rotation
        self.shared_frame = shared_frame
        self.plane_jacobian = plane_jacobian
        self.frames: set[int] = set()  # epochs given a deskewed frame (:meth:`add_frame`)
        # epochs whose points were spread in time / taken at one instant, as the odometry
        # saw them (RelativePose.time_spread): an instant has no deskewing error
        self._spread: set[int] = set()
        self._instant: set[int] = set()
        self._steps: dict[int, np.ndarray] = {}  # curr -> (12,) motion into it, its variance
        self._z_observed: dict[int, bool] = {}  # curr -> whether its step's z was measured
        self._cache: dict[tuple[int, int], np.ndarray] = {}  # (last step, delta) -> cov
        self._max_delta = 0
        # weights -> (steps when computed, run-wide mean square): refreshed as the run grows
        # by a tenth (recomputing it at every epoch would cost the square of the run).
        self._run_wide: dict[tuple[int, ...], tuple[int, np.ndarray]] = {}

    def add(self, rel: RelativePose) -> None:
        """Record a delta = 1 relative pose with its translation measured (others ignored;
        any relative pose tells whether its epoch ``curr`` was spread in time)."""
        if rel.time_spread is not None:
            (self._spread if rel.time_spread else self._instant).add(rel.curr)
        if rel.delta != 1 or not rel.translation_observed:
            return
        T = np.asarray(rel.T_prev_curr, dtype=float)
        var = np.zeros(6)
        if rel.covariance is not None and np.all(np.isfinite(rel.covariance)):
            # (roll, pitch, yaw) increments are the rotation vector's to first order at
            # the small roll and pitch of one epoch; z's when it was measured.
            var[:5] = np.diag(np.asarray(rel.covariance, dtype=float).reshape(5, 5))
            var[5] = rel.sigma_z**2 if rel.z_observed and np.isfinite(rel.sigma_z) else 0.0
        rotvec = Rotation.from_matrix(T[:3, :3]).as_rotvec()
        motion = np.concatenate([rotvec, T[:3, 3], var])
        known = self._steps.get(rel.curr)
        if known is not None and np.array_equal(known, motion):
            return  # the same step again (batch: fed before the graph is built, then again)
        self._steps[rel.curr] = motion
        self._z_observed[rel.curr] = rel.z_observed
        # Estimates whose windows reach this step are stale (keyed by the last step their
        # window reaches, which lies at most 2 half_window + 1 + delta after its first).
        reach = 2 * self.half_window + 2 + self._max_delta
        for last in range(rel.curr, rel.curr + reach + 1):
            for delta in range(self._max_delta + 1):
                self._cache.pop((last, delta), None)

    def _mean_square(self, weights: tuple[int, ...], anchors: Iterable[int]) -> np.ndarray | None:
        """(6,) mean over ``anchors`` ``a`` of the square of ``sum_i weights[i]
        motion_{a+i}``, over those whose steps are all known (None: none is); with ``net``
        less the variance the odometry's covariances declare for it, at least 0."""
        w = np.asarray(weights, dtype=float)[:, None]
        total, count = np.zeros(6), 0
        for a in anchors:
            run = [self._steps[a + i] for i in range(len(weights)) if a + i in self._steps]
            if len(run) == len(weights):
                steps = np.array(run)
                total += (w * steps[:, :6]).sum(axis=0) ** 2
                total -= self.net * (w * w * steps[:, 6:]).sum(axis=0)
                count += 1
        return np.maximum(total / count, 0.0) if count else None

    def _local_variance(self, weights: tuple[int, ...], anchor: int) -> np.ndarray:
        """(6,) :meth:`_mean_square` over the anchors within ``half_window`` of ``anchor``;
        where the odometry measured none of them (a gap of unresolved epochs), the run's
        (so far): nothing is known there but what the run's motion does elsewhere."""
        h = self.half_window
        local = self._mean_square(weights, range(anchor - h, anchor + h + 1))
        if local is not None:
            return local
        n = len(self._steps)
        if weights not in self._run_wide or self._run_wide[weights][0] * 1.1 < n:
            whole = self._mean_square(weights, list(self._steps))
            self._run_wide[weights] = (n, np.zeros(6) if whole is None else whole)
        return self._run_wide[weights][1]

    def pose_covariance(self, epoch: int) -> np.ndarray:
        """(6, 6) diagonal covariance of epoch ``epoch``'s deskewing perturbation,
        ``E[dxi dxi^T] / 3`` with ``dxi = motion_{k+1} - motion_k`` (the motion during its
        acquisition less the one it was deskewed with); zeros without known changes."""
        if self.instant(epoch):
            return np.zeros((6, 6))
        key = (epoch + self.half_window + 1, 0)  # the last step its window can reach
        if key not in self._cache:
            self._cache[key] = np.diag(TIME_SPREAD * self._local_variance((-1, 1), epoch))
        return self._cache[key]

    def instant(self, epoch: int) -> bool:
        """Whether epoch ``epoch``'s points were taken at one instant (no deskewing error):
        as the odometry saw it, or, where it is not known (the first epoch), as every
        epoch known was (a run of snapshot scans)."""
        if epoch in self._instant or epoch in self._spread:
            return epoch in self._instant
        return bool(self._instant) and not self._spread

    def plane_pose_covariance(self, epoch: int) -> np.ndarray:
        """(6, 6) the share of :meth:`pose_covariance` given to epoch ``epoch``'s plane
        factors: all of it, or without ``plane_rotation`` its translation block only (the
        rotation block zero). The rotation part is one error shared by all the epoch's
        planes; inflating every normal independently by it down-weights their geometry
        (measured: the ATE rose on the built-in scenes, ``config.smoothing.deskew_noise``),
        while the relative-pose factors keep it (their difference of two epochs')."""
        cov = self.pose_covariance(epoch)
        if self.shared_frame or self.plane_jacobian:
            return np.zeros_like(cov)  # in the graph's deskewed frames instead
        if self.plane_rotation:
            return cov
        out = np.zeros_like(cov)
        out[3:, 3:] = cov[3:, 3:]
        return out

    def plane_motion_change(self, epoch: int) -> np.ndarray | None:
        """(6, 6) diagonal covariance of epoch ``epoch``'s change of motion ``E[dxi dxi^T]``
        (the twist its points were deskewed with is off by about it per epoch span) for its
        plane factors' own Jacobians with ``plane_jacobian``, else None.

        Measured at the true poses of procedural world 16 (2D rig, 6 mm): a plane's error
        from deskewing with the previous interval's twist followed its Jacobian times the
        twist's error with correlation 0.93-0.998 and slope 1.0-1.06 (n1, n2, d), its NEES
        (3 DoF) fell from 315 (the fit's covariance) to 2.0 with this term; the fit's own
        covariance was consistent (NEES 3.0) for exactly deskewed points."""
        if not self.plane_jacobian:
            return None
        if self.instant(epoch):
            return np.zeros((6, 6))
        cov = self.pose_covariance(epoch) / TIME_SPREAD
        if not self._z_observed.get(epoch, True):
            cov = cov.copy()
            cov[5, 5] = max(cov[5, 5], self._vertical_mean_square())
        return cov

    def _vertical_mean_square(self) -> float:
        """Mean square of the steps' vertical motion where it was measured (m^2; of all
        steps when none was): the error of a vertical velocity the odometry did not
        measure but deskewed with (held or bridged), whose changes say nothing of it.

        World 2 (2D rig, 6 mm, 300 epochs): z measured in a quarter of the steps, the
        others' z off by 19 mm rms against 13.5 mm of true vertical motion per step, the
        ground's offset off by 8-13 mm at sigmas of 0.3 mm."""
        zs = [m[5] for k, m in self._steps.items() if self._z_observed.get(k, False)]
        if not zs:
            zs = [m[5] for m in self._steps.values()]
        return float(np.mean(np.square(zs))) if zs else 0.0

    def add_frame(
        self, epoch: int, pose_key: int, frame_key: int, T: np.ndarray, update: GraphUpdate
    ) -> None:
        """With ``shared_frame``, epoch ``epoch``'s deskewed frame (Pose3 ``frame_key``, initial
        guess ``T`` (4, 4)) and its :func:`deskew_frame_factor` into ``update`` (a
        ``graph.GraphUpdate``: ``factors``, ``values``, ``timestamps``), unless the epoch's
        perturbation is not known yet (then its planes see the pose)."""
        tie = deskew_frame_factor(pose_key, frame_key, self.pose_covariance(epoch))
        if not self.shared_frame or tie is None:
            return
        update.factors.add(tie)
        update.values.insert(frame_key, gtsam.Pose3(T))
        update.timestamps[frame_key] = float(epoch)
        self.frames.add(epoch)

    def relative_covariance(self, prev: int, curr: int) -> np.ndarray:
        """(5, 5) covariance of the 5-DoF error (rotation vector, x, y) of the relative
        pose from ``prev`` to ``curr`` due to the deskewing of its two epochs: the
        difference of their perturbations, ``(dxi_curr - dxi_prev) / sqrt(3)``.
        Consecutive changes of motion are strongly correlated (sway is slow against the
        epoch rate), so this is far below the sum of the two epochs' covariances."""
        delta = curr - prev
        if self.instant(prev) and self.instant(curr):
            return np.zeros((5, 5))
        self._max_delta = max(self._max_delta, delta)
        key = (curr + self.half_window + 1, delta)
        if key not in self._cache:
            weights = [0] * (delta + 2)
            weights[0], weights[1] = 1, -1
            weights[-2] -= 1
            weights[-1] += 1
            var = TIME_SPREAD * self._local_variance(tuple(weights), prev)
            self._cache[key] = np.diag(var[:5])
        return self._cache[key]

    def loop_covariance(self, old: int, curr: int, T_old_curr: np.ndarray) -> np.ndarray:
        """(5, 5) covariance of a loop factor's 5-DoF error (rotation vector, x, y; its
        tangent, :func:`planodom_factors.pose5.pose5_error`) due to the deskewing of its two
        epochs ``old`` and ``curr`` (relative pose ``T_old_curr`` (4, 4)): each epoch's
        :meth:`pose_covariance` through the factor's Jacobian. Independent, unlike
        :meth:`relative_covariance`'s neighbours: a loop's epochs lie far apart in time,
        and the sway's changes of motion are not correlated over a lap."""
        T = np.asarray(T_old_curr, dtype=float)
        _, H_old, H_curr = pose5_error(T, np.eye(4), T, jacobians=True)
        assert H_old is not None and H_curr is not None
        P_old, P_curr = self.pose_covariance(old), self.pose_covariance(curr)
        return H_old @ P_old @ H_old.T + H_curr @ P_curr @ H_curr.T


def between_keys(
    model: DeskewNoise | None,
    prev: int,
    curr: int,
    pose: Callable[[int], int],
    frame: Callable[[int], int],
) -> tuple[tuple[int, int], np.ndarray | None]:
    """The keys and the deskewing covariance (5, 5) of a relative pose's between factor:
    between the two epochs' deskewed frames, without it, where both have one (the
    relative pose was measured from their planes: its deskewing error is the frames'
    own); else between the poses, with :meth:`DeskewNoise.relative_covariance` (None
    without a model)."""
    if model is None:
        return (pose(prev), pose(curr)), None
    if prev in model.frames and curr in model.frames:
        return (frame(prev), frame(curr)), None
    return (pose(prev), pose(curr)), model.relative_covariance(prev, curr)


def deskew_from_config(mode: str) -> DeskewNoise | None:
    """The model ``smoothing.deskew_noise`` = ``mode`` selects (None for "none")."""
    if mode == "none":
        return None
    return DeskewNoise(
        net=mode.endswith("_net"),
        plane_rotation=mode != "twist_change_offsets",
        shared_frame=mode.startswith("twist_change_frame"),
        plane_jacobian=mode.startswith("twist_change_jacobian"),
    )


#: Sigma (rad, m) below which a component of a deskewed frame's factor is floored: a zero
#: would make its noise model singular; the stiffness of the first pose's gauge prior
#: (``smoothing.prior_sigma``): 1e-5 made a fixed-lag smoother's system indeterminate
#: (Cholesky and QR) on a synthetic sequence with "..._net" zeroing components.
FRAME_SIGMA_FLOOR = 1e-4


def deskew_frame_factor(
    pose_key: int, frame_key: int, pose_cov: np.ndarray
) -> gtsam.NonlinearFactor | None:
    """The factor tying an epoch's deskewed frame ``frame_key`` (Pose3, the frame its
    planes were effectively measured in) to its pose ``pose_key``: ``Log(X^-1 F)`` ~ N(0,
    ``pose_cov`` (6, 6), the epoch's deskewing perturbation, rotation then translation).
    One perturbation shared by all the epoch's planes, as the deskewing error is: its
    planes' factors on ``F`` are then correlated through it, where inflating each plane's
    covariance by its share treats them as independent (and down-weights them all).
    None when the perturbation is not known (all zero): the planes then see the pose."""
    var = np.diag(np.asarray(pose_cov, dtype=float))
    if not np.any(var > 0.0):
        return None
    sigmas = np.sqrt(np.maximum(var, FRAME_SIGMA_FLOOR**2))
    noise = gtsam.noiseModel.Diagonal.Sigmas(sigmas)
    return gtsam.BetweenFactorPose3(pose_key, frame_key, gtsam.Pose3(), noise)


def plane_deskew_covariance(normal: np.ndarray, pose_cov: np.ndarray) -> np.ndarray:
    """(3, 3) covariance, in ``gtsam.OrientedPlane3`` tangent coordinates (Unit3 basis of
    ``normal`` (2), offset (1)), of a plane (3,) ``normal`` whose frame is perturbed by
    ``(w, v)`` with covariance ``pose_cov`` (6, 6): to first order the plane's points move
    by ``w x p + v``, so ``dn = w x n`` and ``dd = -n . v``."""
    n = np.asarray(normal, dtype=float)
    B = np.asarray(gtsam.Unit3(n).basis())  # (3, 2)
    skew = np.array([[0.0, -n[2], n[1]], [n[2], 0.0, -n[0]], [-n[1], n[0], 0.0]])
    J = np.zeros((3, 6))
    J[:2, :3] = -B.T @ skew  # w x n = -[n]x w
    J[2, 3:] = -n
    return J @ pose_cov @ J.T
