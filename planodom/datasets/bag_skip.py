"""Index a ROS 2 bag with ``BagOptions.skip_broken_parts``: the parts that do not open
left out first (:func:`.bag_parts.skipped_parts`), then those found damaged further in
once reading them failed (:class:`.bag_parts.DamagedPartError`), the index read again
without them."""

from __future__ import annotations

import tempfile
from pathlib import Path

from planodom.datasets.bag_index import BagIndex, bag_errors, index_bag, open_reader
from planodom.datasets.bag_options import BagOptions
from planodom.datasets.bag_parts import (
    BrokenPart,
    DamagedPartError,
    damaged_parts,
    readable_view,
    skipped_parts,
    tf_in_skipped_part,
)
from planodom.errors import DatasetError


def _index(
    location: Path, opts: BagOptions, read_from: Path | None, broken: list[BrokenPart]
) -> BagIndex:
    """The index of the bag at ``location``, read from ``read_from`` (None: itself)."""
    reader = open_reader(location, read_from)
    try:
        with tf_in_skipped_part(broken):
            return index_bag(reader, location, opts.topic_list, opts.gt_topic, opts.time_field)
    finally:
        with bag_errors(location):
            reader.close()


def index_skipping(
    location: Path, opts: BagOptions
) -> tuple[BagIndex, list[BrokenPart], tempfile.TemporaryDirectory | None]:
    """The index of the bag at ``location``, the parts left out and the view read instead
    of the bag (None: the bag itself). Without ``opts.skip_broken_parts`` any broken part
    is a DatasetError naming it."""
    broken, view = skipped_parts(location, opts.skip_broken_parts)
    while True:
        read_from = None if view is None else Path(view.name)
        try:
            return _index(location, opts, read_from, broken), broken, view
        except DamagedPartError as exc:
            known = {p.path.name for p in broken}
            new = [p for p in exc.parts if p.path.name not in known]
            if opts.skip_broken_parts and not new:  # the parts left out blamed again
                new = damaged_parts(location, broken)
            if not opts.skip_broken_parts or not new:
                raise
            broken = sorted(broken + new, key=lambda p: p.number)
            if len(broken) == broken[0].count:
                raise DatasetError(
                    f"{location}: cannot read bag: {broken[0].describe()}, as are all the others"
                ) from None
            view = readable_view(location, broken)
