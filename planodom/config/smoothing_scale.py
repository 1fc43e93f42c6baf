"""Configuration of the batch covariances' noise scale (planodom.smoothing.variance_components)."""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class CovarianceScaleConfig(Section):
    """The scale of the batch graph's noise models estimated from its own residuals
    (a part of :class:`~planodom.config.smoothing.SmoothingConfig`)."""

    covariance_scale: Literal["none", "posterior", "groups"] = "none"
    """Batch covariances: "none" the noise models as built; "posterior" one a posteriori
    variance factor of the measurements (relative poses, planes, loop factors: weighted
    squared residuals over their redundancy, with the priors, vertical and fallback
    pseudo-observations and the robust outliers at their own weight) multiplies their
    covariances; "groups" one factor per group (relative poses, planes, loop factors:
    Foerstner's variance component estimation). The poses' covariances are then those of
    the reweighted graph (planodom.smoothing.variance_components)."""
    covariance_scale_estimate: Literal["keep", "resolve"] = "keep"
    """With ``covariance_scale``: "keep" the estimate (only the covariances change);
    "resolve" Gauss-Newton on the reweighted graph (the covariance graph: robust inliers
    with their Gaussian twin, outliers under the kernel) from the estimate, the variance
    factors estimated again at each step."""
