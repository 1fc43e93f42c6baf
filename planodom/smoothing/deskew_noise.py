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

``Cov(dxi)`` is estimated from the run's delta = 1 relative poses as they arrive (a
streaming estimate, the same for batch and fixed-lag smoothing): per component the
robust variance (1.4826 MAD squared) of consecutive differences, less the variance the
odometry's own covariances account for (each difference holds two independent
estimates), never below zero. Nothing here is fitted to a world: the term is the
measured non-constancy of the motion, and it vanishes for a constant twist or a scan
acquired at one instant.
"""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.spatial.transform import Rotation

from planodom.odometry.relative import RelativePose

#: Differences of consecutive motions needed before the term is estimated.
MIN_DIFFERENCES = 5
#: 1.4826 MAD is a normal distribution's standard deviation.
MAD_TO_SIGMA = 1.4826
#: ``E[(t / dt)^2]`` for times spread uniformly over the epoch from its reference time.
TIME_SPREAD = 1.0 / 3.0


class DeskewNoise:
    """Running estimate of the covariance (6, 6) of an epoch's deskewing perturbation.

    Its tangent is (rotation vector (rad), translation (m)), body frame. Feed it every
    measured delta = 1 relative pose (:meth:`add`, any order of epochs); read
    :meth:`pose_covariance`.
    """

    def __init__(self) -> None:
        self._steps: dict[int, tuple[np.ndarray, np.ndarray]] = {}  # curr -> motion, noise var
        self._cached: np.ndarray | None = None
        self._relative: dict[int, np.ndarray] = {}  # delta -> (5, 5)
        self._refreshed_at = 0

    def add(self, rel: RelativePose) -> None:
        """Record a delta = 1 relative pose with its translation measured (others ignored)."""
        if rel.delta != 1 or not rel.translation_observed or rel.covariance is None:
            return
        cov = np.asarray(rel.covariance, dtype=float).reshape(5, 5)
        if not np.all(np.isfinite(cov)):
            return
        T = np.asarray(rel.T_prev_curr, dtype=float)
        motion = np.concatenate([Rotation.from_matrix(T[:3, :3]).as_rotvec(), T[:3, 3]])
        # (roll, pitch, yaw) increments are the rotation vector's to first order at the
        # small roll and pitch of one epoch; z's variance when it was measured, else none.
        sz2 = rel.sigma_z**2 if rel.z_observed and np.isfinite(rel.sigma_z) else 0.0
        noise = np.concatenate([np.diag(cov)[:3], np.diag(cov)[3:], [sz2]])
        self._steps[rel.curr] = (motion, noise)

    def _refresh(self) -> None:
        """Drop the cached estimates once the steps grew by a tenth since they were made
        (the estimate is a median over all steps: refreshing at every epoch would cost
        the square of the run's length)."""
        n = len(self._steps)
        if n >= max(self._refreshed_at + 1, 1.1 * self._refreshed_at):
            self._cached, self._relative, self._refreshed_at = None, {}, n

    def _robust_variance(self, weights: tuple[int, ...]) -> np.ndarray:
        """(6,) variance of ``sum_i weights[i] motion_{k+i}`` over every run of consecutive
        epochs (robust, less the odometry's share), zeros with too few of them."""
        w = np.asarray(weights, dtype=float)[:, None]
        values, noise = [], []
        for k in self._steps:
            run = [self._steps[k + i] for i in range(len(weights)) if k + i in self._steps]
            if len(run) == len(weights):
                values.append((w * np.array([r[0] for r in run])).sum(axis=0))
                noise.append((w * w * np.array([r[1] for r in run])).sum(axis=0))
        if len(values) < MIN_DIFFERENCES:
            return np.zeros(6)
        d = np.array(values)
        mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0)
        return np.maximum((MAD_TO_SIGMA * mad) ** 2 - np.median(np.array(noise), axis=0), 0.0)

    def pose_covariance(self) -> np.ndarray:
        """(6, 6) diagonal covariance of an epoch's deskewing perturbation, ``Cov(dxi) / 3``
        (zeros until ``MIN_DIFFERENCES`` consecutive differences were seen)."""
        self._refresh()
        if self._cached is None:
            self._cached = np.diag(TIME_SPREAD * self._robust_variance((-1, 1)))
        return self._cached

    def relative_covariance(self, delta: int) -> np.ndarray:
        """(5, 5) covariance of the 5-DoF error (rotation vector, x, y) of a relative pose
        over ``delta`` epochs from the deskewing of its two epochs: the difference of their
        perturbations, ``(dxi_k - dxi_{k-delta}) / sqrt(3)``. Consecutive changes of motion
        are strongly correlated (sway is slow against the epoch rate), so this is far below
        twice :meth:`pose_covariance` (which assumes them independent)."""
        self._refresh()
        if delta not in self._relative:
            weights = [0] * (delta + 2)
            weights[0], weights[1], weights[-2], weights[-1] = 1, -1, -1, 1
            if delta == 1:
                weights = [1, -2, 1]
            var = TIME_SPREAD * self._robust_variance(tuple(weights))
            self._relative[delta] = np.diag(var[:5])
        return self._relative[delta]


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
