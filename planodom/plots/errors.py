"""``errors.png``: per-epoch 5-DoF increment errors over time, with ±2σ bands."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from planodom.metrics import POSE5_NAMES
from planodom.plots import pyplot, save

#: Per DoF: axis label and the factor from SI (rad, m) to the plotted unit.
UNITS = {
    "roll": ("roll (deg)", np.degrees(1.0)),
    "pitch": ("pitch (deg)", np.degrees(1.0)),
    "yaw": ("yaw (deg)", np.degrees(1.0)),
    "x": ("x (cm)", 100.0),
    "y": ("y (cm)", 100.0),
}


def plot_errors(
    path: str | Path,
    times: np.ndarray,
    errors: Mapping[str, Mapping[str, np.ndarray]],
    sigmas: np.ndarray | None = None,
    *,
    title: str = "per-epoch errors",
    band_label: str = "±2σ (odometry)",
) -> Path:
    """Five panels (roll, pitch, yaw, x, y) of increment errors against time.

    Args:
        times: (K,) seconds of the increments (the later epoch of each); drawn from 0.
        errors: ``{label: {"roll": (K,), ..., "y": (K,)}}`` signed errors, rad and m
            (:func:`planodom.metrics.per_epoch_errors`); empty without a reference.
        sigmas: (K, 5) standard deviations of (roll, pitch, yaw, x, y), rad and m: the
            ±2σ band (NaN: none at that epoch).
    """
    plt = pyplot()
    t = np.asarray(times, dtype=np.float64)
    t = t - t[0] if len(t) else t
    fig, axes = plt.subplots(5, 1, figsize=(8.0, 9.0), sharex=True, layout="constrained")
    for j, (ax, name) in enumerate(zip(axes, POSE5_NAMES, strict=True)):
        label, scale = UNITS[name]
        if sigmas is not None and len(t):
            band = 2.0 * scale * np.asarray(sigmas)[:, j]
            ax.fill_between(t, -band, band, color="0.5", alpha=0.25, lw=0, label=band_label)
        for (series, values), colour in zip(
            errors.items(), ("tab:blue", "tab:orange"), strict=False
        ):
            ax.plot(t, scale * np.asarray(values[name]), lw=0.9, color=colour, label=series)
        ax.axhline(0.0, color="0.3", lw=0.6)
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[-1].set_xlabel("time (s)")
    handles, labels = axes[0].get_legend_handles_labels()
    if handles:
        axes[0].legend(handles, labels, loc="upper right", fontsize=8, ncol=len(handles))
    if not errors:
        title += " (no reference: the ±2σ bands only)"
    axes[0].set_title(title)
    return save(fig, path)
