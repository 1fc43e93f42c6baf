"""The deskewing error in the covariances the odometry states (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.plane_deskew_noise` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class StatedDeskewNoiseConfig(Section):
    """Whether the steps' stated covariances hold both epochs' deskewing error (``odometry``)."""

    stated_deskew_noise: Literal["off", "shared"] = "off"
    """``shared``: after the run, every resolved step's stated (roll, pitch, yaw, x, y)
    covariance (``RelativePose.covariance``, ``covariances.npz``'s ``relative``) also
    holds both its epochs' deskewing errors, each one twist error shared by the epoch's
    planes: ``M_a Q_a M_a^T + M_b Q_b M_b^T``, ``M`` the change of the step fitted to its
    associated plane pairs when an epoch's planes move by their deskewing Jacobians
    (switched on in the extraction) and ``Q = span^2 Sigma``, ``Sigma`` the run's rms
    change of the twist between successive OK steps (:mod:`planodom.odometry.
    stated_deskew`). The smoothing's relative poses (delta 1..D) state it too. The
    estimate is the default's: the poses do not change. Not with ``smoothing.
    sandwich_relative_ends: both``, which models the same error in the sandwich. ``off``
    (default): the planes' fit covariances propagated alone."""
