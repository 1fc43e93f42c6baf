"""Pictures of a run for a person to read (matplotlib, Agg backend, PNG files).

Kept out of the algorithms: nothing under :mod:`planodom` but the CLI, the results
writers and the experiments imports this package.

- :mod:`.trajectory`: ``trajectory.png``, a top view of the estimate over the reference
  with the unresolved and degenerate epochs marked;
- :mod:`.errors`: ``errors.png``, per-epoch 5-DoF increment errors over time with
  ±2σ bands from the covariances;
- :mod:`.planes`: ``planes.png``, planes per epoch, pair associations, consensus inliers;
- :mod:`.run`: the three of an odometry or smoothing run, the two of ``planodom eval``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

#: Resolution of the written PNGs, dots per inch.
DPI = 110


def pyplot() -> Any:
    """``matplotlib.pyplot`` on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save(fig: Any, path: str | Path) -> Path:
    """Save ``fig`` to ``path`` as PNG, close it, and return the path."""
    plt = pyplot()
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return Path(path)
