"""The ``planodom`` command line: parses arguments, calls the library, prints tables.

Known failures (:class:`planodom.errors.PlanodomError`) are reported in one line, without
a traceback, and exit with status 2.
"""

from __future__ import annotations

import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console

from planodom.errors import PlanodomError

app = typer.Typer(
    help="Odometry from planar landmarks, smoothed with factor graphs.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
experiment_app = typer.Typer(help="Regenerate the paper's and the smoothing experiments.")
app.add_typer(experiment_app, name="experiment")

console = Console()
err_console = Console(stderr=True)


def reports_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn the library's known errors into a one-line message and exit status 2."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except PlanodomError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except FileExistsError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper


OutDir = Annotated[Path, typer.Option("--out", "-o", help="Output directory.")]
Scene = Annotated[str, typer.Option(help="Built-in scene: paper-loop | urban-canyon.")]
RigName = Annotated[
    str, typer.Option("--rig", help="Built-in rig: isoclinal | lidar16 | lidar32 | lidar64.")
]
Noise = Annotated[
    str,
    typer.Option(help="Range noise sigma in metres, or a preset: none, lms221, low-cost, worst."),
]
Seed = Annotated[int, typer.Option(help="Noise seed.")]
Epochs = Annotated[
    int | None, typer.Option("--epochs", help="Number of epochs (default: one lap).")
]
Motion = Annotated[
    str,
    typer.Option(help="continuous: each point from the pose at its time; snapshot: one pose."),
]


def _noise_value(noise: str) -> float | str:
    try:
        return float(noise)
    except ValueError:
        return noise


def _simulate(scene: str, rig: str, noise: str, seed: int, epochs: int | None, motion: str):
    from planodom.simulation import simulate_named

    with console.status(f"simulating {scene} with the {rig} rig"):
        return simulate_named(
            scene, rig, noise=_noise_value(noise), seed=seed, n_epochs=epochs, motion=motion
        )


@app.command()
@reports_errors
def simulate(
    out: OutDir,
    scene: Scene = "paper-loop",
    rig: RigName = "isoclinal",
    noise: Noise = "0.0",
    seed: Seed = 0,
    epochs: Epochs = None,
    motion: Motion = "continuous",
    overwrite: Annotated[bool, typer.Option(help="Replace a dataset at --out.")] = False,
) -> None:
    """Simulate a built-in scene and write it as a dataset (scans, poses.tum, rig.yaml)."""
    from planodom.report import simulation_table
    from planodom.simulation.export import write_simulated_dataset

    run = _simulate(scene, rig, noise, seed, epochs, motion)
    with console.status(f"writing {len(run)} scans to {out}"):
        write_simulated_dataset(run, out, scene_name=scene, overwrite=overwrite)
    console.print(simulation_table(run, title=f"{scene} / {rig} -> {out}"))


ConfigFile = Annotated[
    Path | None, typer.Option("--config", "-c", help="YAML file with config overrides.")
]


def _load_config(path: Path | None, **odometry: object):
    from planodom.config import PlanodomConfig

    cfg = PlanodomConfig() if path is None else PlanodomConfig.from_yaml(path)
    updates = {k: v for k, v in odometry.items() if v is not None}
    if updates:
        data = cfg.model_dump()
        data["odometry"].update(updates)
        cfg = PlanodomConfig.from_dict(data, source="command line")
    return cfg


def _progress(description: str):
    """A rich progress bar in epochs; returns (progress, callback(k, n))."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    progress = Progress(
        TextColumn(description),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("epochs"),
        TimeRemainingColumn(),
        console=err_console,
        transient=True,
    )
    task = progress.add_task(description, total=None)

    def callback(k: int, n: int) -> None:
        progress.update(task, completed=k, total=n)

    return progress, callback


def _dataset_or_scenario(dataset: Path | None, scenario: str | None, out: Path, **sim: object):
    """Load ``dataset``, or simulate ``scenario`` into ``out/dataset`` and load that."""
    from planodom.datasets import load_dataset
    from planodom.errors import ConfigError

    if (dataset is None) == (scenario is None):
        raise ConfigError("give either a DATASET directory or --scenario NAME")
    if dataset is not None:
        return load_dataset(dataset)
    from planodom.simulation.export import write_simulated_dataset

    run = _simulate(scenario, **sim)  # type: ignore[arg-type]
    with console.status("writing the simulated dataset"):
        return write_simulated_dataset(run, out / "dataset", scene_name=scenario, overwrite=True)


Scenario = Annotated[
    str | None,
    typer.Option(help="Simulate this built-in scene (paper-loop, urban-canyon) instead."),
]
Pipeline = Annotated[
    str | None, typer.Option(help="wocsc | sda-mean | ocsc | mean (default: config's).")
]
Delta = Annotated[int | None, typer.Option(help="Associate epoch k with k - delta.")]


@app.command()
@reports_errors
def run(
    out: OutDir,
    dataset: Annotated[Path | None, typer.Argument(help="Dataset directory.")] = None,
    scenario: Scenario = None,
    rig: RigName = "isoclinal",
    noise: Noise = "lms221",
    seed: Seed = 0,
    epochs: Epochs = None,
    motion: Motion = "continuous",
    config: ConfigFile = None,
    pipeline: Pipeline = None,
    delta: Delta = None,
) -> None:
    """Extract planes and run the paper's odometry over a dataset (or a built-in scenario).

    Writes poses.tum, poses_kitti.txt, epochs.csv, config.yaml and, with ground truth,
    metrics.json to --out, and prints a summary.
    """
    from planodom import results
    from planodom.odometry import run_odometry
    from planodom.report import motion_assumption, odometry_table
    from planodom.rig import Rig

    cfg = _load_config(config, pipeline=pipeline, delta=delta)
    out = results.prepare_output(out)
    data = _dataset_or_scenario(
        dataset, scenario, out, rig=rig, noise=noise, seed=seed, epochs=epochs, motion=motion
    )
    progress, callback = _progress("odometry")
    with progress:
        odo = run_odometry(data, cfg, Rig.from_dict(data.rig), progress=callback)
    metrics = results.write_odometry_run(out, odo, data.gt_poses)
    console.print(f"[dim]{motion_assumption(odo.config or cfg)}[/]", highlight=False)
    console.print(odometry_table(odo, metrics, title=f"planodom run -> {out}"))


@app.command()
@reports_errors
def smooth(
    out: OutDir,
    dataset: Annotated[Path | None, typer.Argument(help="Dataset directory.")] = None,
    window: Annotated[
        int | None, typer.Option(help="Fixed-lag window W in epochs (implies --mode windowed).")
    ] = None,
    delta: Annotated[
        int | None, typer.Option(help="Relative poses for delta = 1..D (default: config's).")
    ] = None,
    mode: Annotated[str | None, typer.Option(help="batch | windowed.")] = None,
    scenario: Scenario = None,
    rig: RigName = "isoclinal",
    noise: Noise = "lms221",
    seed: Seed = 0,
    epochs: Epochs = None,
    motion: Motion = "continuous",
    config: ConfigFile = None,
) -> None:
    """Smooth the odometry with a factor graph (batch, or a fixed-lag window).

    Writes the smoothed poses.tum / poses_kitti.txt, the raw odometry as odometry.tum,
    config.yaml and, with ground truth, metrics.json for both.
    """
    from planodom import results
    from planodom.report import comparison_table
    from planodom.rig import Rig
    from planodom.smoothing.run import run_smoothing

    cfg = _load_config(config)
    mode = mode or ("windowed" if window is not None else "batch")
    out = results.prepare_output(out)
    data = _dataset_or_scenario(
        dataset, scenario, out, rig=rig, noise=noise, seed=seed, epochs=epochs, motion=motion
    )
    progress, callback = _progress("odometry and relative poses")
    with progress:
        sm = run_smoothing(
            data,
            cfg,
            Rig.from_dict(data.rig),
            window=window,
            delta=delta,
            mode=mode,
            progress=lambda stage, k, n: callback(k, n),
        )
    odo_metrics = results.write_odometry_run(out, sm.odometry, data.gt_poses)
    results.write_trajectory(out, sm.times, sm.poses)  # the smoothed trajectory is the output
    results.write_tum(out / "odometry.tum", sm.times, sm.odometry.poses)
    results.write_config(out, sm.config)
    smoothed = results.trajectory_metrics(sm.poses, data.gt_poses)
    results.write_metrics(out, {"odometry": odo_metrics, f"smoothing_{mode}": smoothed})
    console.print(
        comparison_table(
            {"odometry": odo_metrics, f"{mode} smoothing": smoothed},
            title=f"planodom smooth -> {out}",
        )
    )


@app.command("eval")
@reports_errors
def evaluate(
    estimate: Annotated[Path, typer.Argument(help="Estimated trajectory, TUM format.")],
    truth: Annotated[
        Path, typer.Argument(help="Ground truth: a TUM file or a dataset with poses.tum.")
    ],
    delta: Annotated[int, typer.Option(help="RPE step in epochs.")] = 1,
    align: Annotated[str, typer.Option(help="none | origin | se3 | 4dof")] = "origin",
) -> None:
    """ATE, RPE, drift and per-epoch 5-DoF errors of a trajectory against ground truth."""
    import numpy as np

    from planodom import metrics
    from planodom.datasets import read_tum
    from planodom.errors import DatasetError
    from planodom.report import metrics_table

    if align not in ("none", "origin", "se3", "4dof"):
        raise DatasetError(f"--align: expected none, origin, se3 or 4dof, got '{align}'")
    t_est, est = read_tum(estimate)
    t_gt, gt = read_tum(truth / "poses.tum" if truth.is_dir() else truth)
    if len(t_est) != len(t_gt) or not np.allclose(t_est, t_gt, atol=1e-6):
        raise DatasetError(
            f"{estimate}: {len(t_est)} poses whose times do not match the {len(t_gt)} of {truth}"
        )
    console.print(metrics_table(metrics.summarize(est, gt, align=align, delta=delta)))


Levels = Annotated[str, typer.Option(help="Comma-separated range noise sigmas in metres.")]
ExpOut = Annotated[Path, typer.Option("--out", "-o", help="Output directory.")]


def _levels(text: str) -> list[float]:
    from planodom.errors import ConfigError

    try:
        levels = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise ConfigError(f"--levels: expected comma-separated numbers, got '{text}'") from None
    if not levels or any(not (x >= 0) for x in levels):
        raise ConfigError(f"--levels: expected sigmas >= 0 in metres, got '{text}'")
    return levels


def _say(message: str) -> None:
    err_console.print(f"[dim]{message}[/]", highlight=False)


@experiment_app.command("paper")
@reports_errors
def experiment_paper(
    out: ExpOut = Path("results/paper"),
    levels: Levels = "0,0.006,0.02,0.1",
    epochs: Epochs = None,
    seed: Seed = 1,
    motion: Motion = "snapshot",
    config: ConfigFile = None,
) -> None:
    """The paper's section VI: Fig. 5 trajectories, Fig. 6 / 7 precision tables."""
    from rich.markdown import Markdown

    from planodom.experiments.paper import (
        markdown_table,
        precision_markdown,
        run_paper_experiment,
    )

    result = run_paper_experiment(
        out, noise_levels=_levels(levels), seed=seed, n_epochs=epochs, motion=motion,
        config=_load_config(config), progress=_say,
    )  # fmt: skip
    console.print(Markdown(precision_markdown(result.precision)))
    keep = ("noise_m", "method", "unresolved", "degenerate", "rot_rms_deg", "xy_rms_m")
    keep += ("drift_percent", "ate_rmse_m")
    console.print(Markdown(markdown_table([{k: r[k] for k in keep} for r in result.summary])))
    for name, path in result.files.items():
        console.print(f"{name}: {path}", highlight=False)


@experiment_app.command("smoothing")
@reports_errors
def experiment_smoothing(
    out: ExpOut = Path("results/smoothing"),
    levels: Levels = "0,0.006,0.02,0.1",
    scenes: Annotated[str, typer.Option(help="Comma-separated built-in scenes.")] = (
        "paper-loop,urban-canyon"
    ),
    window: Annotated[int, typer.Option(help="Fixed-lag window W, epochs.")] = 10,
    delta: Annotated[int, typer.Option(help="Relative poses for delta = 1..D.")] = 3,
    epochs: Epochs = None,
    seed: Seed = 1,
    motion: Motion = "snapshot",
    config: ConfigFile = None,
) -> None:
    """Raw odometry vs delta > 1 vs windowed vs batch smoothing, with NEES."""
    from pathlib import Path as _Path

    from planodom.experiments.smoothing import run_smoothing_experiment

    result = run_smoothing_experiment(
        out, noise_levels=_levels(levels), scenes=[x for x in scenes.split(",") if x],
        window=window, delta=delta, seed=seed, n_epochs=epochs, motion=motion,
        config=_load_config(config), progress=_say,
    )  # fmt: skip
    for name, path in getattr(result, "files", {}).items():
        if _Path(path).suffix == ".md":
            from rich.markdown import Markdown

            console.print(Markdown(_Path(path).read_text()))
        console.print(f"{name}: {path}", highlight=False)


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
