"""The deskewing error in the odometry's plane covariances (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class PlaneDeskewNoiseConfig(Section):
    """Whether an extracted plane's covariance holds its deskewing error (``odometry``)."""

    plane_deskew_noise: Literal["off", "twist"] = "off"
    """Pairwise pipelines (not ``map``: ``planemap.deskew_variance`` there): ``twist`` adds
    to the covariance of every plane of an epoch deskewed with a twist the error that
    twist's uncertainty leaves in it, ``J Sigma J^T`` with ``J`` the plane's first-order
    change with the twist (``Plane.deskew_jacobian`` times the epoch's span, switched on
    in the extraction) and ``Sigma`` the twist's covariance from its sigmas
    (:mod:`planodom.odometry.twist_sigma`: each a root of a trace, so ``sigma^2 / 3`` per
    axis), :mod:`planodom.odometry.plane_deskew`. The association, the consensus's
    refinement, the steps' covariances and the gates then see it, and so do the smoothing's
    factors built from these planes and steps. ``off`` (default): the fit's covariance
    alone. An epoch not deskewed (taken at one instant, or extracted without a twist) gets
    nothing."""
