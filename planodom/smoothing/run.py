"""End to end: scans -> planes and odometry (delta = 1) -> relative poses delta = 2..D -> smoothing.

The paper's odometry (:func:`planodom.odometry.run_odometry`, delta = 1) extracts each
epoch's planes, gives the raw trajectory and the relative pose of each epoch from its
reference epoch (``k - 1``, or an earlier one when ``k - 1`` has too few planes): these
are reused as they are (:func:`smoothing_relatives`). The stored planes then give the
other relative poses between epochs ``k - delta`` and ``k`` for delta = 1..D
(:func:`planodom.odometry.estimate_relative_pose`, with the odometry's chained motion as
prior and association bounds widened with delta, as the streaming odometry does; not
solved again without the prior unless the chain crosses an epoch the odometry bridged); a
streaming result whose planes were extracted again later (the first epoch, deskewed once
a twist is known) is recomputed too. Every resolved relative pose becomes a 5-DoF factor
(a rotation-only factor when the odometry reports "degenerate": rotation measured,
translation not), every SDA chain a landmark.

The odometry's own vertical estimate (from associated ground planes) is not used as a
factor: the plane factors of the ground landmark carry the same information.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence, Set
from dataclasses import dataclass, field, replace

import numpy as np

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane, invert_transform
from planodom.odometry import (
    OdometryRun,
    RelativePose,
    Status,
    config_for_gap,
    estimate_relative_pose,
    run_odometry,
)
from planodom.odometry.platform import with_platform
from planodom.odometry.run import EpochSequence
from planodom.odometry.stated_deskew import (
    epoch_deskew_covariances,
    run_twist_change,
    stated_relatives,
)
from planodom.rig import Rig
from planodom.smoothing.batch import SmoothingResult, smooth_batch
from planodom.smoothing.motion import measured_step_prior
from planodom.smoothing.redeskew import redeskew_passes, refresh_first_epoch
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
            "relatives" (delta = 1..D), "smoothing" (the first solve) and "redeskew" (all
            of ``smoothing.redeskew_passes`` and ``first_epoch_refresh``).
        redeskewed: with ``smoothing.redeskew_passes`` or ``first_epoch_refresh``, the
            odometry run whose planes ``result`` and ``relatives`` come from (the scans
            deskewed along the smoothed poses, the first epoch extracted again). None:
            they come from ``odometry``'s.
    """

    result: SmoothingResult
    odometry: OdometryRun
    relatives: list[RelativePose]
    times: np.ndarray
    config: PlanodomConfig
    seconds: dict[str, float] = field(default_factory=dict)
    redeskewed: OdometryRun | None = None

    @property
    def poses(self) -> np.ndarray:
        """(E, 4, 4) smoothed ``T_world_base``."""
        return self.result.poses


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


def _checked(rel: RelativePose, planes_curr: Sequence[Plane]) -> RelativePose:
    """``rel``, unresolved when its rotation rests on fewer than two non-parallel
    associated planes: then it is the prior's, not a measurement (the associations still
    track planes)."""
    if rel.measured and not rotation_determined(planes_curr, rel.associations):
        return replace(rel, status=Status.UNRESOLVED)
    return rel


def relative_poses(
    planes: Sequence[Sequence[Plane]],
    config: PlanodomConfig,
    deltas: Sequence[int],
    guess_poses: np.ndarray | None = None,
    progress: Progress | None = None,
    skip: Set[tuple[int, int]] = frozenset(),
    time_spread: Sequence[bool | None] | None = None,
    bridged: Set[int] | None = None,
) -> list[RelativePose]:
    """Relative poses between epochs ``k - delta`` and ``k`` for each delta in ``deltas``.

    Args:
        planes: E epochs of planes (base frame).
        config: pipeline configuration (association, odometry).
        deltas: epoch gaps, e.g. ``range(2, D + 1)``.
        guess_poses: (E, 4, 4) a trajectory guess (the delta = 1 odometry); its relative
            motion is the prior of each estimate. None: no prior.
        progress: called as ``progress("relatives", done, total)``.
        skip: ``(prev, curr)`` epoch pairs not to estimate (known already).
        time_spread: (E,) per epoch whether its points were spread in time (None: not
            known), given to each estimate as ``RelativePose.time_spread`` of its ``curr``
            (planes alone do not tell; the deskew-noise model needs it,
            :mod:`planodom.smoothing.deskew_noise`). None: all unknown.
        bridged: with ``guess_poses``, the epochs whose step the guess did not measure
            (bridged by constant velocity); a pair spanning none of them has a measured
            prior and is not solved again without it (``odometry.retry_without_prior``
            then applies only across a bridge). None: as configured for every pair.
            Why: the prior-free pass of a pair the odometry measured mostly finds a wrong
            consensus (on the 2D-rig lap of procedural world 6 at 6 mm, all five wrong
            plane associations of delta > 1 came from it, parallel walls 2 m apart), and
            its rotation-only result has no translation (zero), not the prior's.
    """
    pairs = [(k - d, k) for d in deltas for k in range(d, len(planes)) if (k - d, k) not in skip]
    configs = {d: config_for_gap(config, d) for d in deltas}
    fixed = {
        d: c.updated({"odometry.retry_without_prior": False}, source="measured prior")
        for d, c in configs.items()
    }
    out: list[RelativePose] = []
    for done, (prev, curr) in enumerate(pairs, start=1):
        prior, cfg = None, configs[curr - prev]
        if guess_poses is not None:
            prior = invert_transform(guess_poses[prev]) @ guess_poses[curr]
            if bridged is not None and not any(e in bridged for e in range(prev + 1, curr + 1)):
                cfg = fixed[curr - prev]
        rel = estimate_relative_pose(planes[prev], planes[curr], cfg, prior)
        rel = rel.between(prev, curr)
        if time_spread is not None:
            rel = replace(rel, time_spread=time_spread[curr])
        out.append(_checked(rel, planes[curr]))
        if progress is not None:
            progress("relatives", done, len(pairs))
    return out


def smoothing_relatives(
    odometry: OdometryRun, config: PlanodomConfig, progress: Progress | None = None
) -> list[RelativePose]:
    """The relative poses for delta = 1..``smoothing.delta_max``: the streaming odometry's
    own results (but those it superseded), then the others estimated from its planes
    (:func:`relative_poses`, its poses as priors, with ``smoothing.relative_prior``
    "measured_steps" the unmeasured translations replaced, its epochs' ``time_spread``;
    with ``odometry.stated_deskew_noise: shared`` stating their epochs' deskewing errors,
    :func:`stated_steps`)."""
    reused = [
        _checked(r, odometry.planes[r.curr])
        for r in odometry.results
        if r is not None and r.curr not in odometry.superseded
    ]
    known = {(r.prev, r.curr) for r in reused}
    deltas = range(1, config.smoothing.delta_max + 1)
    spread = epoch_time_spread(odometry)
    bridged = {k for k, r in enumerate(odometry.results) if k and (r is None or not r.measured)}
    prior = odometry.poses
    if config.smoothing.relative_prior == "measured_steps":
        measured = [
            r is not None and r.measured and r.translation_observed for r in odometry.results
        ]
        prior = measured_step_prior(np.asarray(odometry.poses), measured)
    rest = relative_poses(odometry.planes, config, deltas, prior, progress, known, spread, bridged)
    if config.odometry.stated_deskew_noise == "shared":
        return stated_steps(odometry, reused, rest)
    return reused + rest


def stated_steps(
    odometry: OdometryRun, reused: list[RelativePose], rest: list[RelativePose]
) -> list[RelativePose]:
    """``odometry.stated_deskew_noise: shared`` for the smoothing's relative poses: those
    estimated from the planes (``rest``) state both their epochs' deskewing errors, sized
    by the odometry run's (:mod:`planodom.odometry.stated_deskew`); the odometry's own
    (``reused``) already do when it ran with the option, else they get them here too."""
    sigma = run_twist_change(odometry.results, np.asarray(odometry.times, dtype=float))
    Q = epoch_deskew_covariances(odometry.results, sigma)
    ran = getattr(getattr(odometry.config, "odometry", None), "stated_deskew_noise", "off")
    if ran != "shared":
        reused = stated_relatives(reused, odometry.planes, Q, odometry.superseded)
    return reused + stated_relatives(rest, odometry.planes, Q)  # from the kept planes


def epoch_time_spread(odometry: OdometryRun) -> list[bool | None]:
    """(E,) per epoch whether its points were spread in time, as the streaming odometry
    saw its scan (``RelativePose.time_spread`` of its result; None: not known, e.g. the
    first epoch or a run on planes)."""
    return [None if r is None else r.time_spread for r in odometry.results]


def smoothing_config(config: PlanodomConfig, mode: str = "batch") -> PlanodomConfig:
    """``config`` with the odometry the smoothing in ``mode`` runs: in batch, deskewed as
    ``smoothing.odometry_deskew_twist`` says (with the coplanar twist, the vertical offset
    taken only where a step measured z unless ``odometry.z_offset_measured_only`` is set),
    and with the planes' deskewing Jacobians (``extraction.deskew_jacobian``) that the
    default covariance model ("auto") reads for the sandwich covariances; a run that only
    does odometry does not compute them."""
    if mode != "batch":
        return config
    config = with_batch_jacobians(config)
    if config.smoothing.odometry_deskew_twist == "coplanar":
        changes: dict[str, object] = {"odometry.deskew_twist": "coplanar"}
        if config.odometry.z_offset_measured_only is None:
            changes["odometry.z_offset_measured_only"] = True
        return config.updated(changes, source="smoothing")
    return config


def with_batch_jacobians(config: PlanodomConfig) -> PlanodomConfig:
    """``config`` with the planes' deskewing Jacobians switched on where the batch's default
    covariance model ("auto", with ``deskew_noise`` and ``covariance_scale`` "none") reads
    them for the sandwich covariances: for an extraction whose planes the batch smooths."""
    smoothing = config.smoothing
    auto = smoothing.covariance_model == "auto" and smoothing.deskew_noise == "none"
    if auto and smoothing.covariance_scale == "none" and not config.extraction.deskew_jacobian:
        return config.updated({"extraction.deskew_jacobian": True}, source="smoothing")
    return config


def run_smoothing(
    source: EpochSequence,
    config: PlanodomConfig | None = None,
    rig: Rig | None = None,
    *,
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
        rig: the vehicle (sensor origins, motion bounds, platform), see
            :func:`planodom.odometry.run_odometry`.
        window: W, epochs of the fixed-lag smoother (default ``smoothing.window``).
        delta: D, relative poses for delta = 1..D (default ``smoothing.delta_max``).
        mode: "batch" (whole sequence, Levenberg-Marquardt, marginals; then
            ``smoothing.redeskew_passes``) or "windowed" (fixed-lag smoother, online).
        odometry: a delta = 1 odometry run of the same source to reuse (skips extraction).
        progress: called as ``progress(stage, done, total)``, stage "odometry",
            "relatives".

    Returns:
        :class:`SmoothingRun`; poses start at identity, like the odometry's.
    """
    if mode not in ("batch", "windowed"):
        raise ConfigError(f"smoothing mode: expected batch or windowed, got {mode!r}")
    changes: dict[str, object] = {"odometry.delta": 1}
    if window is not None:
        changes["smoothing.window"] = window
    if delta is not None:
        changes["smoothing.delta_max"] = delta
    cfg = smoothing_config((config or PlanodomConfig()).updated(changes, source="smoothing"), mode)
    rig = rig or getattr(source, "rig", None) or Rig()
    cfg = with_platform(cfg, rig)  # as run_odometry: also for the passes after it
    seconds: dict[str, float] = {}

    if odometry is None:
        step = None if progress is None else (lambda k, n: progress("odometry", k, n))
        odometry = run_odometry(source, cfg, rig, progress=step)
    seconds["extraction"] = odometry.seconds.get("extraction", 0.0)
    seconds["odometry"] = odometry.seconds.get("odometry", 0.0)
    start = time.perf_counter()
    relatives = smoothing_relatives(odometry, cfg, progress)
    seconds["relatives"] = time.perf_counter() - start

    if mode == "windowed":
        result = smooth_windowed(odometry.planes, relatives, cfg.smoothing)
    else:
        result = smooth_batch(odometry.planes, relatives, cfg)
    seconds["smoothing"] = result.runtime_s
    run = SmoothingRun(result, odometry, relatives, np.asarray(odometry.times), cfg, seconds)
    if mode == "batch":
        _redeskew(run, source, rig)
    return run


def _redeskew(run: SmoothingRun, source: EpochSequence, rig: Rig) -> None:
    """``smoothing.redeskew_passes``, then ``smoothing.first_epoch_refresh``, on ``run``
    (batch), in place: its result, relative poses and ``redeskewed`` become the last
    step's (:mod:`planodom.smoothing.redeskew`)."""

    def smooth(odometry: OdometryRun) -> tuple[list[RelativePose], SmoothingResult]:
        relatives = smoothing_relatives(odometry, run.config)
        return relatives, smooth_batch(odometry.planes, relatives, run.config)

    for step in (redeskew_passes, refresh_first_epoch):
        odometry = run.redeskewed or run.odometry
        out = step(source, odometry, run.result, run.config, rig, smooth)
        if out is not None:
            run.result, run.relatives, run.redeskewed = out.result, out.relatives, out.odometry
            run.seconds["redeskew"] = run.seconds.get("redeskew", 0.0) + out.seconds
