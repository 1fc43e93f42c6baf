"""The paper's section VI with our simulator: four noise levels, two pipelines.

For each range-noise sigma (0, 6 mm, 2 cm, 10 cm) the default paper loop is simulated with
the isoclinal rig, planes are extracted, and the odometry runs with the two sequences of
the paper's Fig. 5: (LDA, WOCSC-R, SDA, mean-T) = ``"sda-mean"`` and
(LDA, WOCSC-R, WOCSC-T) = ``"wocsc"`` (more pipelines can be given). Outputs:

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

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from planodom.config import PlanodomConfig
from planodom.experiments.plots import save_grid, top_view
from planodom.geometry import invert_transform
from planodom.metrics import POSE5_NAMES, drift, per_epoch_errors, relative_motions, summarize
from planodom.odometry import OdometryRun, run_odometry
from planodom.rig import Rig

#: The paper's noise levels, metres.
PAPER_NOISE_LEVELS = (0.0, 0.006, 0.02, 0.10)
#: The two sequences of the paper's Fig. 5.
PAPER_METHODS = ("sda-mean", "wocsc")
#: Plot colours of Fig. 5.
COLOURS = {"sda-mean": "tab:green", "wocsc": "magenta", "ocsc": "tab:orange", "mean": "tab:red"}


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


@dataclass
class PaperExperiment:
    """All runs of the experiment and its tables (lists of flat dicts), plus written files."""

    runs: list[LevelRun]
    precision: list[dict[str, object]]
    summary: list[dict[str, object]]
    files: dict[str, Path] = field(default_factory=dict)


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


def markdown_table(rows: Sequence[dict[str, object]], digits: int = 4) -> str:
    """A GitHub Markdown table of flat dict rows (floats in ``digits`` significant digits)."""
    if not rows:
        return ""
    cols = list(rows[0])

    def fmt(v: object) -> str:
        return f"{v:.{digits}g}" if isinstance(v, float) else str(v)

    lines = ["| " + " | ".join(cols) + " |", "|" + "---|" * len(cols)]
    lines += ["| " + " | ".join(fmt(r[c]) for c in cols) + " |" for r in rows]
    return "\n".join(lines) + "\n"


def precision_markdown(rows: Sequence[dict[str, object]]) -> str:
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
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    levels = sorted({lr.noise for lr in runs})
    ncol = min(2, len(levels))
    nrow = int(np.ceil(len(levels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.5 * ncol, 5.5 * nrow), squeeze=False)
    for ax, noise in zip(axes.ravel(), levels, strict=False):
        here = [lr for lr in runs if lr.noise == noise]
        gt = here[0].gt_poses[:, :3, 3]
        tracks = [(lr.method, lr.run.poses, COLOURS.get(lr.method)) for lr in here]
        top_view(ax, gt, tracks, f"sigma = {noise * 1000:g} mm")
    save_grid(fig, axes, len(levels), path)


def write_csv(path: Path, rows: Sequence[dict[str, object]]) -> None:
    import csv

    with path.open("w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]) if rows else [])
        writer.writeheader()
        writer.writerows(rows)


def run_paper_experiment(
    out: str | Path | None = None,
    noise_levels: Sequence[float] = PAPER_NOISE_LEVELS,
    methods: Sequence[str] = PAPER_METHODS,
    seed: int = 1,
    n_epochs: int | None = None,
    motion: str = "snapshot",
    config: PlanodomConfig | None = None,
    progress: Callable[[str], None] | None = None,
) -> PaperExperiment:
    """Run the experiment; write its figures and tables to ``out`` when given.

    Args:
        out: output directory (created), or None to only compute.
        noise_levels: range noise sigmas, metres. methods: pipeline names.
        seed: noise seed. n_epochs: epochs per level (default: one lap).
        motion: "snapshot" (the paper's simulator) or "continuous" (deskewing).
        config: base configuration; its ``odometry.pipeline`` is replaced per method.
        progress: called with a short message at each step.
    """
    from planodom.extraction import extract_planes
    from planodom.simulation import simulate_named

    base = config or PlanodomConfig()
    say = progress or (lambda msg: None)
    runs: list[LevelRun] = []
    for noise in noise_levels:
        say(f"simulating sigma = {noise * 1000:g} mm")
        sim = simulate_named("paper-loop", "isoclinal", noise=noise, seed=seed,
                             n_epochs=n_epochs, motion=motion)  # fmt: skip
        shared = None
        t_extract = 0.0
        if motion == "snapshot":
            say(f"extracting planes of {len(sim)} epochs")
            c0 = time.perf_counter()
            shared = [extract_planes(scan, base.extraction) for scan in sim]
            t_extract = time.perf_counter() - c0
        for method in methods:
            say(f"odometry {method} at sigma = {noise * 1000:g} mm")
            cfg = base.model_copy(
                update={"odometry": base.odometry.model_copy(update={"pipeline": method})}
            )
            if shared is not None:
                run = run_odometry(shared, cfg, times=sim.times)
                seconds = {"extraction": t_extract, "odometry": run.seconds["odometry"]}
            else:
                origins = np.array([s.T_base_sensor[:3, 3] for s in sim.rig.sensors])
                run = run_odometry(sim, cfg, Rig(sensor_origins=origins))
                seconds = dict(run.seconds)
            runs.append(_level_run(noise, method, run, sim.poses, sim.epoch_rate, seconds))

    result = PaperExperiment(runs, precision_rows(runs), summary_rows(runs))
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        files = {
            "trajectories": out / "trajectories.png",
            "precision_md": out / "precision.md",
            "precision_csv": out / "precision.csv",
            "summary_md": out / "summary.md",
            "summary_csv": out / "summary.csv",
            "config": out / "config.yaml",
        }
        plot_trajectories(runs, files["trajectories"])
        files["precision_md"].write_text(precision_markdown(result.precision))
        write_csv(files["precision_csv"], result.precision)
        files["summary_md"].write_text(markdown_table(result.summary))
        write_csv(files["summary_csv"], result.summary)
        base.to_yaml(files["config"])
        result.files = files
    return result
