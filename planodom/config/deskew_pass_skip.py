"""Which epochs a deskewing pass extracts again (fields of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.stated_deskew_noise` is.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.section import Section


class DeskewPassSkipConfig(Section):
    """Whether the deskewing passes keep the streaming pass's extraction of an epoch."""

    deskew_pass_skip: Literal["none", "twist", "planes"] = "none"
    """``odometry.deskew_passes`` > 0: a pass extracts an epoch again only where the twist
    its curve gives over the epoch's sweep (the secant of the curve over the points'
    times) differs from the twist the streaming pass deskewed the epoch with by more than
    a chi-square test at ``deskew_pass_skip_quantile`` allows; elsewhere the pass takes
    the streaming pass's planes, moved to the pass's reference time along the curve
    (:mod:`planodom.odometry.pass_skip`). ``twist``: the difference against the curve's
    own uncertainty (the variance of the step the sweep lies in, the odometry's
    covariance, over the step's time). ``planes``: the move of the epoch's planes the
    difference implies (their deskewing Jacobians, switched on in the extraction)
    against their fit covariances. ``none`` (default): every epoch the curve deskews is
    extracted again."""

    deskew_pass_skip_quantile: Annotated[float, Field(gt=0, lt=1)] = 0.99
    """``deskew_pass_skip`` ``twist`` or ``planes``: the chi-square quantile of the test (one DoF
    per tangent component with a finite variance): an epoch whose streaming twist is
    the true one is extracted again with probability one minus this, if the stated
    covariances are right (a probability, not fitted to a scene)."""
