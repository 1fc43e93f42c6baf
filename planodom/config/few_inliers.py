"""Few inlier planes that fix every direction (a base of ``PlanemapConfig``).

In its own module as :mod:`.lead_weights` is; the rule is
:mod:`planodom.odometry.planemap.few_inliers`, the count it relaxes
``planemap.min_inliers``.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from planodom.config.lead_weights import LeadWeightsConfig


class FewInliersConfig(LeadWeightsConfig):
    """Whether an epoch with fewer than ``min_inliers`` inlier planes may be resolved."""

    few_inliers: Literal["unresolved", "observed"] = "unresolved"
    """A registration with fewer than ``min_inliers`` but at least ``few_inliers_floor``
    inlier planes: ``unresolved``, left unresolved (as every such count before);
    ``observed``, resolved when those planes' information fixes every direction, each
    rotation axis' 1-sigma within ``unobserved_rotation_deg`` and each translation
    direction's (the vertical too) within ``unobserved_translation_m`` (the limits the
    status is judged by; an epoch they judge partly observed stays unresolved here). Lidar
    world 335 (indoor, 64 beams, no ring or time: floor, ceiling, two walls and an end
    wall, 5 planes an epoch in its corridor) at 6 mm: an extraction deskewed with its twist
    gave those 5 planes, all inliers, rotation 1-sigma 0.03 / 0.13 / 0.04 deg, and was
    left unresolved; the odometry then took whichever other extraction reached 6 planes
    (most often the one without the twist, its swaying walls in fragments), and one epoch
    none did: the map rebuilt from one scan, 20 epochs of roll and pitch errors of
    0.1-0.2 deg alternating in sign, 76 % of the run's squared rotation error (LIDAR335 in
    docs/RESULTS.md)."""
    few_inliers_floor: Annotated[int, Field(ge=3)] = 4
    """Fewest inlier planes ``few_inliers: observed`` resolves an epoch with: three
    planes with independent normals fix the six degrees of freedom, a fourth leaves one
    redundant constraint for the robust kernel to find an outlier by (4: the value
    ``min_inliers`` was measured with on world 37's corridors, see there)."""
