"""Planar landmarks from laser scans: ``extract_planes(scan, config, twist, sensor_origins)``.

Two paths, chosen by ``ExtractionConfig.mode`` (auto: by the number of rings), and one
plane builder they share:

- :mod:`.rig2d` (a 2D-scanner rig, few rings): scan lines split into straight segments,
  merged over sweeps into traces, traces of different scanners grouped into planes
  (seeded only by two traces that cross), each group refit on its points; without a twist
  on a moving epoch, all in time windows of about one sweep (:mod:`.rig2d.windows`).
- :mod:`.lidar` (a 3D scan, many rings or none): region growing on the range image when
  rings and times allow, else a seeded RANSAC loop (reproducible across processes, unlike
  open3d's), with coplanar inliers split into connected pieces; each candidate refit
  robustly.
- :mod:`.planes`: the plane builder (TLS covariance, orientation towards the sensor, CPEF
  confidence, support polygon, true label).

:mod:`.pipeline` reads top to bottom: checks, deskewing (:mod:`.deskew`), the path, the
planes. :mod:`.kernels` holds the small numba helpers the paths share.
"""

from planodom.extraction.deskew import deskew_points
from planodom.extraction.pipeline import ExtractionResult, extract, extract_planes

__all__ = [
    "ExtractionResult",
    "deskew_points",
    "extract",
    "extract_planes",
]
