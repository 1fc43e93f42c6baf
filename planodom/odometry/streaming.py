"""Streaming odometry: one epoch in, one pose out (``PlaneOdometry``), and whole runs.

Per epoch k: extract planes (deskewed with the constant-velocity twist of the last
estimate), associate them with the planes of epoch ``k - delta`` (a short history is
kept), estimate the relative pose with the constant-velocity prediction as prior, and
chain: ``T_world_k = T_world_{k-delta} @ T_{k-delta}_k``. The first epoch defines the
world frame (identity). When the reference epoch has fewer than two planes, the latest
earlier epoch with two or more is used instead (bounds scaled by the gap). An unresolved
epoch (no associated non-parallel pair) is bridged by constant velocity (the last
increment's twist times the elapsed time; standing still before any motion is known) and
marked: its result has ``status == "unresolved"`` and ``fallback == True``.
"""

from __future__ import annotations

import time as _time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace

import gtsam
import numpy as np

from planodom.association import PlaneArrays
from planodom.config import PlanodomConfig
from planodom.geometry import Plane, invert_transform
from planodom.odometry.pipeline import RelativePose, estimate_relative_pose
from planodom.scan import Scan

Extractor = Callable[..., list[Plane]]
_RANK = {"unresolved": 0, "degenerate": 1, "ok": 2}


def se3_log(T: np.ndarray) -> np.ndarray:
    """Twist ``(wx, wy, wz, vx, vy, vz)`` (6,) with ``T = exp(xi)``, T (4, 4)."""
    return np.asarray(gtsam.Pose3.Logmap(gtsam.Pose3(np.asarray(T, dtype=np.float64))))


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """``exp(xi)`` (4, 4) of a twist ``(wx, wy, wz, vx, vy, vz)`` (6,)."""
    return np.asarray(gtsam.Pose3.Expmap(np.asarray(xi, dtype=np.float64)).matrix())


def with_dataset_bounds(config: PlanodomConfig, rig: object) -> PlanodomConfig:
    """``config`` with the motion bounds a dataset states, when it states any.

    A ``rig.yaml`` may say how fast its vehicle moves between consecutive epochs::

        motion_bounds: {max_translation_m: 3.0, max_rotation_deg: 45.0}

    Each bound becomes the larger of the config's and the dataset's (both are
    assumptions of a maximum, so the union is the safe one).
    """
    bounds = getattr(rig, "motion_bounds", None)  # a planodom.rig.Rig
    if bounds is None:
        return config
    a = config.association
    update = {
        key: max(float(getattr(a, key)), float(getattr(bounds, key)))
        for key in ("max_translation_m", "max_rotation_deg")
        if getattr(bounds, key) is not None
    }
    return config.model_copy(update={"association": a.model_copy(update=update)})


def motion_assumption(config: PlanodomConfig) -> str:
    """One line stating what the absolute constraints of the association assume."""
    a, d = config.association, config.odometry.delta
    return (
        f"association assumes at most {a.max_translation_m:g} m and {a.max_rotation_deg:g} deg "
        f"of motion between consecutive epochs (x{d} for delta = {d}); with a "
        f"constant-velocity prior, {a.prior_translation_m:g} m / {a.prior_rotation_deg:g} deg "
        "around it (config association.max_*/prior_*, or motion_bounds in rig.yaml)"
    )


def rig_sensor_origins(rig: object) -> np.ndarray | None:
    """Sensor positions (S, 3) (or (3,) for one sensor) of a :class:`planodom.rig.Rig`."""
    origins = getattr(rig, "sensor_origins", None)
    if origins is None or len(origins) == 0:
        return None
    origins = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    return origins[0] if len(origins) == 1 else origins


def _default_extractor() -> Extractor:
    from planodom.extraction import extract_planes

    return extract_planes


@dataclass
class _Epoch:
    """What the odometry keeps of a registered epoch: its planes (and their arrays), and,
    for re-extraction, its scan and the twist it was deskewed with (None: not deskewed)."""

    index: int
    planes: list[Plane]
    arrays: PlaneArrays
    scan: Scan | None = None
    twist: np.ndarray | None = None


class PlaneOdometry:
    """Streaming plane odometry.

    Args:
        config: the pipeline configuration (default: defaults).
        extractor: ``extractor(scan, extraction_config, twist=..., [sensor_origins=...])
            -> list[Plane]``; default :func:`planodom.extraction.extract_planes`.
        sensor_origins: sensor positions in the base frame, metres ((3,) or (S, 3) by
            ring), passed to the extractor to orient normals; None: its default.

    Attributes:
        config: the pipeline configuration.
        poses: ``T_world_base`` (4, 4) of every registered epoch (the first is identity).
        times: reference time of every epoch, seconds.
        results: per epoch the :class:`RelativePose` to its reference epoch (None for
            the first epoch); ``reference_index[k]`` says which epoch that was.
        reference_index: per epoch the epoch it was associated with: ``k - delta``, or,
            when that one has fewer than two planes, the latest earlier epoch that has
            (so that a blind epoch does not also cost the next one); -1 for the first.
        last_planes: the planes of the last epoch (a short history is kept).
    """

    def __init__(
        self,
        config: PlanodomConfig | None = None,
        extractor: Extractor | None = None,
        sensor_origins: np.ndarray | None = None,
    ):
        self.config = config or PlanodomConfig()
        self._extract = extractor
        self.sensor_origins = sensor_origins
        self.poses: list[np.ndarray] = []
        self.times: list[float] = []
        self.results: list[RelativePose | None] = []
        self.reference_index: list[int] = []
        # The last delta epochs, and the last one with two planes or more.
        self._history: deque[_Epoch] = deque(maxlen=self.config.odometry.delta)
        self._last_usable: _Epoch | None = None
        self._twist: np.ndarray | None = None
        self._velocities: deque[np.ndarray] = deque(maxlen=self.config.odometry.velocity_window)
        self._steps: list[np.ndarray] = []  # T_{k-1}_k per epoch (identity first)

    @property
    def last_relative(self) -> RelativePose | None:
        """The relative pose found for the last epoch (None before the second)."""
        return self.results[-1] if self.results else None

    @property
    def last_planes(self) -> list[Plane]:
        return self._history[-1].planes if self._history else []

    @property
    def last_pose(self) -> np.ndarray | None:
        return self.poses[-1] if self.poses else None

    @property
    def twist(self) -> np.ndarray | None:
        """Constant-velocity body twist (6,), rad/s and m/s, predicted for the next epoch
        (angular rate of the last increment, median recent linear velocity)."""
        return self._twist

    def _next_time(self, time: float | None) -> float:
        if time is not None:
            return float(time)
        if not self.times:
            return 0.0
        return self.times[-1] + self.config.odometry.epoch_period_s

    def extract(self, scan: Scan) -> list[Plane]:
        """The planes of one epoch, deskewed with the constant-velocity twist of the last
        estimate (when ``deskew`` is on and one is known)."""
        return self._extract_with(scan, self._twist if self.config.odometry.deskew else None)

    def _extract_with(self, scan: Scan, twist: np.ndarray | None) -> list[Plane]:
        """The planes of ``scan`` deskewed with exactly ``twist`` (None: not deskewed)."""
        if self._extract is None:
            self._extract = _default_extractor()
        kwargs = {} if self.sensor_origins is None else {"sensor_origins": self.sensor_origins}
        return list(self._extract(scan, self.config.extraction, twist=twist, **kwargs))

    def register_epoch(self, scan: Scan, time: float | None = None) -> np.ndarray:
        """Extract the planes of one epoch and register them; returns ``T_world_base``.

        With ``deskew`` and points spread in time, the constant-velocity twist is only a
        prediction: when the epoch's own estimate implies an angular rate or a velocity
        that differs from it by more than ``deskew_rate_tolerance_deg_s`` /
        ``deskew_speed_tolerance_mps``, the epoch is extracted again with them (at most
        ``deskew_iterations`` times, while the status does not get worse); a reference
        epoch that was never deskewed (the first) is extracted again too. When the
        predicted twist leaves the epoch unresolved or degenerate, it is also tried
        without deskewing, so that a wrong twist cannot lock the odometry out.

        Args:
            scan: the epoch's points in the base frame (with per-point times if known).
            time: the epoch's reference time, seconds (default: previous + epoch period).
        """
        ocfg = self.config.odometry
        t = self._next_time(time)
        k = len(self.poses)
        spread = bool(ocfg.deskew and scan.t is not None and len(scan.t) and np.ptp(scan.t) > 0)
        twist = self._twist if spread else None
        epoch = self._new_epoch(k, scan, twist)
        if k == 0:
            return self._commit(epoch, t, None)
        dt = t - self.times[-1]
        est = self._relative(epoch.arrays, t, k)
        if spread and dt > 0 and twist is not None and est[0].status != "ok":
            plain = self._new_epoch(k, scan, None)
            est_plain = self._relative(plain.arrays, t, k)
            if _RANK[est_plain[0].status] > _RANK[est[0].status]:
                epoch, est = plain, est_plain
        for _ in range(ocfg.deskew_iterations if spread and dt > 0 else 0):
            if est[0].status == "unresolved":
                break
            used = np.zeros(6) if epoch.twist is None else epoch.twist
            new = self._refined_twist(se3_log(est[1]) / dt, used, est[0].status == "ok")
            ref = self._reference()
            stale_ref = ref.scan is not None and ref.twist is None
            if not stale_ref and np.array_equal(new, used):
                break
            if stale_ref:
                self._reextract(ref, new)
            again = self._new_epoch(k, scan, new)
            est_again = self._relative(again.arrays, t, k)
            if _RANK[est_again[0].status] < _RANK[est[0].status]:
                break
            epoch, est = again, est_again
        return self._commit(epoch, t, est)

    def register_planes(self, planes: Sequence[Plane], time: float | None = None) -> np.ndarray:
        """Register an epoch given its planes (base frame); returns ``T_world_base`` (4, 4)."""
        t = self._next_time(time)
        planes = list(planes)
        epoch = _Epoch(len(self.poses), planes, PlaneArrays.from_planes(planes))
        est = self._relative(epoch.arrays, t, len(self.poses)) if self.poses else None
        return self._commit(epoch, t, est)

    def _new_epoch(self, k: int, scan: Scan, twist: np.ndarray | None) -> _Epoch:
        planes = self._extract_with(scan, twist)
        return _Epoch(k, planes, PlaneArrays.from_planes(planes), scan, twist)

    def _reextract(self, epoch: _Epoch, twist: np.ndarray) -> None:
        """Extract a kept epoch again with ``twist`` (its pose is not changed)."""
        epoch.planes = self._extract_with(epoch.scan, twist)
        epoch.arrays = PlaneArrays.from_planes(epoch.planes)
        epoch.twist = twist
        if len(epoch.planes) >= 2 and (
            self._last_usable is None or self._last_usable.index <= epoch.index
        ):
            self._last_usable = epoch

    def _refined_twist(self, own: np.ndarray, used: np.ndarray, measured: bool) -> np.ndarray:
        """The twist to extract again with: the epoch's own angular rate and (when its
        translation was measured) linear velocity, each only where it differs from the
        twist used by more than its tolerance; else ``used`` unchanged."""
        ocfg = self.config.odometry
        new = used.copy()
        if np.degrees(np.linalg.norm(own[:3] - used[:3])) > ocfg.deskew_rate_tolerance_deg_s:
            new[:3] = own[:3]
        if measured and np.linalg.norm(own[3:] - used[3:]) > ocfg.deskew_speed_tolerance_mps:
            new[3:] = own[3:]
        return new

    def _commit(self, epoch: _Epoch, t: float, est) -> np.ndarray:
        """Append the epoch: its pose from the step of ``est`` (None for the first)."""
        if est is None:
            T_world, result, step, ref = np.eye(4), None, np.eye(4), -1
        else:
            result, step, ref = est
            T_world = _orthonormalised(self.poses[-1] @ step)
            dt = t - self.times[-1]
            if dt > 0:
                self._twist = self._predicted_twist(se3_log(step) / dt, result.status == "ok")
        self.poses.append(T_world)
        self._steps.append(step)
        self.times.append(t)
        self.results.append(result)
        self.reference_index.append(ref)
        self._history.append(epoch)
        if len(epoch.planes) >= 2:
            self._last_usable = epoch
        return T_world

    def _predicted_twist(self, twist: np.ndarray, measured: bool) -> np.ndarray:
        """The constant-velocity twist for the next epoch: the angular rate of the last
        step, and the median linear velocity of the last ``velocity_window`` steps whose
        translation was measured (one wrong translation must not steer the deskewing and
        the prior of the following epochs; a degenerate step only repeats its prior)."""
        if measured:
            self._velocities.append(twist[3:])
        if not self._velocities:
            return twist
        return np.r_[twist[:3], np.median(np.array(self._velocities), axis=0)]

    def _reference(self) -> _Epoch:
        """The epoch the next one is associated with (see ``reference_index``)."""
        ref = self._history[0]
        if len(ref.planes) < 2 and self._last_usable is not None:
            ref = self._last_usable
        return ref

    def _relative(
        self, planes: PlaneArrays, t: float, k: int
    ) -> tuple[RelativePose, np.ndarray, int]:
        """The relative pose to the reference epoch, the step ``T_{k-1}_k`` it implies, and
        the reference's index.

        Poses are chained through steps (products of rigid transforms), never through the
        inverse of a chained world pose, so rounding cannot grow from epoch to epoch.
        """
        reference = self._reference()
        ref, ref_planes = reference.index, reference.arrays
        gap = k - ref
        T_ref_last = np.eye(4)  # T_{ref}_{k-1}
        for step in self._steps[ref + 1 :]:
            T_ref_last = T_ref_last @ step
        dt = t - self.times[-1]
        prediction = None  # constant velocity: T_{ref}_k
        if self._twist is not None and dt > 0:
            prediction = T_ref_last @ se3_exp(self._twist * dt)
        prior = prediction if self.config.odometry.use_motion_prior else None

        cfg = self.config
        if gap > 1:
            a = cfg.association
            cfg = cfg.model_copy(
                update={
                    "association": a.model_copy(
                        update={
                            "max_translation_m": a.max_translation_m * gap,
                            "max_rotation_deg": min(a.max_rotation_deg * gap, 180.0),
                        }
                    )
                }
            )
        result = estimate_relative_pose(ref_planes, planes, cfg, prior)
        if result.status == "unresolved":
            T_rel = prediction if prediction is not None else T_ref_last
            result = replace(result, T_prev_curr=T_rel, fallback=True)
        step = _orthonormalised(invert_transform(T_ref_last) @ result.T_prev_curr)
        return result, step, ref


def _orthonormalised(T: np.ndarray, tol: float = 1e-12) -> np.ndarray:
    """``T`` (4, 4) with its rotation projected on SO(3) (SVD) once rounding exceeds ``tol``."""
    R = T[:3, :3]
    if np.max(np.abs(R.T @ R - np.eye(3))) <= tol:
        return T
    U, _, Vt = np.linalg.svd(R)
    out = T.copy()
    out[:3, :3] = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    return out


@dataclass
class OdometryRun:
    """A whole run of the streaming odometry.

    Attributes:
        poses: (N, 4, 4) ``T_world_base`` per epoch (first is identity).
        times: (N,) seconds.
        results: per epoch the relative pose result (None for the first).
        n_planes: (N,) planes extracted per epoch.
        planes: the planes of every epoch (base frame), for smoothing and diagnostics.
        seconds: wall time spent in extraction and in odometry, seconds.
        config: the configuration the run used (with a dataset's motion bounds).
    """

    poses: np.ndarray
    times: np.ndarray
    results: list[RelativePose | None]
    n_planes: np.ndarray
    planes: list[list[Plane]] = field(default_factory=list)
    seconds: dict[str, float] = field(default_factory=dict)
    config: PlanodomConfig | None = None

    @property
    def statuses(self) -> list[str]:
        return ["first" if r is None else r.status for r in self.results]

    @property
    def n_unresolved(self) -> int:
        return sum(s == "unresolved" for s in self.statuses)

    @property
    def n_degenerate(self) -> int:
        return sum(s == "degenerate" for s in self.statuses)

    def rows(self) -> list[dict[str, object]]:
        """One dict per epoch: time, status, the 5-DoF increment, sigmas and diagnostics."""
        out = []
        for k, r in enumerate(self.results):
            row: dict[str, object] = {"epoch": k, "time": float(self.times[k])}
            row["n_planes"] = int(self.n_planes[k])
            if r is None:
                row["status"] = "first"
                out.append(row)
                continue
            p5, s5 = r.pose5, r.sigmas5
            row["status"] = r.status
            for i, name in enumerate(("roll", "pitch", "yaw", "x", "y")):
                row[name] = float(p5[i])
            row["z"] = float(r.T_prev_curr[2, 3])
            row["z_observed"] = r.z_observed
            for i, name in enumerate(("roll", "pitch", "yaw", "x", "y")):
                row[f"sigma_{name}"] = float(s5[i])
            row["n_lda_pairs"] = len(r.lda)
            row["n_sda"] = len(r.plane_associations)
            row["n_translation_pairs"] = r.n_translation_pairs
            rc, tc = r.rotation_consensus, r.translation_consensus
            row["rotation_error"] = rc.best_error if rc else float("nan")
            row["rotation_inliers"] = rc.n_inliers if rc else 0
            row["translation_error"] = tc.best_error if tc else float("nan")
            row["translation_inliers"] = tc.n_inliers if tc else 0
            row["used_prior"] = r.used_prior
            row["fallback"] = r.fallback
            out.append(row)
        return out


def run_odometry(
    source: Sequence[Scan] | object,
    config: PlanodomConfig | None = None,
    progress: Callable[[int, int], None] | None = None,
    extractor: Extractor | None = None,
    times: Sequence[float] | None = None,
    sensor_origins: np.ndarray | None = None,
) -> OdometryRun:
    """Run :class:`PlaneOdometry` over a sequence of epochs.

    Args:
        source: a sequence of :class:`Scan` (``len`` and indexing), e.g. a dataset; its
            ``times`` attribute (N,) seconds is used when present and ``times`` is None,
            its ``rig`` (``rig.yaml`` dict) for sensor origins and ``motion_bounds``
            (:func:`with_dataset_bounds`). Items may also be plane lists (no extraction).
        config: pipeline configuration.
        progress: called as ``progress(k, n)`` after each epoch.
        extractor: ``extractor(scan, extraction_config, twist=...) -> list[Plane]``;
            default :func:`planodom.extraction.extract_planes`.
        times: epoch reference times (N,), seconds.
        sensor_origins: see :class:`PlaneOdometry`; default: from ``source.rig`` when it
            is a ``rig.yaml`` dict with ``sensor_origins`` or a simulation ``Rig``.
    """
    cfg = with_dataset_bounds(config or PlanodomConfig(), getattr(source, "rig", None))
    if sensor_origins is None:
        sensor_origins = rig_sensor_origins(getattr(source, "rig", None))
    base_extract = extractor
    spent = {"extraction": 0.0}

    def timed_extract(*args, **kwargs) -> list[Plane]:
        nonlocal base_extract
        if base_extract is None:
            base_extract = _default_extractor()
        c0 = _time.perf_counter()
        out = base_extract(*args, **kwargs)
        spent["extraction"] += _time.perf_counter() - c0
        return out

    odo = PlaneOdometry(cfg, timed_extract, sensor_origins)
    n = len(source)  # type: ignore[arg-type]
    if times is None:
        times = getattr(source, "times", None)
    total = 0.0
    n_planes = np.zeros(n, dtype=int)
    all_planes: list[list[Plane]] = []
    for k in range(n):
        item = source[k]  # type: ignore[index]
        t_k = None if times is None else float(times[k])
        c0 = _time.perf_counter()
        if isinstance(item, Scan):
            odo.register_epoch(item, t_k)
        else:
            odo.register_planes(list(item), t_k)
        total += _time.perf_counter() - c0
        planes = odo.last_planes
        n_planes[k] = len(planes)
        all_planes.append(planes)
        if progress is not None:
            progress(k + 1, n)
    return OdometryRun(
        poses=np.array(odo.poses).reshape(-1, 4, 4),
        times=np.array(odo.times),
        results=odo.results,
        n_planes=n_planes,
        planes=all_planes,
        seconds={"extraction": spent["extraction"], "odometry": total - spent["extraction"]},
        config=cfg,
    )
