"""The unit of a cloud topic's time offsets, chosen by the span of its sweeps against the
period between its messages, checked by hand."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.datasets.bag_time_units import TopicTimes, choose_unit, period_s

MS = 1_000_000


def _times(name: str, dtype: str, sweeps: list[list[float]]) -> TopicTimes:
    times = TopicTimes()
    for values in sweeps:
        times.add(name, np.array(values, dtype=dtype))
    return times


def _stamps(n: int, period_ns: int = 100 * MS) -> np.ndarray:
    return 1_700_000_000 * 10**9 + np.arange(n, dtype=np.int64) * period_ns


def test_period_is_the_median_step_of_distinct_stamps() -> None:
    stamps = np.array([0, 100, 100, 200, 450, 550]) * MS  # a duplicate, a dropped message
    assert period_s(stamps) == pytest.approx(0.1)
    assert period_s(np.array([5, 5])) is None


@pytest.mark.parametrize(
    "dtype, sweep, unit",
    [
        ("uint32", [0, 50_000_000, 99_000_000], "ns"),  # 99 ms as ns
        ("uint32", [0, 50_000, 99_000], "us"),  # 99 us as ns, 99 ms as us
        ("float32", [0.0, 0.05, 0.099], "s"),
        ("float64", [0.0, 50.0, 99.0], "ms"),  # 99 s as s, 99 ms as ms
        ("uint32", [0, 5_000_000], "ns"),  # a cloud cropped to 18 deg of the turn: still ns
    ],
)
def test_the_reading_whose_span_is_nearer_the_period(dtype: str, sweep: list, unit: str) -> None:
    chosen = choose_unit(_times("t", dtype, [sweep] * 4), _stamps(4))
    assert chosen.unit == unit
    assert chosen.scale == {"ns": 1e-9, "us": 1e-6, "s": 1.0, "ms": 1e-3}[unit]
    if unit in ("ns", "s"):
        assert chosen.note is None
    else:
        assert f"time field 't' ({dtype}) read as " in chosen.note
        assert "not clear-cut" not in chosen.note


def test_boundary_is_the_geometric_mean_of_the_readings() -> None:
    # a 100 ms period: spans below 100 ms / sqrt(1000) = 3.16 ms (as ns) vote microseconds
    assert choose_unit(_times("t", "uint32", [[0, 3_200_000]] * 3), _stamps(3)).unit == "ns"
    assert choose_unit(_times("t", "uint32", [[0, 3_100_000]] * 3), _stamps(3)).unit == "us"


def test_disagreeing_sweeps_are_noted_and_the_majority_read() -> None:
    sweeps = [[0, 99_000]] * 3 + [[0, 99_000_000]]  # three as us, one as ns
    chosen = choose_unit(_times("offset_time", "uint32", sweeps), _stamps(4))
    assert chosen.unit == "us"
    assert "not clear-cut: 1 of 4 sweeps span nearer the period as nanoseconds" in chosen.note
    tie = choose_unit(_times("t", "uint32", [[0, 99_000], [0, 99_000_000]]), _stamps(2))
    assert tie.unit == "ns" and "1 of 2 sweeps" in tie.note  # the documented unit on a tie


def test_without_a_period_or_a_span_the_documented_unit() -> None:
    assert choose_unit(_times("t", "uint32", [[0, 99_000]]), _stamps(1)).unit == "ns"
    assert choose_unit(_times("t", "float32", [[0.5, 0.5]] * 3), _stamps(3)).unit == "s"
    assert choose_unit(_times("t", "uint32", [[]] * 3), _stamps(3)).unit == "ns"


def test_times_without_some_sweeps_drop_only_their_spans() -> None:
    times = TopicTimes()
    for sweep, span in [(0, 99_000), (1, 99_000_000), (3, 98_000), (4, 0)]:  # 2: no times
        times.add("t", np.array([5, 5 + span], dtype="uint32"), sweep)
    assert times.without(np.array([], dtype=np.int64)) is times
    kept = times.without(np.array([0, 2]))
    assert list(kept.spans) == [99_000_000.0, 98_000.0, 0.0]
    assert list(kept.sweeps) == [1, 3, 4]
    assert (kept.name, kept.dtype, kept.largest) == ("t", "uint32", 99_000_005.0)
    assert list(times.spans) == [99_000.0, 99_000_000.0, 98_000.0, 0.0]  # itself untouched


@pytest.mark.parametrize(
    "dtype, sweep, unit",
    [
        ("uint32", [0, 50, 99], "us"),  # integer ms: 99 ns or 99 us of a 100 ms period
        ("float64", [0.0, 5e4, 9.9e4], "ms"),  # float us: 99 000 s or 99 s
    ],
)
def test_neither_reading_near_the_period_is_said(dtype: str, sweep: list, unit: str) -> None:
    """Integer milliseconds were read as microseconds (a sweep of 0.1 ms) with a note that
    read as if the choice fitted; it now says that neither reading does."""
    chosen = choose_unit(_times("t", dtype, [sweep] * 4), _stamps(4))
    assert chosen.unit == unit and chosen.note is not None
    assert "neither reading spans near the period: another unit" in chosen.note
    fitting = choose_unit(_times("t", "uint32", [[0, 5_000_000]] * 4), _stamps(4))
    assert fitting.note is None  # 5 ms of 100 ms: within the vote's boundary, no word
