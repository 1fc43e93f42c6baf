"""Odometry from planar landmarks: the relative-pose solver and the streaming odometry.

- :func:`estimate_relative_pose`: the 5-DoF relative pose of two plane sets (paper V):
  rotation (:mod:`.rotation`), translation (:mod:`.translation`), covariance
  (:mod:`.propagate`), put together in :mod:`.solver`.
- :class:`RelativePose` (:mod:`.relative`): what it returns, shared with the smoother;
  :class:`Status` ranks it.
- :class:`PlaneOdometry` (:mod:`.odometry`): streaming, one epoch at a time, with the
  deskewing policy of :mod:`.deskew`; :func:`run_odometry` (:mod:`.run`): a whole run,
  its config resolved against the dataset's platform first (:func:`with_platform`).
"""

from planodom.odometry.odometry import PlaneOdometry
from planodom.odometry.platform import with_platform
from planodom.odometry.relative import RelativePose, SolverDiagnostics, Status
from planodom.odometry.rows import epoch_rows
from planodom.odometry.run import OdometryRun, run_odometry, with_motion_bounds
from planodom.odometry.solver import PIPELINES, config_for_gap, estimate_relative_pose

__all__ = [
    "PIPELINES",
    "OdometryRun",
    "PlaneOdometry",
    "RelativePose",
    "SolverDiagnostics",
    "Status",
    "config_for_gap",
    "epoch_rows",
    "estimate_relative_pose",
    "run_odometry",
    "with_motion_bounds",
    "with_platform",
]
