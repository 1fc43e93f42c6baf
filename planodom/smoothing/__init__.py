"""Factor-graph smoothing of plane odometry on gtsam: batch and fixed-lag.

- :mod:`.landmarks`: plane tracks from strict associations (one landmark per plane).
- :mod:`.graph`: factors and values epoch by epoch (5-DoF between factors, plane factors,
  priors); gauge and observability notes. :mod:`.noise`: their noise models.
- :mod:`.run`: :func:`run_smoothing`, scans to smoothed trajectory.
- :mod:`.batch`: :func:`smooth_batch`, Levenberg-Marquardt and marginal covariances.
- :mod:`.windowed`: :class:`WindowedSmoother`, a fixed-lag smoother run online.
- :mod:`.synthetic`: seeded synthetic problems for tests and benchmarks.
"""

from planodom.smoothing.batch import SmoothingResult, smooth_batch
from planodom.smoothing.graph import GraphBuilder, GraphStats
from planodom.smoothing.landmarks import LandmarkTracker
from planodom.smoothing.windowed import WindowedSmoother, smooth_windowed

__all__ = [
    "GraphBuilder",
    "GraphStats",
    "LandmarkTracker",
    "SmoothingResult",
    "WindowedSmoother",
    "smooth_batch",
    "smooth_windowed",
]
