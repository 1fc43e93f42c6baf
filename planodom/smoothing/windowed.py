"""Windowed smoothing: a fixed-lag smoother over the last W epochs, run epoch by epoch.

Keys carry their epoch as timestamp; the smoother marginalises keys older than
``W - 1`` epochs. Plane landmarks (and their anchors) are re-stamped whenever they are
observed, so a plane stays in the window while it is seen; with ``delta_max < W`` every
association reaches a pose and a landmark that are still in the window.
"""

from __future__ import annotations

import time
from collections.abc import Sequence

import gtsam
import numpy as np

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import PlanodomError
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.batch import (
    SmoothingResult,
    full_config,
    group_by_epoch,
    smoothing_config,
)
from planodom.smoothing.graph import A, F, GraphBuilder, L, X
from planodom.smoothing.inputs import check_epochs
from planodom.smoothing.jacobian_marginal import jacobian_marginal
from planodom.smoothing.windowed_loops import WindowedLoopBuilder


def relinearize_thresholds(config: SmoothingConfig) -> float | gtsam.ISAM2ThresholdMap:
    """iSAM2's relinearisation threshold: ``relinearize_threshold`` for every variable, or
    per kind of key (poses, anchors, deskewed frames; plane landmarks) when
    ``relinearize_threshold_planes`` is set.

    A plane landmark is known far better than the 0.01 (rad, m) that suits a pose (a
    corridor wall's normal to ~1e-4 rad, its offset to ~1 mm): under 0.01 its
    linearisation point stayed 3-4 mrad and 3-5 mm off the estimate through a corridor
    (world 32 at 2 cm, epochs 69-114), whose walls observe nothing along the travel, and
    that linearisation error alone moved the window 6-7 m along it (measured against the
    batch from the chained odometry: with the planes at 1e-5 and no marginalisation the
    two agree). With marginalisation the threshold reaches only the landmarks no marginal
    holds yet: gtsam's fixed-lag smoother keeps every variable of a marginal's separator
    at its linearisation point until it leaves (iSAM2's fixed variables, first-estimate
    Jacobians; on world 32 at 2 cm, 5-7 of the window's 7-9 landmarks), so a wall is
    relinearised only until its first observer leaves. Mixed, off by default
    (docs/RESULTS.md, LAGWALL; relinearising the held variables too, the marginals'
    residuals moved to first order, measured worse or unstable: FEJLAG).
    """
    if config.relinearize_threshold_planes is None:
        return config.relinearize_threshold
    thresholds = gtsam.ISAM2ThresholdMap()
    for key, dim in ((X, 6), (A, 6), (F, 6)):
        thresholds.insert(
            (chr(gtsam.Symbol(key(0)).chr()), np.full(dim, config.relinearize_threshold))
        )
    thresholds.insert(
        (chr(gtsam.Symbol(L(0)).chr()), np.full(3, config.relinearize_threshold_planes))
    )
    return thresholds


class WindowedSmoother:
    """Online fixed-lag smoothing (gtsam.IncrementalFixedLagSmoother or BatchFixedLagSmoother).

    Call :meth:`add_epoch` once per epoch; :attr:`poses` holds, per epoch, the latest
    estimate while it was in the window (the lagged, smoothed output) and
    :attr:`online_poses` the estimate when it was the newest epoch. With
    ``compute_covariances`` and the incremental backend, :attr:`covariances` holds each
    pose's marginal covariance (6, 6) at the same moment as :attr:`poses`: the last
    update before it leaves the window (``IncrementalFixedLagSmoother.marginalCovariance``),
    in gtsam's Pose3 tangent ``[rot (rad), trans (m)]``, body frame. Unlike the batch
    marginals they include the uncertainty of the first pose's prior (``prior_sigma``)
    and of the marginalised past. The batch backend has no marginals (None).
    """

    def __init__(
        self,
        config: SmoothingConfig | PlanodomConfig | None = None,
        T_world_first: np.ndarray | None = None,
    ) -> None:
        self.config = smoothing_config(config)
        self.builder = GraphBuilder(self.config, T_world_first)
        self.loops: WindowedLoopBuilder | None = None
        if self.config.windowed_loop_closure:
            full = full_config(config).updated(
                {
                    "smoothing.loop_every_epochs": self.config.windowed_loop_every_epochs,
                    "smoothing.loop_closure": True,
                },
                source="fixed-lag loop closure",
            )
            self.builder = self.loops = WindowedLoopBuilder(full, T_world_first)
        self.lag = float(self.config.window - 1)
        self.smoother: gtsam.FixedLagSmoother
        #: iSAM2's factorisation now ("auto" starts with Cholesky, see the config).
        self.factorization = "QR" if self.config.windowed_factorization == "QR" else "CHOLESKY"
        if self.config.windowed_backend == "incremental":
            self.smoother = gtsam.IncrementalFixedLagSmoother(self.lag, self._isam_params())
        else:
            lm = gtsam.LevenbergMarquardtParams()
            lm.setMaxIterations(self.config.max_iterations)
            lm.setLinearSolverType("MULTIFRONTAL_QR")  # see _isam_params
            self.smoother = gtsam.BatchFixedLagSmoother(self.lag, lm)
        self.poses: list[np.ndarray] = []
        self.online_poses: list[np.ndarray] = []
        self.initial_poses: list[np.ndarray] = []
        self.covariances: list[np.ndarray] = []
        self.runtime_s = 0.0
        self.qr_fallbacks = 0
        #: the epochs at which Cholesky failed and the smoother went on with QR.
        self.qr_fallback_epochs: list[int] = []
        #: (epoch, -w_min / w_max) per QR fallback whose held marginals were indefinite
        #: beyond round-off of their own scale (the worst of them; their unobserved
        #: directions dropped, :mod:`.jacobian_marginal`): reported, not an error.
        self.indefinite_marginals: list[tuple[int, float]] = []

    def _isam_params(self) -> gtsam.ISAM2Params:
        """iSAM2's parameters, factorisation :attr:`factorization`.

        QR where Cholesky fails: the window's absolute position is only as certain as the
        marginalised past (weak after long unresolved stretches) while plane factors are
        stiff (and robust kernels weigh outlying ones down by orders of magnitude);
        Cholesky squares that condition number and gives up. Elsewhere Cholesky is the
        same solution at a fraction of the time (measured on a 32-beam lidar lap, 50
        planes an epoch: 2.4 times faster, the same trajectory to 1 mm).
        """
        params = gtsam.ISAM2Params()
        params.setRelinearizeThreshold(relinearize_thresholds(self.config))
        params.relinearizeSkip = 1
        params.setFactorization(self.factorization)
        # Dogleg (a trust region) rather than Gauss-Newton bounds each step where a
        # window held only by fallback and rotation-only factors is nearly singular.
        params.setOptimizationParams(gtsam.ISAM2DoglegParams())
        return params

    def _fall_back_to_qr(self) -> None:
        """Rebuild the incremental smoother with QR from the failed one's state: its
        factors (the marginals of the past among them, and the update that failed, which
        iSAM2 took in before eliminating), linearisation point and key timestamps. The
        marginals, Hessians under Cholesky, are split into Jacobian factors first
        (:mod:`.jacobian_marginal`: QR's own conversion fails on their round-off); those
        indefinite beyond round-off of their own scale are recorded in
        :attr:`indefinite_marginals`."""
        old = self.smoother
        assert isinstance(old, gtsam.IncrementalFixedLagSmoother)
        held = old.getFactors()
        point = old.getLinearizationPoint()
        factors = gtsam.NonlinearFactorGraph()
        indefinite: list[float] = []
        for factor in (held.at(i) for i in range(held.size())):
            if isinstance(factor, gtsam.LinearContainerFactor) and not factor.isJacobian():
                factors.add(jacobian_marginal(factor, point, indefinite=indefinite))
            elif factor is not None:  # removed factors leave empty slots
                factors.add(factor)
        timestamps: dict[int, float] = dict(old.timestamps())
        self.factorization = "QR"
        self.smoother = gtsam.IncrementalFixedLagSmoother(self.lag, self._isam_params())
        self.smoother.update(factors, point, timestamps)  # type: ignore[arg-type]  # gtsam stub, as in add_epoch
        self.qr_fallbacks += 1
        self.qr_fallback_epochs.append(self.builder.n_epochs - 1)
        if indefinite:
            self.indefinite_marginals.append((self.builder.n_epochs - 1, max(indefinite)))

    @property
    def has_marginals(self) -> bool:
        """Whether :attr:`covariances` are computed (config and backend)."""
        return self.config.compute_covariances and isinstance(
            self.smoother, gtsam.IncrementalFixedLagSmoother
        )

    def _marginal(self, epoch: int) -> np.ndarray:
        """(6, 6) the window's marginal covariance of pose ``epoch`` (NaN if gtsam fails)."""
        try:
            return np.asarray(self.smoother.marginalCovariance(X(epoch)))  # type: ignore[attr-defined]
        except RuntimeError:
            return np.full((6, 6), np.nan)

    @property
    def n_epochs(self) -> int:
        """Epochs added so far."""
        return self.builder.n_epochs

    def add_epoch(
        self, planes: Sequence[Plane], relatives: Sequence[RelativePose] = ()
    ) -> np.ndarray:
        """Add the next epoch and update the window.

        Args:
            planes: the epoch's measured planes (base frame, normals towards the sensor).
            relatives: relative poses from earlier epochs to this one (delta <= delta_max).

        Returns:
            (4, 4) the current estimate of this epoch's ``T_world_base``.
        """
        start = time.perf_counter()
        k = self.builder.n_epochs
        oldest = max(0, k - (self.config.window - 1))
        update = self.builder.add_epoch(planes, relatives, min_epoch=oldest)
        self.initial_poses.append(self.builder.poses[k])
        try:
            try:
                self.smoother.update(update.factors, update.values, update.timestamps)  # type: ignore[arg-type]  # gtsam stub: Mapping[SupportsInt, ...] rejects dict[int, float]
            except RuntimeError:  # gtsam's IndeterminantLinearSystemException
                if self.factorization != "CHOLESKY":
                    raise
                self._fall_back_to_qr()
        except RuntimeError as exc:
            first = " ".join(str(exc).split()[:10])
            raise PlanodomError(
                f"fixed-lag smoother failed at epoch {k} ({first}); "
                "try smoothing.windowed_backend 'batch' or batch smoothing"
            ) from exc
        estimate = self.smoother.calculateEstimate()
        self.builder.update_estimates(estimate, since=oldest)
        self.builder.forget(oldest)
        if self.loops is not None:  # keep the marginals of the landmarks about to leave
            isam = self.smoother.getISAM2()  # type: ignore[attr-defined]
            for j in self.loops.leaving(oldest):
                self.loops.keep_marginal(j, isam)
        self.poses.append(self.builder.poses[k])
        for e in range(oldest, k + 1):
            self.poses[e] = self.builder.poses[e]
        self.online_poses.append(self.builder.poses[k])
        if self.has_marginals:  # the oldest pose leaves the window at the next update
            self.covariances.append(np.full((6, 6), np.nan))
            self.covariances[oldest] = self._marginal(oldest)
        self.runtime_s += time.perf_counter() - start
        return self.builder.poses[k]

    def result(self) -> SmoothingResult:
        """The smoothed trajectory so far (E, 4, 4), its marginal covariances (E, 6, 6)
        (see the class; the poses still in the window at their current estimate) and the
        graph's statistics."""
        covariances = None
        if self.has_marginals and self.covariances:
            k = self.n_epochs - 1
            for e in range(max(0, k - (self.config.window - 1)), k + 1):
                self.covariances[e] = self._marginal(e)
            covariances = np.stack(self.covariances)
        return SmoothingResult(
            poses=np.stack(self.poses),
            initial_poses=np.stack(self.initial_poses),
            covariances=covariances,
            landmarks=self.builder.landmark_planes(),
            stats=self.builder.stats,
            mode="windowed",
            runtime_s=self.runtime_s,
            online_poses=np.stack(self.online_poses),
            qr_fallback_epochs=list(self.qr_fallback_epochs),
            indefinite_marginals=list(self.indefinite_marginals),
        )


def smooth_windowed(
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativePose],
    config: SmoothingConfig | PlanodomConfig | None = None,
) -> SmoothingResult:
    """Run :class:`WindowedSmoother` over a whole sequence (inputs as :func:`smooth_batch`;
    the first pose at identity, else use the class)."""
    check_epochs(epochs_planes, relative_poses, name="smooth_windowed")
    smoother = WindowedSmoother(config)
    by_epoch = group_by_epoch(relative_poses, len(epochs_planes))
    for k, planes in enumerate(epochs_planes):
        smoother.add_epoch(planes, by_epoch[k])
    return smoother.result()
