"""The plane-map registration's weights under a led twist (a base of ``PlanemapConfig``).

In its own module as :mod:`.map_lead_shrink` is; the lead itself is ``odometry.
map_twist_lead``, the weighting :mod:`planodom.odometry.planemap.lead_weights`.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from planodom.config.section import Section


class LeadWeightsConfig(Section):
    """How a plane-map epoch extracted again with its led twist is weighted."""

    lead_weights: Literal["off", "stated", "unknown"] = "off"
    """``odometry.map_twist_lead`` on (a sweep registered at its middle): ``stated``, an
    epoch extracted again with a twist led from a measured step registers each of its
    planes with the variance the led twist's error gives it through the plane's own
    deskewing Jacobian (``Plane.deskew_jacobian``, switched on in the extraction: a plane
    whose points span little time, or lie near the sensor, carries little of it), the
    error's variance per axis in closed form from the lead's inputs (the two steps' stated
    rate variances, the Wiener gain of ``odometry.map_lead_shrink`` and the change it leaves
    unled; the velocity's stated variance and its unled change; plus the known gap between
    the twist used and the lead), and with the laser bias ``led_bias_m`` in place of
    ``laser_bias_m`` (the map refit with it). The 2 cm bias also absorbs the deskewing
    error (docs/RESULTS.md, LIDARACC, LIDARFLOOR): with that error modelled per plane it
    can go down where the deskewing is good. Every other extraction (the first, with the
    prediction; scans without point times; KITTI 0005) keeps ``laser_bias_m`` and no such
    term. Measured on lidar worlds 301-319 (150 epochs, against main's default;
    docs/RESULTS.md, LIDARW): rotation rms geometric-mean ratio 0.956 at 6 mm, 0.771 at 2
    cm (every world better; median 6.0x -> 4.7x the oracle), ATE 1.043 / 0.901 (world 315 at
    6 mm 0.52 -> 0.82 mm), no epoch unresolved. Off: its rule asked for the ATE < 1 at both
    noises. ``unknown``: the led twist's error is one unknown shared by the scan's planes,
    not an independent term per plane: the registration solves the pose and a correction
    of the twist the scan was deskewed with together (continuous time, the planes' time
    moments, :mod:`planodom.odometry.planemap.ctreg`, switched on in the extraction), the
    correction's prior zero-mean with that closed-form variance per axis
    (:mod:`planodom.odometry.planemap.led_twist`); the pose is the joint solve's, the map
    is updated with the planes moved by the correction, the laser bias is ``led_bias_m``
    as with ``stated``; the correction is not fed back into the epoch's twist (the lead
    and the next prediction stay the steps'). A rule of the estimator (no threshold).
    Measured on lidar worlds 321-339 (150 epochs, against main's default; docs/RESULTS.md,
    LIDARTW): rotation rms geometric-mean ratio 0.934 at 6 mm, 0.851 at 2 cm; ATE 1.110 /
    0.942 (the indoor 64-beam world 335 at 6 mm 22 -> 39 mm, 329 2.1 -> 3.3 mm), no epoch
    newly unresolved. Off: its rule asked for the ATE < 1 at both noises."""
    led_bias_m: float = Field(0.005, ge=0, le=1)
    """With ``lead_weights: stated``, the laser bias sigma (m) of a scan extracted again
    with its led twist. The procedural lidars have no per-laser bias (the 2 cm of
    ``laser_bias_m`` is a datasheet's, and on KITTI 0005 the lines' own offsets measure 5-7
    mm); a real lidar's should be its own. Chosen among 1, 5 mm on seen lidar worlds (33,
    245, 251; docs/RESULTS.md, LIDARW), not on the worlds it was decided on."""
