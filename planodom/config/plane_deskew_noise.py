"""The deskewing error in the odometry's plane covariances (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class PlaneDeskewNoiseConfig(Section):
    """Whether an extracted plane's covariance holds its deskewing error (``odometry``)."""

    plane_deskew_noise: Literal["off", "twist", "change"] = "off"
    """Pairwise pipelines (not ``map``: ``planemap.deskew_variance`` there): add to the
    covariance of every plane of an epoch deskewed with a twist the error a twist error
    leaves in it, ``J Sigma J^T`` with ``J`` the plane's first-order change with the
    twist (``Plane.deskew_jacobian`` times the epoch's span, switched on in the
    extraction; :mod:`planodom.odometry.plane_deskew`). ``twist``: ``Sigma`` from the
    sigmas of the twist the epoch was deskewed with (:mod:`planodom.odometry.twist_sigma`:
    each a root of a trace, ``sigma^2 / 3`` per axis); ``change``: from the run's change of
    the twist over one epoch, noise included (``TwistUncertainty.raw_change``), as the
    smoothing's ``deskew_noise`` sizes it. The association, the refinement, the steps'
    covariances and the gates then see it, and so do the smoothing's factors built from
    these planes and steps. ``off`` (default): the fit's covariance alone. An epoch not
    deskewed (taken at one instant, or extracted without a twist) gets nothing."""
