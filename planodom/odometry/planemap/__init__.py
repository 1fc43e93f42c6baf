"""Plane-landmark odometry against a local plane map, point-to-plane costs from plane
moments (``odometry.pipeline: map``; settings in ``PlanodomConfig.planemap``).

- :mod:`.moments`: plane moments, the moment cost and its Jacobians, the noise model;
- :mod:`.landmarks`: the local map (fading, merging, pruning);
- :mod:`.register`: association with adaptive gates, robust Gauss-Newton, candidate score;
- :mod:`.fallback`: scan-to-scan hypotheses (widening gates, LDA without motion bounds);
- :mod:`.pose`: the result as a :class:`planodom.odometry.relative.RelativePose`;
- :mod:`.odometry`: :class:`PlaneMapOdometry` (estimate, then commit, per scan).
"""

from planodom.odometry.planemap.moments import Moments
from planodom.odometry.planemap.odometry import MapEstimate, PlaneMapOdometry, uses_plane_map

__all__ = ["MapEstimate", "Moments", "PlaneMapOdometry", "uses_plane_map"]
