"""The ``planodom`` command line: parses arguments, calls the library, prints tables.

Known failures (:class:`planodom.errors.PlanodomError`) are reported in one line, without
a traceback, and exit with status 2.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import sys
import typing
from collections.abc import Callable, Iterator
from dataclasses import dataclass
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
        except (PlanodomError, FileExistsError) as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        console.print(f"planodom {version('planodom')}", highlight=False)
        raise typer.Exit()


@app.callback()
def main_options(
    version: Annotated[
        bool | None,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = None,
) -> None:
    """Odometry from planar landmarks, smoothed with factor graphs."""


OutDir = Annotated[Path, typer.Option("--out", "-o", help="Output directory.")]
Scene = Annotated[
    str,
    typer.Option(
        help="Built-in scene: paper-loop | urban-canyon, or a procedural world drawn from "
        "--seed: random | random-outdoor | random-indoor."
    ),
]
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
ConfigFile = Annotated[
    Path | None, typer.Option("--config", "-c", help="YAML file with config overrides.")
]
DatasetDir = Annotated[Path | None, typer.Argument(help="Dataset directory.")]
Scenario = Annotated[
    str | None,
    typer.Option(
        help="Simulate this built-in scene (paper-loop, urban-canyon, random, random-outdoor, "
        "random-indoor) instead."
    ),
]


def _simulate(scene: str, rig: str | None, noise: str, seed: int, epochs: int | None, motion: str):
    from planodom.simulation import simulate_named

    try:
        sigma: float | str = float(noise)
    except ValueError:
        sigma = noise  # a preset name
    with console.status(f"simulating {scene} with the {rig or 'drawn'} rig"):
        return simulate_named(scene, rig, noise=sigma, seed=seed, n_epochs=epochs, motion=motion)


@dataclass(frozen=True)
class Source:
    """Where ``run`` and ``smooth`` take their epochs from: a dataset directory, or a
    built-in scenario simulated with the given rig, noise, seed, length and motion."""

    dataset: Path | None
    scenario: str | None
    rig: str
    noise: str
    seed: int
    epochs: int | None
    motion: str

    def load(self, out: Path):
        """The dataset, or the scenario simulated into ``out/dataset`` and loaded; creates
        the output folder ``out``."""
        from planodom.datasets import load_dataset
        from planodom.errors import ConfigError
        from planodom.results import prepare_output

        if (self.dataset is None) == (self.scenario is None):
            raise ConfigError("give either a DATASET directory or --scenario NAME")
        prepare_output(out)
        if self.dataset is not None:
            return load_dataset(self.dataset)
        from planodom.simulation.export import write_simulated_dataset

        sim = (self.scenario, self.rig, self.noise, self.seed, self.epochs, self.motion)
        run = _simulate(*sim)  # type: ignore[arg-type]
        with console.status("writing the simulated dataset"):
            return write_simulated_dataset(run, out / "dataset", self.scenario, overwrite=True)


#: The options of :class:`Source`, shared by ``run`` and ``smooth`` (:func:`takes_source`).
_SOURCE_OPTIONS = (
    ("dataset", DatasetDir, None),
    ("scenario", Scenario, None),
    ("rig", RigName, "isoclinal"),
    ("noise", Noise, "lms221"),
    ("seed", Seed, 0),
    ("epochs", Epochs, None),
    ("motion", Motion, "continuous"),
)


def _bundles(name: str, make: Callable[..., Any], options: tuple) -> Callable:
    """A decorator giving a command the typer ``options`` (name, annotation, default) and
    passing them to it as one argument ``name`` = ``make(**options)``."""

    def decorate(func: Callable[..., Any]) -> Callable[..., Any]:
        keyword = inspect.Parameter.KEYWORD_ONLY
        hints = typing.get_type_hints(func, include_extras=True)  # resolved, for typer
        own = [
            p.replace(kind=keyword, annotation=hints[p.name])
            for p in inspect.signature(func).parameters.values()
            if p.name != name
        ]
        shared = [inspect.Parameter(n, keyword, default=d, annotation=a) for n, a, d in options]

        @functools.wraps(func)
        def wrapper(**kwargs: Any) -> Any:
            bundle = make(**{option: kwargs.pop(option) for option, _, _ in options})
            return func(**{name: bundle}, **kwargs)

        wrapper.__signature__ = inspect.Signature(own + shared)  # type: ignore[attr-defined]
        return wrapper

    return decorate


#: ``run`` and ``smooth`` take their epochs from one :class:`Source` option set.
takes_source = _bundles("source", Source, _SOURCE_OPTIONS)


def _load_config(path: Path | None, changes: dict[str, object] | None = None):
    """The config of ``path`` (defaults without), with the non-None ``changes`` (dotted
    field names, e.g. ``odometry.delta``) applied through ``PlanodomConfig.updated``."""
    from planodom.config import PlanodomConfig

    cfg = PlanodomConfig() if path is None else PlanodomConfig.from_yaml(path)
    changes = {k: v for k, v in (changes or {}).items() if v is not None}
    return cfg.updated(changes, source="command line") if changes else cfg


@contextlib.contextmanager
def _progress(description: str) -> Iterator[Callable[[int, int], None]]:
    """A rich progress bar in epochs while the block runs; yields ``callback(k, n)``."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeRemainingColumn,
    )

    columns = (BarColumn(), MofNCompleteColumn(), TextColumn("epochs"), TimeRemainingColumn())
    with Progress(TextColumn(description), *columns, console=err_console, transient=True) as bar:
        task = bar.add_task(description, total=None)
        yield lambda k, n: bar.update(task, completed=k, total=n)


RandomRigName = Annotated[
    str | None,
    typer.Option(
        "--rig",
        help="Built-in rig: isoclinal | lidar16 | lidar32 | lidar64 (default isoclinal); for "
        "a random scene also a family drawn from the seed: rig2d | lidar16 | lidar32 | "
        "lidar64 (default: the world's own rig).",
    ),
]


@app.command()
@reports_errors
def simulate(
    out: OutDir,
    scene: Scene = "paper-loop",
    rig: RandomRigName = None,
    noise: Noise = "0.0",
    seed: Annotated[int, typer.Option(help="Noise seed; for a random scene also the world.")] = 0,
    epochs: Epochs = None,
    motion: Motion = "continuous",
    overwrite: Annotated[bool, typer.Option(help="Replace a dataset at --out.")] = False,
) -> None:
    """Simulate a built-in scene and write it as a dataset (scans, poses.tum, rig.yaml)."""
    from planodom.report import simulation_table
    from planodom.simulation.export import write_simulated_dataset
    from planodom.simulation.named import RANDOM_SCENES

    rig = rig or (None if scene in RANDOM_SCENES else "isoclinal")
    run = _simulate(scene, rig, noise, seed, epochs, motion)
    with console.status(f"writing {len(run)} scans to {out}"):
        write_simulated_dataset(run, out, scene_name=scene, overwrite=overwrite)
    console.print(simulation_table(run, title=f"{run.scene.name} / {run.sensor_rig.name} -> {out}"))


@app.command()
@reports_errors
@takes_source
def run(
    out: OutDir,
    source: Source,
    config: ConfigFile = None,
    pipeline: Annotated[
        str | None, typer.Option(help="wocsc | sda-mean | ocsc | mean (default: config's).")
    ] = None,
    delta: Annotated[int | None, typer.Option(help="Associate epoch k with k - delta.")] = None,
) -> None:
    """Extract planes and run the paper's odometry over a dataset (or a built-in scenario).

    Writes poses.tum, poses_kitti.txt, epochs.csv, config.yaml and, with ground truth,
    metrics.json to --out, and prints a summary.
    """
    from planodom import results
    from planodom.odometry import motion_assumption, run_odometry
    from planodom.report import odometry_table

    cfg = _load_config(config, {"odometry.pipeline": pipeline, "odometry.delta": delta})
    data = source.load(out)
    with _progress("odometry") as callback:
        odo = run_odometry(data, cfg, progress=callback)
    metrics = results.write_odometry_run(out, odo, data.gt_poses)
    console.print(f"[dim]{motion_assumption(odo.config or cfg)}[/]", highlight=False)
    console.print(odometry_table(odo, metrics, title=f"planodom run -> {out}"))


@app.command()
@reports_errors
@takes_source
def smooth(
    out: OutDir,
    source: Source,
    mode: Annotated[str | None, typer.Option(help="batch | windowed.")] = None,
    window: Annotated[
        int | None, typer.Option(help="Fixed-lag window W in epochs (implies --mode windowed).")
    ] = None,
    delta: Annotated[
        int | None, typer.Option(help="Relative poses for delta = 1..D (default: config's).")
    ] = None,
    config: ConfigFile = None,
) -> None:
    """Smooth the odometry with a factor graph (batch, or a fixed-lag window).

    Writes the smoothed poses.tum / poses_kitti.txt, the raw odometry as odometry.tum,
    config.yaml and, with ground truth, metrics.json for both.
    """
    from planodom import results
    from planodom.report import comparison_table
    from planodom.smoothing.run import run_smoothing

    cfg = _load_config(config)  # before simulating: a bad file fails at once
    mode = mode or ("windowed" if window is not None else "batch")
    data = source.load(out)
    with _progress("odometry and relative poses") as callback:
        sm = run_smoothing(
            data, cfg, window=window, delta=delta, mode=mode,
            progress=lambda stage, k, n: callback(k, n),
        )  # fmt: skip
    odo_metrics = results.write_odometry_run(out, sm.odometry, data.gt_poses)
    results.write_trajectory(out, sm.times, sm.poses)  # the smoothed trajectory is the output
    results.write_tum(out / "odometry.tum", sm.times, sm.odometry.poses)
    results.write_config(out, sm.config)
    smoothed = results.trajectory_metrics(sm.poses, data.gt_poses)
    results.write_metrics(out, {"odometry": odo_metrics, f"smoothing_{mode}": smoothed})
    rows = {"odometry": odo_metrics, f"{mode} smoothing": smoothed}
    console.print(comparison_table(rows, title=f"planodom smooth -> {out}"))


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
    summary = metrics.summarize(est, gt, align=align, delta=delta)  # type: ignore[arg-type]
    console.print(metrics_table(summary))


@app.command("config")
@reports_errors
def show_config(config: ConfigFile = None) -> None:
    """Print the resolved configuration (defaults, or a file over them) as YAML.

    The output loads back unchanged: ``planodom config > my.yaml``, edit, ``--config my.yaml``.
    """
    typer.echo(_load_config(config).to_yaml(), nl=False)


Levels = Annotated[str, typer.Option(help="Comma-separated range noise sigmas in metres.")]
ExpOut = Annotated[Path, typer.Option("--out", "-o", help="Output directory.")]
ExpSeed = Annotated[int, typer.Option(help="Noise seed.")]
ExpMotion = Annotated[str, typer.Option(help="snapshot (the paper's simulator) | continuous.")]


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


def _print_files(files: dict[str, Path]) -> None:
    """The written files, Markdown tables rendered."""
    from rich.markdown import Markdown

    for name, path in files.items():
        if path.suffix == ".md":
            console.print(Markdown(path.read_text()))
        console.print(f"{name}: {path}", highlight=False)


def _simulation(epochs: int | None, seed: int, motion: str):
    from planodom.experiments.simulated import Simulation

    return Simulation(seed=seed, n_epochs=epochs, motion=motion)


#: The experiments' simulation options, passed as one ``Simulation``.
takes_simulation = _bundles(
    "simulation",
    _simulation,
    (("epochs", Epochs, None), ("seed", ExpSeed, 1), ("motion", ExpMotion, "snapshot")),
)


@experiment_app.command("paper")
@reports_errors
@takes_simulation
def experiment_paper(
    simulation: Any,
    out: ExpOut = Path("results/paper"),
    levels: Levels = "0,0.006,0.02,0.1",
    config: ConfigFile = None,
) -> None:
    """The paper's section VI: Fig. 5 trajectories, Fig. 6 / 7 precision tables."""
    from planodom.experiments.paper import run_paper_experiment

    result = run_paper_experiment(
        out, noise_levels=_levels(levels), simulation=simulation, config=_load_config(config),
        progress=_say,
    )  # fmt: skip
    _print_files(result.files)


@experiment_app.command("smoothing")
@reports_errors
@takes_simulation
def experiment_smoothing(
    simulation: Any,
    scenes: Annotated[str, typer.Option(help="Comma-separated built-in scenes.")] = (
        "paper-loop,urban-canyon"
    ),
    levels: Levels = "0,0.006,0.02,0.1",
    window: Annotated[int, typer.Option(help="Fixed-lag window W, epochs.")] = 10,
    delta: Annotated[int, typer.Option(help="Relative poses for delta = 1..D.")] = 3,
    out: ExpOut = Path("results/smoothing"),
    config: ConfigFile = None,
) -> None:
    """Raw odometry vs delta > 1 vs windowed vs batch smoothing, with NEES."""
    from planodom.experiments.smoothing import run_smoothing_experiment

    result = run_smoothing_experiment(
        out, noise_levels=_levels(levels), scenes=[x for x in scenes.split(",") if x],
        window=window, delta=delta, simulation=simulation, config=_load_config(config),
        progress=_say,
    )  # fmt: skip
    _print_files(result.files)


@experiment_app.command(
    "generalisation", context_settings={"allow_extra_args": True, "ignore_unknown_options": True}
)
@reports_errors
def experiment_generalisation(
    ctx: typer.Context,
    worlds: Annotated[int, typer.Option(help="Random worlds 0 .. N-1 (even: 2D rig).")] = 20,
    noise: Annotated[
        list[float] | None,
        typer.Option(help="Range noise sigmas (m): --noise 0 0.006 0.02 0.1 (or repeated)."),
    ] = None,
    epochs: Annotated[int, typer.Option(help="Epochs per run (0: one lap).")] = 300,
    quick: Annotated[
        bool, typer.Option(help="CI size: 2 worlds (2D rig, lidar), 25 epochs, 6 mm.")
    ] = False,
    out: ExpOut = Path("results/generalisation"),
    config: ConfigFile = None,
) -> None:
    """Unseen worlds: planodom (wocsc, sda-mean) vs the oracle, KISS-ICP and open3d ICP."""
    from planodom.errors import ConfigError
    from planodom.experiments.generalisation import run_generalisation_experiment

    try:  # the values after the first of "--noise 0 0.006 0.02" arrive as extra arguments
        extra = [float(x) for x in ctx.args]
    except ValueError:
        raise ConfigError(f"unexpected arguments {' '.join(ctx.args)}") from None
    if extra and not noise:
        raise ConfigError(f"unexpected arguments {' '.join(ctx.args)}")
    noise = (noise or []) + extra
    levels = noise or [0.0, 0.006, 0.02, 0.1]
    if quick:
        worlds, epochs, levels = 2, 25, (noise or [0.006])
    result = run_generalisation_experiment(
        out, n_worlds=worlds, noise_levels=levels, n_epochs=epochs or None,
        config=_load_config(config), progress=_say,
    )  # fmt: skip
    _print_files({k: v for k, v in result.files.items() if k != "runs_md"})


if __name__ == "__main__":  # pragma: no cover
    sys.exit(app())
