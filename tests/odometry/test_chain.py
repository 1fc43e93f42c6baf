"""The inverse of a chain of steps (planodom.odometry.chain)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import invert_transform, transform_from_rpy_xyz
from planodom.odometry.chain import inverse_chain


def test_the_inverse_of_no_steps_is_invert_transforms_of_the_identity():
    """The constant a reference one epoch back uses: invert_transform's bytes (its -0.0
    translation included); with steps, invert_transform of their product."""
    eye = np.eye(4)
    assert inverse_chain(eye, []).tobytes() == invert_transform(eye).tobytes()
    T = transform_from_rpy_xyz(0.1, -0.05, 0.3, 1.0, -2.0, 0.5)
    assert inverse_chain(T, [T]).tobytes() == invert_transform(T).tobytes()
    np.testing.assert_allclose(inverse_chain(T, [T]) @ T, eye, atol=1e-15)
