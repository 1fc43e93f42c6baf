"""Chains of steps: the inverse of one without inverting the identity each epoch (SPEED2D8),
and a run's steps and its poses chained again through changed ones (the passes after a run:
:mod:`.bridge_ends`, :mod:`.degenerate_ends`)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import invert_transform, orthonormalised

#: ``invert_transform(np.eye(4))`` (its -0.0 included), once: a reference one epoch back
_EYE_INVERTED = invert_transform(np.eye(4))
_EYE_INVERTED.flags.writeable = False


def inverse_chain(T_ref_last: np.ndarray, steps: list[np.ndarray]) -> np.ndarray:
    """``invert_transform(T_ref_last)``, (4, 4), where ``T_ref_last`` is the product of
    ``steps`` (the identity when there are none, then returned as a read-only constant)."""
    return invert_transform(T_ref_last) if steps else _EYE_INVERTED


def run_steps(poses: np.ndarray) -> np.ndarray:
    """(E, 4, 4) the steps ``T_{k-1}_k`` of ``poses`` (E, 4, 4), the identity first."""
    steps = np.empty((len(poses), 4, 4))
    steps[0] = np.eye(4)
    steps[1:] = invert_transform(poses[:-1]) @ poses[1:]
    return steps


def rechained(poses: np.ndarray, steps: np.ndarray, first: int) -> np.ndarray:
    """A copy of ``poses`` (E, 4, 4) chained again through ``steps`` (E, 4, 4) from epoch
    ``first`` on: ``out[k] = orthonormalised(out[k - 1] @ steps[k])``."""
    out = poses.copy()
    for k in range(first, len(poses)):
        out[k] = orthonormalised(out[k - 1] @ steps[k])
    return out
