"""Rich tables for the CLI (kept out of the algorithm modules)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from rich.table import Table

from planodom.config import PlanodomConfig
from planodom.simulation.simulate import SimulatedRun


def motion_assumption(config: PlanodomConfig) -> str:
    """One line stating what the absolute constraints of the association assume."""
    a, d = config.association, config.odometry.delta
    return (
        f"association assumes at most {a.max_translation_m:g} m and {a.max_rotation_deg:g} deg "
        f"of motion between consecutive epochs (x{d} for delta = {d}); with a "
        f"constant-velocity prior, {a.prior_translation_m:g} m / {a.prior_rotation_deg:g} deg "
        "around it (config association.max_*/prior_*, or motion_bounds in rig.yaml)"
    )


def simulation_table(run: SimulatedRun, title: str = "simulation") -> Table:
    """Summary of a simulated run: epochs, duration, distance, points and no-returns."""
    n_points = np.array([len(s) for s in run.scans])
    ranges = [np.concatenate([r.ravel() for r in epoch]) for epoch in run.ranges]
    no_return = np.mean([np.mean(~np.isfinite(r)) for r in ranges]) if ranges else np.nan
    steps = np.diff(run.poses[:, :3, 3], axis=0)
    table = Table(title=title, show_header=False)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    rows = {
        "epochs": f"{len(run)}",
        "epoch rate": f"{run.epoch_rate:g} Hz",
        "duration": f"{len(run) / run.epoch_rate:.1f} s",
        "distance travelled": f"{np.linalg.norm(steps, axis=1).sum():.1f} m",
        "sensors": f"{len(run.sensor_rig.sensors)} ({run.sensor_rig.name})",
        "motion": run.motion,
        "points per epoch (median)": f"{np.median(n_points):.0f}" if len(n_points) else "-",
        "beams without return": f"{100 * no_return:.1f} %",
        "surfaces in scene": f"{len(run.scene.surfaces)}",
    }
    for key, value in rows.items():
        table.add_row(key, value)
    return table


def metrics_table(metrics: Mapping[str, float], title: str = "metrics") -> Table:
    """Two-column table of a flat metrics dict (keys carry their units)."""
    table = Table(title=title, show_header=False)
    table.add_column("metric")
    table.add_column("value", justify="right")
    for key, value in metrics.items():
        table.add_row(key, f"{value:.6g}" if isinstance(value, float) else str(value))
    return table


def odometry_table(run: object, metrics: Mapping[str, float], title: str = "odometry") -> Table:
    """Summary of an odometry run: statuses, speed and, with ground truth, the errors."""
    rows = [
        ("epochs", "epochs", "{:.0f}"),
        ("epochs with a reference (the errors' span)", "evaluated_epochs", "{:.0f}"),
        ("unresolved epochs (fallback: constant velocity)", "unresolved_epochs", "{:.0f}"),
        ("degenerate epochs (translation not observed)", "degenerate_epochs", "{:.0f}"),
        ("planes per epoch (median)", "planes_per_epoch_median", "{:.0f}"),
        ("front end speed", "epochs_per_second", "{:.1f} epochs/s"),
        ("distance travelled", "distance_m", "{:.1f} m"),
        ("ATE rmse (3D / horizontal)", ("ate_rmse_m", "ate_rmse_m_xy"), "{:.3f} / {:.3f} m"),
        ("final drift (horizontal)", ("drift_m_xy", "drift_percent_xy"), "{:.3f} m = {:.2f} %"),
        ("RPE translation rmse", "rpe_trans_rmse_m", "{:.4f} m"),
        ("RPE rotation rmse", "rpe_rot_rmse_deg", "{:.4f} deg"),
    ]
    for name in ("roll", "pitch", "yaw"):
        rows.append(
            (
                f"{name} rate error mean / std",
                (f"{name}_err_mean_deg", f"{name}_err_std_deg"),
                "{:.4f} / {:.4f} deg",
            )
        )
    for name in ("x", "y"):
        rows.append(
            (
                f"{name} error mean / std",
                (f"{name}_err_mean_m", f"{name}_err_std_m"),
                "{:.4f} / {:.4f} m",
            )
        )
    table = Table(title=title, show_header=False)
    table.add_column("quantity")
    table.add_column("value", justify="right")
    for label, keys, fmt in rows:
        keys = (keys,) if isinstance(keys, str) else keys
        if all(k in metrics for k in keys):
            values = [metrics[k] for k in keys]
            slow = keys == ("epochs_per_second",) and 0 < values[0] < 0.05
            # below 0.05 epochs/s the one decimal read 0.0 (a run on 10M-point scans)
            text = _slow_speed(values[0]) if slow else fmt.format(*values)
            table.add_row(label, text)
    return table


def _slow_speed(epochs_per_second: float) -> str:
    """A front end speed below 0.05 epochs/s, which one decimal shows as 0.0."""
    return f"{epochs_per_second:.2g} epochs/s ({1 / epochs_per_second:.3g} s an epoch)"


#: Columns of a comparison table: (header, metrics key, format).
COMPARISON_COLUMNS = (
    ("ATE xy [m]", "ate_rmse_m_xy", "{:.3f}"),
    ("ATE 3D [m]", "ate_rmse_m", "{:.3f}"),
    ("RPE t [m]", "rpe_trans_rmse_m", "{:.4f}"),
    ("RPE r [deg]", "rpe_rot_rmse_deg", "{:.4f}"),
    ("drift xy [%]", "drift_percent_xy", "{:.2f}"),
)


def comparison_table(rows: Mapping[str, Mapping[str, float]], title: str = "") -> Table:
    """One row per estimator with the headline metrics (ATE and RPE are rmse)."""
    table = Table(title=title)
    table.add_column("estimator")
    for header, _, _ in COMPARISON_COLUMNS:
        table.add_column(header, justify="right")
    for name, m in rows.items():
        cells = [fmt.format(m[key]) if key in m else "-" for _, key, fmt in COMPARISON_COLUMNS]
        table.add_row(name, *cells)
    return table
