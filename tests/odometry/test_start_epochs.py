"""The start's undeskewed epochs deskewed once a step is measured
(:mod:`planodom.odometry.start_epochs`, ``odometry.start_refresh``)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from planes_factory import observe, square_polygon

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, se3_log, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry, Status, start_epochs
from planodom.scan import Scan

DT, SPEED, SPAN = 0.1, 4.0, 0.1  # s, m/s along x, s of each epoch's points


def plane(normal, centroid, half, truth_id) -> Plane:  # noqa: ANN001
    n, c = np.asarray(normal, float), np.asarray(centroid, float)
    support = PlaneSupport(c, square_polygon(c, n, half), 200)
    return Plane(n, float(-n @ c), confidence=0.8, support=support, truth_id=truth_id)


#: a corridor along x (two parallel walls and the ground: the translation along x is not
#: measured) and a wall across it, seen from the third epoch (index 2) on.
CORRIDOR = [
    plane([0, -1, 0], [5, 2, 0.5], 4, 0),
    plane([0, 1, 0], [5, -2, 0.5], 4, 1),
    plane([0, 0, 1], [5, 0, -1.5], 5, 2),
]
ACROSS = plane([-1, 0, 0], [30, 0, 0.5], 2, 3)


def run(
    start_refresh: bool, walls_only: Callable[[int, np.ndarray | None], bool] | None = None,
    n: int = 5, across_from: int = 2,
) -> tuple[PlaneOdometry, list[tuple[int, np.ndarray | None]]]:  # fmt: skip
    """``n`` epochs at SPEED along the corridor; each scan's points spread over SPAN s. The
    extractor sees the planes from the pose at the points' mean time, less the motion the
    twist it is given deskews (the twist's x velocity times that time), the wall across
    from epoch ``across_from`` on; only the two walls where ``walls_only(epoch, twist)``."""
    calls: list[tuple[int, np.ndarray | None]] = []

    def extractor(scan, cfg, twist=None):  # noqa: ANN001, ANN202
        k = int(scan.points[0, 0])
        calls.append((k, None if twist is None else np.array(twist)))
        used = 0.0 if twist is None else float(twist[3])
        x = SPEED * DT * k + (SPEED - used) * SPAN / 2
        seen = CORRIDOR + ([ACROSS] if k >= across_from else [])
        if walls_only is not None and walls_only(k, twist):
            seen = CORRIDOR[:2]
        return observe(seen, transform_from_rpy_xyz(0, 0, 0, x, 0, 0))

    cfg = PlanodomConfig().updated(
        {"odometry.pipeline": "wocsc", "odometry.start_refresh": start_refresh}
    )
    odo = PlaneOdometry(cfg, extractor=extractor)
    for k in range(n):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, SPAN]), DT * k)
    return odo, calls


def test_the_start_is_deskewed_and_its_steps_move_once_the_motion_is_measured():
    off, _ = run(False)
    on, calls = run(True)
    # the scenario: the first two steps are degenerate (no velocity), the third measured;
    # without the option the first epochs stand still and epoch 0 is never deskewed
    assert [r.status for r in off.results[1:4]] == [Status.DEGENERATE] * 2 + [Status.OK]
    assert abs(off.poses[1][0, 3]) < 0.05 and abs(off.poses[2][0, 3]) < 0.05
    truth = SPEED * DT * np.arange(5)
    x_on = np.array([T[0, 3] for T in on.poses])
    np.testing.assert_allclose(x_on, truth, atol=0.01)
    # epochs 0-2 (1 and 2 deskewed with the zero velocity the degenerate steps carried)
    # extracted last with the measured twist (SPEED along x)
    last = {k: twist for k, twist in calls}
    for k in (0, 1, 2):
        np.testing.assert_allclose(last[k], [0, 0, 0, SPEED, 0, 0], atol=0.05)
    assert on.start.first_twist is not None
    np.testing.assert_allclose(on.start.first_twist, last[0])
    # the steps estimated again carry the twist their epoch's planes were deskewed with
    for k in (1, 2):
        assert on.results[k].deskew_twist is not None and k not in on.superseded


def test_on_by_default_and_nothing_without_point_times():
    assert PlanodomConfig().odometry.start_refresh is True
    a, calls_a = run(False)
    assert all(k != 0 or twist is None for k, twist in calls_a)  # epoch 0 never deskewed


def test_a_degenerate_step_kept_over_a_worse_estimate_takes_the_measured_velocity():
    """Epoch 1 extracted again with the measured twist keeps only the two parallel walls
    (its steps on the new planes are then unresolved, worse than degenerate): the steps
    into and out of it keep their planes as they were, but estimated again with the
    measured velocity's prior, not standing still along the corridor."""

    def walls_only(k, twist):  # noqa: ANN001, ANN202
        return k == 1 and twist is not None and twist[3] > SPEED / 2

    on, calls = run(True, walls_only)
    assert any(walls_only(k, twist) for k, twist in calls)  # the scenario happened
    truth = SPEED * DT * np.arange(5)
    x_on = np.array([T[0, 3] for T in on.poses])
    np.testing.assert_allclose(x_on, truth, atol=0.01)
    for k in (1, 2):  # still degenerate, on planes epoch 1 no longer holds
        assert on.results[k].status is Status.DEGENERATE and k in on.superseded


def test_a_start_longer_than_max_epochs_is_refreshed_while_its_scans_are_small(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The first measured step is epoch 25 (the wall across seen from then on), past
    MAX_EPOCHS: its tiny scans fit in MAX_BYTES, so the start is still deskewed and its
    degenerate steps take the measured velocity; with no bytes allowed beyond MAX_EPOCHS
    (scans too large), it is left standing still as before."""
    n, first = 27, 25
    assert first > start_epochs.MAX_EPOCHS
    truth = SPEED * DT * np.arange(n)
    on, _ = run(True, n=n, across_from=first)
    assert [r.status for r in on.results[1:first]] == [Status.DEGENERATE] * (first - 1)
    np.testing.assert_allclose([T[0, 3] for T in on.poses], truth, atol=0.01)
    monkeypatch.setattr(start_epochs, "MAX_BYTES", 0)
    bounded, _ = run(True, n=n, across_from=first)
    assert abs(bounded.poses[first - 1][0, 3]) < 0.05  # the zero velocity carried


#: the speed, m/s, a searched start guessed (``start_twist_search``'s candidate): the
#: prediction the start's epochs were deskewed with and their degenerate steps' prior
GUESS = 1.5


def searched_run(
    speed: str, deskew_iterations: int, searched: bool = True
) -> tuple[PlaneOdometry, list[tuple[int, np.ndarray | None]]]:
    """:func:`run`'s corridor (the wall across from epoch 2 on: step 3 the first OK one),
    its start as a search leaves it (``searched``): from epoch 1 on the prediction is the
    guessed speed :data:`GUESS` along x, and with ``odometry.start_search_speed``
    ``speed``."""
    calls: list[tuple[int, np.ndarray | None]] = []

    def extractor(scan, cfg, twist=None):  # noqa: ANN001, ANN202
        k = int(scan.points[0, 0])
        calls.append((k, None if twist is None else np.array(twist)))
        used = 0.0 if twist is None else float(twist[3])
        x = SPEED * DT * k + (SPEED - used) * SPAN / 2
        return observe(CORRIDOR + ([ACROSS] if k >= 2 else []),
                       transform_from_rpy_xyz(0, 0, 0, x, 0, 0))  # fmt: skip

    cfg = PlanodomConfig().updated({
        "odometry.pipeline": "wocsc", "odometry.start_twist_search": True,
        "odometry.start_search_speed": speed, "odometry.deskew_iterations": deskew_iterations,
    })  # fmt: skip
    odo = PlaneOdometry(cfg, extractor=extractor)
    odo.start.searched = searched
    for k in range(5):
        if k == 1:
            odo.twist = np.array([0.0, 0.0, 0.0, GUESS, 0.0, 0.0])
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, SPAN]), DT * k)
    return odo, calls


def test_the_measured_twist_is_the_steps_own_motion_over_its_interval():
    odo, _ = run(True)
    result = odo.results[3]
    got = start_epochs.measured_twist(odo, result)
    np.testing.assert_allclose(got, se3_log(result.T_prev_curr) / DT, atol=1e-12)
    np.testing.assert_allclose(got, [0, 0, 0, SPEED, 0, 0], atol=0.05)  # the truth


@pytest.mark.parametrize("deskew_iterations", [0, 1, 2])
def test_a_searched_start_takes_the_measured_speed_not_the_guess(deskew_iterations: int):
    """Without the policy's own re-extraction (0 iterations) the measured epoch keeps the
    guessed speed it was predicted with and ``candidate`` refreshes the start with it: the
    degenerate steps move at the guess. With one, the measured step's own speed is off
    (its reference deskewed with the guess, its epoch with its own): a second round on
    epochs deskewed alike finds the truth. ``measured`` ends at the truth each time."""
    truth = SPEED * DT * np.arange(5)
    measured, calls = searched_run("measured", deskew_iterations)
    assert [r.status for r in measured.results[1:4]] == [Status.DEGENERATE] * 2 + [Status.OK]
    np.testing.assert_allclose([T[0, 3] for T in measured.poses], truth, atol=0.01)
    last = {k: twist for k, twist in calls}
    for k in range(4):  # the start and the measured epoch extracted last at the truth
        np.testing.assert_allclose(last[k], [0, 0, 0, SPEED, 0, 0], atol=0.05)
    np.testing.assert_allclose(measured.twist[3:], [SPEED, 0, 0], atol=0.05)
    if deskew_iterations == 0:
        candidate, _ = searched_run("candidate", 0)
        x = np.array([T[0, 3] for T in candidate.poses])
        np.testing.assert_allclose(x[1:3], GUESS * DT * np.arange(1, 3), atol=0.01)


def test_measured_changes_nothing_where_no_search_gave_the_start():
    a, calls_a = searched_run("measured", 0, searched=False)
    b, calls_b = searched_run("candidate", 0, searched=False)
    np.testing.assert_array_equal(np.array(a.poses), np.array(b.poses))
    assert len(calls_a) == len(calls_b)
