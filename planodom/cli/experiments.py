"""``planodom experiment paper | smoothing | consistency | generalisation | baselines |
loops``: the experiments behind the paper's figures, the covariances' consistency,
procedural worlds, planodom against point-based peers on recordings, loop closure."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any

import typer

from planodom.cli.common import (
    ConfigFile,
    Epochs,
    bundles,
    console,
    err_console,
    experiment_app,
    load_config,
    reports_errors,
)

Levels = Annotated[str, typer.Option(help="Comma-separated range noise sigmas in metres.")]
ExpOut = Annotated[
    Path | None,
    typer.Option(
        "--out",
        "-o",
        help="Output folder (default: a new results/<experiment>/<timestamp>, linked as "
        "results/<experiment>/latest).",
    ),
]
ExpOverwrite = Annotated[
    bool,
    typer.Option("--overwrite", help="Replace an earlier experiment's tables and plots at --out."),
]
#: What an experiment writes: a folder holding anything else is never written into.
EXPERIMENT_SUFFIXES = (".md", ".csv", ".png", ".yaml")
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


def _worlds(worlds: int) -> int:
    """``--worlds``, or ConfigError: none (or fewer) ran nothing and wrote empty tables."""
    from planodom.errors import ConfigError

    if worlds < 1:
        raise ConfigError(f"--worlds {worlds}: expected 1 or more worlds")
    return worlds


def _lap_epochs(epochs: int) -> int | None:
    """``--epochs`` of a procedural-world experiment: None for 0 (one lap), or ConfigError
    for a negative count or 1 (its errors are of steps between epochs)."""
    from planodom.errors import ConfigError

    if epochs == 0:
        return None
    if epochs < 2:
        raise ConfigError(f"--epochs {epochs}: expected 0 (one lap) or 2 or more")
    return epochs


def _say(message: str) -> None:
    err_console.print(f"[dim]{message}[/]", highlight=False)


def _print_files(files: dict[str, Path]) -> None:
    """The written files, Markdown tables rendered."""
    from rich.markdown import Markdown

    for name, path in files.items():
        if path.suffix == ".md":
            console.print(Markdown(path.read_text()))
        console.print(f"{name}: {path}", highlight=False)


def _is_experiment_file(entry: Path) -> bool:
    return entry.is_file() and not entry.is_symlink() and entry.suffix in EXPERIMENT_SUFFIXES


@contextlib.contextmanager
def _out_folder(
    name: str, out: Path | None, overwrite: bool, inputs: tuple[Path, ...] = ()
) -> Iterator[Path]:
    """The folder experiment ``name`` writes into, made before it runs (so that a long
    experiment can write its tables as it goes, and a taken folder is refused before
    hours of work, not after): ``out``, which must be new or empty, or with
    ``overwrite`` hold only an earlier experiment's files (removed first); by default a
    new ``results/<name>/<timestamp>``, linked as ``results/<name>/latest`` once it holds
    anything. Nothing an earlier run or the user left is ever written over unasked; a
    folder made for a run that failed before writing anything is removed again."""
    from planodom.entry import interrupted_import
    from planodom.outputs import check_target, link_latest, timestamped_folder

    if out is None:
        folder = timestamped_folder(Path("results") / name)
    else:
        folder = check_target(
            out, overwrite=overwrite, inputs=inputs, owned=_is_experiment_file,
            what="experiment results",
        )  # fmt: skip
    made = not folder.exists()
    for entry in [] if made else sorted(folder.iterdir()):
        entry.unlink()  # --overwrite, every entry an experiment's file (checked above)
    folder.mkdir(parents=True, exist_ok=True)
    try:
        yield folder
    except (KeyboardInterrupt, ImportError) as exc:  # each table is written whole
        if not interrupted_import(exc):
            raise
        written = any(folder.iterdir())
        exc.add_note(f"the tables written so far are kept in {folder}" if written else
                     f"nothing written to {folder}")  # fmt: skip
        raise
    finally:
        if made and not any(folder.iterdir()):
            folder.rmdir()
        elif out is None:
            link_latest(folder)


def _simulation(epochs: int | None, seed: int, motion: str):
    from planodom.experiments.simulated import Simulation

    return Simulation(seed=seed, n_epochs=epochs, motion=motion)


#: The experiments' simulation options, passed as one ``Simulation``.
takes_simulation = bundles(
    "simulation",
    _simulation,
    (("epochs", Epochs, None), ("seed", ExpSeed, 1), ("motion", ExpMotion, "snapshot")),
)


@experiment_app.command("paper")
@reports_errors
@takes_simulation
def experiment_paper(
    simulation: Any,
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    levels: Levels = "0,0.006,0.02,0.1",
    config: ConfigFile = None,
) -> None:
    """The paper's section VI: Fig. 5 trajectories, Fig. 6 / 7 precision tables."""
    from planodom.experiments.paper import run_paper_experiment

    noise_levels, cfg = _levels(levels), load_config(config)
    with _out_folder("paper", out, overwrite) as folder:
        result = run_paper_experiment(
            folder, noise_levels=noise_levels, simulation=simulation, config=cfg, progress=_say
        )
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
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    config: ConfigFile = None,
) -> None:
    """Raw odometry vs delta > 1 vs windowed vs batch smoothing, with NEES."""
    from planodom.experiments.smoothing import run_smoothing_experiment

    noise_levels, cfg = _levels(levels), load_config(config)
    chosen = [x for x in scenes.split(",") if x]
    with _out_folder("smoothing", out, overwrite) as folder:
        result = run_smoothing_experiment(
            folder, noise_levels=noise_levels, scenes=chosen, window=window, delta=delta,
            simulation=simulation, config=cfg, progress=_say,
        )  # fmt: skip
    _print_files(result.files)


@experiment_app.command(
    "generalisation", context_settings={"allow_extra_args": True, "ignore_unknown_options": True}
)
@reports_errors
def experiment_generalisation(
    ctx: typer.Context,
    worlds: Annotated[int, typer.Option(help="Random worlds 0 .. N-1 (even: 2D rig).")] = 20,
    first_world: Annotated[
        int, typer.Option(min=0, help="Index of the first world (20 on: held out).")
    ] = 0,
    noise: Annotated[
        list[float] | None,
        typer.Option(help="Range noise sigmas (m): --noise 0 0.006 0.02 0.1 (or repeated)."),
    ] = None,
    epochs: Annotated[int, typer.Option(help="Epochs per run (0: one lap).")] = 300,
    quick: Annotated[
        bool, typer.Option(help="CI size: 2 worlds (2D rig, lidar), 25 epochs, 6 mm.")
    ] = False,
    rig: Annotated[
        str, typer.Option(help="all | rig2d (even worlds only) | lidar (odd worlds only).")
    ] = "all",
    methods: Annotated[
        str,
        typer.Option(
            help="Comma-separated, of planodom, planodom-wocsc, planodom-sda-mean, "
            "planodom-offline, oracle, kiss-icp, open3d-icp (default: all but sda-mean "
            "and offline)."
        ),
    ] = "",
    motion: Annotated[
        str, typer.Option(help="vehicle | handheld (every world a hand-held lidar's walk).")
    ] = "vehicle",
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    config: ConfigFile = None,
) -> None:
    """Unseen worlds: planodom (default, and the paper's wocsc) vs the oracle and the peers."""
    from planodom.errors import ConfigError
    from planodom.experiments.generalisation import (
        DEFAULT_METHODS,
        METHODS,
        run_generalisation_experiment,
    )

    try:  # the values after the first of "--noise 0 0.006 0.02" arrive as extra arguments
        extra = [float(x) for x in ctx.args]
    except ValueError:
        raise ConfigError(f"unexpected arguments {' '.join(ctx.args)}") from None
    if extra and not noise:
        raise ConfigError(f"unexpected arguments {' '.join(ctx.args)}")
    noise = (noise or []) + extra
    if rig not in ("all", "rig2d", "lidar"):
        raise ConfigError(f"--rig {rig!r}: expected all, rig2d or lidar")
    if motion not in ("vehicle", "handheld"):
        raise ConfigError(f"--motion {motion!r}: expected vehicle or handheld")
    chosen = [m.strip() for m in methods.split(",") if m.strip()] or list(DEFAULT_METHODS)
    strange = [m for m in chosen if m not in METHODS]
    if strange:
        raise ConfigError(
            f"--methods: unknown {', '.join(strange)}; expected of {', '.join(METHODS)}"
        )
    levels = noise or [0.0, 0.006, 0.02, 0.1]
    if quick:
        worlds, epochs, levels = 2, 25, (noise or [0.006])
    worlds, n_epochs = _worlds(worlds), _lap_epochs(epochs)
    cfg = load_config(config)
    with _out_folder("generalisation", out, overwrite) as folder:
        result = run_generalisation_experiment(
            folder, n_worlds=worlds, noise_levels=levels, n_epochs=n_epochs, config=cfg,
            progress=_say, methods=chosen,
            rigs=("rig2d", "lidar") if rig == "all" else (rig,), first_world=first_world,
            motion=motion,
        )  # fmt: skip
    _print_files({k: v for k, v in result.files.items() if k != "runs_md"})


@experiment_app.command("baselines")
@reports_errors
def experiment_baselines(
    datasets: Annotated[
        list[Path], typer.Argument(help="Recordings (no poses.tum: KISS-ICP is the reference).")
    ],
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    wocsc: Annotated[bool, typer.Option(help="Also the paper's wocsc pipeline.")] = False,
    limit: Annotated[int | None, typer.Option(help="Read at most this many scans.")] = None,
    step: Annotated[int, typer.Option(min=1, help="Use every k-th scan.")] = 1,
    turn: Annotated[float, typer.Option(help="Turn scan k by k * TURN deg about z.")] = 0.0,
    alternate: Annotated[bool, typer.Option(help="Turn by (k % 2) * TURN instead.")] = False,
    config: ConfigFile = None,
) -> None:
    """planodom's odometry vs KISS-ICP and open3d ICP on the same scans (one run)."""
    from planodom.experiments.baselines import run_baselines_experiment

    cfg = load_config(config)
    with _out_folder("baselines", out, overwrite, inputs=tuple(datasets)) as folder:
        result = run_baselines_experiment(
            datasets, folder, cfg, wocsc=wocsc, limit=limit, step=step, turn_deg=turn,
            alternate=alternate, progress=_say,
        )  # fmt: skip
    _print_files(result.files)


@experiment_app.command("loops")
@reports_errors
def experiment_loops(
    worlds: Annotated[int, typer.Option(help="Procedural worlds 0 .. N-1 (even: 2D rig).")] = 6,
    first_world: Annotated[
        int, typer.Option(min=0, help="Index of the first world (20 on: held out).")
    ] = 0,
    epochs: Annotated[int, typer.Option(help="Epochs per run (0: one lap).")] = 0,
    quick: Annotated[bool, typer.Option(help="CI size: world 0, 120 epochs, 6 mm.")] = False,
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    config: ConfigFile = None,
) -> None:
    """Loop closure: odometry, fixed-lag and batch without and with loops, oracle (issue 14)."""
    from planodom.experiments.loops import run_loop_experiment

    levels: tuple[float, ...] = (0.006, 0.02)
    if quick:
        worlds, epochs, levels = 1, 120, (0.006,)
    worlds, n_epochs = _worlds(worlds), _lap_epochs(epochs)
    cfg = load_config(config)
    with _out_folder("loops", out, overwrite) as folder:
        result = run_loop_experiment(
            folder, range(first_world, first_world + worlds), levels, n_epochs, cfg,
            progress=_say,
        )  # fmt: skip
    _print_files(result.files)


@experiment_app.command("consistency")
@reports_errors
@takes_simulation
def experiment_consistency(
    simulation: Any,
    scenes: Annotated[str, typer.Option(help="Comma-separated built-in scenes.")] = "paper-loop",
    levels: Levels = "0.006,0.02,0.1",
    out: ExpOut = None,
    overwrite: ExpOverwrite = False,
    config: ConfigFile = None,
) -> None:
    """NEES of every factor kind (relative poses per delta, planes) and of the smoothed
    poses against the truth, with the chi2 95 % interval of each mean."""
    from planodom.experiments.consistency import run_consistency_experiment
    from planodom.experiments.tables import write_tables

    noise_levels, cfg = _levels(levels), load_config(config)
    with _out_folder("consistency", out, overwrite) as folder:
        tables = run_consistency_experiment(
            [x for x in scenes.split(",") if x], noise_levels, (simulation.seed,),
            simulation.n_epochs or 200, cfg, motion=simulation.motion, progress=_say,
        )  # fmt: skip
        files = write_tables(folder, tables)
    _print_files(files)
