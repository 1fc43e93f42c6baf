"""``smoothing.loop_factor_deskew``: the loop-candidate factors alone take both epochs'
deskewing error (planodom.smoothing.noise.loop_deskew_model), on the synthetic closed loop
of tests/smoothing/test_loop_closure.py."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.errors import ConfigError
from planodom.smoothing.batch import smooth_batch
from planodom_factors.pose5 import pose5_error
from tests.smoothing.test_loop_candidates import _candidates_only
from tests.smoothing.test_loop_closure import _loop_problem


@pytest.fixture(scope="module")
def problem():
    """The loop with its consecutive steps jittered (1 mrad, 1 cm, seeded): the synthetic
    motion is constant, and a constant twist has no deskewing error to add."""
    truth, planes, relatives = _loop_problem()
    rng = np.random.default_rng(5)
    jittered = []
    for r in relatives:
        if r.delta == 1 and r.translation_observed:
            P = np.eye(4)
            P[:3, :3] = Rotation.from_rotvec(rng.normal(0, 1e-3, 3)).as_matrix()
            P[:3, 3] = rng.normal(0, 0.01, 3)
            r = replace(r, T_prev_curr=np.asarray(r.T_prev_curr, dtype=float) @ P)
        jittered.append(r)
    return truth, planes, jittered


def _deskew_covariance(relatives, epoch: int) -> np.ndarray:
    """(6, 6) by hand: a third of the mean square of the changes of motion (rotation
    vector, translation of the delta = 1 steps) at the anchors within 2 epochs of
    ``epoch`` whose two steps are known (the model's documented estimate)."""
    motion = {
        r.curr: np.concatenate([Rotation.from_matrix(r.T_prev_curr[:3, :3]).as_rotvec(),
                                r.T_prev_curr[:3, 3]])
        for r in relatives if r.delta == 1 and r.translation_observed
    }  # fmt: skip
    changes = [motion[a + 1] - motion[a] for a in range(epoch - 2, epoch + 3)
               if a in motion and a + 1 in motion]  # fmt: skip
    return np.diag(np.mean(np.square(changes), axis=0) / 3.0)


def _numeric_jacobians(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(5, 6) each: the factor error's derivatives by central differences, each pose
    perturbed on the right by (rotation vector, translation), at the measured pose."""
    out = []
    for side in (0, 1):
        H = np.zeros((5, 6))
        for i in range(6):
            cols = []
            for h in (1e-6, -1e-6):
                d = np.zeros(6)
                d[i] = h
                P = np.eye(4)
                P[:3, :3] = Rotation.from_rotvec(d[:3]).as_matrix()
                P[:3, 3] = d[3:]
                poses = [np.eye(4), T.copy()]
                poses[side] = poses[side] @ P
                cols.append(pose5_error(T, poses[0], poses[1])[0])
            H[:, i] = (cols[0] - cols[1]) / 2e-6
        out.append(H)
    return out[0], out[1]


def test_loop_factors_take_both_epochs_deskewing_error(problem):
    truth, planes, relatives = problem
    off = smooth_batch(planes, relatives, _candidates_only())
    on = smooth_batch(
        planes,
        relatives,
        _candidates_only().updated({"smoothing.loop_factor_deskew": "both_epochs"}),
    )
    before = {(f.epoch, f.old): f for f in off.loop_factors}
    assert len(on.loop_factors) >= 2 and {(f.epoch, f.old) for f in on.loop_factors} == set(before)
    for f in on.loop_factors:
        H_old, H_curr = _numeric_jacobians(f.T_old_curr)
        added = H_old @ _deskew_covariance(relatives, f.old) @ H_old.T
        added += H_curr @ _deskew_covariance(relatives, f.epoch) @ H_curr.T
        assert np.trace(added) > 0  # the synthetic steps change: a real error to add
        np.testing.assert_allclose(
            f.covariance - before[(f.epoch, f.old)].covariance, added,
            rtol=1e-5, atol=1e-6 * np.max(np.diag(added)),
        )  # fmt: skip


def test_a_deskew_noise_model_keeps_its_own_loop_covariance(problem):
    """With ``deskew_noise`` set, the loop factors take that model's error, as before:
    the option adds nothing twice."""
    truth, planes, relatives = problem
    cfg = _candidates_only().updated({"smoothing.deskew_noise": "twist_change"})
    a = smooth_batch(planes, relatives, cfg)
    b = smooth_batch(
        planes, relatives, cfg.updated({"smoothing.loop_factor_deskew": "both_epochs"})
    )
    assert a.loop_factors
    for fa, fb in zip(a.loop_factors, b.loop_factors, strict=True):
        np.testing.assert_array_equal(fa.covariance, fb.covariance)


def test_a_bad_value_is_refused():
    with pytest.raises(ConfigError, match="loop_factor_deskew"):
        _candidates_only().updated({"smoothing.loop_factor_deskew": "yes"})
