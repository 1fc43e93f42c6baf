"""The inverse of a chain of steps, without inverting the identity each epoch (SPEED2D8)."""

from __future__ import annotations

import numpy as np

from planodom.geometry import invert_transform

#: ``invert_transform(np.eye(4))`` (its -0.0 included), once: a reference one epoch back
_EYE_INVERTED = invert_transform(np.eye(4))
_EYE_INVERTED.flags.writeable = False


def inverse_chain(T_ref_last: np.ndarray, steps: list[np.ndarray]) -> np.ndarray:
    """``invert_transform(T_ref_last)``, (4, 4), where ``T_ref_last`` is the product of
    ``steps`` (the identity when there are none, then returned as a read-only constant)."""
    return invert_transform(T_ref_last) if steps else _EYE_INVERTED
