"""The ``planodom`` command line: parses arguments, calls the library, prints tables.

Known failures (:class:`planodom.errors.PlanodomError`, OS errors on a named file) are
reported in one line, without a traceback, and exit with status 2
(:func:`planodom.cli.common.reports_errors`). Results folders are written whole or not at
all, never over the inputs or earlier results (:func:`planodom.results.results_folder`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from planodom.cli import evaluate as _evaluate  # noqa: F401  (registers eval and convert)
from planodom.cli import experiments as _experiments  # noqa: F401  (registers the commands)
from planodom.cli.common import (
    ConfigFile,
    Epochs,
    Motion,
    Noise,
    OutDir,
    Overwrite,
    ScanEpochs,
    Scene,
    SkipBadScans,
    Source,
    app,
    console,
    load_config,
    progress_bar,
    reports_errors,
    simulate_scene,
    takes_source,
    warn,
)
from planodom.cli.help_text import reflow_help
from planodom.errors import ConfigError

__all__ = ["app"]


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
    out: Annotated[Path, typer.Option("--out", "-o", help="Dataset folder to write.")],
    scene: Scene = "paper-loop",
    rig: RandomRigName = None,
    noise: Noise = "0.0",
    seed: Annotated[int, typer.Option(help="Noise seed; for a random scene also the world.")] = 0,
    epochs: Epochs = None,
    motion: Motion = "continuous",
    handheld: Annotated[
        bool,
        typer.Option(help="A random scene's route walked with a hand-held lidar (yaw swings)."),
    ] = False,
    overwrite: Annotated[bool, typer.Option(help="Replace a dataset at --out.")] = False,
) -> None:
    """Simulate a built-in scene and write it as a dataset (scans, poses.tum, rig.yaml).

    The dataset is written beside --out and moved into place when complete; --overwrite
    replaces only a dataset (scans/, poses.tum, rig.yaml), never a folder of other files.
    """
    from planodom.datasets.dataset import is_dataset_entry
    from planodom.outputs import check_target
    from planodom.report import simulation_table
    from planodom.simulation.export import write_simulated_dataset
    from planodom.simulation.named import RANDOM_SCENES

    # refuse an existing folder before simulating, not after (checked again when writing)
    check_target(out, overwrite=overwrite, owned=is_dataset_entry, what="a dataset")
    rig = rig or (None if scene in RANDOM_SCENES else "isoclinal")
    run = simulate_scene(scene, rig, noise, seed, epochs, motion, handheld)
    with console.status(f"writing {len(run)} scans to {out}"):
        write_simulated_dataset(run, out, scene_name=scene, overwrite=overwrite)
    console.print(simulation_table(run, title=f"{run.scene.name} / {run.sensor_rig.name} -> {out}"))


def _inputs(source: Source, config: Path | None) -> list[Path]:
    """The files and folders a run reads, which its results may not touch (for a ROS 2
    bag's .db3 / .mcap file, its bag folder: results were written into it)."""
    from planodom.datasets.bag_paths import is_bag_part

    inputs = [p for p in (source.dataset, config) if p is not None]
    given = source.dataset
    if given is not None and is_bag_part(given):
        inputs.append(given.parent)
    return inputs


def _report_skipped(data: ScanEpochs, metrics: dict, poses) -> None:
    """List in metrics.json the scans skipped and the recording's notes (warned of)."""
    data.reference_order(poses, metrics)  # the estimate's ``poses``: a reference misread?
    if data.notes:
        metrics["recording_notes"] = data.notes
    if data.skipped:
        warn(f"{len(data.skipped)} unreadable scan(s) skipped, listed in metrics.json")
        metrics["skipped_scans"] = data.skipped


def _report_far_points(data: ScanEpochs, metrics: dict) -> None:
    """Warn of (and list in metrics.json) scans with points beyond any sensor's range, scans
    without points and scans that repeat the one before them (a frozen driver): the
    reasons for an unresolved epoch nothing else names."""
    from planodom.scan import MAX_RANGE_M

    if data.empty:
        warn(
            f"{len(data.empty)} scan(s) hold no points (first: {next(iter(data.empty))}): "
            "no planes, so their epochs are bridged at constant velocity (listed in "
            "metrics.json)"
        )
        metrics["scans_without_points"] = list(data.empty)
    if data.repeated.found:
        warn(data.repeated.note())
        metrics["scans_repeated"] = list(data.repeated.found)

    if data.far:
        name, (far, total, extent) = next(iter(data.far.items()))
        # one sweep spans at most twice the sensor's range: a wider scan is not in metres
        why = (
            f"the scan itself spans {extent:.3g} m, more than any lidar sees: not metres "
            "(millimetres? scale the coordinates to metres)"
            if extent > 2 * MAX_RANGE_M
            else "not in the vehicle's frame (a map-frame export?)"
        )
        warn(
            f"{len(data.far)} scan(s) hold points more than {MAX_RANGE_M:g} m from the base "
            f"origin, farther than any lidar measures (first: {name}, {far} of {total} "
            f"points): {why}; their epochs are likely unresolved (listed in metrics.json)"
        )
        metrics["scans_beyond_sensor_range"] = list(data.far)


def _report_gaps(odo, metrics: dict) -> None:
    """Warn of (and list in metrics.json) gaps in the epoch times (scans missing,
    :data:`planodom.odometry.epoch_time.GAP_PERIODS`); across a long one
    (:func:`planodom.odometry.epoch_time.is_gap`) the odometry carries no motion, so the
    epoch after it is registered without a prediction (a recording with an hour cut out
    had run 'ok' with 14 cm errors after the cut, and no word)."""
    import numpy as np

    if len(odo.times) < 3:
        return
    from planodom.odometry.epoch_time import GAP_PERIODS, RESET_PERIODS, epoch_periods

    periods = epoch_periods(odo.times)
    gaps = np.flatnonzero(periods >= GAP_PERIODS)
    if len(gaps):
        k = int(gaps[0])
        seconds = float(odo.times[k + 1] - odo.times[k])
        warn(
            f"{len(gaps)} gap(s) in the epoch times (first: before epoch {k + 1}, {seconds:g} s "
            f"= {periods[k]:.0f} epoch periods): the odometry predicts across short gaps at "
            f"constant velocity and carries no motion across gaps of {RESET_PERIODS} periods "
            "or more; check the epochs after them (listed in metrics.json)"
        )
        metrics["epochs_after_gaps"] = [int(e) + 1 for e in gaps]


def _report_beyond_bounds(odo, metrics: dict) -> None:
    """Warn of (and list in metrics.json) epochs whose estimated step exceeds the motion
    bounds the association assumed: there the odometry has most likely lost track, which
    its statuses alone may not show (seen on a hand-held VLP-16 walk: 'ok' epochs of 9 m)."""
    import numpy as np

    from planodom.geometry import invert_transform, se3_log
    from planodom.odometry.epoch_time import epoch_periods

    if odo.config is None or len(odo.poses) < 2:
        return
    a = odo.config.association
    steps = invert_transform(odo.poses[:-1]) @ odo.poses[1:]
    metres = np.linalg.norm(steps[:, :3, 3], axis=1)
    degrees = np.degrees(np.linalg.norm(se3_log(steps)[:, :3], axis=1))
    # the bounds are per epoch period: a step over a gap in the recording (dropped scans)
    # spans as many periods and may move as many times more
    periods = np.maximum(1.0, epoch_periods(odo.times))
    beyond = np.flatnonzero(
        (metres > a.max_translation_m * periods) | (degrees > a.max_rotation_deg * periods)
    )
    if len(beyond):
        k = int(beyond[0])
        warn(
            f"{len(beyond)} epoch(s) moved more than the association's motion bounds "
            f"({a.max_translation_m:g} m, {a.max_rotation_deg:g} deg an epoch period; first: "
            f"epoch {k + 1}, "
            f"{metres[k]:.2f} m, {degrees[k]:.1f} deg): the odometry has probably lost track "
            "there (listed in metrics.json); if the platform is that fast, raise "
            "motion_bounds in rig.yaml"
        )
        metrics["epochs_beyond_motion_bounds"] = [int(e) + 1 for e in beyond]


def _report_inconsistent(odo, metrics: dict) -> None:
    """Warn of (and list in metrics.json) epochs the odometry reported unresolved because
    their estimate contradicted the motion assumption (``RelativePose.inconsistent``: a
    step beyond the motion bounds, ``planemap.motion_bound_gate``, or a degenerate step
    off the constant-velocity prediction, ``odometry.degenerate_gate``); bridged."""
    epochs = [k for k, r in enumerate(odo.results) if r is not None and r.inconsistent]
    if not epochs or odo.config is None:
        return
    a = odo.config.association
    warn(
        f"{len(epochs)} epoch(s) bridged by constant velocity (first: epoch {epochs[0]}): "
        f"their estimate contradicted the motion assumption ({a.max_translation_m:g} m, "
        f"{a.max_rotation_deg:g} deg an epoch, or the constant-velocity prediction) and "
        "is not kept (listed in metrics.json); if the platform is that fast, raise "
        "motion_bounds in rig.yaml"
    )
    metrics["inconsistent_epochs"] = epochs


def _report_partial_rotation(odo, metrics: dict) -> None:
    """List in metrics.json the epochs whose planes fixed only part of the rotation, the
    rest the prediction's (``RelativePose.rotation_partly_observed``,
    ``planemap.partial_rotation: prediction``), as the degenerate epochs are counted."""
    epochs = [k for k, r in enumerate(odo.results) if r is not None and r.rotation_partly_observed]
    if epochs:
        metrics["rotation_partly_observed_epochs"] = epochs


def _write_pictures(folder: Path, data: ScanEpochs, odo, sm=None, name: str = "") -> None:
    """``covariances.npz`` and the three pictures of a run (and of its smoothing ``sm``)."""
    from planodom.covariances import FILE, odometry_covariances, write_covariances
    from planodom.plots.run import write_run_plots
    from planodom.smoothing.diagnostics import fallback_warning

    arrays = odometry_covariances(odo)
    if sm is not None:  # and the smoothing's warnings
        arrays[f"smoothed_{sm.result.mode}"] = sm.result.covariances
        for line in (sm.result.covariance_note, fallback_warning(sm.result)):
            if line:
                warn(line)
    write_covariances(folder / FILE, arrays)
    smoothed = None if sm is None else sm.poses
    with console.status("drawing the plots"):
        write_run_plots(folder, odo, data.gt_poses, smoothed, name=name)


@app.command()
@reports_errors
@takes_source
def run(
    source: Source,
    out: OutDir = None,
    overwrite: Overwrite = False,
    skip_bad_scans: SkipBadScans = False,
    config: ConfigFile = None,
    pipeline: Annotated[
        str | None,
        typer.Option(help="auto | map | wocsc | sda-mean | ocsc | mean (default: config's)."),
    ] = None,
    delta: Annotated[int | None, typer.Option(help="Associate epoch k with k - delta.")] = None,
) -> None:
    """Extract planes and run the paper's odometry over a dataset (or a built-in scenario).

    DATASET is a dataset directory, a ROS 1 .bag / ROS 2 bag folder (read with the bag
    options) or a KITTI sequence folder. Writes poses.tum, poses_kitti.txt, epochs.csv,
    covariances.npz, trajectory.png, errors.png, planes.png, config.yaml and, with ground
    truth, metrics.json to --out, and prints a summary.
    """
    from planodom import results
    from planodom.odometry import run_odometry
    from planodom.report import motion_assumption, odometry_table

    source.check()
    cfg = load_config(config, {"odometry.pipeline": pipeline, "odometry.delta": delta})
    inputs = _inputs(source, config)
    with results.results_folder(out, overwrite=overwrite, inputs=inputs) as folder:
        data = source.load(folder.tmp, skip_bad_scans)
        _check_run_delta(cfg.odometry.delta, delta is not None, len(data))
        with progress_bar("odometry") as callback, data.naming_errors():
            odo = run_odometry(data, cfg, data.rig, progress=data.progress(callback))
        data.close()
        metrics = results.odometry_metrics(odo, data.gt_poses)
        metrics |= results.kitti_metrics(odo.poses, data.gt_poses, data.Tr)
        _report_skipped(data, metrics, odo.poses)
        _report_far_points(data, metrics)
        _report_gaps(odo, metrics)
        _report_beyond_bounds(odo, metrics)
        _report_inconsistent(odo, metrics)
        _report_partial_rotation(odo, metrics)
        results.write_odometry_run(folder.tmp, odo, metrics, data.Tr)
        _write_pictures(folder.tmp, data, odo, name="planodom run")
    console.print(f"[dim]{motion_assumption(odo.config or cfg)}[/]", highlight=False)
    console.print(odometry_table(odo, metrics, title=f"planodom run -> {folder.path}"))


def _check_run_delta(delta: int, given: bool, n: int) -> None:
    """Refuse a delta no epoch can use: with ``delta >= n`` no epoch has an epoch k - delta
    (the streaming odometry would associate every epoch with the first, under bounds
    widened delta-fold)."""
    if delta > 1 and delta >= n:
        name = "--delta" if given else "odometry.delta"
        raise ConfigError(
            f"{name} {delta}: epoch k is associated with epoch k - delta, so the "
            f"{n} epoch(s) need delta < {n}"
        )


def _smoothing_delta(delta: int | None, window: int | None, mode: str, cfg, n: int):
    """``(window, delta)`` to run with; ConfigError in terms of --delta / --window."""
    if delta is None:
        d = cfg.smoothing.delta_max
        if window is not None and window <= d:
            raise ConfigError(
                f"--window {window}: the fixed-lag window must exceed the largest delta "
                f"D = {d} (--delta, or smoothing.delta_max in the config)"
            )
        return window, delta
    if not 1 <= delta < n:
        raise ConfigError(f"--delta {delta}: relative poses need 1 <= delta < {n} (the epochs)")
    w = cfg.smoothing.window if window is None else window
    if delta < w:
        return window, delta
    if mode == "windowed":
        raise ConfigError(
            f"--delta {delta}: must be smaller than the fixed-lag window W = {w} "
            "(--window, or smoothing.window in the config)"
        )
    return delta + 1, delta  # batch smoothing has no window: keep the config's check quiet


@app.command()
@reports_errors
@takes_source
def smooth(
    source: Source,
    out: OutDir = None,
    overwrite: Overwrite = False,
    skip_bad_scans: SkipBadScans = False,
    mode: Annotated[str | None, typer.Option(help="batch | windowed.")] = None,
    window: Annotated[
        int | None, typer.Option(help="Fixed-lag window W in epochs (implies --mode windowed).")
    ] = None,
    delta: Annotated[
        int | None, typer.Option(help="Relative poses for delta = 1..D (default: config's).")
    ] = None,
    loop_closure: Annotated[
        bool | None,
        typer.Option(
            "--loop-closure/--no-loop-closure",
            help="Re-identify revisited walls in a global plane map and close loops, in the "
            "mode run: batch sets smoothing.loop_closure (default on), --mode windowed sets "
            "smoothing.windowed_loop_closure (fixed-lag loop closure; default off: on a 2D "
            "rig it can cut the drift, on lidar it doubles the time for no gain). Default: "
            "the config's.",
        ),
    ] = None,
    config: ConfigFile = None,
) -> None:
    """Smooth the odometry with a factor graph (batch, or a fixed-lag window).

    DATASET as for ``run``. Writes the smoothed poses.tum / poses_kitti.txt, the raw
    odometry as odometry.tum, covariances.npz (the odometry's and the smoothed marginals),
    trajectory.png, errors.png, planes.png, config.yaml and, with ground truth,
    metrics.json for both.
    """
    from planodom import results
    from planodom.report import comparison_table
    from planodom.smoothing.run import run_smoothing

    source.check()
    cfg = load_config(config)  # before simulating: a bad file fails at once
    mode = mode or ("windowed" if window is not None else "batch")
    if mode not in ("batch", "windowed"):
        raise ConfigError(f"--mode: expected batch or windowed, got '{mode}'")
    if loop_closure is not None:  # the mode's own switch (batch's initial guess unchanged)
        key = "windowed_loop_closure" if mode == "windowed" else "loop_closure"
        cfg = cfg.updated({f"smoothing.{key}": loop_closure}, source="--loop-closure")
    inputs = _inputs(source, config)
    with results.results_folder(out, overwrite=overwrite, inputs=inputs) as folder:
        data = source.load(folder.tmp, skip_bad_scans)
        window, delta = _smoothing_delta(delta, window, mode, cfg, len(data))
        with progress_bar("odometry and relative poses") as callback, data.naming_errors():
            step = data.progress(callback)
            sm = run_smoothing(
                data, cfg, data.rig, window=window, delta=delta, mode=mode,
                progress=lambda stage, k, n: step(k, n),
            )  # fmt: skip
        data.close()
        odo_metrics = results.odometry_metrics(sm.odometry, data.gt_poses)
        odo_metrics |= results.kitti_metrics(sm.odometry.poses, data.gt_poses, data.Tr)
        _report_skipped(data, odo_metrics, sm.odometry.poses)
        _report_far_points(data, odo_metrics)
        _report_gaps(sm.odometry, odo_metrics)
        _report_beyond_bounds(sm.odometry, odo_metrics)
        _report_inconsistent(sm.odometry, odo_metrics)
        _report_partial_rotation(sm.odometry, odo_metrics)
        results.write_odometry_run(folder.tmp, sm.odometry, odo_metrics, data.Tr)
        results.write_trajectory(folder.tmp, sm.times, sm.poses, data.Tr)  # the output
        results.write_tum(folder.tmp / "odometry.tum", sm.times, sm.odometry.poses)
        results.write_config(folder.tmp, sm.config)
        smoothed = results.smoothing_metrics(sm.result, data.gt_poses, data.Tr)
        _write_pictures(folder.tmp, data, sm.odometry, sm, name=f"planodom smooth ({mode})")
        results.write_metrics(folder.tmp, {"odometry": odo_metrics, f"smoothing_{mode}": smoothed})
    title = f"planodom smooth -> {folder.path}"
    if data.gt_poses is None:  # nothing to compare: what the odometry under it did
        from planodom.report import odometry_table

        console.print(odometry_table(sm.odometry, odo_metrics, title=f"{title} (no reference)"))
        return
    rows = {"odometry": odo_metrics, f"{mode} smoothing": smoothed}
    console.print(comparison_table(rows, title=title))


@app.command("config")
@reports_errors
def show_config(config: ConfigFile = None) -> None:
    """Print the resolved configuration (defaults, or a file over them) as YAML.

    The output loads back unchanged: ``planodom config > my.yaml``, edit, ``--config my.yaml``.
    """
    typer.echo(load_config(config).to_yaml(), nl=False)


reflow_help(app)  # last: every command registered
