"""The start's epochs deskewed again with the converged velocity
(:mod:`planodom.odometry.start_converged`, ``odometry.start_redeskew: converged``)."""

from __future__ import annotations

import numpy as np
from planes_factory import observe, square_polygon

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, transform_from_rpy_xyz
from planodom.odometry import PlaneOdometry, Status
from planodom.odometry.relative import RelativePose
from planodom.odometry.start_converged import (
    CHI2_95_3,
    CHI2_99_2,
    ConvergedStart,
    informed,
    rotation_agrees,
    velocity_agrees,
)
from planodom.scan import Scan

DT, SPEED, SPAN = 0.1, 4.0, 0.2  # s, m/s along x (the truth), s of each epoch's points
#: the along-track error (m) of each epoch's wall across as extracted: the noise of the
#: first step's translation (epoch 1's wall 3 cm off: a first speed 0.3 m/s too fast)
WALL_NOISE = {1: 0.03}


def plane(normal, centroid, half, truth_id) -> Plane:  # noqa: ANN001
    n, c = np.asarray(normal, float), np.asarray(centroid, float)
    support = PlaneSupport(c, square_polygon(c, n, half), 200)
    return Plane(n, float(-n @ c), confidence=0.8, support=support, truth_id=truth_id)


#: a corridor along x with walls across it ahead and at an angle: every step measures x, y
WORLD = [
    plane([0, -1, 0], [5, 3, 0.5], 6, 0),
    plane([0, 1, 0], [5, -3, 0.5], 6, 1),
    plane([0, 0, 1], [5, 0, -1.5], 8, 2),
    plane([-1, 0, 0], [30, 0, 0.5], 3, 3),
    plane([-0.6, -0.8, 0], [20, 8, 0.5], 3, 4),
]


def run(option: str, tilt_again: float = 0.0, n: int = 12, guard: str = "step", **more):  # noqa: ANN003, ANN201
    """``n`` epochs at SPEED along x; each scan's points spread over SPAN s, their planes
    seen from the pose at the points' mean time less the motion the given twist deskews
    (its x velocity times that time, as :mod:`.test_start_epochs`), epoch k's wall across
    WALL_NOISE[k] off. With ``tilt_again`` (deg), epoch 1 extracted once epoch 3 was
    registered (only the re-deskewing does that) sees every plane pitched by it about
    the base y axis: a wrong rotation the guard must refuse (``guard``:
    ``odometry.start_redeskew_guard``). Returns the odometry and
    per epoch the x velocity of its last extraction's twist and its extractions' count."""
    last: dict[int, float] = {}
    state = {"seen": 0}

    def extractor(scan, cfg, twist=None):  # noqa: ANN001, ANN202
        k = int(scan.points[0, 0])
        state["seen"] = max(state["seen"], k)
        used = 0.0 if twist is None else float(twist[3])
        last[k] = used
        x = SPEED * DT * k + (SPEED - used) * SPAN / 2
        T = transform_from_rpy_xyz(0, 0, 0, x, 0, 0)
        planes = observe(WORLD, T)
        if k in WALL_NOISE:
            wall = planes[3]
            planes[3] = Plane(wall.normal, wall.offset + WALL_NOISE[k], confidence=0.8,
                              support=wall.support, truth_id=wall.truth_id)  # fmt: skip
        if tilt_again and k == 1 and state["seen"] >= 3:
            R = transform_from_rpy_xyz(0, np.radians(tilt_again), 0, 0, 0, 0)
            planes = [p.transformed(R) for p in planes]
        return planes

    cfg = PlanodomConfig().updated(
        {"odometry.pipeline": "wocsc", "odometry.start_redeskew": option,
         "odometry.start_redeskew_guard": guard, **{f"odometry.{k}": v for k, v in more.items()}}
    )  # fmt: skip
    odo = PlaneOdometry(cfg, extractor=extractor)
    for k in range(n):
        odo.register_epoch(Scan(np.full((2, 3), float(k)), t=[0.0, SPAN]), DT * k)
    return odo, last


def test_off_by_default():
    assert PlanodomConfig().odometry.start_redeskew == "off"


def test_the_start_is_deskewed_again_with_the_converged_velocity():
    """Epoch 1's wall 3 cm off makes the first step 0.3 m/s too fast; epochs 0 and 1 are
    deskewed with it (6 cm over the points' mean time SPAN / 2 ... the truth is SPEED).
    With ``converged`` the mean of the steps that follow, weighed by their covariances,
    deskews them again: their last extraction's speed is near the truth, and the
    planes of epoch 0, the run's frame, are where the truth puts them."""
    off, last_off = run("off")
    on, last_on = run("converged")
    assert all(r.status is Status.OK for r in on.results[1:])
    assert abs(last_off[0] - SPEED) > 0.1  # the scenario: epoch 0 deskewed with step 1's
    start = on.start.converged
    assert isinstance(start, ConvergedStart) and start.converged_at is not None
    assert start.velocity is not None and len(start.steps) >= 2
    assert abs(start.velocity[0] - SPEED) < 0.5 * abs(last_off[0] - SPEED)
    for k in range(start.converged_at + 1):  # extracted last with the mean
        assert abs(last_on[k] - start.velocity[0]) < 1e-9
    # epoch 0's wall across, against the truth (seen from the identity at 30 m)
    truth = observe(WORLD, np.eye(4))[3].offset
    err_off = abs(off.planes[0][3].offset - truth)
    err_on = abs(on.planes[0][3].offset - truth)
    assert err_on < 0.5 * err_off
    # and the positions of the start's epochs, against the truth
    x_true = SPEED * DT * np.arange(len(on.poses))
    e_off = np.abs([T[0, 3] for T in off.poses] - x_true)[: start.converged_at + 1]
    e_on = np.abs([T[0, 3] for T in on.poses] - x_true)[: start.converged_at + 1]
    assert e_on.max() <= e_off.max() + 1e-3


def test_a_re_solved_step_whose_rotation_disagrees_is_not_kept():
    """Epoch 1 extracted again sees its planes pitched 10 deg: the steps into and out of
    it estimated again turn by that much, far outside their covariances: both keep
    their old estimates (marked superseded), whose rotation is the truth's."""
    on, _ = run("converged", tilt_again=10.0)
    assert on.start.converged is not None and on.start.converged.converged_at is not None
    for k in (1, 2):
        R = on.results[k].T_prev_curr[:3, :3]
        assert np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))) < 0.1
        assert k in on.superseded


def _pose(pitch_deg: float, sigma_deg: float) -> RelativePose:
    T = transform_from_rpy_xyz(0, np.radians(pitch_deg), 0, 0.4, 0, 0)
    C = np.diag([np.radians(sigma_deg) ** 2] * 3 + [1e-4, 1e-4])
    return RelativePose(T, C)


def test_rotation_agreement_is_the_chi_square_bound_on_both_covariances():
    # the difference d against the summed variance 2 s^2: agrees while d^2 / (2 s^2) <= chi2
    s = 0.1
    bound = np.sqrt(CHI2_95_3 * 2) * s  # deg
    assert rotation_agrees(_pose(0, s), _pose(0.99 * bound, s))
    assert not rotation_agrees(_pose(0, s), _pose(1.01 * bound, s))
    assert not rotation_agrees(_pose(0, s), _pose(16.0, s))  # START356's step
    assert rotation_agrees(RelativePose(np.eye(4), None), _pose(16.0, s))  # not judged


def test_guard_all_undoes_the_whole_round_a_refused_step_was_in():
    """``start_redeskew_guard: all``: the pitched re-extraction of epoch 1 refuses a step,
    so the round is undone: every epoch keeps the planes the option-off run has, no step
    is superseded, the poses are the option-off run's (and the steps' rotation the
    truth's)."""
    off, _ = run("off", tilt_again=10.0)
    on, _ = run("converged", tilt_again=10.0, guard="all")
    assert on.start.converged is not None and on.start.converged.converged_at is None
    assert not on.superseded & {1, 2, 3, 4}
    for k in range(5):
        np.testing.assert_allclose([p.offset for p in on.planes[k]],
                                   [p.offset for p in off.planes[k]], atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(np.array(on.poses), np.array(off.poses), atol=1e-12)
    for k in (1, 2):
        R = on.results[k].T_prev_curr[:3, :3]
        assert np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1))) < 0.1


def test_the_epochs_rate_is_the_steps_own_or_the_one_it_was_deskewed_with():
    """:func:`epoch_twist` against the twist the step was made from (closed form): the
    step's own rate with ``step``, the epoch's last deskewing rate with ``kept``; the x,
    y velocity given, the vertical velocity the step's."""
    from types import SimpleNamespace

    from planodom.geometry import twist_step
    from planodom.odometry.kept_epoch import KeptEpoch
    from planodom.odometry.start_converged import epoch_twist

    true = np.array([0.01, -0.02, 0.3, 4.0, 0.1, 0.05])
    steps = [np.eye(4), twist_step(true, DT), twist_step(true, DT)]
    velocity = np.array([3.9, 0.0])
    was = np.array([0.0, 0.0, 0.25, 3.5, 0.0, 0.0])
    epoch = KeptEpoch(2, [], None, twist=was)  # type: ignore[arg-type]
    for rate, expected in (("step", true[:3]), ("kept", was[:3])):
        cfg = PlanodomConfig().updated({"odometry.start_redeskew_rate": rate})
        odo = SimpleNamespace(times=[0.0, DT, 2 * DT], _steps=steps, config=cfg)
        got = epoch_twist(odo, 2, velocity, epoch)  # type: ignore[arg-type]
        np.testing.assert_allclose(got, np.r_[expected, velocity, true[5]], atol=1e-9)
    # the first epoch takes its step out of it
    got = epoch_twist(odo, 0, velocity, None)  # type: ignore[arg-type]
    np.testing.assert_allclose(got, np.r_[true[:3], velocity, true[5]], atol=1e-9)


def test_information_test_is_four_times_the_first_steps_in_every_direction():
    """Closed form: the mean's information against 4x the first step's (the deskewing
    error's standard deviation halved), in every direction, not on the trace."""
    first = np.diag([1 / 0.03**2, 1 / 0.04**2])
    assert informed(4.0 * first, first)
    assert not informed(3.9 * first, first)
    # two steps of equal noise: twice the first's, a converged "move" is not enough
    assert not informed(2.0 * first, first)
    # 382's case: a precise along-track mean, lateral information only 1.1x the first's
    assert not informed(np.diag([10 / 0.03**2, 1.1 / 0.04**2]), first)
    # a later step far more precise than the first outweighs it alone
    assert informed(first + np.diag([1 / 0.01**2, 1 / 0.015**2]), first)


def test_velocity_agreement_is_the_chi_square_bound_on_both_covariances():
    """Closed form: a re-estimated step's x, y velocity against the first estimate's,
    the difference d (m/s) against the summed variance 2 s^2 / dt^2."""
    s, dt = 0.004, DT  # m per step
    C = np.diag([1e-6] * 3 + [s**2, s**2])
    bound = np.sqrt(CHI2_99_2 * 2) * s / dt  # m/s

    def step(v: float) -> RelativePose:
        return RelativePose(transform_from_rpy_xyz(0, 0, 0, v * dt, 0, 0), C)

    assert velocity_agrees(step(4.0), step(4.0 + 0.99 * bound), dt)
    assert not velocity_agrees(step(4.0), step(4.0 + 1.01 * bound), dt)
    assert not velocity_agrees(step(1.97), step(2.43), dt)  # START3's world 398
    assert velocity_agrees(RelativePose(np.eye(4), None), step(2.43), dt)  # not judged


def test_information_test_waits_for_four_times_the_first_steps_information():
    """Epoch 1's wall 3 cm off, the steps after it agree: ``move`` stops once a step
    moves the mean by less than its standard error, on four steps whose information is
    just under four times the first's (the steps' covariances differ slightly);
    ``information`` waits one step more, until it is four times the first's in every
    direction, and still brings the velocity and epoch 0's wall across to the truth."""
    off, last_off = run("off")
    move, _ = run("converged", guard="all")
    on, _ = run("converged", guard="all", start_redeskew_test="information",
                start_redeskew_translation_guard=True)  # fmt: skip
    stopped, start = move.start.converged, on.start.converged
    assert stopped is not None and stopped.converged_at is not None
    assert stopped.information is not None and stopped.first is not None
    assert not informed(stopped.information, stopped.first)
    assert start is not None and start.converged_at is not None
    assert start.information is not None and start.first is not None
    assert informed(start.information, start.first)
    assert start.converged_at > stopped.converged_at
    assert start.velocity is not None
    assert abs(start.velocity[0] - SPEED) < 0.5 * abs(last_off[0] - SPEED)
    truth = observe(WORLD, np.eye(4))[3].offset
    assert abs(on.planes[0][3].offset - truth) < 0.5 * abs(off.planes[0][3].offset - truth)


def test_significant_test_acts_only_on_a_correction_beyond_the_means_noise(monkeypatch):  # noqa: ANN001
    """``significant``: with epoch 1's wall 3 cm off (the first step 0.3 m/s fast) the
    mean's correction is many standard errors and the start is deskewed again (its
    wall across brought to the truth); with every wall where the truth puts it, the
    first step is the truth's, the correction within the mean's noise, and the start
    stays as the option-off run has it."""
    off, _ = run("off")
    on, _ = run("converged", guard="all", start_redeskew_test="significant")
    assert on.start.converged is not None and on.start.converged.converged_at is not None
    truth = observe(WORLD, np.eye(4))[3].offset
    assert abs(on.planes[0][3].offset - truth) < 0.5 * abs(off.planes[0][3].offset - truth)
    monkeypatch.setattr(f"{__name__}.WALL_NOISE", {})
    off, _ = run("off")
    on, _ = run("converged", guard="all", start_redeskew_test="significant")
    assert on.start.converged is not None and on.start.converged.converged_at is None
    for k in range(6):
        np.testing.assert_allclose([p.offset for p in on.planes[k]],
                                   [p.offset for p in off.planes[k]], atol=1e-12)  # fmt: skip
