"""Loop closure in fixed-lag smoothing: old landmarks re-enter the window from their marginals.

The fixed-lag smoother (:class:`planodom.smoothing.windowed.WindowedSmoother`) marginalises
a landmark (its ``L(j)`` and, anchored, ``A(j)``) once no epoch in the window has seen it.
The global map and the matching are those of batch loop closure
(:class:`planodom.smoothing.loops.LoopClosingBuilder`, the same candidates, bounds and
"tracked" verification), run at every ``loop_every_epochs``-th epoch (the keyframes) on the
smoother's estimates. What differs is the tie to a landmark that has left the window:

- when a landmark is about to leave (its last epoch is the window's oldest), its joint
  marginal information over its keys (``IncrementalFixedLagSmoother``'s iSAM2:
  ``jointMarginalInformation``) is kept, as a Gaussian factor at the linearisation point
  (:meth:`WindowedLoopBuilder.keep_marginal`);
- when a match ties an observation to a landmark that has left, the landmark re-enters
  the window under its old keys, at its last estimate, with that Gaussian as a
  ``gtsam.LinearContainerFactor`` (the prior gtsam's own marginalisation would have left
  on it, relinearised by the container), and the new observation is a robust plane factor
  on it (as in batch).

Why a prior from the marginal rather than the landmark's old factors: those factors hold
poses that have been marginalised too, so bringing them back would re-open the whole past;
the marginal is the landmark's information at the moment it left, in one small factor.
Its keys' joint marginal (anchor and plane together) is needed, not the plane's alone: an
anchored landmark is observed only as ``anchor * plane``, the anchor's gauge prior is
loose (1 m, 1 rad), and the plane's own marginal carries that gauge freedom.

Known approximation: the marginal is treated as independent of the window; its
correlation with the poses still in the window (through the marginalised past) is
dropped, and the landmark's observations informed the window once already (through the
marginalisation). Both are small where loop closure matters: the poses' drift since the
landmark left dominates the landmark's own uncertainty. There is no gate after the fact
(batch's :func:`planodom.smoothing.loop_records.gate_reidentifications`): the past is
fixed once marginalised; the verification and the robust kernel on the ties stand for it.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np

from planodom.config import PlanodomConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.graph import GraphUpdate
from planodom.smoothing.loops import WALL_SIN, LoopClosingBuilder


class WindowedLoopBuilder(LoopClosingBuilder):
    """:class:`LoopClosingBuilder` for the fixed-lag smoother (see the module docstring).

    Attributes:
        marginals: landmark id -> its keys' marginal (a ``LinearContainerFactor``) kept when
            it last left the window, and its linearisation point.
        reentered: landmarks brought back into the window by a tie (count).
    """

    def __init__(self, config: PlanodomConfig, T_world_first: np.ndarray | None = None) -> None:
        super().__init__(config, T_world_first)
        self.marginals: dict[int, tuple[gtsam.LinearContainerFactor, gtsam.Values]] = {}
        self.reentered = 0
        self._min_epoch = 0

    def add_epoch(
        self, planes: Sequence[Plane], relatives: Sequence[RelativePose] = (), min_epoch: int = 0
    ) -> GraphUpdate:
        """:meth:`LoopClosingBuilder.add_epoch` with the window's oldest epoch noted."""
        self._min_epoch = min_epoch
        return super().add_epoch(planes, relatives, min_epoch)

    def leaving(self, oldest: int) -> list[int]:
        """Wall landmarks whose keys leave the window at the next update unless seen
        again: only walls are ever tied (:data:`planodom.smoothing.loops.WALL_SIN`), and
        each kept marginal costs an iSAM2 joint marginal (most of the time on lidar)."""
        return [
            j
            for j, lm in self.landmarks.items()
            if lm.last_epoch == oldest and abs(lm.plane_world[2]) <= WALL_SIN
        ]

    def keep_marginal(self, j: int, isam: gtsam.ISAM2) -> None:
        """Keep landmark j's joint marginal over its keys from the smoother's ``isam``:
        information ``I`` (n, n) about the linearisation point's tangent, mean at iSAM2's
        delta, as the factor ``0.5 |R (x - delta)|^2`` with ``R^T R = I``."""
        lm = self.landmarks[j]
        keys = [lm.key] if lm.anchor_key is None else [lm.anchor_key, lm.key]
        try:
            info = np.asarray(isam.jointMarginalInformation(keys).fullMatrix())
        except RuntimeError:  # indeterminant: keep the previous marginal, if any
            return
        delta, point = isam.getDelta(), gtsam.Values()
        linearization = isam.getLinearizationPoint()
        mean = np.concatenate([delta.at(key) for key in keys])
        try:
            R = np.linalg.cholesky(0.5 * (info + info.T)).T
        except np.linalg.LinAlgError:
            return
        blocks, start = [], 0
        for key in keys:
            dim = delta.at(key).size
            blocks.append((key, R[:, start : start + dim]))
            point.insert(key, linearization.atPose3(key) if key == lm.anchor_key else
                         linearization.atOrientedPlane3(key))  # fmt: skip
            start += dim
        unit = gtsam.noiseModel.Unit.Create(len(mean))
        if len(blocks) == 1:
            factor = gtsam.JacobianFactor(blocks[0][0], blocks[0][1], R @ mean, unit)
        else:
            (k1, A1), (k2, A2) = blocks
            factor = gtsam.JacobianFactor(k1, A1, k2, A2, R @ mean, unit)
        self.marginals[j] = (gtsam.LinearContainerFactor(factor, point), point)

    def _tie(self, update: GraphUpdate, j: int, i: int, predicted_normal: np.ndarray) -> None:
        """:meth:`LoopClosingBuilder._tie`, bringing landmark j back into the window first
        when it has left it (its marginal as prior, its last estimate as value)."""
        lm = self.landmarks[j]
        keys = [lm.key] if lm.anchor_key is None else [lm.anchor_key, lm.key]
        # Keys stamped ``min_epoch - 1`` are still in the smoother: its update of this
        # epoch would marginalise them, and the tie's new stamp keeps them instead.
        if lm.last_epoch < self._min_epoch - 1 and not update.values.exists(lm.key):
            kept = self.marginals.get(j)
            if kept is None:  # never captured (left before any update): no prior
                return
            marginal, point = kept
            update.factors.add(marginal)
            for key in keys:
                if key == lm.anchor_key:
                    update.values.insert(key, point.atPose3(key))
                else:
                    update.values.insert(key, point.atOrientedPlane3(key))
            self.reentered += 1
        super()._tie(update, j, i, predicted_normal)
        for key in keys:
            update.timestamps[key] = float(update.epoch)

    def forget(self, before: int) -> None:
        """Keep every epoch's planes (the map's extents and matches read the landmarks'
        last observations); only the bookkeeping of the window's factors is dropped."""
        for key in [key for key in self._factor_landmark if key[0] < before]:
            del self._factor_landmark[key]
