"""The motion inside the epoch measured point by point (``sweep_refine``)."""

from __future__ import annotations

from typing import Literal

from pydantic import ConfigDict, Field

from planodom.config.section import Section


class SweepRefineConfig(Section):
    """Passes that measure the motion inside every epoch against the planes of the epoch
    before and run the odometry again on the points deskewed by it, point by point
    (:mod:`planodom.odometry.sweep_refine`); for scans whose points carry times (a 2D
    rig's sweeps). Off by default (``passes: 0``): docs/RESULTS.md, "The motion inside
    the epoch", has the figures."""

    model_config = ConfigDict(allow_inf_nan=False)

    passes: int = Field(0, ge=0, le=5)
    """Measure-and-re-run passes after the odometry (0: off)."""
    degree: int = Field(2, ge=0, le=6)
    """Degree of the polynomial in time of the rotation's correction to the curve through
    the epoch poses (a rotation vector): 3 follows a turn rate whose change itself
    changes inside the epoch (the curve's own degree, ``odometry.deskew_order``)."""
    translation_degree: int = Field(1, ge=0, le=6)
    """Degree of the translation's correction: 1 (an offset and a velocity) for a vehicle
    whose speed changes slowly over an epoch; higher degrees let the few planes of a 2D
    rig's epoch pull the translation along their own errors."""
    gate_m: float = Field(0.1, gt=0)
    """A point is measured against the nearest reference plane within this distance (m):
    the curve's deskewing moves points by under 2 cm on the simulated 2D-rig worlds, plus
    three sigmas of 2 cm range noise."""
    margin_m: float = Field(1.0, ge=0)
    """... and only where it projects within this distance (m) of the reference plane's
    support (the vehicle moves 0.2-0.4 m an epoch, and each epoch sees a wall further)."""
    min_points: int = Field(50, ge=7)
    """Fewer points on reference planes than this: the epoch keeps its deskewing."""
    prior_rotation_deg: float = Field(1.0, gt=0)
    """Sigma (deg) of the zero-mean prior of each rotation coefficient of the correction:
    it only holds the directions the points leave open (the curve's rotation over an
    epoch is off by hundredths of a degree)."""
    prior_translation_m: float = Field(0.1, gt=0)
    """Sigma (m) of the prior of each translation coefficient (as the rotation's)."""
    prior: Literal["fixed", "twist"] = "fixed"
    """``fixed``: the priors above on every coefficient, the reference planes taken as
    exact; ``twist``: a MAP estimate (:mod:`planodom.odometry.sweep_prior`): the
    coefficients of degree 1 and up get the run's twist change over half the epoch as
    their sigma, and each reference plane's error (its fit covariance, and its
    deskewing Jacobian's share of the twist change) is an unknown with that prior."""
    guard: Literal["off", "streaming"] = "off"
    """``streaming``: after the passes, an epoch where the last pass did not converge (its
    status worse than the streaming pass's, or its step off the one of the poses its
    motion was measured along by more than ``odometry.deskew_rate_tolerance_deg_s`` /
    ``deskew_speed_tolerance_mps``, or no motion measured) keeps the streaming pass's
    estimate (:func:`planodom.odometry.splice.unconverged`, as ``odometry.
    deskew_pass_guard`` does for the deskewing passes); ``off``: the last pass's."""
