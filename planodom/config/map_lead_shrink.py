"""The shrinking of a plane-map epoch's led rate (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is; the lead itself is ``odometry.map_twist_lead``.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.section import Section

#: a positive finite number, or None for off
PositiveOrOff = Annotated[float, Field(gt=0, allow_inf_nan=False)] | None


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
    map_lead_acceleration: Literal["off", "rate", "stated"] = "off"
    """``map_twist_lead`` on: "rate", the points of an epoch whose rate is led are first
    rotated by ``exp(alpha t^2 / 2)`` (``t`` the point's time from the sweep's reference
    time), ``alpha`` the rate's change per second from the twist the previous epoch was
    kept with to the one the extraction is given, then deskewed with that twist: a
    deskewing second order in time for the rotation; "stated": that change shrunk per
    axis by its noise as ``map_lead_shrink`` shrinks the lead (:mod:`planodom.odometry.
    lead_acceleration`); "off": the constant twist alone. Why: the constant twist leaves
    each sweep an offset that follows the angular acceleration; with the lead these
    offsets no longer cancel over a turn (lidar world 9, 6 mm, 300 epochs: yaw error
    +36 mdeg over its sharp turn, ATE 19.6 mm without the lead, 25.7 with it; deskewed
    along the true rate and its change, 3.8 mm; "rate" 10.8 mm, "stated" 10.6 mm, rotation
    rms per step 0.0040 -> 0.0042 / 0.0040 deg; LIDAR9, docs/RESULTS.md). Seen lidar worlds
    1, 3, 5, 9 (6 mm): ATE geometric-mean ratio 0.77 / 0.70, rotation 1.00 / 0.995. No
    threshold (the 6.5 of "stated" is the led rates' algebra). Off: not yet measured on
    worlds no session has run."""
    map_lead_vertical_tolerance_mps: PositiveOrOff = None
    """``map_twist_lead`` on: the vertical velocity's own tolerance (m/s; None, off: it
    goes with the velocity under ``map_lead_speed_tolerance_mps``). When set, an epoch's
    own vertical velocity replaces the one it was deskewed with wherever they differ by
    more than this, whatever the horizontal velocity does (which keeps its tolerance).
    Why: a spinning lidar's sweep starts and ends behind the sensor, so a vertical
    velocity error ``d`` leaves a floor or ceiling seen all around at radius ``r`` with a
    sawtooth height error and tilts its plane about the forward axis by ``d T / (pi r)``
    (period ``T``): 3 cm/s at 10 Hz and 3 m, 0.018 deg. On the indoor 64-beam lidar world
    329 (6 mm, 150 epochs) the velocity its epochs were finally deskewed with was 3.4 cm/s
    off the sweeps' true vertical velocity (rms, the prediction's, kept within the 5 cm/s
    speed tolerance); the true vertical velocity alone in every extraction took the
    rotation rms from step 3 on from 0.0100 to 0.0038 deg (LIDAR13, docs/RESULTS.md).
    Experimental, off: see LIDAR13 for the deciding runs."""
