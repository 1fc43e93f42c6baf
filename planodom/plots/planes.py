"""``planes.png``: what the odometry saw per epoch: planes, pair associations, inliers."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from planodom.plots import pyplot, save
from planodom.plots.trajectory import STATUS_MARKERS


def _column(rows: Sequence[Mapping[str, object]], key: str) -> np.ndarray:
    return np.array([float(r.get(key, np.nan)) for r in rows])  # type: ignore[arg-type]


def plot_planes(
    path: str | Path, rows: Sequence[Mapping[str, object]], *, title: str = "planes"
) -> Path:
    """Three panels against time from an odometry run's per-epoch rows
    (:func:`planodom.odometry.epoch_rows`): planes extracted; LDA pair associations and
    strict (SDA) plane associations; the consensus inliers of the rotation and the
    translation. Unresolved and degenerate epochs are shaded."""
    plt = pyplot()
    t = _column(rows, "time")
    t = t - t[0] if len(t) else t
    fig, axes = plt.subplots(3, 1, figsize=(8.0, 7.0), sharex=True, layout="constrained")
    panels = (
        ("planes", (("n_planes", "planes extracted"),)),
        ("associations", (("n_lda_pairs", "LDA pairs"), ("n_sda", "SDA planes"))),
        (
            "consensus inliers",
            (("rotation_inliers", "rotation"), ("translation_inliers", "translation")),
        ),
    )
    statuses = [str(r.get("status", "")) for r in rows]
    half = 0.5 * float(np.median(np.diff(t))) if len(t) > 1 else 0.05
    for ax, (ylabel, series) in zip(axes, panels, strict=True):
        for status, (_, colour, name) in STATUS_MARKERS.items():
            idx = [k for k, s in enumerate(statuses) if s == status]
            for n, k in enumerate(idx):
                ax.axvspan(t[k] - half, t[k] + half, color=colour, alpha=0.2, lw=0,
                           label=name if n == 0 else None)  # fmt: skip
        for key, label in series:
            ax.step(t, _column(rows, key), where="mid", lw=1.0, label=label)
        ax.set_ylabel(ylabel)
        ax.set_ylim(bottom=0)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=8, ncol=4)
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(title)
    return save(fig, path)
