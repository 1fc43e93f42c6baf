"""The motion model of the streaming odometry's prediction (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class MotionModelConfig(Section):
    """What the predicted twist assumes of the platform (field of ``odometry``)."""

    motion_model: Literal["constant_velocity", "nonholonomic", "nonholonomic_degenerate"] = (
        "constant_velocity"
    )
    """The twist predicted for the next epoch (deskewing, prior, bridge, and, with
    ``refine_unmeasured: prediction``, what a degenerate step's unmeasured direction
    keeps): ``constant_velocity``: the recent twist as it was measured (its angular rate,
    the median linear velocity of the recent measured steps); ``nonholonomic``: the same
    with the linear velocity along the base's forward axis (x) only, its lateral (y) and
    vertical (z) components zero, as a wheeled vehicle whose base frame is its own
    (x forward, z up) moves (:func:`planodom.odometry.motion_model.predicted_motion`).
    Never for a hand-held sensor. Aimed at degenerate stretches (the ground and one wall)
    whose unmeasured horizontal direction the prediction carries: the 2D rig's
    generalisation worlds 118 (2 cm) and 108 (6 mm). Off by default: see docs/RESULTS.md
    ("Non-holonomic prediction") for what it did over the 2D-rig worlds."""
