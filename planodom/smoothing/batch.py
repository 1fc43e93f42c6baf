"""Batch smoothing: the whole sequence in one graph, Levenberg-Marquardt, pose marginals."""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import cast

import gtsam
import numpy as np

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.batch_covariances import batch_covariances, sandwich_inputs
from planodom.smoothing.graph import GraphBuilder, GraphStats
from planodom.smoothing.initial_ahead import GuessAhead, finished
from planodom.smoothing.initial_check import checked_guess
from planodom.smoothing.inputs import check_epochs
from planodom.smoothing.linear_solve import solve_step
from planodom.smoothing.loop_candidates import CandidateLoopBuilder
from planodom.smoothing.loop_gate import consistent_hypotheses, loop_start, test_hypotheses
from planodom.smoothing.loop_gate_parts import gate_loops
from planodom.smoothing.loop_records import (
    LoopFactor,
    LoopMatch,
    Reidentification,
    gate_reidentifications,
)
from planodom.smoothing.loops import LoopClosingBuilder
from planodom.smoothing.noise import loop_deskew_model
from planodom.smoothing.variance_components import VarianceComponents
from planodom_factors.batched import BatchedResiduals


@dataclass
class SmoothingResult:
    """Smoothed trajectory and what went into it.

    Attributes:
        poses: (E, 4, 4) smoothed ``T_world_base``.
        initial_poses: (E, 4, 4) the initial guess (odometry chained with the smallest
            resolved delta, constant velocity where unresolved; or the fixed-lag
            smoother's estimate, ``smoothing.batch_initial``).
        covariances: (E, 6, 6) marginal covariances of the poses in gtsam's Pose3 tangent
            ``[rot (rad), trans (m)]`` at the estimate, right perturbation (body frame),
            relative to the first pose unless ``covariances_relative_to_first`` is off
            (see :func:`.marginals.pose_covariances`), or None when not computed.
        landmarks: landmark id -> (4,) world plane ``(n, d)``.
        stats: counts of factors, landmarks, flips, unresolved epochs.
        mode: "batch" or "windowed".
        runtime_s: wall time of building and optimising, seconds.
        online_poses: (E, 4, 4) windowed only: each pose as estimated when its epoch was
            the newest (the real-time output); None for batch.
        errors: optimiser's error (0.5 sum of squared whitened residuals) per iteration.
        reidentifications: loop closure: the observations tied to old landmarks
            (:mod:`planodom.smoothing.loops`), with the gate's verdict and the truth.
        loop_matches: loop closure: each epoch's match against the map, with the
            verification's verdict.
        covariance_note: why ``covariances`` is None although asked for, or what the
            graph leaves undetermined (variables left out, poses' axes NaN; see
            :func:`.marginals.pose_covariances`).
        loop_factors: loop closure: the 5-DoF loop-candidate factors
            (:mod:`planodom.smoothing.loop_candidates`), with the gate's verdict.
        variance_components: ``smoothing.covariance_scale``: the noise models' variance
            factors estimated from the residuals (:mod:`.variance_components`).
        covariance_s: wall time of the covariances (part of ``runtime_s``), seconds.
        covariance_model: batch: "sandwich" or "fitted", the model the covariances came
            from (``smoothing.covariance_model``, "auto" resolved); "" when not computed.
        qr_fallback_epochs: the fixed-lag smoother's epochs at which Cholesky failed and
            it went on with QR (windowed: its own; batch: its windowed initial guess's,
            ``smoothing.batch_initial``).
        indefinite_marginals: (epoch, -w_min / w_max) of those fallbacks whose held
            marginals were indefinite beyond round-off of their own scale and split
            (:attr:`.windowed.WindowedSmoother.indefinite_marginals`).
        initial_check: batch with ``batch_initial`` "checked": the windowed guess's worst
            squared Mahalanobis distance from the chained odometry, its span (a, b), and
            whether the batch started from the chained odometry instead
            (:mod:`.initial_check`); None otherwise.
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
    covariance_note: str | None = None
    reidentifications: list[Reidentification] = field(default_factory=list)
    loop_matches: list[LoopMatch] = field(default_factory=list)
    loop_factors: list[LoopFactor] = field(default_factory=list)
    variance_components: VarianceComponents | None = None
    covariance_s: float = 0.0
    covariance_model: str = ""
    qr_fallback_epochs: list[int] = field(default_factory=list)
    indefinite_marginals: list[tuple[int, float]] = field(default_factory=list)
    initial_check: tuple[float, int, int, bool] | None = None


def smoothing_config(config: SmoothingConfig | PlanodomConfig | None) -> SmoothingConfig:
    """The smoothing section of a config (defaults when None)."""
    if config is None:
        return SmoothingConfig()
    return config.smoothing if isinstance(config, PlanodomConfig) else config


def full_config(config: SmoothingConfig | PlanodomConfig | None) -> PlanodomConfig:
    """The whole configuration: ``config`` itself, or the defaults with its smoothing
    section (loop closure also reads the odometry's and extraction's sections)."""
    if isinstance(config, PlanodomConfig):
        return config
    return PlanodomConfig(smoothing=smoothing_config(config))


def group_by_epoch(
    relatives: Sequence[RelativePose], n_epochs: int
) -> Mapping[int, list[RelativePose]]:
    """Relative poses keyed by their ``curr`` epoch (0..n_epochs-1)."""
    out: dict[int, list[RelativePose]] = {k: [] for k in range(n_epochs)}
    for rel in relatives:
        if 0 <= rel.curr < n_epochs:
            out[rel.curr].append(rel)
    return out


def _solve(
    linear: gtsam.GaussianFactorGraph, ordering: gtsam.Ordering, multifrontal: bool = True
) -> tuple[gtsam.VectorValues, bool]:
    """A linear step: :func:`.linear_solve.solve_step` (Cholesky, sequential Cholesky, QR),
    and whether the multifrontal Cholesky was refused (or, ``multifrontal`` False, skipped)."""
    return solve_step(linear, ordering, multifrontal)


def _damping(dims: Sequence[tuple[int, int]], lam: float) -> gtsam.GaussianFactorGraph:
    """Levenberg-Marquardt's damping ``lam * I`` as linear factors, one per (key, tangent
    dimension) in ``dims``, in their order."""
    out = gtsam.GaussianFactorGraph()
    root = np.sqrt(lam)
    for key, dim in dims:
        out.add(key, root * np.eye(dim), np.zeros(dim), gtsam.noiseModel.Unit.Create(dim))
    return out


def levenberg_marquardt(
    graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    max_iterations: int = 100,
    relative_error_tol: float = 1e-6,
    absolute_error_tol: float = 1e-9,
    lambda_initial: float = 1e-5,
    lambda_max: float = 1e10,
    sticky: bool = False,
) -> tuple[gtsam.Values, list[float]]:
    """Levenberg-Marquardt on a nonlinear graph, the loop in Python, the algebra in gtsam.

    Why not ``gtsam.LevenbergMarquardtOptimizer``: inside gtsam's optimiser the values are
    a C++ object without a Python wrapper, so each call of a ``CustomFactor``'s error
    function copies the whole ``Values`` into Python (pybind11's copy policy for const
    references): O(N) per factor, O(N^2) per iteration. Measured on a 1 000-epoch graph:
    4.4 s per Gauss-Newton iteration inside gtsam, 0.7 s for the same linearise and solve
    called from Python. Here ``graph.linearize`` and ``graph.error`` are called on the
    Python-owned values, which pybind11 passes by reference.

    Linear steps by Cholesky, sequential where gtsam's multifrontal check refuses a clique,
    and by QR when that fails too (:mod:`.linear_solve`: a long stretch bridged by weak
    fallback factors next to stiff plane factors gave Hessian condition numbers of 1e16 and
    more on the paper loop; QR is 7-10x slower).

    The 5-DoF, rotation and vertical factors' residuals and Jacobians come from one compiled
    pass per evaluation (:class:`planodom_factors.batched.BatchedResiduals`: the same numbers,
    a third less time in ``linearize`` and half in ``error``), the damping factors are built
    once per lambda.

    Damping: ``lambda * I`` on every variable's tangent (gtsam's default); lambda / 10 on a
    successful step, * 10 on a failed one. Stops when the relative decrease of the error
    falls below ``relative_error_tol`` or its absolute decrease below ``absolute_error_tol``,
    or when lambda exceeds ``lambda_max``. With ``sticky`` (``sequential_after_refusal``)
    once gtsam refuses a multifrontal step, the call's later steps skip it.

    Returns:
        The optimised values and the error (0.5 sum of squared whitened residuals) at the
        start and after each accepted step.
    """
    ordering = gtsam.Ordering.ColamdNonlinearFactorGraph(graph)
    zero = values.zeroVectors()
    dims = [(key, zero.at(key).size) for key in values.keys()]
    batched = BatchedResiduals(graph, values)
    error = batched.initial_error
    errors = [error]
    lam = lambda_initial
    damping: dict[float, gtsam.GaussianFactorGraph] = {}  # lambda -> its factors, built once
    refused = False  # a multifrontal step refused in this call
    for _ in range(max_iterations):
        linear = batched.linearize(values)
        while lam <= lambda_max:
            damped = gtsam.GaussianFactorGraph()
            damped.push_back(linear)
            if lam not in damping:
                damping[lam] = _damping(dims, lam)
            damped.push_back(damping[lam])
            try:
                step, refusal = _solve(damped, ordering, not (sticky and refused))
                refused |= refusal
                candidate = values.retract(step)
                new_error = batched.error(candidate)
            except RuntimeError:  # indeterminant even for QR at this damping: damp more
                new_error = np.inf
            if new_error <= error:
                break
            lam *= 10.0
        else:
            return values, errors
        decrease = error - new_error
        values, error = candidate, new_error
        errors.append(error)
        lam = max(lam / 10.0, 1e-12)
        if decrease <= max(relative_error_tol * errors[-2], absolute_error_tol):
            break
    return values, errors


def _gated(
    builder: LoopClosingBuilder,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    estimate: gtsam.Values,
    errors: list[float],
) -> gtsam.Values:
    """Re-identifications and loop-candidate factors inconsistent with the estimate out
    (loop hypotheses also by what they cost the rest of the graph, once each),
    solved again from the initial ``values`` (not from an estimate a wrong tie has
    pulled), or from the estimate with ``loop_gate_resolve_from: estimate``; at most
    three rounds (four with loop factors)."""
    cfg = builder.config
    for _ in range(4 if getattr(builder, "loop_factors", None) else 3):
        # loop factors first: the Gaussian start lets a wrong hypothesis pull the
        # estimate, and re-identifications would fail by its pull
        removed = gate_loops(builder, graph, gaussian, values, estimate)
        removed = removed or test_hypotheses(builder, graph, gaussian, values, estimate)
        if not removed and not gate_reidentifications(builder, graph, gaussian, estimate):
            break
        warm = cfg.loop_gate_resolve_from == "estimate"
        start = loop_start(builder, graph, gaussian, estimate if warm else values)
        estimate, more = levenberg_marquardt(
            graph, start, cfg.max_iterations, cfg.relative_error_tol,
            sticky=cfg.sequential_after_refusal,
        )  # fmt: skip
        errors += more
    return estimate


def first_measured_step(relative_poses: Sequence[RelativePose]) -> np.ndarray | None:
    """(4, 4) ``T_prev_curr`` of the earliest delta = 1 relative pose that measured the
    translation, or None: the batch's fallback before it (the odometry knew no velocity
    there; the whole run is known, so the motion is carried back from its first
    measurement, :meth:`.GraphBuilder._fallback_motion`)."""
    steps = [r for r in relative_poses if r.delta == 1 and r.measured and r.translation_observed]
    first = min(steps, key=lambda r: r.curr, default=None)
    return None if first is None else np.asarray(first.T_prev_curr, dtype=float)


def _builder(
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativePose],
    config: SmoothingConfig | PlanodomConfig | None,
    T_world_first: np.ndarray | None,
) -> tuple[GraphBuilder, SmoothingResult | GuessAhead | None]:
    """The batch's graph builder (with loop closure and candidates as configured), its
    initial poses from the fixed-lag smoother when ``batch_initial`` is "windowed" (and
    that smoother's result, else None; with ``batch_initial_concurrent`` the smoother
    running ahead in a child process, :mod:`.initial_ahead`, its poses arriving)."""
    cfg = smoothing_config(config)
    full = full_config(config)
    builder: GraphBuilder = GraphBuilder(cfg, T_world_first)
    if cfg.loop_closure:
        loop_builder = CandidateLoopBuilder if cfg.loop_candidates else LoopClosingBuilder
        builder = loop_builder(full, T_world_first)
        if isinstance(builder, CandidateLoopBuilder):  # (smoothing.loop_factor_deskew)
            builder.loop_deskew = loop_deskew_model(cfg, relative_poses)
    if cfg.fallback_start == "first_step":
        builder.first_step = first_measured_step(relative_poses)
    for rel in relative_poses if builder.deskew is not None else ():
        builder.deskew.add(rel)  # type: ignore[union-attr]  # batch: the whole run's, at once
    if cfg.sandwich_plane_share == "own":  # the sandwich's Q, before any plane factor
        observed = enumerate((k, p) for k, planes in enumerate(epochs_planes) for p in planes)
        Q, _ = sandwich_inputs(cfg, dict(observed), relative_poses, len(epochs_planes))
        builder.plane_share = Q if Q is not None and np.any(Q) else None
    if cfg.batch_initial == "odometry":
        return builder, None
    # Its poses only: no marginals (a third of the fixed-lag smoother's time on lidar).
    first = full.updated({"smoothing.compute_covariances": False}, source="initial guess")
    if cfg.batch_initial == "windowed" and cfg.batch_initial_concurrent:
        # the same poses, computed in a child process while the graph is built
        ahead = GuessAhead(epochs_planes, relative_poses, first, T_world_first)
        builder.initial_poses = cast(np.ndarray, ahead)  # indexed by epoch, as the stack
        return builder, ahead
    from planodom.smoothing.windowed import smooth_windowed

    guess = smooth_windowed(epochs_planes, relative_poses, first)
    builder.initial_poses = guess.poses
    if cfg.batch_initial == "checked":  # the chained odometry where it contradicts it
        chained, worst, span = checked_guess(guess.poses, relative_poses, full, builder.first_step)
        guess.initial_check = (worst, *span, chained is not None)
        if chained is not None:
            builder.initial_poses = None
    if T_world_first is not None and builder.initial_poses is not None:
        builder.initial_poses = np.asarray(T_world_first) @ builder.initial_poses
    return builder, guess


def smooth_batch(
    epochs_planes: Sequence[Sequence[Plane]],
    relative_poses: Sequence[RelativePose],
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
    check_epochs(epochs_planes, relative_poses, T_world_first)
    start = time.perf_counter()
    builder, guess = _builder(epochs_planes, relative_poses, config, T_world_first)
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    gaussian: dict[int, gtsam.NonlinearFactor] = {}
    fallback: list[int] = []  # indices of the fallback factors
    plane_factors: dict[int, tuple[int, Plane]] = {}  # their epochs and planes
    by_epoch = group_by_epoch(relative_poses, len(epochs_planes))
    with finished(guess):  # (batch_initial_concurrent: the child's end)
        for k, planes in enumerate(epochs_planes):
            n_reids = len(getattr(builder, "reidentifications", ()))
            update = builder.add_epoch(planes, by_epoch[k])
            for r in getattr(builder, "reidentifications", ())[n_reids:]:
                r.factor += graph.size()
            gaussian |= {graph.size() + i: f for i, f in update.gaussian.items()}
            fallback += [graph.size() + i for i in update.fallback]
            plane_factors |= {graph.size() + i: obs for i, obs in update.planes.items()}
            graph.push_back(update.factors)
            values.insert(update.values)
    initial = np.stack([builder.poses[k] for k in range(len(epochs_planes))])
    consistent_hypotheses(builder, graph, gaussian)

    estimate, errors = levenberg_marquardt(
        graph, loop_start(builder, graph, gaussian, values), cfg.max_iterations,
        cfg.relative_error_tol, sticky=cfg.sequential_after_refusal,
    )  # fmt: skip
    if isinstance(builder, LoopClosingBuilder):
        estimate = _gated(builder, graph, gaussian, values, estimate, errors)
    covariances, note, components, covariance_s, model = None, None, None, 0.0, ""
    if cfg.compute_covariances:
        cov_start = time.perf_counter()
        estimate, covariances, note, components, model = batch_covariances(
            builder, graph, gaussian, fallback, estimate, len(epochs_planes), plane_factors,
            relative_poses,
        )  # fmt: skip
        covariance_s = time.perf_counter() - cov_start
    builder.update_estimates(estimate)
    poses = np.stack([builder.poses[k] for k in range(len(epochs_planes))])
    return SmoothingResult(
        poses=poses,
        initial_poses=initial,
        covariances=covariances,
        landmarks=builder.landmark_planes(),
        stats=builder.stats,
        mode="batch",
        runtime_s=time.perf_counter() - start,
        errors=errors,
        covariance_note=note,
        reidentifications=list(getattr(builder, "reidentifications", [])),
        loop_matches=list(getattr(builder, "matches", [])),
        loop_factors=list(getattr(builder, "loop_factors", [])),
        variance_components=components,
        covariance_s=covariance_s,
        covariance_model=model,
        qr_fallback_epochs=[] if guess is None else guess.qr_fallback_epochs,
        indefinite_marginals=[] if guess is None else guess.indefinite_marginals,
        initial_check=None if guess is None else guess.initial_check,
    )
