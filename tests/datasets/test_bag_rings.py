"""The ring ids a topic's points carry that are no ring of its lidar, by hand."""

from __future__ import annotations

import pytest

from planodom.datasets.bag_rings import ring_block, stray_note, stray_span


@pytest.mark.parametrize(
    ("ids", "block"),
    [
        (range(16), (0, 15)),  # a VLP-16
        (range(1, 17), (1, 16)),  # numbered from 1
        (range(100, 116), (100, 115)),  # from an offset
        ([*range(7), *range(8, 16)], (0, 15)),  # laser 7 dead all along
        ([*range(16), 17], (0, 17)),  # one unused id beside one: a dead laser, kept
        ([*range(16), 200], (0, 15)),  # a stray id
        ([*range(16), 65535], (0, 15)),  # a float field's 65535.0
        ([0, *range(100, 116)], (100, 115)),  # a stray id below an offset numbering
        ([*range(16), 40, 41, 300], (0, 15)),  # strays on both sides of a gap
        ([*range(16), *range(32, 48)], (0, 47)),  # two lidars merged, equal sides: kept
        ([-1, *range(16)], (0, 15)),  # a signed field's "no ring"
        ([-5, -1], None),
    ],
)
def test_the_block_of_a_lidars_numbering(ids, block) -> None:
    assert ring_block(dict.fromkeys(ids, 3)) == block


def test_the_span_and_note_only_when_some_ids_are_stray() -> None:
    assert stray_span(dict.fromkeys(range(16), 3)) is None
    assert stray_span({}) is None
    counts = dict.fromkeys(range(16), 100) | {200: 4, -1: 2}
    assert stray_span(counts) == (0, 15)
    assert stray_note("/points", counts, (0, 15)) == (
        "topic '/points': 6 points carry ring ids that are no ring of its lidar's numbering "
        "beside its rings 0..15 (2 ids: -1, 200; negative, or apart from the others by more "
        "unused ids than they count); left out"
    )
    assert stray_span({-1: 5}) == (0, -1)


def test_ring_counts_by_table_and_by_sort() -> None:
    import numpy as np

    from planodom.datasets.bag_rings import ring_counts

    assert ring_counts(np.array([3, -1, 3, 7])) == [(-1, 1), (3, 2), (7, 1)]
    assert ring_counts(np.array([0, 1 << 20, 0])) == [(0, 2), (1 << 20, 1)]
