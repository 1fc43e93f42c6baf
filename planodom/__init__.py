"""planodom: odometry from planar landmarks, smoothed with GTSAM factor graphs.

The public API (imported lazily: ``import planodom`` stays cheap until a name is used)::

    import planodom

    data = planodom.open_recording("run.bag", planodom.BagOptions(gt_topic="/odom"))
    odo = planodom.PlaneOdometry(planodom.PlanodomConfig(), sensor_origins=data.rig.sensor_origins)
    for scan in data:                        # planodom.Scan: points (N, 3) m, base frame
        T_world_base = odo.register_epoch(scan)   # (4, 4), the first epoch is the identity

Data: :func:`open_recording` (a bag, a KITTI sequence or a dataset directory),
:func:`load_dataset`, :class:`BagOptions`, :class:`Scan`, :class:`Rig`. Stages:
:func:`extract_planes` (a scan to :class:`Plane` s), :func:`estimate_relative_pose` (two
epochs' planes to a :class:`RelativePose`, 5-DoF with a (5, 5) covariance),
:class:`PlaneOdometry` (streaming), :func:`run_odometry` (a whole sequence).
Smoothing: :func:`smooth_batch`, :class:`WindowedSmoother` (the fixed-lag smoother, also
named :data:`FixedLagSmoother`), :func:`run_smoothing`. Configuration:
:class:`PlanodomConfig`. Errors: :class:`PlanodomError` and its kinds.

Conventions: ``T_a_b`` (4, 4) maps frame b to frame a; planes ``n . p + d = 0``; SI units
(m, s, rad) unless a name says ``_deg``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from planodom.errors import (
    ConfigError,
    DatasetError,
    GeometryError,
    OutputError,
    OutputExistsError,
    PlanodomError,
)

#: The installed version, read on first use (importlib.metadata costs more than the rest of
#: ``import planodom``, which the ``planodom`` command does before it can handle a Ctrl-C).
__version__: str

if TYPE_CHECKING:
    from planodom.config import PlanodomConfig
    from planodom.datasets import load_dataset
    from planodom.datasets.bag_options import BagOptions
    from planodom.datasets.recording import open_recording
    from planodom.extraction import extract_planes
    from planodom.geometry import Plane
    from planodom.odometry import (
        OdometryRun,
        PlaneOdometry,
        RelativePose,
        Status,
        estimate_relative_pose,
        run_odometry,
    )
    from planodom.rig import Rig
    from planodom.scan import Scan
    from planodom.smoothing import SmoothingResult, WindowedSmoother, smooth_batch
    from planodom.smoothing.run import SmoothingRun, run_smoothing

    FixedLagSmoother = WindowedSmoother

#: Public name -> module it lives in (imported on first use).
_LAZY = {
    "PlanodomConfig": "planodom.config",
    "load_dataset": "planodom.datasets",
    "BagOptions": "planodom.datasets.bag_options",
    "open_recording": "planodom.datasets.recording",
    "extract_planes": "planodom.extraction",
    "Plane": "planodom.geometry",
    "OdometryRun": "planodom.odometry",
    "PlaneOdometry": "planodom.odometry",
    "RelativePose": "planodom.odometry",
    "Status": "planodom.odometry",
    "estimate_relative_pose": "planodom.odometry",
    "run_odometry": "planodom.odometry",
    "Rig": "planodom.rig",
    "Scan": "planodom.scan",
    "SmoothingResult": "planodom.smoothing",
    "WindowedSmoother": "planodom.smoothing",
    "smooth_batch": "planodom.smoothing",
    "SmoothingRun": "planodom.smoothing.run",
    "run_smoothing": "planodom.smoothing.run",
}
#: Other names for the same objects (the issue's and gtsam's word for the windowed one).
_ALIASES = {"FixedLagSmoother": "WindowedSmoother"}

__all__ = [
    "BagOptions",
    "ConfigError",
    "DatasetError",
    "FixedLagSmoother",
    "GeometryError",
    "OdometryRun",
    "OutputError",
    "OutputExistsError",
    "Plane",
    "PlaneOdometry",
    "PlanodomConfig",
    "PlanodomError",
    "RelativePose",
    "Rig",
    "Scan",
    "SmoothingResult",
    "SmoothingRun",
    "Status",
    "WindowedSmoother",
    "__version__",
    "estimate_relative_pose",
    "extract_planes",
    "load_dataset",
    "open_recording",
    "run_odometry",
    "run_smoothing",
    "smooth_batch",
]


def __getattr__(name: str) -> Any:
    if name == "__version__":
        globals()[name] = _version()
        return globals()[name]
    target = _ALIASES.get(name, name)
    if target not in _LAZY:
        raise AttributeError(f"module 'planodom' has no attribute {name!r}")
    value = getattr(importlib.import_module(_LAZY[target]), target)
    globals()[name] = value  # later look-ups skip this function
    return value


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("planodom")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
