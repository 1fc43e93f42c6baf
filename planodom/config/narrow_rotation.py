"""Whether narrow planes give the rotation (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from planodom.config.section import Section


class NarrowRotationConfig(Section):
    """Whether the planes of narrow seeds may seed and vote on the rotation."""

    narrow_rotation: Literal["all", "last"] = "all"
    """``last``: the LDA pairs that hold a narrow plane (its scanners' lines crossing
    under ``extraction.min_cross_angle_deg``, from ``extraction.narrow_seed_last_deg``'s
    seeds: :mod:`planodom.extraction.rig2d.narrow`) seed and vote on the rotation, and
    the translation consensus built on them, only when no pair without one is left
    (:mod:`planodom.odometry.rotation_planes`); the refinement's translation uses every
    associated plane, weighted by its covariance, either way. A narrow plane's tilt about
    its lines is fixed by their small crossing: the lines' shared errors (the
    deskewing's residue) tilt it by their size over the crossing's sine, which its fit
    covariance does not hold, and the rotation of one pair takes its normal in full.
    On the paper loop the ATE that ``narrow_seed_last_deg`` adds came from the rotation
    of the steps with a narrow plane, their translation lowered it. ``all``: every pair
    (default): with ``last`` and ``narrow_seed_last_deg: 0.5`` the rule failed
    (docs/RESULTS.md, NARROW4): world 312 at 6 mm 5.9 -> 15.0 m, random-outdoor at
    sigma 0 0.06 -> 0.43 m, random-indoor at sigma 0 1.42 -> 1.61 m."""
