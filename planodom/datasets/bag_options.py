"""How a bag is read: :class:`BagOptions`, shared by :func:`~planodom.datasets.rosbag.open_bag`,
:func:`~planodom.datasets.rosbag.convert_bag`, :func:`~planodom.datasets.recording.open_recording`
and the CLI (``--base-frame``, ``--epoch-rate``, ``--topic``, ``--gt-topic``, ``--time-field``,
``--echo``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, fields

from planodom.datasets.bag_multiecho import ECHO_MODES
from planodom.errors import DatasetError

DEFAULT_BASE_FRAME = "base_link"
DEFAULT_EPOCH_RATE = 10.0


@dataclass(frozen=True)
class BagOptions:
    """The options of reading a ROS bag.

    Attributes:
        base_frame: tf frame of the vehicle the points and the reference are expressed in.
        epoch_rate: epochs per second, Hz; an epoch gathers the sweeps of one
            ``1 / epoch_rate`` window.
        topics: scan topics to read, in ring order (empty: every LaserScan,
            MultiEchoLaserScan, PointCloud2 or Livox topic with messages, sorted by name).
        gt_topic: reference trajectory: a pose topic or ``"tf:PARENT:CHILD"`` (None: none).
        time_field: the clouds' per-point time field: ``"auto"`` (the first of
            :data:`~planodom.datasets.scan_io.TIME_FIELDS` present), ``"none"`` (ignore
            per-point times, e.g. a sensor clock that is not the stamps'), or a field name.
        skip_broken_parts: a ROS 2 bag's storage files that cannot be read (a split
            recording's part missing, cut short, overwritten) are left out and the others
            read, noted with the time span missing (:mod:`.bag_parts`); off: an error
            naming the part.
        echo: the returns read of each beam of a ``MultiEchoLaserScan``: ``first`` (the
            nearest), ``last``, ``strongest`` (by intensity) or ``all``
            (:mod:`.bag_multiecho`).
    """

    base_frame: str = DEFAULT_BASE_FRAME
    epoch_rate: float = DEFAULT_EPOCH_RATE
    topics: tuple[str, ...] = field(default=())
    gt_topic: str | None = None
    time_field: str = "auto"
    skip_broken_parts: bool = False
    echo: str = "first"

    def __post_init__(self) -> None:
        # a list (or a CLI's repeated option) becomes a tuple: the options stay hashable
        object.__setattr__(self, "topics", tuple(self.topics or ()))
        rate = self.epoch_rate
        if not (isinstance(rate, int | float) and math.isfinite(rate) and rate > 0):
            raise DatasetError(f"epoch rate must be a positive number of Hz, got {rate!r}")
        if not (isinstance(self.time_field, str) and self.time_field.strip()):
            raise DatasetError(
                f"time field must be auto, none or a field name, got {self.time_field!r}"
            )
        if self.echo not in ECHO_MODES:
            raise DatasetError(f"echo must be one of {', '.join(ECHO_MODES)}, got {self.echo!r}")

    @classmethod
    def of(
        cls,
        base_frame: str = DEFAULT_BASE_FRAME,
        epoch_rate: float = DEFAULT_EPOCH_RATE,
        topics: Sequence[str] | None = None,
        gt_topic: str | None = None,
        time_field: str = "auto",
        echo: str = "first",
    ) -> BagOptions:
        """The options from possibly-None values (as a command line gives them)."""
        topics = tuple(topics or ())
        return cls(base_frame, epoch_rate, topics, gt_topic, time_field, echo=echo)

    def given(self) -> list[str]:
        """Names of the options that differ from their defaults."""
        default = BagOptions()
        return [f.name for f in fields(self) if getattr(self, f.name) != getattr(default, f.name)]

    @property
    def topic_list(self) -> list[str] | None:
        """The topics as a list, None for "every scan topic"."""
        return list(self.topics) or None
