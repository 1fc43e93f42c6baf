"""The deskewing offset of a step's twist where the step did not measure z
(``odometry.z_offset_measured_only``, pairwise pipelines).

A step measured by walls alone does not measure its vertical translation: the solver
keeps the prediction's (:mod:`planodom.odometry.pass_bounds`, ``z_prior``). The twist
offset (:func:`planodom.odometry.deskew.twist_offset`) corrects what the deskewing of
the two epochs put into a *measured* step; added to the vertical of an unmeasured one, it
makes the epoch's own twist, and so the next prediction, walk by the difference of two
deskewing twists' vertical velocities, which the walls do not fix either (HEIGHT,
docs/RESULTS.md: 2D-rig world 142's lap with the coplanar twist, whose fitted vertical
velocity swung by 10-60 m/s: steps of -1.3 m, the lap 759 m low). With the option the
vertical keeps the prediction's velocity (the motion model's, carried by constant
velocity).
"""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig
from planodom.odometry.deskew import twist_offset
from planodom.odometry.kept_epoch import KeptEpoch
from planodom.odometry.relative import RelativePose


def step_twist_offset(
    epoch: KeptEpoch,
    reference_twist: np.ndarray | None,
    dt: float,
    relative: RelativePose,
    config: OdometryConfig,
) -> np.ndarray | None:
    """(6,) :func:`twist_offset` of ``epoch`` (its scan and twist) against a reference
    deskewed with ``reference_twist`` ``dt`` s before, rad/s and m/s (None: nothing is
    offset), with its vertical velocity zero when ``relative`` did not measure z and
    ``config.z_offset_measured_only`` (module docstring)."""
    offset = twist_offset(epoch.scan, epoch.twist, reference_twist, dt)
    if offset is None or relative.z_observed or not config.z_offset_measured_only:
        return offset
    return np.r_[offset[:5], 0.0]
