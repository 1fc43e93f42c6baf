"""Epochs the odometry could not measure, and relative poses with a measured prior."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.geometry import invert_transform, make_transform, se3_log
from planodom.odometry import Status
from planodom.smoothing import smooth_batch
from planodom.smoothing.run import relative_poses
from planodom.smoothing.synthetic import make_sequence

GAUSSIAN = SmoothingConfig(robust_kernel="none", deskew_noise="none", batch_initial="odometry")


def test_unresolved_epochs_follow_the_odometrys_prediction() -> None:
    seq = make_sequence(20, seed=9, vertical_sigma=0.0)
    # Nothing but delta = 1 relative poses, no planes: an unresolved epoch's pose rests on
    # its fallback factor alone. Epochs 8..11 unresolved, their T_prev_curr the
    # odometry's prediction (here the true step); epoch 15 has no relative pose at all.
    relatives = [
        replace(r, status=Status.UNRESOLVED) if 8 <= r.curr <= 11 else r
        for r in seq.relatives
        if r.delta == 1 and r.curr != 15
    ]
    steps = invert_transform(seq.poses[:-1]) @ seq.poses[1:]  # steps[k - 1]: into k
    # the last measured step repeated (constant velocity) would be off by 0.7-1.5 deg
    off = se3_log(invert_transform(steps[6])[None] @ steps[7:11])
    assert np.all(np.linalg.norm(off[:, :3], axis=1) > 0.01)
    last = GAUSSIAN.model_copy(update={"fallback_step": "last"})
    result = smooth_batch([[] for _ in range(20)], relatives, last)
    assert result.stats.unresolved_epochs == [8, 9, 10, 11, 15]
    est = invert_transform(result.poses[:-1]) @ result.poses[1:]
    for k in range(1, 20):  # rotation and horizontal translation (5-DoF factors)
        expected = steps[13] if k == 15 else steps[k - 1]  # 15: the last measured step
        np.testing.assert_allclose(est[k - 1][:3, :3], expected[:3, :3], atol=1e-6)
        np.testing.assert_allclose(est[k - 1][:2, 3], expected[:2, 3], atol=1e-6)


def test_a_measured_prior_is_not_dropped_for_a_prior_free_consensus() -> None:
    seq = make_sequence(12, seed=1, step_m=0.5)
    config = PlanodomConfig()
    guess = seq.poses.copy()  # a guess 1.5 m off from epoch 6 on (beyond the prior bounds)
    guess[6:] = guess[6:] @ make_transform(np.eye(3), [1.5, 0.0, 0.0])[None]

    def errors(bridged: set[int] | None) -> dict[tuple[int, int], tuple[Status, float]]:
        out = {}
        for r in relative_poses(seq.planes, config, [2], guess, bridged=bridged):
            true = invert_transform(seq.poses[r.prev]) @ seq.poses[r.curr]
            out[r.prev, r.curr] = (
                r.status,
                float(np.linalg.norm(r.T_prev_curr[:2, 3] - true[:2, 3])),
            )
        return out

    measured, across_bridge, as_configured = errors(set()), errors({6}), errors(None)
    for pair in ((4, 6), (5, 7)):  # spanning the jump
        assert measured[pair][0] is not Status.OK  # the prior's bounds hold: no translation
        assert across_bridge[pair][0] is Status.OK and across_bridge[pair][1] < 1e-9
        assert as_configured[pair] == across_bridge[pair]
    assert measured[(2, 4)] == across_bridge[(2, 4)] == (Status.OK, measured[(2, 4)][1])
    assert measured[(2, 4)][1] < 1e-9


def test_rotation_only_start_carries_the_first_measured_step_back() -> None:
    seq = make_sequence(12, seed=4, vertical_sigma=0.0)
    # A run that starts at speed with rotation-only epochs 1..3 (the odometry knew no
    # velocity yet), no planes: their translation rests on the fallback factors alone.
    relatives = [
        replace(r, status=Status.DEGENERATE) if r.curr <= 3 else r
        for r in seq.relatives
        if r.delta == 1
    ]
    steps = invert_transform(seq.poses[:-1]) @ seq.poses[1:]  # steps[k - 1]: into k
    first = smooth_batch([[] for _ in range(12)], relatives, GAUSSIAN)
    still = smooth_batch(
        [[] for _ in range(12)],
        relatives,
        SmoothingConfig.model_validate({**GAUSSIAN.model_dump(), "fallback_start": "identity"}),
    )
    for result, expected in ((first, steps[3][:2, 3]), (still, np.zeros(2))):
        est = invert_transform(result.poses[:-1]) @ result.poses[1:]
        for k in range(1, 4):  # the rotation measured, the translation the fallback's
            np.testing.assert_allclose(est[k - 1][:3, :3], steps[k - 1][:3, :3], atol=1e-6)
            np.testing.assert_allclose(est[k - 1][:2, 3], expected, atol=1e-6)
        for k in range(4, 12):  # measured
            np.testing.assert_allclose(est[k - 1][:2, 3], steps[k - 1][:2, 3], atol=1e-6)
    assert np.linalg.norm(steps[3][:2, 3]) > 0.5  # identity is a wrong prediction here


def test_one_wrong_step_before_a_rotation_only_stretch_is_not_repeated() -> None:
    """Constant velocity along x; epoch 6's measured step 0.25 m too long, epochs 7..18
    rotation-only (translation unmeasured). "last" repeats the wrong step in every
    fallback (12 x 0.25 m along the track, the true error of the chained guess), "medoid"
    takes the true step from the last five measured ones: only epoch 6's own error
    remains (ground truth: the true poses)."""
    seq = make_sequence(26, seed=3, vertical_sigma=0.0)
    steps = invert_transform(seq.poses[:-1]) @ seq.poses[1:]
    relatives = []
    for r in seq.relatives:
        if r.delta != 1:
            continue
        if r.curr == 6:
            r = replace(r, T_prev_curr=r.T_prev_curr @ make_transform(np.eye(3), [0.25, 0, 0]))
        elif 7 <= r.curr <= 18:
            r = replace(r, status=Status.DEGENERATE)
        relatives.append(r)
    # the sequence's steps barely change: the medoid of any five is within 5 cm of each
    assert np.ptp(np.linalg.norm(steps[:, :2, 3], axis=1)) < 0.05
    end = {}
    for mode in ("last", "medoid"):
        config = GAUSSIAN.model_copy(update={"fallback_step": mode})
        result = smooth_batch([[] for _ in range(26)], relatives, config)
        end[mode] = float(np.linalg.norm(result.poses[-1][:2, 3] - seq.poses[-1][:2, 3]))
    assert end["last"] > 2.5
    assert end["medoid"] < 0.25 + 12 * 0.05
