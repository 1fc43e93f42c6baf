"""Top-view trajectory panels shared by the experiments (matplotlib, kept out of the algorithms)."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from planodom.outputs import write_whole


def top_view(ax, gt: np.ndarray, tracks: Iterable[tuple[str, np.ndarray, str | None]], title: str):
    """Truth (blue crosses, at most ~150) and each ``(label, poses (E, 4, 4), colour)`` in xy."""
    every = max(1, len(gt) // 150)
    ax.plot(gt[::every, 0], gt[::every, 1], "x", color="tab:blue", ms=4, label="truth")
    for label, poses, colour in tracks:
        p = poses[:, :3, 3]
        ax.plot(p[:, 0], p[:, 1], "-", color=colour, lw=1.2, label=label)
    ax.set_title(title)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize=8)


def save_grid(fig, axes, n_used: int, path: Path) -> None:
    """Hide the unused panels of ``axes``, save ``fig`` to ``path`` and close it."""
    import matplotlib.pyplot as plt

    for ax in axes.ravel()[n_used:]:
        ax.axis("off")
    fig.tight_layout()
    write_whole(path, lambda tmp: fig.savefig(tmp, dpi=120))  # whole or not at all
    plt.close(fig)


#: One panel: title, truth (E, 3) positions, and ``(label, poses (E, 4, 4), colour)`` tracks.
Panel = tuple[str, np.ndarray, list[tuple[str, np.ndarray, str | None]]]


def plot_panels(panels: Sequence[Panel], path: Path) -> None:
    """Top views (:func:`top_view`) in a grid of two columns, saved to ``path`` (PNG)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ncol = min(2, len(panels))
    nrow = int(np.ceil(len(panels) / ncol))
    fig, axes = plt.subplots(nrow, ncol, figsize=(6.5 * ncol, 5.5 * nrow), squeeze=False)
    for ax, (title, gt, tracks) in zip(axes.ravel(), panels, strict=False):
        top_view(ax, gt, tracks, title)
    save_grid(fig, axes, len(panels), path)
