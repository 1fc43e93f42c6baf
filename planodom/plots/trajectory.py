"""``trajectory.png``: a top view of an estimate over its reference."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from planodom.plots import pyplot, save

#: Marker style of the epochs an odometry could not fully measure.
STATUS_MARKERS = {
    "unresolved": ("x", "tab:red", "unresolved (constant velocity)"),
    "degenerate": ("o", "tab:orange", "degenerate (rotation only)"),
}


def plot_trajectory(
    path: str | Path,
    estimate: np.ndarray,
    reference: np.ndarray | None = None,
    *,
    statuses: Sequence[str] | None = None,
    others: Sequence[tuple[str, np.ndarray]] = (),
    title: str = "trajectory",
    label: str = "estimate",
) -> Path:
    """Top view (x, y in metres) of ``estimate`` (E, 4, 4), over ``reference`` (E', 4, 4).

    Both are drawn as given: align the estimate into the reference's frame first
    (:func:`planodom.metrics.aligned`). ``statuses`` (E,) marks "unresolved" and
    "degenerate" epochs on the estimate; ``others`` adds ``(label, poses)`` tracks (e.g.
    the raw odometry beside the smoothed). The first pose is a black square.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 6.0), layout="constrained")
    if reference is not None:
        ref = reference[:, :3, 3]
        ax.plot(ref[:, 0], ref[:, 1], "-", color="0.55", lw=3.0, alpha=0.6, label="reference")
    for (name, poses), colour in zip(
        others, ("tab:orange", "tab:green", "tab:purple"), strict=False
    ):
        p = poses[:, :3, 3]
        ax.plot(p[:, 0], p[:, 1], "-", color=colour, lw=1.0, label=name)
    p = estimate[:, :3, 3]
    ax.plot(p[:, 0], p[:, 1], "-", color="tab:blue", lw=1.4, label=label)
    ax.plot(p[0, 0], p[0, 1], "s", color="black", ms=7, label="start")
    if statuses is not None:
        status = np.asarray(statuses)
        for value, (marker, colour, name) in STATUS_MARKERS.items():
            idx = np.flatnonzero(status == value)
            if len(idx):
                ax.plot(p[idx, 0], p[idx, 1], marker, color=colour, ms=6, mfc="none",
                        mew=1.5, label=f"{name}: {len(idx)}")  # fmt: skip
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title)
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    return save(fig, path)
