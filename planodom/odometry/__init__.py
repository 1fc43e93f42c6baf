"""Odometry from planar landmarks: rotation, translation, the pipelines, streaming.

- :func:`estimate_relative_pose`: the 5-DoF relative pose of two plane sets (paper V).
- :class:`PlaneOdometry`: streaming, one epoch at a time; :func:`run_odometry`: a whole run.
"""

from planodom.odometry.pipeline import (
    PIPELINES,
    RelativePose,
    estimate_relative_pose,
    pipeline_methods,
)
from planodom.odometry.streaming import (
    OdometryRun,
    PlaneOdometry,
    motion_assumption,
    run_odometry,
    with_dataset_bounds,
)

__all__ = [
    "PIPELINES",
    "OdometryRun",
    "PlaneOdometry",
    "RelativePose",
    "estimate_relative_pose",
    "motion_assumption",
    "pipeline_methods",
    "run_odometry",
    "with_dataset_bounds",
]
