"""The guard of ``odometry.refinement: moments`` (a field of ``OdometryConfig``).

A base of :class:`planodom.config.odometry.OdometryConfig`, in its own module as
:mod:`.odometry_guards` is.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from planodom.config.association import Positive
from planodom.config.pair_rotation import PairRotationConfig


class MomentRefineConfig(PairRotationConfig):
    """How far ``refinement: moments`` may move the consensus (field of ``odometry``)."""

    moment_gate_chi2: Positive | None = None
    """``refinement: moments``: the refined pose is kept only when its change from the
    consensus's (roll, pitch, yaw, x, y) has a squared Mahalanobis distance under the
    consensus's covariance of at most this (:mod:`planodom.odometry.moment_refine`); None:
    the association's inlier bounds only. 20.5 is the chi-square quantile 0.999 of 5 DoF
    (a probability, not fitted to a scene); on the 2D rig, refinements that moved the
    consensus by 50 or more were worse against the truth on 12 of 17 (worlds 154 and 158),
    those below 15 better on most (docs/RESULTS.md MOMENTS2). Off: by its rule it did not
    become the default (worlds 160-198)."""

    moment_translation: Literal["moments", "offsets"] = "moments"
    """``refinement: moments``: where the refined step's translation comes from.
    ``"moments"``: the moments' solve (rotation and translation together). ``"offsets"``:
    the solve's rotation, then the translation refinement's fit of the plane offsets under
    it (:func:`planodom.odometry.refine.plane_translation`, the default pipeline's): an
    epoch's offset error then enters the steps into and out of it with opposite signs,
    where the moments' centroid residuals weigh one epoch's normal error by the other
    epoch's centroids (docs/RESULTS.md MOMENTS3). Off: by its rule it did not become the
    default (worlds 160-198: ATE 0.83 / 0.80 of the default's at 6 mm / 2 cm in geometric
    mean, but world 166 3.5-3.8x worse and the per-step xy no better)."""

    moment_passes: Literal["all", "deskew_passes"] = "all"
    """``refinement: moments``: in which passes of a run over scans with point times.
    ``"all"``: the streaming pass and the deskewing passes (``deskew_passes``);
    ``"deskew_passes"``: only the deskewing passes, the streaming pass refining the
    translation (``refinement: translation``), so that its twists, which deskew its next
    epochs and choose their planes, are the default's (with ``deskew_passes: 0`` the
    moments are then not used). On world 386 at 6 mm the moments in the streaming pass
    sent a stretch of few planes down other extractions whose OK steps were 0.5-2.5 deg
    off (docs/RESULTS.md DESKEW13). Off (``"all"``): measured on seen worlds only."""

    moment_extractions: Literal["all", "committed"] = "all"
    """``refinement: moments``: which of an epoch's extractions are refined
    (:mod:`planodom.odometry.moment_when`). ``"all"``: every extraction the deskewing policy
    tries, as it is estimated, the policy choosing among refined steps (254 on world 498's
    150 epochs); ``"committed"``: only the one the policy commits, chosen among the
    consensus's steps as by the default; its refined step still sets the next epoch's
    deskewing twist. Off (``"all"``): measured on worlds 560-678 only (docs/RESULTS.md
    ROT2D17)."""

    moment_after_ok: int = Field(0, ge=0)
    """``refinement: moments``: refine an epoch's step only when this many steps
    before it were OK and none of the last this many epochs follows a gap in the epoch
    times (a start, and the epochs after an unresolved or degenerate stretch, keep the
    consensus's step; :mod:`planodom.odometry.moment_when`); 0: every OK step. Off (0):
    measured on worlds 560-678 only (docs/RESULTS.md ROT2D17)."""
