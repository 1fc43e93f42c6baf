"""End to end: scans -> planes and odometry (delta = 1) -> relative poses delta = 2..D -> smoothing.

The paper's odometry (:func:`planodom.odometry.run_odometry`, delta = 1) extracts each
epoch's planes and gives the raw trajectory; the stored planes then give the relative
poses between epochs ``k - delta`` and ``k`` for delta = 1..D
(:func:`planodom.odometry.estimate_relative_pose`, with the odometry's chained motion as
prior and association bounds widened with delta, as the streaming odometry does). The
delta = 1 poses are recomputed rather than taken from the streaming run, whose reference
epoch may be an earlier one when epoch ``k - 1`` has too few planes. Every
resolved relative pose becomes a 5-DoF factor (a rotation-only factor when the odometry
reports "degenerate": rotation measured, translation not), every SDA chain a landmark.

The odometry's own vertical estimate (from associated ground planes) is not used as a
factor: the plane factors of the ground landmark carry the same information.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, invert_transform
from planodom.odometry import OdometryRun, RelativePose, estimate_relative_pose, run_odometry
from planodom.smoothing.batch import SmoothingResult, smooth_batch
from planodom.smoothing.graph import RelativeMeasurement
from planodom.smoothing.windowed import smooth_windowed

Progress = Callable[[str, int, int], None]


@dataclass
class SmoothingRun:
    """A whole smoothing run and its inputs.

    Attributes:
        result: the smoothed trajectory (``result.poses`` (E, 4, 4), first at identity).
        odometry: the delta = 1 odometry run (raw trajectory, planes, results).
        relatives: every relative pose used, delta = 1..D.
        times: (E,) epoch times, seconds.
        config: the resolved configuration (``smoothing.window`` / ``delta_max`` set).
        seconds: wall time of "extraction", "odometry" (the delta = 1 streaming run),
            "relatives" (delta = 1..D) and "smoothing".
    """

    result: SmoothingResult
    odometry: OdometryRun
    relatives: list[RelativeMeasurement]
    times: np.ndarray
    config: PlanodomConfig
    seconds: dict[str, float] = field(default_factory=dict)

    @property
    def poses(self) -> np.ndarray:
        """(E, 4, 4) smoothed ``T_world_base``."""
        return self.result.poses


def from_relative_pose(rel: RelativePose, prev: int, curr: int) -> RelativeMeasurement:
    """The graph's view of an odometry result between epochs ``prev`` and ``curr``."""
    measured = rel.status in ("ok", "degenerate") and not rel.fallback
    return RelativeMeasurement(
        sources=source_associations(rel),
        prev=prev,
        curr=curr,
        T_prev_curr=np.asarray(rel.T_prev_curr, dtype=float),
        associations=np.asarray(rel.plane_associations, dtype=int).reshape(-1, 2),
        ok=measured,
        covariance=np.asarray(rel.covariance, dtype=float),
        translation_observed=rel.status == "ok",
    )


def source_associations(rel: RelativePose) -> np.ndarray | None:
    """(S, 2) the plane associations (prev, curr) a relative pose was computed from.

    The winning rotation pair and translation pair of the consensus, ``(i1, i2, j1, j2)``
    each, give the associations ``(i1, j1)`` and ``(i2, j2)``. None when a DoF measured
    does not come from one pair (a mean over all pairs, or no winning pair recorded): the
    relative pose is then always a factor.
    """
    pairs = [rel.rotation_pair]
    if rel.status == "ok":
        pairs.append(rel.translation_pair)
    if any(p is None for p in pairs):
        return None
    rows = np.concatenate([np.asarray(p, dtype=int).reshape(2, 2).T for p in pairs])
    return np.unique(rows, axis=0)


def rotation_determined(
    planes_curr: Sequence[Plane], associations: np.ndarray, min_angle_deg: float = 10.0
) -> bool:
    """Whether the associated planes can determine a rotation: two non-parallel normals.

    Args:
        planes_curr: the current epoch's planes. associations: (M, 2) indices (prev, curr).
        min_angle_deg: smallest angle between two normals that counts as non-parallel.
    """
    idx = np.asarray(associations, dtype=int).reshape(-1, 2)[:, 1]
    idx = idx[(idx >= 0) & (idx < len(planes_curr))]
    if len(idx) < 2:
        return False
    normals = np.stack([planes_curr[i].normal for i in idx])
    cross = np.linalg.norm(np.cross(normals[:, None], normals[None]), axis=2)
    return bool(cross.max() >= np.sin(np.radians(min_angle_deg)))


def config_for_delta(config: PlanodomConfig, delta: int) -> PlanodomConfig:
    """Association bounds widened for a gap of ``delta`` epochs (as the streaming odometry)."""
    if delta <= 1:
        return config
    a = config.association
    widened = a.model_copy(
        update={
            "max_translation_m": a.max_translation_m * delta,
            "max_rotation_deg": min(a.max_rotation_deg * delta, 180.0),
        }
    )
    return config.model_copy(update={"association": widened})


def relative_poses(
    planes: Sequence[Sequence[Plane]],
    config: PlanodomConfig,
    deltas: Sequence[int],
    guess_poses: np.ndarray | None = None,
    progress: Progress | None = None,
) -> list[RelativeMeasurement]:
    """Relative poses between epochs ``k - delta`` and ``k`` for each delta in ``deltas``.

    Args:
        planes: E epochs of planes (base frame).
        config: pipeline configuration (association, odometry).
        deltas: epoch gaps, e.g. ``range(2, D + 1)``.
        guess_poses: (E, 4, 4) a trajectory guess (the delta = 1 odometry); its relative
            motion is the prior of each estimate. None: no prior.
        progress: called as ``progress("relatives", done, total)``.
    """
    out: list[RelativeMeasurement] = []
    n = len(planes)
    total = sum(max(n - d, 0) for d in deltas)
    done = 0
    for delta in deltas:
        cfg = config_for_delta(config, delta)
        for k in range(delta, n):
            prior = None
            if guess_poses is not None:
                prior = invert_transform(guess_poses[k - delta]) @ guess_poses[k]
            rel = estimate_relative_pose(planes[k - delta], planes[k], cfg, prior)
            measurement = from_relative_pose(rel, k - delta, k)
            if measurement.ok and not rotation_determined(planes[k], measurement.associations):
                # A rotation from fewer than two non-parallel associated planes is the
                # prior's, not a measurement: keep the associations, drop the factor.
                measurement = replace(measurement, ok=False)
            out.append(measurement)
            done += 1
            if progress is not None:
                progress("relatives", done, total)
    return out


def run_smoothing(
    source: Sequence,
    config: PlanodomConfig | None = None,
    window: int | None = None,
    delta: int | None = None,
    mode: str = "batch",
    odometry: OdometryRun | None = None,
    progress: Progress | None = None,
) -> SmoothingRun:
    """Extract planes, run the odometry, and smooth the trajectory.

    Args:
        source: a sequence of :class:`planodom.scan.Scan` (a dataset or a simulated run),
            or of plane lists; ``source.times`` is used when present.
        config: pipeline configuration (default: defaults).
        window: W, epochs of the fixed-lag smoother (default ``smoothing.window``).
        delta: D, relative poses for delta = 1..D (default ``smoothing.delta_max``).
        mode: "batch" (whole sequence, Levenberg-Marquardt, marginals) or "windowed"
            (fixed-lag smoother, online).
        odometry: a delta = 1 odometry run of the same source to reuse (skips extraction).
        progress: called as ``progress(stage, done, total)``, stage "odometry",
            "relatives".

    Returns:
        :class:`SmoothingRun`; poses start at identity, like the odometry's.
    """
    if mode not in ("batch", "windowed"):
        raise ConfigError(f"smoothing mode: expected batch or windowed, got {mode!r}")
    cfg = config or PlanodomConfig()
    smoothing = cfg.smoothing.model_dump()
    if window is not None:
        smoothing["window"] = window
    if delta is not None:
        smoothing["delta_max"] = delta
    data = cfg.model_dump()
    data["smoothing"] = smoothing
    data["odometry"]["delta"] = 1
    cfg = PlanodomConfig.from_dict(data, source="smoothing")
    seconds: dict[str, float] = {}

    if odometry is None:
        step = None if progress is None else (lambda k, n: progress("odometry", k, n))
        odometry = run_odometry(source, cfg, progress=step)
    seconds["extraction"] = odometry.seconds.get("extraction", 0.0)
    seconds["odometry"] = odometry.seconds.get("odometry", 0.0)
    start = time.perf_counter()
    relatives = relative_poses(
        odometry.planes, cfg, range(1, cfg.smoothing.delta_max + 1), odometry.poses, progress
    )
    seconds["relatives"] = time.perf_counter() - start

    smooth = smooth_batch if mode == "batch" else smooth_windowed
    result = smooth(odometry.planes, relatives, cfg.smoothing)
    seconds["smoothing"] = result.runtime_s
    return SmoothingRun(result, odometry, relatives, np.asarray(odometry.times), cfg, seconds)
