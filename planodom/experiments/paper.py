"""The paper's section VI with our simulator: four noise levels, two pipelines.

For each range-noise sigma (0, 6 mm, 2 cm, 10 cm) the default paper loop is simulated with
the isoclinal rig, planes are extracted, and the odometry runs with the two sequences of
the paper's Fig. 5: (LDA, WOCSC-R, SDA, mean-T) = ``"sda-mean"`` and
(LDA, WOCSC-R, WOCSC-T) = ``"wocsc"`` (more pipelines can be given), each as the paper
has it: without the least-squares refinement over all associated planes that planodom adds
by default (``odometry.refinement``; with it both pipelines give the same translation).
The method ``"planodom"`` runs the configuration as given. Outputs:

- ``trajectories.png``: Fig. 5, top view per noise level: truth (blue crosses),
  sda-mean (green), wocsc (magenta);
- ``precision.md`` / ``precision.csv``: Fig. 6 and 7, mean and standard deviation of the
  roll, pitch and yaw rate errors (deg/s) and of the x, y translation errors (m per
  epoch) per method and noise level, over the epochs whose status is "ok";
- ``summary.md`` / ``summary.csv``: per method and level the unresolved and degenerate
  epoch counts, rms errors, the worst error over "ok" epochs, drift and ATE, and the
  front end's epochs per second.

With ``motion="snapshot"`` (the paper's simulator: every sweep of an epoch cast from one
pose) the planes are extracted once per level and shared by the methods; with
``"continuous"`` each method deskews with its own constant-velocity twist, so each runs
extraction itself.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.plots import plot_panels
from planodom.experiments.simulated import DEFAULT_SIMULATION, Simulation, simulate_level
from planodom.experiments.tables import ExperimentResult, Rows, write_tables
from planodom.geometry import invert_transform
from planodom.metrics import POSE5_NAMES, drift, per_epoch_errors, relative_motions, summarize
from planodom.odometry import OdometryRun, run_odometry

#: The paper's noise levels, metres.
PAPER_NOISE_LEVELS = (0.0, 0.006, 0.02, 0.10)
#: The two sequences of the paper's Fig. 5, and planodom's default configuration.
PAPER_METHODS = ("sda-mean", "wocsc", "planodom")
#: Plot colours of Fig. 5.
COLOURS = {
    "planodom": "tab:blue",
    "sda-mean": "tab:green",
    "wocsc": "magenta",
    "ocsc": "tab:orange",
    "mean": "tab:red",
}


@dataclass
class LevelRun:
    """One noise level and method: the run and its errors against the truth.

    Attributes:
        noise: range noise sigma, metres. method: pipeline name.
        run: the odometry run. gt_poses: (E, 4, 4) truth, first epoch at identity.
        errors: (E-1, 5) per-epoch increment errors (roll, pitch, yaw rad; x, y m).
        ok: (E-1,) bool, epochs whose status is "ok".
        epoch_rate: Hz. seconds: wall time of extraction and odometry.
    """

    noise: float
    method: str
    run: OdometryRun
    gt_poses: np.ndarray
    errors: np.ndarray
    ok: np.ndarray
    epoch_rate: float
    seconds: dict[str, float] = field(default_factory=dict)


#: The paper experiment's runs, tables "precision" and "summary", and files.
PaperExperiment = ExperimentResult[LevelRun]


def _level_run(noise, method, run, gt, rate, seconds) -> LevelRun:
    gt_rel = invert_transform(gt[0])[None] @ gt
    err = per_epoch_errors(relative_motions(run.poses), relative_motions(gt_rel))
    errors = np.column_stack([err[name] for name in POSE5_NAMES])
    ok = np.array([r is not None and r.status == "ok" for r in run.results[1:]], dtype=bool)
    return LevelRun(noise, method, run, gt_rel, errors, ok, rate, seconds)


def precision_rows(runs: Sequence[LevelRun]) -> list[dict[str, object]]:
    """Fig. 6 / 7 rows: per noise level, method and DoF, the mean and std of the errors.

    Angular DoF as rate errors in deg/s (increment error times the epoch rate),
    translations in metres per epoch; over "ok" epochs.
    """
    rows = []
    for lr in runs:
        e = lr.errors[lr.ok]
        for j, name in enumerate(POSE5_NAMES):
            angular = j < 3
            x = np.degrees(e[:, j]) * lr.epoch_rate if angular else e[:, j]
            rows.append(
                {
                    "noise_m": lr.noise,
                    "method": lr.method,
                    "dof": f"{name} rate" if angular else name,
                    "unit": "deg/s" if angular else "m",
                    "mean": float(x.mean()) if len(x) else float("nan"),
                    "std": float(x.std()) if len(x) else float("nan"),
                    "epochs": int(len(x)),
                }
            )
    return rows


def summary_rows(runs: Sequence[LevelRun]) -> list[dict[str, object]]:
    """Per level and method: counts, rms and worst errors, drift, ATE and throughput."""
    rows = []
    for lr in runs:
        e = lr.errors[lr.ok]
        rot = np.degrees(np.linalg.norm(e[:, :3], axis=1)) if len(e) else np.zeros(0)
        xy = np.linalg.norm(e[:, 3:5], axis=1) if len(e) else np.zeros(0)
        d = drift(lr.run.poses, lr.gt_poses, xy_only=True)
        m = summarize(lr.run.poses, lr.gt_poses, align="origin")
        n = len(lr.run.poses)
        front = lr.seconds.get("extraction", 0.0) + lr.seconds.get("odometry", 0.0)
        rows.append(
            {
                "noise_m": lr.noise,
                "method": lr.method,
                "epochs": n,
                "unresolved": lr.run.n_unresolved,
                "degenerate": lr.run.n_degenerate,
                "rot_rms_deg": float(np.sqrt(np.mean(rot**2))) if len(rot) else float("nan"),
                "xy_rms_m": float(np.sqrt(np.mean(xy**2))) if len(xy) else float("nan"),
                "rot_max_deg": float(rot.max()) if len(rot) else float("nan"),
                "xy_max_m": float(xy.max()) if len(xy) else float("nan"),
                "drift_m": d["final_error"],
                "drift_percent": d["percent"],
                "ate_rmse_m": m["ate_rmse_m"],
                "front_end_epochs_per_s": n / front if front > 0 else float("nan"),
            }
        )
    return rows


def precision_markdown(rows: Rows) -> str:
    """Fig. 6 / 7 as one Markdown table: a row per method and DoF, ``mean / std`` per level."""
    levels = sorted({r["noise_m"] for r in rows})
    keys = list(dict.fromkeys((r["method"], r["dof"], r["unit"]) for r in rows))
    cell = {(r["noise_m"], r["method"], r["dof"]): r for r in rows}
    head = ["method", "DoF", "unit"] + [f"sigma {lv * 1000:g} mm: mean / std" for lv in levels]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for method, dof, unit in keys:
        vals = []
        for lv in levels:
            r = cell.get((lv, method, dof))
            vals.append("-" if r is None else f"{r['mean']:.3g} / {r['std']:.3g}")
        lines.append("| " + " | ".join([method, dof, unit, *vals]) + " |")
    return "\n".join(lines) + "\n"


def plot_trajectories(runs: Sequence[LevelRun], path: Path) -> None:
    """Fig. 5: one top view per noise level, truth and every method's trajectory."""
    panels = []
    for noise in sorted({lr.noise for lr in runs}):
        here = [lr for lr in runs if lr.noise == noise]
        tracks = [(lr.method, lr.run.poses, COLOURS.get(lr.method)) for lr in here]
        panels.append((f"sigma = {noise * 1000:g} mm", here[0].gt_poses[:, :3, 3], tracks))
    plot_panels(panels, path)


def _method_changes(method: str) -> dict[str, object]:
    """Config changes for one method: a pipeline name runs as in the paper (no refinement
    over all associated planes); ``"planodom"`` is the configuration as given."""
    if method == "planodom":
        return {}
    return {"odometry.pipeline": method, "odometry.refinement": "none"}


def run_paper_experiment(
    out: str | Path | None = None,
    noise_levels: Sequence[float] = PAPER_NOISE_LEVELS,
    methods: Sequence[str] = PAPER_METHODS,
    simulation: Simulation = DEFAULT_SIMULATION,
    config: PlanodomConfig | None = None,
    progress: Callable[[str], None] | None = None,
) -> PaperExperiment:
    """Run the experiment; write its figures and tables to ``out`` when given.

    Args:
        out: output directory (created), or None to only compute.
        noise_levels: range noise sigmas, metres. methods: pipeline names.
        simulation: seed, epochs per level (default: one lap) and motion: "snapshot" (the
            paper's simulator) or "continuous" (deskewing).
        config: base configuration; a paper pipeline replaces its ``odometry.pipeline``
            and switches the refinement off (:func:`_method_changes`).
        progress: called with a short message at each step.
    """
    base = config or PlanodomConfig()
    say = progress or (lambda msg: None)
    runs: list[LevelRun] = []
    for noise in noise_levels:
        say(f"simulating sigma = {noise * 1000:g} mm and extracting planes")
        level = simulate_level("paper-loop", noise, base, simulation,
                               extract=simulation.motion == "snapshot")  # fmt: skip
        sim = level.sim
        for method in methods:
            say(f"odometry {method} at sigma = {noise * 1000:g} mm")
            cfg = base.updated(_method_changes(method), source="paper experiment")
            if level.planes is not None:
                run = run_odometry(level.planes, cfg, times=sim.times.tolist())
                seconds = {"extraction": level.extraction_s, "odometry": run.seconds["odometry"]}
            else:
                run = run_odometry(sim, cfg, sim.rig)
                seconds = dict(run.seconds)
            runs.append(_level_run(noise, method, run, sim.poses, sim.epoch_rate, seconds))

    tables = {"precision": precision_rows(runs), "summary": summary_rows(runs)}
    result = PaperExperiment(runs, tables)
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = {"trajectories": out / "trajectories.png", "config": out / "config.yaml"}
        plot_trajectories(runs, files["trajectories"])
        files |= write_tables(out, tables, markdown={"precision": precision_markdown})
        base.to_yaml(files["config"])
        result.files = files
    return result
