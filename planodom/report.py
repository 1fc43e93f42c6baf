"""Rich tables for the CLI (kept out of the algorithm modules)."""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from rich.table import Table

from planodom.simulation.simulate import SimulatedRun


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
        "sensors": f"{len(run.rig.sensors)} ({run.rig.name})",
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
