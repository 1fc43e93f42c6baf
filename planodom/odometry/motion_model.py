"""The motion model of the pairwise odometry's prediction (``odometry.motion_model``).

A wheeled vehicle whose base frame is its own (x forward, z up) moves along its forward
axis: over a step its body-frame linear velocity has no lateral (y) and no vertical (z)
component, up to the slip and the suspension's heave. The constant-velocity prediction
repeats the measured velocity whole; where a stretch of degenerate epochs (the ground
and one wall) does not measure a horizontal direction, what the prediction carries into
it is all that direction gets (``odometry.refine_unmeasured: prediction``), and a
lateral velocity measured wrong before the stretch is carried to its end (issue 11:
generalisation world 118 at 2 cm, a sideways 1.5-2.9 m/s held over 30 epochs).
``nonholonomic`` predicts no lateral velocity (the vertical one is kept: the ground
measures it, and a base that pitches on its suspension moves along its own z).
"""

from __future__ import annotations

import numpy as np

from planodom.config import PlanodomConfig
from planodom.odometry.relative import RelativePose


def predicted_motion(twist: np.ndarray, model: str) -> np.ndarray:
    """(6,) the twist (rad/s, m/s; angular rate first, then linear velocity, body frame)
    predicted under ``model`` from the constant-velocity prediction ``twist`` (6,):
    ``"constant_velocity"``: ``twist`` itself; ``"nonholonomic"``: a copy with the lateral
    (y) linear velocity zero."""
    if model == "constant_velocity":
        return twist
    if model != "nonholonomic":
        raise ValueError(f"unknown motion model {model!r}")
    out = np.array(twist, dtype=np.float64, copy=True)
    out[4] = 0.0
    return out


def vertical_prediction(config: PlanodomConfig, relative: RelativePose) -> tuple[str, str, str]:
    """The last three arguments of :func:`planodom.odometry.trend.predicted_twist` for a
    step ``relative``: ``planemap.prediction``, ``odometry.motion_model``, and what its
    vertical velocity counts as (``odometry.unobserved_vertical`` where z was not
    observed, else "held": its own)."""
    vertical = "held" if relative.z_observed else config.odometry.unobserved_vertical
    return config.planemap.prediction, config.odometry.motion_model, vertical
