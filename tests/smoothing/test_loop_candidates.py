"""Loop-candidate factors (planodom.smoothing.loop_candidates) on the synthetic closed loop
of tests/smoothing/test_loop_closure.py: a drifted chain whose lap end revisits its start."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.config import PlanodomConfig
from planodom.errors import ConfigError
from planodom.geometry import invert_transform, make_transform, pose5_from_transform
from planodom.odometry import RelativePose, Status
from planodom.smoothing import loop_candidates
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.loop_drift import run_drift
from planodom.smoothing.loop_records import LoopFactor, loop_factor_counts
from planodom.smoothing.loops import LoopClosingBuilder
from tests.smoothing.test_loop_closure import N_LAP, _config, _end_error, _loop_problem


@pytest.fixture(scope="module")
def problem():
    return _loop_problem()


def _candidates_only(on: bool = True) -> PlanodomConfig:
    """Loop closure by old-epoch candidates alone: no map match has enough planes."""
    return _config(True).updated(
        {"smoothing.loop_min_matches": 1000, "smoothing.loop_candidates": on}
    )


def test_loop_candidates_alone_close_the_loop(problem):
    truth, planes, relatives = problem
    without = smooth_batch(planes, relatives, _candidates_only(False))
    res = smooth_batch(planes, relatives, _candidates_only())
    assert not without.loop_factors and not res.reidentifications
    kept = [f for f in res.loop_factors if not f.removed]
    assert len(kept) >= 2
    for f in kept:  # each measures the true relative pose of a revisit, within 3 sigma
        assert f.epoch - f.old >= 20
        true = invert_transform(truth[f.old]) @ truth[f.epoch]
        err = pose5_from_transform(invert_transform(true) @ f.T_old_curr)
        assert np.linalg.norm(err[3:]) < 0.3 and abs(err[2]) < np.radians(2.0)
        assert not f.wrong(truth)
    assert _end_error(res.initial_poses, truth) > 1.5  # the drift the loop must close
    assert _end_error(without.poses, truth) > 0.4
    assert _end_error(res.poses, truth) < 0.6 * _end_error(without.poses, truth)


def test_planted_wrong_loop_poses_are_refused_or_removed(problem, monkeypatch):
    """Loop poses shifted 3 m at every candidate after the lap (consistent with each
    other, so they pass the confirmation). With the map, they disagree with its accepted
    correction and tie nothing; without it (candidates alone), the gate removes them and
    the result is that of no loop closure."""
    truth, planes, relatives = problem
    original = loop_candidates.CandidateLoopBuilder.match_old_epoch

    def shifted(self, k, e):
        rel = original(self, k, e)
        if rel is None:
            return None
        return replace(rel, T_prev_curr=rel.T_prev_curr @ make_transform(np.eye(3), [3.0, 0, 0]))

    plain = smooth_batch(planes, relatives, _candidates_only(False))
    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "match_old_epoch", shifted)
    with_map = smooth_batch(planes, relatives, _config(True))
    assert not with_map.loop_factors
    assert _end_error(with_map.poses, truth) < 0.3  # the map still closes the loop
    alone = smooth_batch(planes, relatives, _candidates_only())
    assert alone.loop_factors  # the shifted poses were verified and confirmed
    counts = loop_factor_counts(alone.loop_factors, truth)
    assert counts["loop_factors_wrong_kept"] == 0
    assert counts["loop_factors_wrong_removed"] == len(alone.loop_factors)
    np.testing.assert_allclose(alone.poses[-1], plain.poses[-1], atol=0.05)


def test_old_epoch_candidates_follow_the_rule(problem, monkeypatch):
    """Every candidate is at least the minimum gap old and within the radius plus its
    translation bound; every epoch left out that satisfies it is farther than the last."""
    truth, planes, relatives = problem
    seen = []
    original = loop_candidates.CandidateLoopBuilder.old_epoch_candidates

    def checked(self, k):
        out = original(self, k)
        c = self.config
        position = self._predicted(k)[:2, 3]
        old = np.arange(max(k - c.loop_min_gap_epochs + 1, 0))
        dist = np.array([np.linalg.norm(self.poses[e][:2, 3] - position) for e in old])
        bound = self._bounds(k, old)[0] if len(old) else np.zeros(0)
        ok = dist <= c.loop_candidate_radius_m + bound
        assert all(e <= k - c.loop_min_gap_epochs and ok[e] for e in out)
        if 0 < len(out) < c.loop_candidate_max:
            assert all(dist[e] >= dist[out[-1]] - 1e-9 for e in np.flatnonzero(ok) if e not in out)
        seen.append(len(out))
        return out

    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "old_epoch_candidates", checked)
    smooth_batch(planes, relatives, _candidates_only())
    assert max(seen) > 0 and seen[: N_LAP // 4] == [0] * (N_LAP // 4)


def test_a_loop_factor_is_wrong_beyond_three_sigma():
    """LoopFactor.wrong against true poses built to put the error at 2 and 4 sigma."""
    gt = np.stack([np.eye(4), make_transform(np.eye(3), [5.0, 1.0, 0.0])])
    cov = np.diag([1e-6, 1e-6, 1e-6, 0.01, 0.01])  # 10 cm in x and y
    for shift, wrong in ((0.2, False), (0.4, True)):
        T = make_transform(np.eye(3), [5.0 + shift, 1.0, 0.3])  # z is not measured
        f = LoopFactor(1, 0, T, cov, 3, 0)
        # the factor error is the true (predicted) minus the measured translation
        np.testing.assert_allclose(f.truth_error(gt), [0, 0, 0, -shift, 0], atol=1e-12)
        assert f.wrong(gt) is wrong


def _step(k: int, xy, status: Status = Status.OK) -> RelativePose:
    T = make_transform(np.eye(3), [xy[0], xy[1], 0.0])
    cov = np.diag([1e-6, 1e-6, 1e-6, 1e-4, 1e-4])
    return RelativePose(T, cov, status, prev=k - 1, curr=k)


def test_run_drift_of_bridged_epochs_grows_as_a_velocity_random_walk():
    """loop_candidate_drift "run": measured steps add their own variance; the n-th bridged
    epoch in a row adds (n^3 - (n-1)^3) / 3 times the mean squared change of consecutive
    measured steps (closed form), at most the fallback's variance, and the count restarts
    after a measured step."""
    cfg = _candidates_only().updated({"smoothing.loop_candidate_drift": "run"})
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    steps = [(0.30, 0.00), (0.32, 0.01), (0.29, -0.01), (0.31, 0.00)]  # epochs 1..4 measured
    plan = [None] + steps + [None] * 4 + [(0.3, 0.0), None, None]
    for k, xy in enumerate(plan):
        rel = [] if k == 0 else [_step(k, xy or (0.3, 0.0), Status.OK if xy else Status.DEGENERATE)]
        builder.add_epoch([], rel)
    changes = np.diff(np.array(steps), axis=0)
    sigma2 = float(np.mean(np.sum(changes**2, axis=1)))  # x plus y, per epoch
    added = np.diff(np.array(builder._variances)[:, 0])
    np.testing.assert_allclose(added[:4], 2e-4)  # measured: x plus y of their covariance
    n = np.arange(1, 5)
    np.testing.assert_allclose(added[4:8], sigma2 * (n**3 - (n - 1) ** 3) / 3.0)
    assert added[8] == pytest.approx(2e-4)
    # the step after the bridge has no measured predecessor: no change recorded
    np.testing.assert_allclose(added[9:], sigma2 * np.array([1.0, 7.0]) / 3.0)
    capped = loop_candidates.CandidateLoopBuilder(cfg)
    capped._walk.change[:] = (1.0, 1.0)  # a change of 1 m per epoch: the fallback caps it
    assert capped._walk.variance(None, 0.25) == 0.25


def test_an_aliased_place_after_a_bridged_stretch_is_refused(problem, monkeypatch):
    """The lap with its epochs 30-59 bridged (translation not measured: the fallback's
    0.5 m per epoch; the trajectory keeps its speed), and every old-epoch match after
    the lap shifted 8 m (an aliased corridor: consistent with each other, they pass the
    confirmation). The chained drift (the fallback's variance) verifies them, to be
    removed after optimisation only; the run's own ("run": the measured steps do not
    change, so the bridge adds nothing) refuses every one before the graph, while the
    true loop poses still verify and close the loop."""
    truth, planes, relatives = problem
    relatives = [replace(r, status=Status.DEGENERATE) if 30 <= r.curr < 60 else r
                 for r in relatives]  # fmt: skip
    run_cfg = _candidates_only().updated({"smoothing.loop_candidate_drift": "run"})
    plain = smooth_batch(planes, relatives, _candidates_only(False))
    right = smooth_batch(planes, relatives, run_cfg)
    counts = loop_factor_counts(right.loop_factors, truth)
    assert counts["loop_factors"] >= 10 and counts["loop_factors_wrong_kept"] == 0
    assert _end_error(right.poses, truth) < 0.5 * _end_error(plain.poses, truth)
    original = loop_candidates.CandidateLoopBuilder.match_old_epoch

    def aliased(self, k, e):
        rel = original(self, k, e)
        if rel is None:
            return None
        return replace(rel, T_prev_curr=rel.T_prev_curr @ make_transform(np.eye(3), [8.0, 0, 0]))

    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "match_old_epoch", aliased)
    chained_cfg = _candidates_only().updated({"smoothing.loop_candidate_drift": "chained"})
    chained = smooth_batch(planes, relatives, chained_cfg)
    assert chained.loop_factors and all(f.wrong(truth) for f in chained.loop_factors)
    run = smooth_batch(planes, relatives, run_cfg)
    assert not run.loop_factors
    np.testing.assert_allclose(run.poses, plain.poses, atol=1e-9)


def test_an_old_epoch_no_neighbour_confirmed_is_passed_over(problem):
    """The first epoch's planes 0.3 m off (extracted before any motion was known) and its
    relative poses to its neighbours rotation-only (its planes agreed with none): with
    ``loop_candidate_old`` "any" the lap's end ties to it, with "translated" to later
    epochs only, every kept loop factor within 3 sigma of the truth."""
    truth, planes, relatives = problem
    planes = list(planes)
    planes[0] = [replace(p, offset=p.offset - 0.3) if abs(p.normal[2]) < 0.5 else p
                 for p in planes[0]]  # fmt: skip
    relatives = [replace(r, status=Status.DEGENERATE) if r.prev == 0 else r for r in relatives]
    tie = {}
    for old in ("any", "translated"):
        cfg = _candidates_only().updated({"smoothing.loop_candidate_old": old})
        tie[old] = smooth_batch(planes, relatives, cfg).loop_factors
    assert any(f.old == 0 for f in tie["any"])
    assert any(f.wrong(truth) for f in tie["any"] if f.old == 0)
    assert tie["translated"] and all(f.old > 0 for f in tie["translated"])
    assert not any(f.wrong(truth) for f in tie["translated"] if not f.removed)


def _turn(k: int, yaw: float | None) -> RelativePose:
    """A delta = 1 step of 0.3 m turning by ``yaw`` (rad); None: unresolved (bridged)."""
    T = make_transform(Rotation.from_euler("z", yaw or 0.0).as_matrix(), [0.3, 0.0, 0.0])
    cov = np.diag([1e-6, 1e-6, 1e-6, 1e-4, 1e-4])
    return RelativePose(T, cov, Status.OK if yaw is not None else Status.UNRESOLVED,
                        prev=k - 1, curr=k)  # fmt: skip


def test_bridged_yaw_drift_is_the_run_yaw_rate_random_walk():
    """loop_drift_yaw "run": the n-th bridged epoch in a row adds (n^3 - (n-1)^3) / 3 times
    the mean squared change of consecutive measured yaw steps (closed form); "fallback" the
    fallback factor's variance; the map's verification takes that drift with
    loop_verify_drift "run" (run_drift of the builder's own sums), else the chained one."""
    yaws = [0.010, 0.014, 0.009, 0.012]  # epochs 1..4 measured, 5..7 bridged
    plan = [None, *yaws, None, None, None]
    added = {}
    for mode in ("fallback", "run"):
        cfg = _candidates_only().updated(
            {"smoothing.loop_drift_yaw": mode, "smoothing.loop_verify_drift": "run"}
        )
        builder = loop_candidates.CandidateLoopBuilder(cfg)
        for k, yaw in enumerate(plan):
            builder.add_epoch([], [] if k == 0 else [_turn(k, yaw)])
        added[mode] = np.diff(np.array(builder._variances)[:, 1])
        spans = [(2, 7), (0, 1)]
        expected = run_drift(builder.travelled, builder._variances, spans, cfg)
        np.testing.assert_allclose(builder._drift_covariance(spans), expected)
        chained = LoopClosingBuilder._drift_covariance(builder, spans)
        assert chained[1, 1] > expected[1, 1]  # the fallback's 0.5 m per bridged epoch
    np.testing.assert_allclose(added["fallback"][:4], 1e-6)
    np.testing.assert_allclose(added["fallback"][4:], 0.05**2)
    sigma2 = float(np.mean(np.diff(yaws) ** 2))
    n = np.arange(1, 4)
    np.testing.assert_allclose(added["run"][:4], 1e-6)
    np.testing.assert_allclose(added["run"][4:], sigma2 * (n**3 - (n - 1) ** 3) / 3.0)
    with pytest.raises(ConfigError, match="loop_verify_drift"):
        PlanodomConfig().updated(
            {"smoothing.loop_verify_drift": "run", "smoothing.loop_candidate_drift": "chained"}
        )


def test_loop_candidate_aliases_keep_every_loop_pose_where_no_wall_repeats(problem):
    """``loop_candidate_aliases``: the lap's walls are not repeated (no two parallel), so
    the test refuses no loop pose: the same loop factors as without it."""
    truth, planes, relatives = problem
    off_cfg = _candidates_only().updated({"smoothing.loop_candidate_aliases": "off"})
    off = smooth_batch(planes, relatives, off_cfg)
    for mode in ("both_epochs", "spacing"):
        on = _candidates_only().updated({"smoothing.loop_candidate_aliases": mode})
        res = smooth_batch(planes, relatives, on)
        assert len(res.loop_factors) >= 2
        assert [(f.epoch, f.old) for f in res.loop_factors] == [
            (f.epoch, f.old) for f in off.loop_factors
        ]


def test_an_aliased_place_tries_no_further_old_epoch(problem, monkeypatch):
    """An epoch whose match is ambiguous is refused, and no other old epoch is tried for
    it (they see less of the place, not more); without the test one is."""
    truth, planes, relatives = problem
    events: list[tuple[str, int]] = []
    original = loop_candidates.CandidateLoopBuilder.match_old_epoch

    def recorded(self, k, e):
        events.append(("try", k))
        return original(self, k, e)

    def ambiguous(*args, **kwargs):
        events.append(("ambiguous", events[-1][1]))
        return -np.inf

    monkeypatch.setattr(loop_candidates.CandidateLoopBuilder, "match_old_epoch", recorded)
    monkeypatch.setattr(loop_candidates, "epoch_ambiguity", ambiguous)
    on = _candidates_only().updated({"smoothing.loop_candidate_aliases": "both_epochs"})
    res = smooth_batch(planes, relatives, on)
    assert any(a == "ambiguous" for a, _ in events) and not res.loop_factors
    nexts = [events[i + 1] for i in range(len(events) - 1) if events[i][0] == "ambiguous"]
    refused = [events[i][1] for i in range(len(events) - 1) if events[i][0] == "ambiguous"]
    assert all(b != ("try", k) for b, k in zip(nexts, refused, strict=True))
    # without the test, those epochs give loop factors
    off = _candidates_only().updated({"smoothing.loop_candidate_aliases": "off"})
    plain = smooth_batch(planes, relatives, off)
    assert {f.epoch for f in plain.loop_factors} & set(refused)


def test_refuse_ambiguous_run_takes_the_runs_drift():
    """loop_refuse_ambiguous "run": the alias test's prior is the run's drift since the
    candidates' sighting (run_drift of the builder's own sums, before any correction),
    tighter than the chained one over bridged epochs; it needs loop_candidate_drift "run"."""
    plan = [None, 0.010, 0.014, 0.009, 0.012, None, None, None]
    cfg = _candidates_only().updated({"smoothing.loop_refuse_ambiguous": "run"})
    builder = loop_candidates.CandidateLoopBuilder(cfg)
    for k, yaw in enumerate(plan):
        builder.add_epoch([], [] if k == 0 else [_turn(k, yaw)])
    expected = run_drift(builder.travelled, builder._variances, [(2, 7)], cfg)
    assert builder._prior_sigma(7, 2, []) == pytest.approx(np.sqrt(expected[1, 1]))
    chained = LoopClosingBuilder._drift_covariance(builder, [(2, 7)])
    assert builder._prior_sigma(7, 2, []) < np.sqrt(chained[1, 1])
    off = loop_candidates.CandidateLoopBuilder(_candidates_only())  # the chained one
    for k, yaw in enumerate(plan):
        off.add_epoch([], [] if k == 0 else [_turn(k, yaw)])
    assert off._prior_sigma(7, 2, []) == pytest.approx(np.sqrt(chained[1, 1]))
    with pytest.raises(ConfigError, match="loop_refuse_ambiguous"):
        PlanodomConfig().updated(
            {"smoothing.loop_refuse_ambiguous": "run", "smoothing.loop_candidate_drift": "chained"}
        )
