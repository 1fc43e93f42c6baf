"""The 2D-rig path's time windows without a twist (``extraction.time_windows``)."""

from __future__ import annotations

from pydantic import ConfigDict, Field

from planodom.config.section import Section


class TimeWindowConfig(Section):
    """The 2D-rig path without a twist (points not deskewed, the odometry's first epochs).

    With per-point times spread over more than ``span_s`` the 2D-rig path only combines
    points acquired within one window of ``span_s`` (:mod:`planodom.extraction.rig2d.windows`):
    traces, seeds and planes are built per window, and one plane per wall is kept. With a
    twist none of this is used."""

    model_config = ConfigDict(allow_inf_nan=False)

    span_s: float = Field(0.015, gt=0)
    """Longest time span (s) of the points combined into one trace, seed or plane: about
    one sweep of a 75 Hz scanner (1 / 75 s), i.e. the crossing traces of a scanner pair in
    the same sweep, between which the vehicle moved at most ``motion_m``. Each wall then
    gives one plane per window; the earliest (closest to the reference time) is kept."""
    motion_m: float = Field(0.03, ge=0)
    """Vehicle displacement assumed within one window (m): 2 m/s x 1 / 75 s = 2.7 cm. Added to the
    member tolerance and the seed floor, and half of it to the RMS limit of a plane."""
    speed_m_s: float = Field(5.0, ge=0)
    """Two planes from different windows are one wall seen twice when their normals are
    within ``repeat_deg`` and their offsets within the member tolerance plus this speed
    (m/s) times their time difference."""
    min_windows: int = Field(3, ge=1)
    """A wall is a plane only when it is found in at least this many windows (of the ~7 sweeps of a
    10 Hz epoch): two lines of one sweep far apart can be coplanar by chance, not in several
    sweeps. On the paper loop at 6 mm, 1 / 2 / 3 gave 85 / 88 / 91 % precision for 5.9 / 5.8 / 5.75
    good planes per epoch. The kept plane's normal and offset are extrapolated to the reference
    time from its windows (a straight line in time)."""
    min_points_over_windows: bool = False
    """A wall's ``extraction.min_plane_points`` counted over the ``min_windows`` windows it
    must be found in, not in each: a window then needs ceil(min_plane_points /
    min_windows) points (at least 3), so the windows of a kept plane hold min_plane_points
    between them, as one epoch's plane does on the other paths. A sparse rig's wall has
    few points in one sweep: issue 11's world 140 (1 deg steps, five 25 Hz sweeps an
    epoch) has 4-18 points per sweep on walls of 21-91 points per epoch, so its first
    epochs found only the ground, were unresolved for 8 epochs (9 later) and the run lost
    12 m (15.3 -> 1.5 m at 2 cm). Off by default: mixed over 60 2D-rig runs (worlds 0-18,
    100-118, 140-158 at 6 mm and 2 cm), 5 runs of worlds 0, 6 and 14 worse by up to 30x,
    with phantom planes of two sweeps at 2 cm (docs/RESULTS.md, GAPS)."""
    sparse_windows_determined: bool = False
    """With ``min_points_over_windows``, a window's plane of fewer than
    ``extraction.min_plane_points`` inliers is kept (and counts as one of a wall's
    windows) only when its points determine it: its normal to
    ``extraction.max_normal_sigma_deg`` and its offset at the base origin to the member
    tolerance, with the epoch's noise sigma rather than the fit's own residual
    (:mod:`planodom.extraction.rig2d.sparsewindows`). Off by default: with
    ``min_points_over_windows`` on 60 2D-rig runs it keeps world 140's gain at 6 mm
    (12.1 -> 4.3 m, longest gap 9 -> 2) and takes world 6 at 2 cm from the old option's
    22.5 m to 2.3 m, but loses world 140's at 2 cm (15.3 -> 16.7 m) and world 6 at 2 cm
    is still 3x its base 0.75 m (docs/RESULTS.md, GAPS3)."""
    repeat_deg: float = Field(5.0, gt=0, le=90)
    """Normal angle (deg) within which planes of two windows may be one wall (the turn of
    the vehicle over an epoch plus the fit error of one sweep's traces)."""
