"""A whole run of the streaming odometry over a sequence of epochs (its per-epoch rows:
:mod:`planodom.odometry.rows`)."""

from __future__ import annotations

import time as _time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol, TypeVar, cast

import numpy as np

from planodom.config import PlanodomConfig
from planodom.extraction.lidar.sweep import sweep_timed
from planodom.geometry import Plane
from planodom.odometry.deskew import time_spread
from planodom.odometry.deskewed_epochs import Curve, Deskewed, DeskewedEpochs
from planodom.odometry.extractor import Extractor, default_extractor
from planodom.odometry.interpolate import curve_steps, epoch_middles, midpoint_nodes
from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.pairwise_deskew import with_pairwise_deskew
from planodom.odometry.pass_skip import pass_planes
from planodom.odometry.platform import with_platform
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.splice import kept_epochs, spliced
from planodom.rig import MotionBounds, Rig
from planodom.scan import Scan

T = TypeVar("T")


class EpochSequence(Protocol):
    """What the odometry runs over: ``len(source)`` epochs, ``source[k]`` a :class:`Scan`
    or the epoch's planes (a dataset, a simulated run, a list)."""

    def __len__(self) -> int: ...

    def __getitem__(self, index: int, /) -> Scan | Sequence[Plane]: ...


class DeskewedSequence(Protocol):
    """Epochs some of which come with their points deskewed already (:class:`Deskewed`)."""

    def __len__(self) -> int: ...

    def __getitem__(self, index: int, /) -> Scan | Sequence[Plane] | Deskewed: ...


@dataclass
class OdometryRun:
    """A whole run of the streaming odometry.

    Attributes:
        poses: (N, 4, 4) ``T_world_base`` per epoch (first is identity).
        times: (N,) seconds.
        results: per epoch the relative pose from its reference epoch (None for the first).
        n_planes: (N,) planes extracted per epoch (at its registration).
        planes: the planes of every epoch (base frame), as last extracted
            (:attr:`PlaneOdometry.planes`), for smoothing and diagnostics.
        superseded: epochs whose result indexes planes extracted again later
            (:attr:`PlaneOdometry.superseded`).
        seconds: wall time spent in extraction and in odometry (over all passes), and
            in deskewing through the poses (``deskew``, passes after the first), seconds.
        config: the configuration the run used (with a rig's platform and motion bounds,
            and the plane-map pipeline's extraction limits when it ran).
        extractions: calls of the extractor over all passes; reused: of them, those
            answered with the streaming pass's planes (``odometry.deskew_pass_skip``).
    """

    poses: np.ndarray
    times: np.ndarray
    results: list[RelativePose | None]
    n_planes: np.ndarray
    planes: list[list[Plane]] = field(default_factory=list)
    superseded: list[int] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    config: PlanodomConfig | None = None
    extractions: int = 0
    reused: int = 0

    @property
    def statuses(self) -> list[str]:
        """Per epoch "first" or the :class:`Status` value."""
        return ["first" if r is None else str(r.status) for r in self.results]

    @property
    def n_unresolved(self) -> int:
        return sum(r is not None and r.status is Status.UNRESOLVED for r in self.results)

    @property
    def n_degenerate(self) -> int:
        return sum(r is not None and r.status is Status.DEGENERATE for r in self.results)


def with_motion_bounds(config: PlanodomConfig, bounds: MotionBounds | None) -> PlanodomConfig:
    """``config`` with the motion bounds a rig states (``rig.yaml``'s ``motion_bounds``).

    Each bound becomes the larger of the config's and the rig's (both are assumptions of a
    maximum, so the union is the safe one).
    """
    if bounds is None:
        return config
    a = config.association
    changes = {
        f"association.{key}": max(float(getattr(a, key)), float(value))
        for key, value in (
            ("max_translation_m", bounds.max_translation_m),
            ("max_rotation_deg", bounds.max_rotation_deg),
        )
        if value is not None
    }
    return config.updated(changes, source="rig motion_bounds") if changes else config


def run_odometry(
    source: EpochSequence,
    config: PlanodomConfig | None = None,
    rig: Rig | None = None,
    *,
    times: Sequence[float] | np.ndarray | None = None,
    progress: Callable[[int, int], None] | None = None,
    extractor: Extractor | None = None,
) -> OdometryRun:
    """Run :class:`PlaneOdometry` over a sequence of epochs.

    Args:
        source: a sequence (``len`` and indexing) of :class:`Scan`, e.g. a dataset, or of
            plane lists (no extraction); its ``times`` attribute (N,) seconds is used when
            present and ``times`` is None.
        config: pipeline configuration.
        rig: the vehicle: its ``sensor_origins`` orient the extracted normals, its
            ``motion_bounds`` widen the association's (:func:`with_motion_bounds`), its
            ``platform`` is the config's ``auto`` (:func:`.platform.with_platform`);
            default: ``source.rig`` when the source has one (a dataset), else ``Rig()``.
        times: epoch reference times (N,), seconds.
        progress: called as ``progress(k, n)`` after each epoch.
        extractor: ``extractor(scan, extraction_config, twist=...) -> list[Plane]``;
            default :func:`planodom.extraction.extract_planes`.

    On scans with point times and ``odometry.deskew_passes`` > 0, the streaming pass is
    followed by passes on the scans deskewed through the poses of the pass before
    (:func:`redeskewed_run`); ``progress`` then counts each pass's epochs anew. Scans
    without point times get them from the azimuth when ``extraction.sweep`` declares the
    lidar's convention (:mod:`planodom.extraction.lidar.sweep`). With
    ``odometry.stated_deskew_noise: shared`` the steps' stated covariances then hold both
    their epochs' deskewing errors (:mod:`.stated_deskew`).
    """
    if rig is None:
        rig = getattr(source, "rig", None) or Rig()
    cfg = with_platform(config or PlanodomConfig(), rig)  # before: it keeps what is set
    cfg = with_motion_bounds(cfg, rig.motion_bounds)
    if times is None:
        times = getattr(source, "times", None)
    source = sweep_timed(source, cfg.extraction.sweep, rig)  # times from the azimuth
    cfg = with_pairwise_deskew(cfg, source)
    spread = any_time_spread(source)  # reads the first scans: once
    first = streaming_config(cfg) if spread else cfg
    pair = _middle_timed_pass(source, first, rig, times, progress, extractor)
    run = pair[0] if pair else _streaming_pass(source, first, rig, times, progress, extractor)
    if pair and cfg.odometry.deskew_passes and cfg.planemap.pass_reference_time == "middle":
        from planodom.odometry.middle_passes import middle_redeskewed_run  # imports this

        run = middle_redeskewed_run(source, pair[1], run, cfg, rig, progress, extractor)
    elif cfg.odometry.deskew_passes and spread:
        run = redeskewed_run(source, run.times, run.poses, cfg, rig, progress, extractor, run)
    if cfg.sweep_refine.passes and spread:
        from planodom.odometry.sweep_refine import sweep_refined_run  # imports this module

        run = sweep_refined_run(source, run, cfg, rig, progress, extractor)
    if cfg.odometry.degenerate_ends == "interpolated":
        from planodom.odometry.degenerate_ends import interpolated_degenerate

        window = cfg.odometry.velocity_window
        poses, results = interpolated_degenerate(run.poses, run.times, run.results, window)
        run = replace(run, poses=poses, results=results)
    if cfg.odometry.bridge_ends == "interpolated":
        from planodom.odometry.bridge_ends import interpolated_bridges

        poses, results = interpolated_bridges(run.poses, run.times, run.results)
        run = replace(run, poses=poses, results=results)
    if cfg.odometry.stated_deskew_noise == "shared":
        from planodom.odometry.stated_deskew import with_stated_deskew  # imports this module

        run = with_stated_deskew(run)  # the stated covariances only; the poses stay
    return run


def streaming_config(config: PlanodomConfig) -> PlanodomConfig:
    """The streaming pass's config: ``config``, but with ``odometry.moment_passes:
    deskew_passes`` the translation refinement instead of the moments'."""
    odo = config.odometry
    if odo.refinement == "moments" and odo.moment_passes == "deskew_passes":
        return config.updated({"odometry.refinement": "translation"}, source="moment_passes")
    return config


def redeskewed_run(
    source: EpochSequence,
    times: np.ndarray,
    poses: np.ndarray,
    config: PlanodomConfig,
    rig: Rig,
    progress: Callable[[int, int], None] | None = None,
    extractor: Extractor | None = None,
    previous: OdometryRun | None = None,
    measured: np.ndarray | None = None,
) -> OdometryRun:
    """The streaming odometry again on the scans deskewed through given poses.

    The poses (from an odometry pass or a smoother) become the nodes of a curve at the
    middle of every epoch (:func:`planodom.odometry.interpolate.midpoint_nodes`). Then,
    ``odometry.deskew_passes`` times, every scan is deskewed to the middle of its epoch
    along the curve and the odometry run on them gives the nodes of the next curve: an
    epoch's planes are seen around its middle, so an error of the curve there moves them
    little, where deskewed to the epoch's start they move by the curve's error over half
    an epoch (measured on the simulated paper loop at sigma = 0: passes to the epoch
    times did not converge below 0.003 deg rms, to the middles they do). A last pass
    deskews every scan to its epoch time along the last curve: its relative poses,
    planes and poses are those of the returned run. Each scan is registered without time
    spread (extracted once, with no twist).

    Only where the poses were measured: an epoch with an unresolved epoch (its pose is a
    bridge, in the pass the poses came from) within ``deskew_order`` epochs of it keeps
    the streaming deskewing (its predicted twist,
    then its own), with its times shifted to the pass's reference time (measured on
    procedural worlds: a bridged pose deskews its neighbours wrongly, and the wrong
    planes leave more epochs unresolved in the next pass).

    Args:
        source: the epochs (:class:`Scan`; plane lists are passed through).
        times: (N,) epoch times, seconds. poses: (N, 4, 4) ``T_world_base``.
        config, rig, progress, extractor: as :func:`run_odometry` (config with the rig's
            motion bounds already applied).
        previous: the run the poses came from (at the epoch times): its wall times are
            added to the new run's, its statuses give ``measured`` when that is None, and
            with ``odometry.deskew_pass_guard: streaming`` an epoch whose step in the last
            pass disagrees with its own keeps its estimate (:mod:`planodom.odometry.splice`).
        measured: (N,) bool, whether each pose was measured (default: all, or from
            ``previous``).
    """
    times = np.asarray(times, dtype=np.float64)
    if measured is None:
        measured = np.ones(len(times), bool) if previous is None else _measured(previous)
    order = config.odometry.deskew_order
    n_fit = fit_nodes(config, times)
    c0 = _time.perf_counter()
    nodes = midpoint_nodes(times, np.asarray(poses), order)
    variances = step_variances(previous, measured)[1:]  # node j (mid j, j + 1): step j -> j + 1
    seconds = {"deskew": _time.perf_counter() - c0}
    middles = epoch_middles(times)
    increments = config.odometry.deskew_fit == "increments"
    counts = (0, 0) if previous is None else (previous.extractions, previous.reused)
    for reference in [middles] * config.odometry.deskew_passes + [times]:
        trusted = _near_all_measured(measured, order)
        curve = Curve(*nodes, variances if n_fit else None, order, n_fit, increments)
        given = pass_planes(config, previous, curve, times, reference, variances)
        deskewed = DeskewedEpochs(source, times, reference, curve, trusted, given)
        run = _streaming_pass(deskewed, config, rig, reference, progress, extractor)
        counts = (counts[0] + run.extractions, counts[1] + run.reused)
        nodes, measured = (reference, run.poses), _measured(run)
        steps = step_variances(run, measured)  # node k, the middle of epoch k: its two steps
        variances = 0.5 * (steps + np.r_[steps[1:], steps[-1:]])
        for key, value in (run.seconds | {"deskew": deskewed.seconds}).items():
            seconds[key] = seconds.get(key, 0.0) + value
    if previous is not None and config.odometry.deskew_pass_guard != "off":
        steps = curve_steps(curve.times, curve.poses, times, curve.order,
                            curve.variances, curve.n_fit, curve.increments)  # fmt: skip
        run = spliced(previous, run, kept_epochs(previous, run, steps, trusted, config))
    if previous is not None:
        for key, value in previous.seconds.items():
            seconds[key] = seconds.get(key, 0.0) + value
    run.seconds = seconds
    run.extractions, run.reused = counts
    return run


def fit_nodes(config: PlanodomConfig, times: np.ndarray) -> int | None:
    """Nodes in the window of the passes' least-squares curve (``odometry.deskew_fit:
    weighted``): those within ``deskew_fit_span_s`` at the run's median epoch period, at
    least ``deskew_order + 2``; None for the interpolating curve."""
    odo = config.odometry
    if odo.deskew_fit == "interpolate" or len(times) < 2:
        return None
    period = float(np.median(np.diff(times)))
    return max(odo.deskew_order + 2, int(round(odo.deskew_fit_span_s / period)) + 1)


def step_variances(run: OdometryRun | None, measured: np.ndarray) -> np.ndarray:
    """(N, 6) variances of the tangent components (rotation rad^2, translation m^2) of the
    step into each epoch, from the odometry's 5x5 covariances (roll, pitch, yaw, x, y;
    the vertical: the mean of x and y, which it does not carry): infinite where the
    epoch is not ``measured`` (N,), 1 where no covariance is known (no run); the first
    epoch's: the second's."""
    n = len(measured)
    out = np.ones((n, 6))
    for k, r in enumerate(run.results if run is not None else []):
        if r is not None and r.covariance is not None:
            d = np.diag(r.covariance)
            out[k] = np.r_[d, 0.5 * (d[3] + d[4])]
    out[~np.asarray(measured, bool)] = np.inf
    if n > 1:
        out[0] = out[1]
    return out


def _measured(run: OdometryRun) -> np.ndarray:
    """(N,) bool: the epoch's pose was measured: the first, or not unresolved (a
    degenerate epoch's rotation is measured and its translation predicted by constant
    velocity, which deskews the straight streets where it happens; measured on the
    simulated urban canyon at sigma = 0: trusting only OK epochs left 0.04 deg)."""
    return np.array(
        [r is None or r.status is not Status.UNRESOLVED for r in run.results], dtype=bool
    )


def _near_all_measured(measured: np.ndarray, reach: int) -> np.ndarray:
    """(N,) bool: every epoch within ``reach`` epochs of each was measured."""
    bad = np.r_[np.zeros(reach, bool), ~measured, np.zeros(reach, bool)].astype(int)
    counts = np.convolve(bad, np.ones(2 * reach + 1, int), mode="valid")
    return counts == 0


def any_time_spread(source: EpochSequence) -> bool:
    """Whether the first scans of ``source`` carry point times that differ (a recording
    has them for all its epochs or for none)."""
    for k in range(min(len(source), 2)):
        item = source[k]
        if isinstance(item, Scan) and time_spread(item):
            return True
    return False


def _middle_timed_pass(
    source: EpochSequence,
    cfg: PlanodomConfig,
    rig: Rig,
    times: Sequence[float] | np.ndarray | None,
    progress: Callable[[int, int], None] | None,
    extractor: Extractor | None,
) -> tuple[OdometryRun, OdometryRun] | None:
    """The streaming pass with each scan registered at its sweep's middle and brought
    back to the epoch times (:mod:`planodom.odometry.planemap.midtime`): for the plane map
    with ``planemap.reference_time: middle``, for the pairwise pipelines with
    ``odometry.pairwise_reference_time: middle``; None when the pipeline's field is off
    or no scan has point times. Returns the run at the epoch times and at the middles."""
    from planodom.odometry.planemap import uses_plane_map
    from planodom.odometry.planemap.midtime import MiddleTimed, at_epoch_times

    first = source[0] if len(source) else None
    if not (isinstance(first, Scan) and any_time_spread(source)):
        return None
    if uses_plane_map(cfg, first):
        if cfg.planemap.reference_time != "middle":
            return None
    elif cfg.odometry.pairwise_reference_time != "middle":
        return None
    if times is None:
        times = np.arange(len(source)) * cfg.odometry.epoch_period_s
    middle = MiddleTimed(source, np.asarray(times, dtype=np.float64))
    # the shifted times are only indexed, each after its epoch was read (MiddleTimed)
    shifted = cast("Sequence[float]", middle.times)
    run = _streaming_pass(middle, cfg, rig, shifted, progress, extractor)
    order = cfg.odometry.deskew_order
    return at_epoch_times(run, middle.epoch_times, order, cfg.planemap.first_pose), run


def _streaming_pass(
    source: EpochSequence | DeskewedSequence,
    cfg: PlanodomConfig,
    rig: Rig,
    times: Sequence[float] | np.ndarray | None,
    progress: Callable[[int, int], None] | None,
    extractor: Extractor | None,
) -> OdometryRun:
    """One pass of :class:`PlaneOdometry` over the epochs (see :func:`run_odometry`)."""
    timed = _TimedExtractor(extractor)
    odo = PlaneOdometry(cfg, timed, rig.sensor_origins)
    n = len(source)
    total = 0.0
    n_planes = np.zeros(n, dtype=int)
    for k in range(n):
        item = source[k]
        t_k = None if times is None else float(times[k])
        c0 = _time.perf_counter()
        if isinstance(item, Deskewed):
            timed.given = None if item.planes is None else (item.deskewed, item.planes)
            odo.register_epoch(item.scan, t_k, item.deskewed)
        elif isinstance(item, Scan):
            odo.register_epoch(item, t_k)
        else:
            odo.register_planes(list(item), t_k)
        total += _time.perf_counter() - c0
        n_planes[k] = len(odo.last_planes)
        if progress is not None:
            progress(k + 1, n)
    return OdometryRun(
        poses=np.array(odo.poses).reshape(-1, 4, 4),
        times=np.array(odo.times),
        results=odo.results,
        n_planes=n_planes,
        planes=odo.planes,
        superseded=sorted(odo.superseded),
        seconds={"extraction": timed.seconds, "odometry": total - timed.seconds},
        config=odo.config,
        extractions=timed.calls,
        reused=timed.reused,
    )


class _TimedExtractor:
    """An extractor that adds up the wall time spent in it (``seconds``) and its ``calls``;
    a call on the scan of ``given`` (scan, planes) returns those planes instead
    (``odometry.deskew_pass_skip``), counted in ``reused``."""

    def __init__(self, extractor: Extractor | None) -> None:
        self.extractor = extractor
        self.seconds = 0.0
        self.calls = self.reused = 0
        self.given: tuple[Scan, list[Plane]] | None = None

    def __call__(self, *args: object, **kwargs: object) -> list[Plane]:
        self.calls += 1
        if self.given is not None and args and args[0] is self.given[0]:
            self.reused += 1
            return list(self.given[1])
        if self.extractor is None:
            self.extractor = default_extractor()
        return self.timed(self.extractor, *args, **kwargs)

    def timed(self, function: Callable[..., T], *args: object, **kwargs: object) -> T:
        """``function(*args, **kwargs)``, its wall time added to ``seconds`` (the
        odometry's own extractions, ``odometry.deskew_twist: coplanar``)."""
        c0 = _time.perf_counter()
        out = function(*args, **kwargs)
        self.seconds += _time.perf_counter() - c0
        return out
