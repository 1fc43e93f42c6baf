"""The declared sweep convention of a spinning lidar (``extraction.sweep``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field, model_validator

from planodom.config.section import Section
from planodom.errors import ConfigError


class SweepConfig(Section):
    """The declared sweep convention of a spinning lidar, to recover per-point times from
    the azimuth when a cloud has none (:mod:`planodom.extraction.lidar.sweep`).

    A spinning lidar fires its columns at a constant rate while it turns, so a point's time
    is a function of its azimuth in the sensor frame once the convention is declared: the
    sense of rotation, the azimuth where the sweep starts (its seam) and the sweep period.
    Nothing is guessed: with ``rotation: none`` (the default) a cloud without times stays
    without them (and is not deskewed). KISS-ICP recovers KITTI's times the same way.
    A point at azimuth ``a`` (sensor frame, from x towards y) gets
    ``t = start_time_s + period_s * f``, ``f`` in [0, 1) the fraction of a turn from
    ``start_azimuth_deg`` to ``a`` in the sense of rotation. Clouds that carry times keep
    them.
    """

    model_config = ConfigDict(allow_inf_nan=False)

    rotation: Literal["none", "ccw", "cw"] = "none"
    """Sense of rotation about the sensor's z axis seen from above: ccw (counter-clockwise,
    azimuth increasing), cw (clockwise); none: no convention declared (times are not
    recovered)."""
    start_azimuth_deg: float = Field(-180.0, ge=-360.0, le=360.0)
    """Azimuth (deg, sensor frame, from x towards y) of the first column of a sweep.
    Default: behind the sensor (-180 deg), where most units put the seam."""
    period_s: float = Field(0.1, gt=0.0, le=10.0)
    """Seconds per revolution (0.1 s: a 10 Hz unit)."""
    start_time_s: float = Field(0.0, ge=-10.0, le=10.0)
    """Time (s) of the sweep's first column relative to the epoch's reference time: 0 when
    the epoch is stamped at the start of the sweep, ``-period_s / 2`` when it is stamped
    half a turn later (KITTI: when the sensor faces forward)."""

    @model_validator(mode="after")
    def _cross_checks(self) -> SweepConfig:
        """The sweep covers the reference time or lies next to it (raises ConfigError)."""
        if abs(self.start_time_s) > self.period_s:
            raise ConfigError(
                "extraction.sweep.start_time_s: must be within one period_s "
                f"({self.period_s!r}) of the epoch's reference time, got {self.start_time_s!r}"
            )
        return self
