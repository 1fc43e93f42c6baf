"""Planar landmarks from laser scans: ``extract_planes(scan, config, twist, sensor_origins)``.

Two paths, chosen by ``ExtractionConfig.mode`` (auto: by the number of rings):

- 2D-scanner rig (few rings): scan lines are split into straight segments in scan order
  (:mod:`.segments`), segments of different scanners and sweeps that lie in one plane are
  grouped, seeded only by two traces of different scanners that cross
  (:mod:`.grouping`), and each group is fit by total least squares on its points
  (:mod:`.groupfit`).
- 3D scan (many rings or none): region growing on the range image when rings and times
  allow (:mod:`.rangeimage`), else a seeded RANSAC loop (:mod:`.ransac`, reproducible
  across processes, unlike open3d's), with coplanar inliers split into connected pieces
  (:mod:`.lidar`).

Points are first deskewed with an optional constant twist (:mod:`.deskew`); without one,
a moving 2D-rig epoch is grouped in time windows of about one sweep
(``ExtractionConfig.max_unskewed_span_s``). Every plane
gets an oriented normal, a (4, 4) TLS covariance (:mod:`.fitting`), a CPEF confidence
(:mod:`.confidence`), support and a true label; see :func:`extract_planes`.
"""

from planodom.extraction.deskew import deskew_points, se3_exp, se3_log
from planodom.extraction.pipeline import ExtractionResult, extract, extract_planes

__all__ = [
    "ExtractionResult",
    "deskew_points",
    "extract",
    "extract_planes",
    "se3_exp",
    "se3_log",
]
