"""MultiEchoLaserScan bags (ROS 1 and ROS 2) of a known geometry, read back exactly.

The scanner looks at a wall at x = WALL m of its frame, a pane in front of part of it: a
beam's echoes are the pane (first), the wall (second); some beams hold echoes that are
no return (below range_min, NaN, inf, negative, beyond range_max) or none at all.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from bag_factory import T0_NS, BagWriter, pose

from planodom.datasets.bag_options import BagOptions
from planodom.datasets.rosbag import open_bag
from planodom.errors import DatasetError

T_BASE_LASER = pose(0.0, 0.0, 0.3, (0.4, -0.1, 0.25))
WALL, PANE = 6.0, 2.5  # m, x of the wall and of the pane in the laser frame
A0, INC, DT = -0.6, 0.02, 2e-4  # rad, rad, s
RANGE_MIN, RANGE_MAX = 0.05, 30.0
MODES = ("first", "last", "strongest", "all")
#: The note on _sweeps()' beam counts (40, 45 and 50 beams, one message each).
CHANGING = (
    "topic '/echoes': its 3 messages hold 3 beam counts (beams in messages: 40 in 1, 45 in 1, "
    "50 in 1: a driver relaunched with another resolution or field of view, or two scanners "
    "on one topic?); each is read with its own angles"
)


def _beams(n: int, k: int) -> list[tuple[list[float], list[float]]]:
    """Echo ranges and intensities of ``n`` beams of sweep ``k``: beam i sees the pane
    (every third beam) and the wall; a few beams carry echoes that are no return."""
    beams = []
    for i in range(n):
        c = math.cos(A0 + i * INC)
        wall, pane = WALL / c, PANE / c
        ranges, power = ([pane, wall], [100.0 + i, 50.0]) if i % 3 == 0 else ([wall], [80.0])
        if i % 3 == 0 and i % 2:
            power = [20.0, 90.0]  # the wall stronger than the pane
        if i % 7 == 1:
            ranges, power = [0.01, *ranges], [500.0, *power]  # the window: no return
        if i % 11 == 2:
            ranges, power = [math.nan, *ranges, math.inf], [0.0, *power, 0.0]
        if i % 13 == 4:
            ranges, power = [-1.0, *ranges, 45.0], [0.0, *power, 900.0]
        if i % 17 == 5 + k:
            ranges, power = [], []  # no echo
        beams.append((ranges, power))
    return beams


def _expected(beams, mode: str, n_intensities: bool = True) -> tuple[list[float], list[int]]:
    """The ranges and beam indices read for ``mode``, by the module docstring's rules."""
    ranges, index = [], []
    for i, (rs, ps) in enumerate(beams):
        ok = [(r, p) for r, p in zip(rs, ps, strict=True) if RANGE_MIN <= r <= RANGE_MAX]
        if not ok:
            continue
        if mode == "all":
            chosen = [r for r, _ in ok]
        elif mode == "first" or (mode == "strongest" and not n_intensities):
            chosen = [ok[0][0]]
        elif mode == "last":
            chosen = [ok[-1][0]]
        else:
            chosen = [max(ok, key=lambda rp: rp[1])[0]]  # max keeps the first of equals
        ranges += chosen
        index += [i] * len(chosen)
    return ranges, index


def _beam_fields(bw: BagWriter, stamp: int, n: int, frame: str) -> dict:
    """The fields a LaserScan and a MultiEchoLaserScan of ``n`` beams share: the same
    header, angles, times and range limits in both."""
    return dict(
        header=bw.header(stamp, frame),
        angle_min=A0,
        angle_max=A0 + INC * (n - 1),
        angle_increment=INC,
        time_increment=DT,
        scan_time=0.1,
        range_min=RANGE_MIN,
        range_max=RANGE_MAX,
    )


def _multi_echo(bw: BagWriter, stamp: int, beams, intensities: bool = True, frame="laser"):
    echo = bw.T["sensor_msgs/msg/LaserEcho"]
    return bw.T["sensor_msgs/msg/MultiEchoLaserScan"](
        **_beam_fields(bw, stamp, len(beams), frame),
        ranges=[echo(echoes=np.array(r, np.float32)) for r, _ in beams],
        intensities=[echo(echoes=np.array(p, np.float32)) for _, p in beams] if intensities else [],
    )


def _laser_scan(bw: BagWriter, stamp: int, ranges: np.ndarray, frame="laser"):
    return bw.T["sensor_msgs/msg/LaserScan"](
        **_beam_fields(bw, stamp, len(ranges), frame),
        ranges=ranges.astype(np.float32),
        intensities=np.zeros(len(ranges), np.float32),
    )


def _write(path: Path, ros: int, sweeps, make) -> None:
    """A bag with the static transform base_link -> laser and ``make(bw, stamp, beams)``
    on /echoes for each sweep's beams (10 Hz)."""
    with BagWriter(path, ros) as bw:
        tf = bw.tf([bw.transform_stamped(T0_NS, "base_link", "laser", T_BASE_LASER)])
        bw.write("/tf_static", tf, T0_NS)
        for k, beams in enumerate(sweeps):
            stamp = T0_NS + k * 100_000_000
            bw.write("/echoes", make(bw, stamp, beams), stamp + 1_000_000)


def _sweeps() -> list:
    return [_beams(40 + 5 * k, k) for k in range(3)]  # the beam count changes: each its own


def _path(tmp_path: Path, ros: int, name: str) -> Path:
    return tmp_path / (f"{name}.bag" if ros == 1 else name)


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("mode", MODES)
def test_each_echo_mode_reads_its_returns_at_the_beams_angles_and_times(
    tmp_path: Path, ros: int, mode: str
) -> None:
    sweeps = _sweeps()
    path = _path(tmp_path, ros, "e")
    _write(path, ros, sweeps, _multi_echo)
    with open_bag(path, BagOptions(echo=mode)) as ds:
        assert len(ds) == 3 and [t.msgtype for t in ds.topics] == [
            "sensor_msgs/msg/MultiEchoLaserScan"
        ]
        assert ds.topics[0].rings == 1 and ds.notes == [CHANGING]
        for k, (scan, beams) in enumerate(zip(ds, sweeps, strict=True)):
            ranges, index = _expected(beams, mode)
            a = A0 + np.array(index) * INC
            r = np.array(ranges, np.float32).astype(np.float64)
            local = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(len(r))])
            expected = local @ T_BASE_LASER[:3, :3].T + T_BASE_LASER[:3, 3]
            assert scan.points.shape == expected.shape
            np.testing.assert_allclose(scan.points, expected, atol=1e-6)
            # closed form: every point on the wall or the pane, in the laser frame
            x = (scan.points - T_BASE_LASER[:3, 3]) @ T_BASE_LASER[:3, :3]
            assert np.all(np.minimum(abs(x[:, 0] - WALL), abs(x[:, 0] - PANE)) < 1e-5)
            np.testing.assert_array_equal(scan.ring, np.zeros(len(r), np.int32))
            offset = ds.times[k] - (T0_NS + k * 100_000_000) / 1e9  # epoch time - stamp
            np.testing.assert_allclose(scan.t + offset, np.array(index) * DT, atol=1e-9)
    if mode == "first":  # the pane where one is, else the wall
        assert np.sum(np.abs(x[:, 0] - PANE) < 1e-5) > 10


@pytest.mark.parametrize("ros", [1, 2])
def test_strongest_without_intensities_reads_the_first_return(tmp_path: Path, ros: int) -> None:
    sweeps = _sweeps()
    _write(_path(tmp_path, ros, "s"), ros, sweeps, lambda bw, s, b: _multi_echo(bw, s, b, False))
    _write(_path(tmp_path, ros, "f"), ros, sweeps, _multi_echo)
    with (
        open_bag(_path(tmp_path, ros, "s"), BagOptions(echo="strongest")) as ds,
        open_bag(_path(tmp_path, ros, "f"), BagOptions(echo="first")) as first,
    ):
        _assert_same(ds, first)
        ranges, _ = _expected(sweeps[0], "strongest", n_intensities=False)
        assert len(ds[0]) == len(ranges)
        lit = sum(len(rs) > 0 for beams in sweeps for rs, _ in beams)  # beams with echoes
        assert ds.notes == [
            CHANGING,
            f"topic '/echoes': 3 of 3 messages carry no intensities for beams with echoes "
            f"({lit} beams in all): --echo strongest reads those beams' first return",
        ]
        assert first.notes == [CHANGING]


def _assert_same(ds, other) -> None:
    np.testing.assert_array_equal(ds.times, other.times)
    assert len(ds) == len(other)
    for scan, truth in zip(ds, other, strict=True):
        np.testing.assert_array_equal(scan.points, truth.points)
        np.testing.assert_array_equal(scan.ring, truth.ring)
        np.testing.assert_array_equal(scan.t, truth.t)


def _first_returns(beams) -> np.ndarray:
    """A LaserScan's ranges holding each beam's first return (inf: none), independently of
    the reader: the echoes tested one by one against the range limits."""
    out = []
    for rs, _ in beams:
        out.append(next((r for r in rs if RANGE_MIN <= r <= RANGE_MAX), math.inf))
    return np.array(out)


@pytest.mark.parametrize("ros", [1, 2])
def test_first_echoes_read_as_the_laser_scan_of_them(tmp_path: Path, ros: int) -> None:
    """The same bag with a LaserScan of each beam's first return gives the same dataset
    (epochs, points, times, rig, notes), blank scans (no echo on any beam) included: the
    only scan topic's are left out of the epochs, noted, as a LaserScan's."""
    sweeps = _sweeps() + [[([], [])] * 30, _beams(50, 0)]
    _write(_path(tmp_path, ros, "m"), ros, sweeps, _multi_echo)
    _write(
        _path(tmp_path, ros, "l"),
        ros,
        sweeps,
        lambda bw, stamp, beams: _laser_scan(bw, stamp, _first_returns(beams)),
    )
    with (
        open_bag(_path(tmp_path, ros, "m")) as ds,
        open_bag(_path(tmp_path, ros, "l")) as scans,
    ):
        assert len(ds) == 4  # the blank scan is left out
        _assert_same(ds, scans)
        np.testing.assert_array_equal(ds.rig.sensor_origins, scans.rig.sensor_origins)
        assert ds.notes == scans.notes and "1 of 5 scans hold no return" in ds.notes[0]


@pytest.mark.parametrize("ros", [1, 2])
def test_a_multi_echo_topic_takes_its_ring_in_topic_order(tmp_path: Path, ros: int) -> None:
    """Beside a LaserScan topic: rings numbered by topic name, or in the order --topic
    gives; each topic in its own frame's extrinsic."""
    T_BASE_REAR = pose(0.0, 0.0, math.pi, (-0.5, 0.0, 0.3))
    path = _path(tmp_path, ros, "two")
    sweeps = _sweeps()
    with BagWriter(path, ros) as bw:
        tf = bw.tf(
            [
                bw.transform_stamped(T0_NS, "base_link", "laser", T_BASE_LASER),
                bw.transform_stamped(T0_NS, "base_link", "rear", T_BASE_REAR),
            ]
        )
        bw.write("/tf_static", tf, T0_NS)
        for k, beams in enumerate(sweeps):
            stamp = T0_NS + k * 100_000_000
            bw.write("/echoes", _multi_echo(bw, stamp, beams), stamp + 1_000_000)
            rear = _laser_scan(bw, stamp + 10_000, _first_returns(beams), "rear")
            bw.write("/scan", rear, stamp + 1_000_000)
    for topics, rings in (((), [0, 1]), (("/scan", "/echoes"), [1, 0])):
        with open_bag(path, BagOptions(topics=topics)) as ds:
            names = [t.name for t in ds.topics]
            assert names == (list(topics) or ["/echoes", "/scan"])
            scan = ds[0]
            echo_ring, scan_ring = rings
            for ring, T in ((echo_ring, T_BASE_LASER), (scan_ring, T_BASE_REAR)):
                x = (scan.points[scan.ring == ring] - T[:3, 3]) @ T[:3, :3]
                assert np.all(np.minimum(abs(x[:, 0] - WALL), abs(x[:, 0] - PANE)) < 1e-5)
            assert np.sum(scan.ring == echo_ring) == np.sum(scan.ring == scan_ring)


def _bad(bw: BagWriter, stamp: int, beams, what: str, k: int):
    msg = _multi_echo(bw, stamp, beams)
    if k != 1:
        return msg
    echo = bw.T["sensor_msgs/msg/LaserEcho"]
    if what == "beams":
        return type(msg)(**{**msg.__dict__, "intensities": msg.intensities[:-1]})
    beams = list(msg.intensities)
    beams[5] = echo(echoes=np.array([1.0, 2.0, 3.0], np.float32))
    return type(msg)(**{**msg.__dict__, "intensities": beams})


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize(
    "what, detail",
    [
        ("beams", "ranges of 45 beams but intensities of 44"),
        ("echoes", "beam 5 has 1 range echoes but 3 intensities"),
    ],
)
def test_intensities_that_do_not_match_the_ranges_are_refused(
    tmp_path: Path, ros: int, what: str, detail: str
) -> None:
    path = _path(tmp_path, ros, "bad")
    sweeps = iter(range(3))

    def make(bw, stamp, beams):
        return _bad(bw, stamp, beams, what, next(sweeps))

    _write(path, ros, _sweeps(), make)
    with pytest.raises(DatasetError) as exc:
        open_bag(path)
    message = str(exc.value)
    assert "\n" not in message
    assert "topic '/echoes': MultiEchoLaserScan (message 1 of the topic, from 0)" in message
    assert "stamped 1700000000.100 s" in message and detail in message


def test_an_unknown_echo_mode_is_refused_naming_the_key() -> None:
    with pytest.raises(DatasetError, match=r"^echo must be one of first, last, strongest, all"):
        BagOptions(echo="nearest")
    assert BagOptions().echo == "first" and BagOptions.of(echo="all").given() == ["echo"]


def test_the_echo_option_of_the_command_line(tmp_path: Path) -> None:
    """``convert --echo all`` writes every return; a bad value, or ``--echo`` for a
    simulation or a dataset directory, is one error line naming the option."""
    from cli_checks import fails, runner

    from planodom.cli import app
    from planodom.datasets import load_dataset

    sweeps = _sweeps()
    _write(tmp_path / "e.bag", 1, sweeps, _multi_echo)
    out = tmp_path / "ds"
    result = runner.invoke(app, ["convert", str(tmp_path / "e.bag"), str(out), "--echo", "all"])
    assert result.exit_code == 0, result.output
    ds = load_dataset(out)
    assert [len(ds[k]) for k in range(3)] == [len(_expected(b, "all")[0]) for b in sweeps]
    fails(["convert", tmp_path / "e.bag", tmp_path / "o", "--echo", "near"], "echo must be")
    fails(["run", "--scenario", "paper-loop", "--echo", "last"], "--echo", "not for --scenario")
    fails(["run", out, "--echo", "last", "--out", tmp_path / "r"], "not a bag", "echo")


def _unlit(bw: BagWriter, stamp: int, beams, k: int):
    """Sweep ``k``'s message; the second's beams 0, 4, 8, ... without intensities."""
    msg = _multi_echo(bw, stamp, beams)
    if k != 1:
        return msg
    none = bw.T["sensor_msgs/msg/LaserEcho"](echoes=np.zeros(0, np.float32))
    lit = [none if i % 4 == 0 else e for i, e in enumerate(msg.intensities)]
    return type(msg)(**{**msg.__dict__, "intensities": lit})


@pytest.mark.parametrize("ros", [1, 2])
@pytest.mark.parametrize("mode", MODES)
def test_the_notes_on_beam_counts_and_missing_intensities_come_exactly_with_their_case(
    tmp_path: Path, ros: int, mode: str
) -> None:
    """One beam count: no note. Some beams of one message without intensities: noted under
    ``strongest`` only, counting that message and those of its beams with echoes, whose
    first return is read (the others their strongest), against the closed form."""
    sweeps = [_beams(45, k) for k in range(3)]
    path = _path(tmp_path, ros, "u")
    order = iter(range(3))
    _write(path, ros, sweeps, lambda bw, s, b: _unlit(bw, s, b, next(order)))
    unlit = [i for i, (rs, _) in enumerate(sweeps[1]) if i % 4 == 0 and rs]
    with open_bag(path, BagOptions(echo=mode)) as ds:
        if mode == "strongest":
            assert ds.notes == [
                f"topic '/echoes': 1 of 3 messages carry no intensities for beams with echoes "
                f"({len(unlit)} beams in all): --echo strongest reads those beams' first return"
            ]
        else:
            assert ds.notes == []
        # a beam without intensities: its echoes' powers falling, so its first return wins
        beams = [
            (rs, [-float(j) for j in range(len(rs))] if i in unlit else ps)
            for i, (rs, ps) in enumerate(sweeps[1])
        ]
        ranges, index = _expected(beams, mode)
        a = A0 + np.array(index) * INC
        r = np.array(ranges, np.float32).astype(np.float64)
        local = np.column_stack([r * np.cos(a), r * np.sin(a), np.zeros(len(r))])
        expected = local @ T_BASE_LASER[:3, :3].T + T_BASE_LASER[:3, 3]
        np.testing.assert_allclose(ds[1].points, expected, atol=1e-6)


@pytest.mark.parametrize("ros", [1, 2])
def test_a_laser_scan_topic_whose_beam_count_changes_is_noted(tmp_path: Path, ros: int) -> None:
    """LaserScans of 30, 31, 30, 32, 33 and 30 beams: the note counts the messages of each
    count, most first, the fourth count summed up; one count: no note."""
    counts = [30, 31, 30, 32, 33, 30]
    sweeps = [_beams(n, 0) for n in counts]
    path = _path(tmp_path, ros, "l")
    _write(path, ros, sweeps, lambda bw, s, b: _laser_scan(bw, s, _first_returns(b)))
    with open_bag(path) as ds:
        assert ds.notes == [
            "topic '/echoes': its 6 messages hold 4 beam counts (beams in messages: 30 in 3, "
            "31 in 1, 32 in 1, …: a driver relaunched with another resolution or field of "
            "view, or two scanners on one topic?); each is read with its own angles"
        ]
        assert [len(ds[k]) for k in range(6)] == [len(_expected(b, "first")[0]) for b in sweeps]
    same = _path(tmp_path, ros, "same")
    _write(same, ros, sweeps[:1] * 3, lambda bw, s, b: _laser_scan(bw, s, _first_returns(b)))
    with open_bag(same) as ds:
        assert ds.notes == []
