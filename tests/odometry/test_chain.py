"""The inverse of a chain of steps (planodom.odometry.chain)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import invert_transform, transform_from_rpy_xyz
from planodom.odometry.chain import inverse_chain, rechained, run_steps


def test_the_inverse_of_no_steps_is_invert_transforms_of_the_identity():
    """The constant a reference one epoch back uses: invert_transform's bytes (its -0.0
    translation included); with steps, invert_transform of their product."""
    eye = np.eye(4)
    assert inverse_chain(eye, []).tobytes() == invert_transform(eye).tobytes()
    T = transform_from_rpy_xyz(0.1, -0.05, 0.3, 1.0, -2.0, 0.5)
    assert inverse_chain(T, [T]).tobytes() == invert_transform(T).tobytes()
    np.testing.assert_allclose(inverse_chain(T, [T]) @ T, eye, atol=1e-15)


def test_a_runs_steps_chain_back_to_its_poses_and_a_changed_step_moves_only_later_ones():
    """Poses from known steps (composed here, independently): ``run_steps`` gives them back;
    ``rechained`` through one changed step keeps the poses before it and moves the later
    ones by exactly that change."""
    S = [transform_from_rpy_xyz(0.01 * k, -0.02, 0.05 * k, 1.0, 0.1 * k, 0.0) for k in range(5)]
    poses = [np.eye(4)]
    for T in S:
        poses.append(poses[-1] @ T)
    P = np.array(poses)
    steps = run_steps(P)
    np.testing.assert_array_equal(steps[0], np.eye(4))
    np.testing.assert_allclose(steps[1:], np.array(S), atol=1e-12)
    changed = steps.copy()
    changed[3] = transform_from_rpy_xyz(0.0, 0.0, 0.2, 2.0, 0.0, 0.0)
    out = rechained(P, changed, 3)
    np.testing.assert_array_equal(out[:3], P[:3])
    np.testing.assert_allclose(out[3], P[2] @ changed[3], atol=1e-12)
    np.testing.assert_allclose(out[5], P[2] @ changed[3] @ S[3] @ S[4], atol=1e-12)
