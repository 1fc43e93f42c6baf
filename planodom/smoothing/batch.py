"""Batch smoothing: the whole sequence in one graph, Levenberg-Marquardt, pose marginals."""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.geometry import Plane
from planodom.smoothing.graph import (
    GraphBuilder,
    GraphStats,
    RelativeMeasurement,
    X,
    group_by_epoch,
)


@dataclass
class SmoothingResult:
    """Smoothed trajectory and what went into it.

    Attributes:
        poses: (E, 4, 4) smoothed ``T_world_base``.
        initial_poses: (E, 4, 4) the initial guess (odometry chained with the smallest
            resolved delta, constant velocity where unresolved).
        covariances: (E, 6, 6) marginal covariances of the poses in gtsam's Pose3 tangent
            ``[rot (rad), trans (m)]`` at the estimate, right perturbation (body frame),
            or None when not computed.
        landmarks: landmark id -> (4,) world plane ``(n, d)``.
        stats: counts of factors, landmarks, flips, unresolved epochs.
        mode: "batch" or "windowed".
        runtime_s: wall time of building and optimising, seconds.
        online_poses: (E, 4, 4) windowed only: each pose as estimated when its epoch was
            the newest (the real-time output); None for batch.
        errors: optimiser's error (0.5 sum of squared whitened residuals) per iteration.
    """

    poses: np.ndarray
    initial_poses: np.ndarray
    covariances: np.ndarray | None
    landmarks: dict[int, np.ndarray]
    stats: GraphStats
    mode: str
    runtime_s: float
    online_poses: np.ndarray | None = None
    errors: list[float] = field(default_factory=list)


def smoothing_config(config: SmoothingConfig | PlanodomConfig | None) -> SmoothingConfig:
    """The smoothing section of a config (defaults when None)."""
    if config is None:
        return SmoothingConfig()
    return config.smoothing if isinstance(config, PlanodomConfig) else config


def pose_covariances(
    graph: gtsam.NonlinearFactorGraph, values: gtsam.Values, n_epochs: int
) -> np.ndarray:
    """(E, 6, 6) marginal covariances of ``X(0..E-1)`` (gtsam.Marginals, Cholesky)."""
    marginals = gtsam.Marginals(graph, values)
    return np.stack([marginals.marginalCovariance(X(k)) for k in range(n_epochs)])


def smooth_batch(
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativeMeasurement],
    config: SmoothingConfig | PlanodomConfig | None = None,
    T_world_first: np.ndarray | None = None,
) -> SmoothingResult:
    """Smooth a whole sequence in one factor graph.

    Args:
        epochs_planes: E lists of measured planes (base frame, normals towards the sensor,
            covariance and confidence as set by extraction).
        relative_poses: 5-DoF relative poses between epochs (any ``delta <= delta_max``);
            their associations track the planes into landmarks.
        config: smoothing settings (``delta_max``, noise floors, kernels, ...).
        T_world_first: (4, 4) pose of the first epoch (default: identity).

    Returns:
        The smoothed poses, their marginal covariances (if ``compute_covariances``), the
        landmarks and the graph's statistics.
    """
    cfg = smoothing_config(config)
    start = time.perf_counter()
    builder = GraphBuilder(cfg, T_world_first)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    by_epoch = group_by_epoch(relative_poses, len(epochs_planes))
    for k, planes in enumerate(epochs_planes):
        update = builder.add_epoch(planes, by_epoch[k])
        graph.push_back(update.factors)
        values.insert(update.values)
    initial = np.stack([builder.poses[k] for k in range(len(epochs_planes))])

    errors: list[float] = []
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(cfg.max_iterations)
    params.setRelativeErrorTol(cfg.relative_error_tol)
    params.iterationHook = lambda _it, _before, after: errors.append(after)
    estimate = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    builder.update_estimates(estimate)
    covariances = (
        pose_covariances(graph, estimate, len(epochs_planes)) if cfg.compute_covariances else None
    )
    poses = np.stack([builder.poses[k] for k in range(len(epochs_planes))])
    return SmoothingResult(
        poses=poses,
        initial_poses=initial,
        covariances=covariances,
        landmarks=builder.landmark_planes(),
        stats=builder.stats,
        mode="batch",
        runtime_s=time.perf_counter() - start,
        errors=[graph.error(values)] + errors,
    )
