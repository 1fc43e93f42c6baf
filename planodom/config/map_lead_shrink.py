"""The shrinking of a plane-map epoch's led rate (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is; the lead itself is ``odometry.map_twist_lead``.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class MapLeadShrinkConfig(Section):
    """How far ``odometry.map_twist_lead`` leads the rate (:mod:`planodom.odometry.trend`)."""

    map_lead_shrink: Literal["off", "stated"] = "stated"
    """``map_twist_lead`` on: ``stated``, the rate's lead shrunk per axis by the Wiener
    gain ``c^2 / (c^2 + v)`` of the change ``c`` it extrapolates (this epoch's own rate
    minus the previous epoch's), ``v`` the two steps' stated rate variances (their
    covariances' rotation diagonals over dt^2; :func:`planodom.odometry.trend.shrunk_lead`):
    a change within the steps' noise is led by little, one far beyond it in full; "off",
    led in full. Why: the lead ``own + 1/2 (own - previous)`` carries 1.6x the own rate's
    noise, and on a 64-beam world whose rate hardly changes (251, 6 mm, 150 epochs) the
    lead made the rotation rms per step worse (0.00067 -> 0.00076 deg) where on world 33
    it halved it (0.0044 -> 0.0023 deg). A rule of the estimator, not tuned. The default,
    with ``map_twist_lead: rate``, since LIDARROT (docs/RESULTS.md), by its rule on the fresh
    lidar worlds 281-299 (150 epochs): rotation geometric-mean ratio 0.775 / 0.807 at 6 mm /
    2 cm, ATE 0.629 / 0.853, no run worse than 1.41x, no unresolved epoch; KITTI raw 0005
    (no point times) and the 2D rig's pairwise pipelines byte-identical."""
