"""``planodom eval`` (a trajectory against a reference) and ``planodom convert`` (a bag
into the dataset format)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

import typer

from planodom.cli.common import (
    BaseFrame,
    EpochRate,
    GtTopic,
    OutDir,
    Overwrite,
    TimeField,
    Topics,
    app,
    console,
    reports_errors,
    warn,
)
from planodom.cli.echo_option import Echo
from planodom.errors import ConfigError, DatasetError, GeometryError

ALIGNMENTS = ("none", "origin", "se3", "4dof")


@app.command("eval")
@reports_errors
def evaluate(
    estimate: Annotated[Path, typer.Argument(help="Estimated trajectory: TUM or KITTI file.")],
    truth: Annotated[
        Path, typer.Argument(help="Reference: a TUM or KITTI file, or a dataset with poses.tum.")
    ],
    delta: Annotated[
        int, typer.Option(help="RPE step in estimated poses (matched, without a gap between).")
    ] = 1,
    align: Annotated[
        str,
        typer.Option(
            help="none | origin (first poses coincide) | se3 (Umeyama, no scale) | "
            "4dof (yaw + translation)."
        ),
    ] = "origin",
    max_diff: Annotated[
        float, typer.Option("--max-diff", help="TUM: largest time difference of a pair, s.")
    ] = 0.01,
    offset: Annotated[float, typer.Option(help="TUM: added to the estimate's times, s.")] = 0.0,
    out: OutDir = None,
    overwrite: Overwrite = False,
) -> None:
    """ATE, RPE, drift and per-epoch 5-DoF errors of a trajectory against a reference.

    Timestamps are associated (nearest within --max-diff), not required to be identical.
    Writes metrics.json, trajectory.png and errors.png to --out and prints the table.
    """
    from planodom import results
    from planodom.evaluation import associate_indexed, evaluate, read_trajectory
    from planodom.plots.run import write_eval_plots
    from planodom.report import metrics_table

    if align not in ALIGNMENTS:
        raise ConfigError(f"--align: expected one of {', '.join(ALIGNMENTS)}, got '{align}'")
    if not max_diff >= 0:
        raise ConfigError(f"--max-diff: expected seconds >= 0, got {max_diff}")
    if not math.isfinite(offset):
        raise ConfigError(f"--offset: expected a finite number of seconds, got {offset}")
    est, ref = read_trajectory(estimate), read_trajectory(truth)
    times, est_poses, ref_poses, index = associate_indexed(est, ref, max_diff, offset)
    if len(times) < 2:
        spans = "" if est.times is None or ref.times is None else _spans(est.times, ref.times)
        raise DatasetError(
            f"{est.path}: {len(times)} pose matched with {ref.path}; errors over the "
            f"trajectory need 2 or more {spans}(see --max-diff and --offset)"
        )
    if len(times) < len(est.poses):  # a reference over part of the run: said, not silent
        warn(
            f"{len(est.poses) - len(times)} of the {len(est.poses)} poses of {est.path} have "
            f"no reference pose within {max_diff:g} s (the reference spans part of the run?): "
            f"the errors are over the {len(times)} matched, and no relative error pairs two "
            "poses across the unmatched ones (the drift's distance takes the reference's "
            "straight line across a gap)"
        )
    if not 1 <= delta < len(times):
        raise ConfigError(
            f"--delta {delta}: the RPE step needs 1 <= delta < {len(times)} (the matched poses)"
        )
    try:
        summary = evaluate(est_poses, ref_poses, align, delta, index)  # type: ignore[arg-type]
    except GeometryError as exc:  # e.g. se3 on poses along a line: name what was aligned
        raise GeometryError(
            f"--align {align}: {exc} ({len(times)} matched poses of {est.path} and "
            f"{ref.path}; --align origin needs no spread)"
        ) from None
    info: dict[str, object] = {"estimate": str(est.path), "reference": str(ref.path)}
    info |= {"align": align, "matched_poses": len(times), "estimate_poses": len(est.poses)}
    info |= {"reference_poses": len(ref.poses)}
    if (order := _quaternion_order(est, ref, est_poses, ref_poses)) is not None:
        warn(order)
        info["notes"] = [order]
    with results.results_folder(out, overwrite=overwrite, inputs=[estimate, truth]) as folder:
        results.write_metrics(folder.tmp, info | summary)
        with console.status("drawing the plots"):
            write_eval_plots(folder.tmp, times, est_poses, ref_poses, align, index=index)  # type: ignore[arg-type]
    title = f"{est.path.name} vs {ref.path.name}: {len(times)} poses matched -> {folder.path}"
    console.print(metrics_table(summary, title=title))


def _quaternion_order(est: Any, ref: Any, est_poses: Any, ref_poses: Any) -> str | None:
    """Whether either TUM file's quaternions read right only as qw qx qy qz
    (:func:`planodom.quaternion_order.wxyz_note`; KITTI files hold matrices)."""
    from planodom.quaternion_order import wxyz_note

    note = None if ref.times is None else wxyz_note(est_poses, ref_poses, str(ref.path))
    if note is None and est.times is not None:
        note = wxyz_note(ref_poses, est_poses, str(est.path))
    return note


def _spans(est: Any, ref: Any) -> str:
    """The two files' time spans, and whether one looks like another unit (ns for s)."""
    a, b = float(est[-1] - est[0]), float(ref[-1] - ref[0])
    text = f"(estimate {est[0]:.6g}..{est[-1]:.6g} s, reference {ref[0]:.6g}..{ref[-1]:.6g} s"
    if min(a, b) > 0 and max(a, b) / min(a, b) > 100:
        text += f"; one lasts {max(a, b) / min(a, b):.3g} times the other: another time unit?"
    return text + ") "


@app.command("convert")
@reports_errors
def convert(
    bag: Annotated[Path, typer.Argument(help="A ROS 1 .bag file or a ROS 2 bag folder.")],
    dataset: Annotated[Path, typer.Argument(help="Dataset directory to write.")],
    base_frame: BaseFrame = "base_link",
    epoch_rate: EpochRate = 10.0,
    topic: Topics = None,
    gt_topic: GtTopic = None,
    time_field: TimeField = "auto",
    echo: Echo = "first",
    overwrite: Annotated[bool, typer.Option(help="Replace a dataset at DATASET.")] = False,
    skip_bad_scans: Annotated[
        bool,
        typer.Option(
            "--skip-bad-scans",
            help="Leave out a ROS 2 bag's storage files that cannot be read (a split "
            "recording's part missing, cut short or overwritten): their time span is a gap.",
        ),
    ] = False,
) -> None:
    """Convert a bag into the dataset format (scans/*.ply with ring and t, rig.yaml, and
    the bag's epoch times in poses.tum with --gt-topic, else in times.txt)."""
    import dataclasses

    from rich.table import Table

    from planodom.datasets.bag_options import BagOptions
    from planodom.datasets.rosbag import convert_bag

    options = BagOptions.of(base_frame, epoch_rate, topic, gt_topic, time_field, echo)
    options = dataclasses.replace(options, skip_broken_parts=skip_bad_scans)
    with console.status(f"converting {bag}"):
        c = convert_bag(bag, dataset, options, overwrite=overwrite)
    for note in c.notes:
        warn(note)
    table = Table(title=f"{c.bag} -> {c.out_dir}", show_header=False)
    rows = {
        "epochs": f"{c.epochs} at {epoch_rate:g} Hz",
        "points": f"{c.points}",
        "scan topics (ring order)": ", ".join(c.topics),
        "rings": f"{c.rings}",
        "time span (s since the Unix epoch)": f"{c.start_time:.3f} .. {c.end_time:.3f}",
        "reference": c.gt_topic or "none (times in times.txt)",
    }
    if c.dropped_epochs:
        rows["epochs outside the reference"] = f"{c.dropped_epochs} (dropped)"
    for key, value in rows.items():
        table.add_row(key, value)
    console.print(table)
