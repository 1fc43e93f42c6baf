"""Smoothing against the paper's odometry: four noise levels, two scenes, four estimators.

For each scene (default loop, urban canyon) and range-noise sigma (0, 6 mm, 2 cm, 10 cm) the
isoclinal rig is simulated, planes are extracted once, and the trajectory is estimated by

- ``odometry d=1``: the paper's odometry, epoch k against epoch k - 1, chained;
- ``odometry d=D``: the paper's future work, epoch k against epoch k - D, chained;
- ``windowed``: fixed-lag smoothing over W epochs with relative poses for delta = 1..D;
- ``batch``: the whole sequence in one graph (same factors), with marginal covariances.

Outputs (``out/``): ``trajectories_<scene>.png`` (top views over the truth, one panel per
noise level), ``summary.md`` / ``summary.csv`` (ATE and RPE via evo, drift at the end,
runtime, epochs per second), ``nees.md`` / ``nees.csv`` (consistency of the batch poses
against their marginal covariances), ``config.yaml``.

NEES (:func:`planodom.metrics.pose_nees`): for each epoch, ``xi = Local(T_est, T_true)``
(gtsam's Pose3 tangent at the estimate, the frame of its marginal covariance P) and
``xi^T P^-1 xi``; over the 6 DoF and over the 5 observed ones (body z marginalised, which
only the weak vertical prior and ground planes constrain). An honest covariance gives
NEES ~ chi2(dof): the table reports the mean and median (chi2 medians: 5.35 for 6 DoF,
4.35 for 5), the fraction of epochs inside the two-sided 95 % interval of chi2(dof), and
that interval. The epochs' NEES are correlated
(one trajectory), so these are diagnostics, not a test.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from planodom.config import PlanodomConfig
from planodom.experiments.paper import PAPER_NOISE_LEVELS
from planodom.experiments.plots import plot_panels
from planodom.experiments.simulated import (
    DEFAULT_SIMULATION,
    SimulatedLevel,
    Simulation,
    simulate_level,
)
from planodom.experiments.tables import ExperimentResult, write_tables
from planodom.metrics import pose_nees, summarize
from planodom.odometry import run_odometry
from planodom.odometry.deskew import time_spread
from planodom.smoothing.batch import SmoothingResult, smooth_batch
from planodom.smoothing.run import relative_poses, with_batch_jacobians
from planodom.smoothing.windowed import smooth_windowed

#: Scenes of the comparison (built-in simulator names).
SCENES = ("paper-loop", "urban-canyon")
#: Estimators in table order, and their plot colours.
COLOURS = {
    "odometry d=1": "tab:green",
    "odometry d=D": "tab:orange",
    "windowed": "tab:purple",
    "batch": "tab:red",
}


@dataclass
class EstimatorRun:
    """One estimate of one simulated run.

    Attributes:
        scene, noise (m), method: what was run. poses: (E, 4, 4) estimate, first at
        identity. gt_poses: (E, 4, 4) truth relative to its first pose. seconds: wall
        time of the estimator itself (see ``summary_rows``). unresolved: epochs without a
        resolved relative pose. smoothing: the smoother's result (smoothers only).
    """

    scene: str
    noise: float
    method: str
    poses: np.ndarray
    gt_poses: np.ndarray
    seconds: float
    unresolved: int
    smoothing: SmoothingResult | None = None


#: The smoothing experiment's runs, tables "summary" and "nees", and files.
SmoothingExperiment = ExperimentResult[EstimatorRun]


def summary_rows(runs: Sequence[EstimatorRun]) -> list[dict[str, object]]:
    """Per scene, noise level and estimator: ATE, RPE, drift, runtime."""
    rows = []
    for r in runs:
        m = summarize(r.poses, r.gt_poses, align="origin")
        n = len(r.poses)
        rows.append(
            {
                "scene": r.scene,
                "noise_mm": r.noise * 1000,
                "method": r.method,
                "epochs": n,
                "unresolved": r.unresolved,
                "ate_rmse_m": m["ate_rmse_m"],
                "rpe_trans_rmse_m": m["rpe_trans_rmse_m"],
                "rpe_rot_rmse_deg": m["rpe_rot_rmse_deg"],
                "drift_m": m["drift_m"],
                "drift_percent": m["drift_percent"],
                "seconds": r.seconds,
                "epochs_per_s": n / r.seconds if r.seconds > 0 else float("nan"),
            }
        )
    return rows


def nees_rows(runs: Sequence[EstimatorRun]) -> list[dict[str, object]]:
    """Consistency of the batch runs' marginal covariances (see module docstring)."""
    rows = []
    for r in runs:
        res = r.smoothing
        if r.method != "batch" or res is None:
            continue
        row: dict[str, object] = {"scene": r.scene, "noise_mm": r.noise * 1000}
        for dof in (6, 5):  # 5: body z, unobserved by the odometry, marginalised
            lo, hi = chi2.ppf([0.025, 0.975], dof)
            v = np.zeros(0)
            if res.covariances is not None:  # epoch 0 is the prior: left out
                nees = pose_nees(res.poses[1:], res.covariances[1:], r.gt_poses[1:], range(dof))
                v = nees[np.isfinite(nees)]
            row[f"mean_nees{dof}"] = float(np.mean(v)) if len(v) else float("nan")
            row[f"median_nees{dof}"] = float(np.median(v)) if len(v) else float("nan")
            row[f"inside95_{dof}dof"] = float(np.mean((v >= lo) & (v <= hi))) if len(v) else 0.0
            row[f"chi2_95_{dof}dof"] = f"[{lo:.2f}, {hi:.2f}]"
        row["note"] = "" if res.covariances is not None else (res.covariance_note or "none")
        rows.append(row)
    return rows


def plot_trajectories(runs: Sequence[EstimatorRun], scene: str, path: Path) -> None:
    """Top views, one panel per noise level: truth (crosses) and every estimator."""
    here = [r for r in runs if r.scene == scene]
    panels = []
    for noise in sorted({r.noise for r in here}):
        level = [r for r in here if r.noise == noise]
        tracks = [(r.method, r.poses, COLOURS.get(r.method)) for r in level]
        title = f"{scene}, sigma = {noise * 1000:g} mm"
        panels.append((title, level[0].gt_poses[:, :3, 3], tracks))
    plot_panels(panels, path)


def run_scene_level(
    level: SimulatedLevel, config: PlanodomConfig, say: Callable[[str], None] = lambda msg: None
) -> list[EstimatorRun]:
    """The four estimators on one simulated run (its planes extracted once, shared)."""
    D = config.smoothing.delta_max
    scene, noise, gt, planes = level.scene, level.noise, level.gt_poses, level.planes
    assert planes is not None, "the smoothing experiment needs the extracted planes"
    times = level.sim.times.tolist()
    runs = []
    say(f"{scene}: odometry d=1 and d={D}")
    odo1 = run_odometry(planes, config.updated({"odometry.delta": 1}), times=times)
    runs.append(EstimatorRun(scene, noise, "odometry d=1", odo1.poses, gt,
                             odo1.seconds["odometry"], odo1.n_unresolved))  # fmt: skip
    odoD = run_odometry(planes, config.updated({"odometry.delta": D}), times=times)
    runs.append(EstimatorRun(scene, noise, "odometry d=D", odoD.poses, gt,
                             odoD.seconds["odometry"], odoD.n_unresolved))  # fmt: skip

    say(f"{scene}: relative poses delta = 1..{D}")
    c0 = time.perf_counter()
    spread = [time_spread(scan) for scan in level.sim]
    relatives = relative_poses(planes, config, range(1, D + 1), odo1.poses, time_spread=spread)
    front = time.perf_counter() - c0  # shared by both smoothers
    for method, smooth in (("windowed", smooth_windowed), ("batch", smooth_batch)):
        say(f"{scene}: {method} smoothing")
        res = smooth(planes, relatives, config.smoothing)
        runs.append(EstimatorRun(scene, noise, method, res.poses, gt, res.runtime_s,
                                 len(res.stats.unresolved_epochs), res))  # fmt: skip
    say(f"{scene}: extraction {level.extraction_s:.1f} s, relative poses {front:.1f} s")
    return runs


def run_smoothing_experiment(
    out: str | Path | None = None,
    noise_levels: Sequence[float] = PAPER_NOISE_LEVELS,
    scenes: Sequence[str] = SCENES,
    config: PlanodomConfig | None = None,
    window: int = 10,
    delta: int = 3,
    simulation: Simulation = DEFAULT_SIMULATION,
    progress: Callable[[str], None] | None = None,
) -> SmoothingExperiment:
    """Run the comparison; write figures and tables to ``out`` when given.

    Args:
        out: output directory (created), or None to only compute.
        noise_levels: range noise sigmas, metres. scenes: built-in scene names.
        config: base configuration; ``smoothing.window`` / ``delta_max`` are replaced.
        window: W of the fixed-lag smoother. delta: D (odometry d=D and delta = 1..D).
        simulation: seed, epochs per run (default: the scene's whole path) and motion
            (:class:`~planodom.experiments.simulated.Simulation`).
        progress: called with a short message at each step.

    The ``seconds`` of a smoother are its own (graph building and optimisation); the
    relative poses for delta = 1..D, shared by both smoothers, are reported by ``progress``.
    """
    changes = {"smoothing.window": window, "smoothing.delta_max": delta}
    base = (config or PlanodomConfig()).updated(changes, source="smoothing experiment")
    say = progress or (lambda msg: None)
    runs: list[EstimatorRun] = []
    for scene in scenes:
        for noise in noise_levels:
            say(f"{scene}: simulating sigma = {noise * 1000:g} mm and extracting planes")
            extracting = with_batch_jacobians(base)  # the batch's sandwich reads them
            level = simulate_level(scene, noise, extracting, simulation)
            runs += run_scene_level(level, base, say)
    result = SmoothingExperiment(runs, {"summary": summary_rows(runs), "nees": nees_rows(runs)})
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = {f"trajectories_{s}": out / f"trajectories_{s}.png" for s in scenes}
        for scene in scenes:
            plot_trajectories(runs, scene, files[f"trajectories_{scene}"])
        files |= write_tables(out, result.tables)
        files["config"] = out / "config.yaml"
        base.to_yaml(files["config"])
        result.files = files
    return result
