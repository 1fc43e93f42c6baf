"""Loop closure in batch smoothing (planodom.smoothing.loops) on a synthetic closed loop.

A vehicle drives 1.15 laps of a circle among vertical walls; its relative poses are
biased (yaw and scale), so the chained guess drifts by metres; the planes are noisy.
Without loop closure the walls seen at the start and again at the end are different
landmarks and the batch follows the drift; with it, they are one.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, invert_transform, make_transform
from planodom.odometry.relative import RelativePose
from planodom.smoothing import loops
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.loop_records import reidentification_counts
from planodom.smoothing.synthetic import _measure_plane
from tests.planes_factory import square_polygon

N_LAP, N_EPOCHS, RADIUS = 80, 96, 12.0
VISIBLE, SIGMA_N, SIGMA_D = 14.0, 0.01, 0.03


def _loop_problem(seed: int = 1):
    rng = np.random.default_rng(seed)
    angle = 2 * np.pi * np.arange(N_EPOCHS) / N_LAP
    poses = []
    for a in angle:
        c, s = np.cos(a + np.pi / 2), np.sin(a + np.pi / 2)
        R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        poses.append(make_transform(R, [RADIUS * np.cos(a), RADIUS * np.sin(a) - RADIUS, 0.0]))
    poses = [invert_transform(poses[0]) @ T for T in poses]
    centre = invert_transform(poses[0])[:3, 3] * 0 + poses[N_LAP // 2][:3, 3] / 2
    walls, centres = [], []
    for az in np.sort(rng.uniform(0, 2 * np.pi, 16)):
        n = -np.array([np.cos(az + rng.uniform(-0.5, 0.5)), np.sin(az), 0.0])
        n /= np.linalg.norm(n)
        c = centre + rng.uniform(16, 24) * np.array([np.cos(az), np.sin(az), 0.0]) + [0, 0, 1.0]
        walls.append(np.append(n, -n @ c))
        centres.append(c)
    walls.append(np.array([0.0, 0.0, 1.0, 1.5]))
    centres.append(np.array([centre[0], centre[1], -1.5]))
    planes, ids = [], []
    for T in poses:
        seen = [w for w, c in enumerate(centres)
                if w == len(walls) - 1 or np.linalg.norm(c[:2] - T[:2, 3]) < VISIBLE]  # fmt: skip
        epoch = []
        for w in seen:
            p = _measure_plane(rng, walls[w], T, SIGMA_N, SIGMA_D, w)
            half = 20.0 if w == len(walls) - 1 else 4.0
            sup_w = PlaneSupport(centres[w], square_polygon(centres[w], walls[w][:3], half), 200)
            epoch.append(Plane(p.normal, p.offset, p.covariance, 1.0,
                               sup_w.transformed(invert_transform(T)), w))  # fmt: skip
        planes.append(epoch)
        ids.append(np.array(seen))
    bias = make_transform(np.array([[np.cos(0.0015), -np.sin(0.0015), 0], [np.sin(0.0015),
                          np.cos(0.0015), 0], [0, 0, 1]]), [0.03, 0.0, 0.0])  # fmt: skip
    relatives = []
    for k in range(1, N_EPOCHS):
        for d in (1, 2):
            if k - d < 0:
                continue
            T = invert_transform(poses[k - d]) @ poses[k] @ bias
            _, i_p, i_c = np.intersect1d(ids[k - d], ids[k], return_indices=True)
            cov = np.diag([1e-6, 1e-6, 4e-6, 4e-4, 4e-4])
            relatives.append(RelativePose(T, cov, associations=np.column_stack([i_p, i_c]),
                                          prev=k - d, curr=k))  # fmt: skip
    return np.stack(poses), planes, relatives


def _config(loop_closure: bool) -> PlanodomConfig:
    return PlanodomConfig().updated(
        {
            "smoothing.delta_max": 2,
            "smoothing.window": 4,
            "smoothing.loop_closure": loop_closure,
            "smoothing.loop_min_gap_epochs": 20,
            "smoothing.compute_covariances": False,
            "smoothing.batch_initial": "odometry",  # the drifted chain, what the map must face
        }
    )


@pytest.fixture(scope="module")
def problem():
    return _loop_problem()


def _end_error(poses: np.ndarray, truth: np.ndarray) -> float:
    return float(np.linalg.norm(poses[-1][:2, 3] - truth[-1][:2, 3]))


def test_loop_closure_removes_the_drift_at_the_loop_end(problem):
    truth, planes, relatives = problem
    without = smooth_batch(planes, relatives, _config(False))
    with_lc = smooth_batch(planes, relatives, _config(True))
    kept = [r for r in with_lc.reidentifications if not r.removed]
    assert len(kept) >= 30
    assert reidentification_counts(with_lc.reidentifications)["wrong_kept"] == 0
    assert _end_error(with_lc.initial_poses, truth) > 1.5  # the drift the loop must close
    assert _end_error(without.poses, truth) > 0.4  # noisy planes along the lap
    assert _end_error(with_lc.poses, truth) < 0.6 * _end_error(without.poses, truth)


@pytest.mark.parametrize("resolve_from", ["initial", "estimate"])
def test_a_planted_false_reidentification_is_rejected(problem, monkeypatch, resolve_from):
    """The gate removes it, and the re-solve closes the loop, started from the initial
    values or from the estimate the wrong tie pulled."""
    truth, planes, relatives = problem
    original = loops.LoopClosingBuilder._reidentify

    def planted(self, update):
        original(self, update)
        if update.epoch == N_LAP + 5:  # tie a wall to an old landmark of another wall
            i = next(i for i, p in enumerate(self.planes[update.epoch]) if abs(p.normal[2]) < 0.5)
            wall = self.planes[update.epoch][i].truth_id
            j = next(j for j, lm in sorted(self.landmarks.items()) if lm.last_seen is not None
                     and abs(lm.plane_world[2]) < 0.5
                     and self.planes[lm.last_seen[0]][lm.last_index].truth_id != wall)  # fmt: skip
            self._tie(update, j, i, self.planes[update.epoch][i].normal)

    monkeypatch.setattr(loops.LoopClosingBuilder, "_reidentify", planted)
    cfg = _config(True).updated({"smoothing.loop_gate_resolve_from": resolve_from})
    res = smooth_batch(planes, relatives, cfg)
    wrong = [r for r in res.reidentifications if r.wrong]
    assert len(wrong) == 1 and wrong[0].removed
    assert _end_error(res.poses, truth) < 0.3  # the loop is still closed


def test_the_map_is_deterministic(problem):
    _, planes, relatives = problem
    a = smooth_batch(planes, relatives, _config(True))
    b = smooth_batch(planes, relatives, _config(True))
    assert [(r.epoch, r.plane, r.landmark, r.removed) for r in a.reidentifications] == [
        (r.epoch, r.plane, r.landmark, r.removed) for r in b.reidentifications
    ]
    np.testing.assert_array_equal(a.poses, b.poses)


def _verified(mode: str) -> PlanodomConfig:
    return _config(True).updated({"smoothing.loop_verify": mode})


@pytest.mark.parametrize("mode", ["consistency", "tracked"])
def test_verified_loop_closure_still_closes_the_loop(problem, mode):
    truth, planes, relatives = problem
    without = smooth_batch(planes, relatives, _config(False))
    res = smooth_batch(planes, relatives, _verified(mode))
    assert reidentification_counts(res.reidentifications)["wrong_kept"] == 0
    assert _end_error(res.poses, truth) < 0.6 * _end_error(without.poses, truth)


def test_refusing_misfit_rotation_only_matches_still_closes_the_loop(problem):
    truth, planes, relatives = problem
    without = smooth_batch(planes, relatives, _config(False))
    res = smooth_batch(
        planes, relatives, _config(True).updated({"smoothing.loop_refuse_misfit": True})
    )
    assert reidentification_counts(res.reidentifications)["wrong_kept"] == 0
    assert _end_error(res.poses, truth) < 0.6 * _end_error(without.poses, truth)


def test_a_match_placing_the_pose_metres_off_is_refused(problem, monkeypatch):
    """Matches whose pose is shifted 3 m (an aliased parallel wall) every other epoch after
    the loop has been closed: the correction each implies disagrees with the accepted one
    (the matches between confirm it), so they tie nothing; without the verification they
    tie their planes."""
    truth, planes, relatives = problem
    planted = {N_LAP + 8, N_LAP + 10}
    original = loops.estimate_relative_pose
    builders = []

    def shifted(map_planes, curr, cfg, prior):
        rel = original(map_planes, curr, cfg, prior=prior)
        if builders[-1].n_epochs - 1 in planted:
            T = rel.T_prev_curr @ make_transform(np.eye(3), [3.0, 0.0, 0.0])
            rel = replace(rel, T_prev_curr=T)
        return rel

    init = loops.LoopClosingBuilder.__init__

    def remember(self, *args, **kwargs):
        init(self, *args, **kwargs)
        builders.append(self)

    monkeypatch.setattr(loops, "estimate_relative_pose", shifted)
    monkeypatch.setattr(loops.LoopClosingBuilder, "__init__", remember)
    tied = {}
    for mode in ("off", "tracked"):
        res = smooth_batch(planes, relatives, _verified(mode))
        tied[mode] = [r for r in res.reidentifications if r.epoch in planted]
        matches = [m for m in builders[-1].matches if m.epoch in planted]
        assert matches  # the planted epochs were matched against the map
    assert tied["off"]
    assert not tied["tracked"]
    assert all(m.verdict == "inconsistent" for m in matches)


def _brute_candidates(builder: loops.LoopClosingBuilder, k: int) -> tuple[list[int], int | None]:
    """The candidate rule of :meth:`LoopClosingBuilder._candidates`, one landmark at a time."""
    c, position = builder.config, builder.poses[k][:3, 3]
    walls, ground, ground_epoch = {}, None, -1
    for j, lm in builder.landmarks.items():
        if lm.last_seen is None:
            continue
        centre, radius = builder._extent_of(j)
        gap = float(np.linalg.norm(centre - position) - radius)
        e, nz = lm.last_seen[0], abs(lm.plane_world[2])
        if gap > c.loop_radius_m:
            continue
        if nz >= loops.GROUND_COS and e > ground_epoch:
            ground, ground_epoch = j, e
        elif nz <= loops.WALL_SIN and e <= k - c.loop_min_gap_epochs:
            walls[j] = gap
    kept = builder._distinct(sorted(walls))
    return sorted(sorted(kept, key=lambda j: (walls[j], j))[: c.loop_max_candidates]), ground


def test_the_candidates_are_those_of_the_rule(problem, monkeypatch):
    """The map's arrays (refreshed as landmarks are seen) select what the rule does."""
    _, planes, relatives = problem
    original = loops.LoopClosingBuilder._candidates
    compared = []

    def checked(self, k):
        out = original(self, k)
        assert out == _brute_candidates(self, k), k
        compared.append(len(out[0]))
        return out

    monkeypatch.setattr(loops.LoopClosingBuilder, "_candidates", checked)
    cfg = _config(True).updated({"smoothing.loop_max_candidates": 3})
    smooth_batch(planes, relatives, cfg)
    assert max(compared) == 3 and min(compared) == 0  # truncated, and empty before the lap
