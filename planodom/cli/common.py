"""What the commands share: the apps, the one error path, options, the epoch source.

The one error path (:func:`reports_errors`): every :class:`PlanodomError` and every OS
error on a named file ends as one line ``error: <file>: <what>`` on stderr and exit
status 2. Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import inspect
import typing
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.text import Text

from planodom.cli.echo_option import Echo
from planodom.cli.simulated import simulate_scene
from planodom.datasets.repeated_scans import RepeatedScans
from planodom.entry import INTERRUPTED, interrupted_import
from planodom.errors import DatasetError, OutputExistsError, PlanodomError
from planodom.scan import Scan, points_beyond_range

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


def one_line(exc: BaseException) -> str:
    """The message of a known failure, in one line."""
    if isinstance(exc, OutputExistsError):
        exc = exc.with_option("--overwrite")
    if isinstance(exc, OSError) and not isinstance(exc, PlanodomError):
        text = f"{exc.filename}: {exc.strerror or exc}"
    else:
        text = str(exc)
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


def reports_errors(func: Callable[..., Any]) -> Callable[..., Any]:
    """Turn known failures into a one-line message on stderr and exit status 2, and a
    Ctrl-C into one line (:func:`interrupted`) and exit status 130 (typer's, silently)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (PlanodomError, OSError) as exc:
            if isinstance(exc, OSError) and exc.filename is None:
                raise  # not about a file the user named: a bug, keep the traceback
            error(one_line(exc))
            raise typer.Exit(2) from None
        except (KeyboardInterrupt, ImportError) as exc:  # an import a Ctrl-C cut short too
            if not interrupted_import(exc):
                raise
            err_console.print(interrupted(exc), style="bold red", soft_wrap=True, markup=False)
            raise typer.Exit(INTERRUPTED) from None

    return wrapper


def interrupted(exc: BaseException) -> str:
    """The line of a command ended by Ctrl-C: what became of its output, as the output
    folders noted on the exception (:func:`planodom.outputs.atomic_folder`)."""
    notes = getattr(exc, "__notes__", [])
    return "; ".join(["interrupted (Ctrl-C)", *notes] if notes else ["interrupted (Ctrl-C)"])


def error(message: str) -> None:
    """``error: message`` on stderr, the message taken literally (no rich markup)."""
    err_console.print(Text.assemble(("error: ", "bold red"), message), soft_wrap=True)


def warn(message: str) -> None:
    """``warning: message`` on stderr."""
    err_console.print(Text.assemble(("warning: ", "bold yellow"), message), soft_wrap=True)


OutDir = Annotated[
    Path | None,
    typer.Option(
        "--out", "-o", help="Results folder (default: a new results/<timestamp>, linked as latest)."
    ),
]
Overwrite = Annotated[
    bool, typer.Option("--overwrite", help="Replace an existing results folder at --out.")
]
SkipBadScans = Annotated[
    bool,
    typer.Option(
        "--skip-bad-scans",
        help="An unreadable scan file becomes an epoch without planes (bridged at constant "
        "velocity, listed in metrics.json) instead of an error; a ROS 2 bag's unreadable "
        "storage file (a split recording's part) is left out, its time span a gap.",
    ),
]
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
DatasetDir = Annotated[
    Path | None,
    typer.Argument(
        help="A dataset directory, a ROS 1 .bag or ROS 2 bag folder, or a KITTI sequence folder."
    ),
]
BaseFrame = Annotated[
    str, typer.Option("--base-frame", help="Bags: tf frame of the vehicle (points, reference).")
]
EpochRate = Annotated[
    float, typer.Option("--epoch-rate", help="Bags: epochs per second, Hz (sweeps per window).")
]
Topics = Annotated[
    list[str] | None,
    typer.Option("--topic", help="Bags: a scan topic, repeated in ring order (default: all)."),
]
GtTopic = Annotated[
    str | None,
    typer.Option(
        "--gt-topic",
        help="Bags: reference poses (Odometry, PoseStamped, PoseWithCovarianceStamped, "
        "TransformStamped topic, a nav_msgs/Path read from its last message, or "
        "tf:PARENT:CHILD), interpolated at the epoch times.",
    ),
]
TimeField = Annotated[
    str,
    typer.Option(
        "--time-field",
        help="Bags and scan files: the per-point time field: auto (t, time, timestamp, "
        "offset_time, time_stamp), none (ignore them: e.g. a sensor clock that is not the "
        "stamps'), or a field name.",
    ),
]
BinLayoutOption = Annotated[
    str,
    typer.Option(
        "--bin-layout",
        help=".bin scan files: kitti (float32 x y z intensity), nuscenes (x y z intensity "
        "ring), xyz (x y z) or auto (kitti or nuscenes, from each file's size and columns; "
        "KITTI sequences: kitti).",
    ),
]
Scenario = Annotated[
    str | None,
    typer.Option(
        help="Simulate this built-in scene (paper-loop, urban-canyon, random, random-outdoor, "
        "random-indoor) instead."
    ),
]


class ScanEpochs:
    """A recording's epochs as the odometry reads them, naming the scan behind a failure.

    ``len``, indexing, ``times``, ``gt_poses`` and ``rig`` are the recording's (a dataset,
    a bag or a KITTI sequence); ``Tr`` is a KITTI sequence's ``T_cam0_velo`` (None for
    others). While an epoch is being processed (from its reading to the progress call
    after it), :meth:`naming_errors` turns a failure that names no file into one naming
    the scan (its file, or the bag and epoch). With ``skip_bad`` a scan that cannot be
    read is an epoch without planes, which the odometry bridges (an unresolved epoch);
    :attr:`skipped` lists them. The recording's :attr:`notes` (a bag's: how it was read,
    e.g. a time unit other than the documented one) are warned of when it is opened.
    """

    def __init__(self, dataset: Any, skip_bad: bool = False) -> None:
        self.dataset, self.skip_bad = dataset, skip_bad
        self.times, self.gt_poses, self.rig = dataset.times, dataset.gt_poses, dataset.rig
        self.Tr: Any = getattr(dataset, "Tr", None)
        self.current: str | None = None
        self.skipped: list[str] = []
        # scan -> (points beyond MAX_RANGE_M, all points, the scan's widest extent, m)
        self.far: dict[str, tuple[int, int, float]] = {}
        self.empty: dict[str, None] = {}  # scans without points (kept in order, once each)
        self.repeated = RepeatedScans()  # scans that repeat the one before them
        self.notes: list[str] = list(getattr(dataset, "notes", []))
        for note in self.notes:
            warn(note)

    def __len__(self) -> int:
        return len(self.dataset)

    def scan_name(self, k: int) -> str:
        """Where epoch ``k``'s scan comes from: its file, or ``<bag> epoch k (t = ... s)``."""
        files = getattr(self.dataset, "scan_files", None)
        if files is not None:
            return str(files[k])
        where = getattr(self.dataset, "path", "recording")
        return f"{where} epoch {k} (t = {float(self.times[k]):.6f} s)"

    def __getitem__(self, k: int) -> Any:
        self.current = self.scan_name(k)
        try:
            scan = self.dataset[k]
        except DatasetError as exc:
            if not self.skip_bad:
                raise
            if (name := self.scan_name(k)) not in self.skipped:  # the first is read twice
                warn(f"{one_line(exc)} (skipped: epoch {k} has no planes)")
                self.skipped.append(name)
            return []  # a plane list: no extraction, an epoch without planes
        if isinstance(scan, Scan):
            far = points_beyond_range(scan)
            if far:
                extent = float((scan.points.max(axis=0) - scan.points.min(axis=0)).max())
                self.far[self.current] = (far, len(scan), extent)
            if len(scan) == 0:
                self.empty[self.current] = None
            self.repeated.check(k, self.current, scan)
        return scan

    def reference_order(self, poses: Any, metrics: dict) -> None:
        """Warn of (and list in metrics.json) a dataset's ``poses.tum`` whose quaternions
        agree with the estimated ``poses`` (E, 4, 4) only read as qw qx qy qz
        (:func:`planodom.quaternion_order.wxyz_note`): its metrics are wrong."""
        from planodom.datasets.dataset import POSES_FILE, Dataset
        from planodom.quaternion_order import wxyz_note

        if not isinstance(self.dataset, Dataset) or self.gt_poses is None:
            return
        note = wxyz_note(poses, self.gt_poses, str(self.dataset.path / POSES_FILE))
        if note is not None:
            warn(note)
            metrics["reference_notes"] = [note]

    def close(self) -> None:
        """Release the recording's files (a bag's reader)."""
        close = getattr(self.dataset, "close", None)
        if close is not None:
            close()

    def progress(self, callback: Callable[[int, int], None]) -> Callable[[int, int], None]:
        """``callback`` for the odometry's ``progress(k, n)``, ending an epoch's span."""

        def step(k: int, n: int) -> None:
            self.current = None
            callback(k, n)

        return step

    @contextlib.contextmanager
    def naming_errors(self) -> Iterator[None]:
        """Re-raise a PlanodomError naming no file, raised within an epoch, naming its scan."""
        try:
            yield
        except PlanodomError as exc:
            if self.current is None or isinstance(exc, DatasetError):
                raise
            raise DatasetError(f"{self.current}: {one_line(exc)}") from exc


@dataclass(frozen=True)
class Source:
    """Where ``run`` and ``smooth`` take their epochs from: a recording (a dataset
    directory, a bag read with the bag options, a KITTI sequence), or a built-in scenario
    simulated with the given rig, noise, seed, length and motion."""

    dataset: Path | None
    scenario: str | None
    rig: str
    noise: str
    seed: int
    epochs: int | None
    motion: str
    base_frame: str = "base_link"
    epoch_rate: float = 10.0
    topic: list[str] | None = None
    gt_topic: str | None = None
    time_field: str = "auto"
    bin_layout: str = "auto"
    echo: str = "first"

    def bag_options(self) -> Any:
        """The :class:`~planodom.datasets.bag_options.BagOptions` of the bag options."""
        from planodom.datasets.bag_options import BagOptions

        return BagOptions.of(
            self.base_frame, self.epoch_rate, self.topic, self.gt_topic, self.time_field, self.echo
        )

    def check(self) -> None:
        from planodom.errors import ConfigError

        if (self.dataset is None) == (self.scenario is None):
            raise ConfigError("give either a DATASET directory or --scenario NAME")
        given = self.bag_options().given()
        if self.scenario is not None and given:
            flags = ", ".join("--" + g.replace("_", "-").replace("topics", "topic") for g in given)
            raise ConfigError(f"{flags}: bag options, not for --scenario")
        if self.scenario is not None and self.bin_layout != "auto":
            raise ConfigError("--bin-layout: for .bin scan files, not for --scenario")
        simulated = [f"--{n}" for n, _, d in _SOURCE_OPTIONS[2:7] if getattr(self, n) != d]
        if self.dataset is not None and simulated:  # ignored before: a whole run, no word
            raise ConfigError(
                f"{', '.join(simulated)}: options of --scenario (a simulation), not for a "
                "recording, which is read whole"
            )

    def load(self, folder: Path, skip_bad: bool = False) -> ScanEpochs:
        """The recording, or the scenario simulated into ``folder/dataset`` and loaded."""
        from planodom.datasets.recording import open_recording

        self.check()
        if self.dataset is not None:
            options = dataclasses.replace(self.bag_options(), skip_broken_parts=skip_bad)
            recording = open_recording(self.dataset, options, self.bin_layout)
            return ScanEpochs(recording, skip_bad)
        from planodom.simulation.export import write_simulated_dataset

        sim = (self.scenario, self.rig, self.noise, self.seed, self.epochs, self.motion)
        run = simulate_scene(*sim)  # type: ignore[arg-type]
        with console.status("writing the simulated dataset"):
            data = write_simulated_dataset(run, folder / "dataset", self.scenario)
        return ScanEpochs(data, skip_bad)


#: The options of :class:`Source`, shared by ``run`` and ``smooth`` (:func:`takes_source`).
_SOURCE_OPTIONS = (
    ("dataset", DatasetDir, None),
    ("scenario", Scenario, None),
    ("rig", RigName, "isoclinal"),
    ("noise", Noise, "lms221"),
    ("seed", Seed, 0),
    ("epochs", Epochs, None),
    ("motion", Motion, "continuous"),
    ("base_frame", BaseFrame, "base_link"),
    ("epoch_rate", EpochRate, 10.0),
    ("topic", Topics, None),
    ("gt_topic", GtTopic, None),
    ("time_field", TimeField, "auto"),
    ("bin_layout", BinLayoutOption, "auto"),
    ("echo", Echo, "first"),
)


def bundles(name: str, make: Callable[..., Any], options: tuple) -> Callable:
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
takes_source = bundles("source", Source, _SOURCE_OPTIONS)


def load_config(path: Path | None, changes: dict[str, object] | None = None):
    """The config of ``path`` (defaults without), with the non-None ``changes`` (dotted
    field names, e.g. ``odometry.delta``) applied through ``PlanodomConfig.updated``."""
    from planodom.config import PlanodomConfig

    cfg = PlanodomConfig() if path is None else PlanodomConfig.from_yaml(path)
    changes = {k: v for k, v in (changes or {}).items() if v is not None}
    return cfg.updated(changes, source="command line") if changes else cfg


@contextlib.contextmanager
def progress_bar(description: str) -> Iterator[Callable[[int, int], None]]:
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
