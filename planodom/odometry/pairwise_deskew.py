"""The deskewing refinement a run makes on the pairwise pipelines only
(``odometry.pairwise_deskew``).

    cfg = with_pairwise_deskew(config, source)   # in run_odometry, after with_platform

``odometry.pairwise_deskew: passes_moments`` means, where a pairwise pipeline runs (the 2D
rig: ``uses_plane_map`` false for the sequence's first epoch), each of
:data:`PASSES_OPTIONS` the config does not set explicitly takes its value there (as
``odometry.platform``'s vehicle options do, :mod:`.platform`: a user's value wins); the
plane map (the lidars) keeps its fields, so its run is unchanged. ``streaming`` (the
default) changes nothing. Of the options, ``deskew_passes`` and ``degenerate_ends`` act on
the plane map too (a pass re-extracts every epoch along the curve; the stretches are
made again after any run); the moments' fields act on the pairwise pipelines only.
Only :func:`planodom.odometry.run.run_odometry` resolves it (the passes are its).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from planodom.config import PlanodomConfig
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.extraction.lidar.sweep import Epochs

#: ``odometry`` fields of the candidate ``p1mpd`` (docs/RESULTS.md, P1MP14): one
#: deskewing pass, the gated moments in the passes only, degenerate stretches made again.
PASSES_OPTIONS: dict[str, object] = {
    "deskew_passes": 1,
    "refinement": "moments",
    "moment_gate_chi2": 20.5,
    "moment_passes": "deskew_passes",
    "degenerate_ends": "interpolated",
}


def with_pairwise_deskew(config: PlanodomConfig, source: Epochs) -> PlanodomConfig:
    """``config`` with ``odometry.pairwise_deskew`` resolved for the sequence ``source``
    by its first epoch (a :class:`Scan`, or planes: pairwise) (module docstring); the
    epoch is read only when the option is on (a dataset reads it from disk)."""
    from planodom.odometry.planemap import uses_plane_map

    odometry = config.odometry
    if odometry.pairwise_deskew != "passes_moments":
        return config
    first = source[0] if len(source) else None
    if uses_plane_map(config, first if isinstance(first, Scan) else None):
        return config
    explicit = odometry.model_fields_set
    changes = {f"odometry.{k}": v for k, v in PASSES_OPTIONS.items() if k not in explicit}
    return config.updated(changes, source="pairwise_deskew") if changes else config
