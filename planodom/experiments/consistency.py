"""Consistency of the smoothing's covariances: NEES against the truth on simulated runs.

For each scene, range-noise sigma and seed the isoclinal rig is simulated, planes are
extracted, the delta = 1 odometry gives the initial trajectory and the relative poses for
delta = 1..D are estimated (as :func:`planodom.smoothing.run.run_smoothing` does). Then:

- **relative poses** (the odometry, per step): the 5-DoF error of each measured relative
  pose (``planodom_factors.pose5.pose5_error``: rotation vector, horizontal translation) against
  the true one, whitened by the covariance its between factor would get
  (:func:`planodom.smoothing.noise.between_covariance`: the propagated covariance of
  :mod:`planodom.odometry.propagate` in the factor's tangent, plus the smoothing floors
  and the deskewing error, :mod:`planodom.smoothing.deskew_noise`);
- **planes**: the error of each extracted plane against its true surface (its
  ``truth_id``) in ``OrientedPlane3`` tangent coordinates (Unit3 basis of the measured
  normal (2), offset (1)), whitened by the TLS fit covariance and by the covariance the
  plane factor uses (:func:`planodom.smoothing.noise.plane_covariance`);
- **smoothed poses** (batch, for each graph variant): per epoch k >= 1,
  ``xi = Log(T_k^-1 G_k)`` in gtsam's Pose3 tangent (rot x, y, z; x, y, z, body frame)
  with estimate and truth both relative to their first pose, whitened by the batch
  covariance (relative to the first pose unless ``covariances_relative_to_first`` is
  off). Body z is left out: the 5-DoF factors never observe it, only ground planes and
  the weak vertical random-walk factor do, so it is not a DoF of the odometry. NEES5
  uses the other five (x, y, roll, pitch, yaw to first order at small roll and pitch):
  ``xi5^T P5^-1 xi5`` with ``P5`` the (5, 5) sub-block of the (6, 6) covariance, i.e.
  z marginalised.

An honest covariance gives NEES ~ chi2(dof), mean dof. The two-sided 95 % interval for the
average of N independent NEES values is ``chi2.ppf([0.025, 0.975], N dof) / N``. Relative
poses and planes are nearly independent from one to the next. The smoothed epochs of a
run are not: the errors of one trajectory are strongly correlated, so the interval with
N = all epochs ("indep.") is too narrow for them, and the one with N = the number of runs
("per run", as if each run gave one chi2 sample) the other extreme; a consistent
smoother's average lies inside the latter.

Graph variants (:data:`VARIANTS`): the configuration as given ("graph"), every relative
pose beside the plane factors ("all", double counting), between factors only
("between"), plane factors only ("planes").
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.experiments.simulated import Simulation, simulate_level
from planodom.geometry import Plane, plane_tangent_covariance
from planodom.metrics import pose_nees, relative_to_first, summarize
from planodom.odometry import RelativePose
from planodom.smoothing.batch import SmoothingResult, smooth_batch
from planodom.smoothing.deskew_noise import DeskewNoise, deskew_from_config
from planodom.smoothing.noise import between_covariance, plane_covariance
from planodom_factors.pose5 import pose5_error

#: Graph variants: smoothing config changes applied on top of the given config.
VARIANTS: dict[str, dict[str, object]] = {
    "graph": {},
    "all": {"between_factors": "all"},
    "between": {"between_factors": "all", "min_landmark_epochs": 10**9},
    "planes": {"between_factors": "none"},
}


@dataclass
class ConsistencyInputs:
    """One simulated run, extracted and through the odometry.

    Attributes:
        scene, noise (m), seed: what was simulated.
        planes: per epoch, the extracted planes (base frame).
        relatives: relative poses for delta = 1..D (odometry).
        gt_poses: (E, 4, 4) truth relative to its first pose.
        T_world_first: (4, 4) the true first pose in the scene's frame.
        surfaces: surface id -> (4,) true plane ``(n, d)`` in the scene's frame.
    """

    scene: str
    noise: float
    seed: int
    planes: list[list[Plane]]
    relatives: list[RelativePose]
    gt_poses: np.ndarray
    T_world_first: np.ndarray
    surfaces: dict[int, np.ndarray]


def simulate_inputs(
    scene: str, noise: float, config: PlanodomConfig, seed: int = 1, **simulation: Any
) -> ConsistencyInputs:
    """Simulate (``simulation``: ``n_epochs``, ``motion`` of
    :class:`~planodom.experiments.simulated.Simulation`), extract and run the odometry
    (delta = 1..``smoothing.delta_max``)."""
    from planodom.odometry import run_odometry
    from planodom.odometry.deskew import time_spread
    from planodom.smoothing.run import relative_poses, with_batch_jacobians

    level = simulate_level(
        scene, noise, with_batch_jacobians(config), Simulation(seed, **simulation)
    )
    sim, planes = level.sim, level.planes
    assert planes is not None
    odo = run_odometry(planes, config.updated({"odometry.delta": 1}), times=sim.times.tolist())
    D = config.smoothing.delta_max
    spread = [time_spread(scan) for scan in sim]
    relatives = relative_poses(planes, config, range(1, D + 1), odo.poses, time_spread=spread)
    surfaces = {s.id: np.append(s.normal, s.offset) for s in sim.scene.surfaces}
    first = sim.poses[0]
    return ConsistencyInputs(scene, noise, seed, planes, relatives, level.gt_poses, first, surfaces)


def deskew_model(relatives: Iterable[RelativePose], config: SmoothingConfig) -> DeskewNoise | None:
    """The deskewing error model the graph builds from these relative poses (batch), or
    None when ``deskew_noise`` is off."""
    model = deskew_from_config(config.deskew_noise)
    if model is None:
        return None
    for r in relatives:
        model.add(r)
    return model


def relative_pose_nees(
    relatives: Iterable[RelativePose], gt_poses: np.ndarray, config: SmoothingConfig
) -> dict[int, np.ndarray]:
    """delta -> (M, 3) NEES of the measured 5-DoF relative poses: all 5 DoF, the rotation
    (3) and the translation (2), against their between factors' covariances."""
    out: dict[int, list[tuple[float, float, float]]] = {}
    relatives = list(relatives)
    deskew = deskew_model(relatives, config)
    for r in relatives:
        if not r.translation_observed:
            continue
        e, _, _ = pose5_error(np.asarray(r.T_prev_curr), gt_poses[r.prev], gt_poses[r.curr])
        dsk = None if deskew is None else deskew.relative_covariance(r.prev, r.curr)
        P = between_covariance(r, config, dsk)
        out.setdefault(r.delta, []).append(
            (
                e @ np.linalg.solve(P, e),
                e[:3] @ np.linalg.solve(P[:3, :3], e[:3]),
                e[3:] @ np.linalg.solve(P[3:, 3:], e[3:]),
            )
        )
    return {d: np.array(v) for d, v in sorted(out.items())}


def plane_errors(plane: Plane, true_plane: np.ndarray, T_world_base: np.ndarray) -> np.ndarray:
    """(3,) error of a measured plane against the true world plane (4,), in the measured
    plane's ``OrientedPlane3`` tangent (Unit3 basis (2), offset (1)) as
    :func:`planodom.geometry.plane_tangent_covariance` has it; the truth is taken with the
    measured orientation."""
    n_w, d_w = true_plane[:3], true_plane[3]
    n = T_world_base[:3, :3].T @ n_w
    d = d_w + n_w @ T_world_base[:3, 3]
    if n @ plane.normal < 0:
        n, d = -n, -d
    dn = np.asarray(gtsam.Unit3(plane.normal).localCoordinates(gtsam.Unit3(n)))
    return np.append(dn, d - plane.offset)


def plane_nees(inputs: ConsistencyInputs, config: SmoothingConfig) -> np.ndarray:
    """(M, 2) NEES (3 DoF) of every labelled plane: with the TLS covariance and with the
    plane factor's covariance."""
    rows = []
    deskew = deskew_model(inputs.relatives, config)
    for k, planes in enumerate(inputs.planes):
        T = inputs.T_world_first @ inputs.gt_poses[k]
        for p in planes:
            if p.truth_id not in inputs.surfaces or p.covariance is None:
                continue
            xi = plane_errors(p, inputs.surfaces[p.truth_id], T)
            tls = plane_tangent_covariance(p)
            # a shared deskewed frame: a plane's marginal error holds all of it
            dsk = None if deskew is None else deskew.plane_pose_covariance(k)
            dsk = deskew.pose_covariance(k) if deskew and deskew.shared_frame else dsk
            change = None if deskew is None else deskew.plane_motion_change(k)
            used = plane_covariance(p, config, dsk, change)
            rows.append(
                (
                    xi @ np.linalg.solve(0.5 * (tls + tls.T), xi),
                    xi @ np.linalg.solve(used, xi),
                )
            )
    return np.array(rows).reshape(-1, 2)


def smoothed_nees(result: SmoothingResult, gt_poses: np.ndarray) -> np.ndarray:
    """(E - 1,) NEES over x, y, roll, pitch, yaw (body z marginalised) of epochs 1..E-1,
    estimate and truth relative to their first pose (module docstring)."""
    if result.covariances is None:
        return np.full(len(result.poses) - 1, np.nan)
    est = relative_to_first(result.poses)
    gt = relative_to_first(gt_poses)
    return pose_nees(est[1:], result.covariances[1:], gt[1:], dofs=range(5))


def variant_config(config: SmoothingConfig, variant: str) -> SmoothingConfig:
    """The smoothing config of a graph variant (:data:`VARIANTS`)."""
    changes = {f"smoothing.{key}": value for key, value in VARIANTS[variant].items()}
    return PlanodomConfig(smoothing=config).updated(changes, source=variant).smoothing


def chi2_interval(dof: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Two-sided ``level`` interval of the average of ``n`` independent chi2(dof) values."""
    if n < 1:
        return float("nan"), float("nan")
    a = (1.0 - level) / 2.0
    lo, hi = chi2.ppf([a, 1.0 - a], dof * n) / n
    return float(lo), float(hi)


def _interval(dof: int, n: int) -> str:
    lo, hi = chi2_interval(dof, n)
    return f"[{lo:.2f}, {hi:.2f}]"


def _stats(values: np.ndarray) -> tuple[int, float, float]:
    v = values[np.isfinite(values)]
    if len(v) == 0:
        return 0, float("nan"), float("nan")
    return len(v), float(np.mean(v)), float(np.median(v))


def consistency_tables(
    inputs_list: Sequence[ConsistencyInputs],
    config: SmoothingConfig,
    variants: Sequence[str] = ("graph",),
) -> dict[str, list[dict[str, object]]]:
    """Tables "odometry", "planes" and "smoothed" (rows of flat dicts) over the runs,
    grouped by scene and noise level (seeds pooled)."""
    groups: dict[tuple[str, float], list[ConsistencyInputs]] = {}
    for inp in inputs_list:
        groups.setdefault((inp.scene, inp.noise), []).append(inp)
    odo_rows, plane_rows, smooth_rows = [], [], []
    for (scene, noise), runs in groups.items():
        head = {"scene": scene, "noise_mm": noise * 1000, "runs": len(runs)}
        per_delta: dict[int, list[np.ndarray]] = {}
        for inp in runs:
            for d, v in relative_pose_nees(inp.relatives, inp.gt_poses, config).items():
                per_delta.setdefault(d, []).append(v)
        for d, parts in sorted(per_delta.items()):
            v = np.concatenate(parts)
            n, mean, median = _stats(v[:, 0])
            odo_rows.append(head | {
                "delta": d, "n": n, "mean_nees5": mean, "chi2_95_mean": _interval(5, n),
                "median_nees5": median, "chi2_median": chi2.median(5),
                "mean_rot3": float(np.mean(v[:, 1])), "mean_trans2": float(np.mean(v[:, 2])),
                "above_q99": float(np.mean(v[:, 0] > chi2.ppf(0.99, 5))),
            })  # fmt: skip
        pv = np.concatenate([plane_nees(inp, config) for inp in runs])
        gross = pv[:, 0] > chi2.ppf(0.999, 3)
        n, _, med_tls = _stats(pv[:, 0])
        plane_rows.append(head | {
            "n": n, "gross": float(np.mean(gross)), "chi2_median": chi2.median(3),
            "median_tls": med_tls, "mean_tls_no_gross": float(np.mean(pv[~gross, 0])),
            "median_used": float(np.median(pv[:, 1])),
            "mean_used_no_gross": float(np.mean(pv[~gross, 1])),
            "chi2_95_mean": _interval(3, int(np.sum(~gross))),
        })  # fmt: skip
        for variant in variants:
            cfg = variant_config(config, variant)
            values, ates, between, planes = [], [], 0, 0
            for inp in runs:
                res = smooth_batch(inp.planes, inp.relatives, cfg)
                values.append(smoothed_nees(res, inp.gt_poses))
                ates.append(summarize(res.poses, inp.gt_poses, align="origin")["ate_rmse_m"])
                between += res.stats.between
                planes += res.stats.plane_factors
            n, mean, median = _stats(np.concatenate(values))
            smooth_rows.append(head | {
                "variant": variant, "n": n, "mean_nees5": mean,
                "chi2_95_indep": _interval(5, n), "chi2_95_per_run": _interval(5, len(runs)),
                "median_nees5": median, "ate_rmse_m": float(np.mean(ates)),
                "between": between, "plane_factors": planes,
            })  # fmt: skip
    return {"odometry": odo_rows, "planes": plane_rows, "smoothed": smooth_rows}


def run_consistency_experiment(
    scenes: Sequence[str] = ("paper-loop",),
    noise_levels: Sequence[float] = (0.006, 0.02, 0.1),
    seeds: Sequence[int] = (1,),
    n_epochs: int | None = 200,
    config: PlanodomConfig | None = None,
    variants: Sequence[str] = ("graph",),
    motion: str = "snapshot",
    progress: Callable[[str], None] | None = None,
) -> dict[str, list[dict[str, object]]]:
    """Simulate every (scene, noise, seed) and return :func:`consistency_tables`."""
    cfg = config or PlanodomConfig()
    say = progress or (lambda msg: None)
    inputs = []
    for scene in scenes:
        for noise in noise_levels:
            for seed in seeds:
                say(f"{scene}, sigma = {noise * 1000:g} mm, seed {seed}")
                inputs.append(
                    simulate_inputs(scene, noise, cfg, seed, n_epochs=n_epochs, motion=motion)
                )
    say("smoothing")
    return consistency_tables(inputs, cfg.smoothing, variants)
