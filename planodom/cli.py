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
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
            raise typer.Exit(2) from None
        except FileExistsError as exc:
            err_console.print(f"[bold red]error:[/] {exc}", highlight=False)
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


def main() -> None:  # pragma: no cover - console entry point
    app()


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
