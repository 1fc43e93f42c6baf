"""An unresolved epoch extracted once more with narrow seeds (``odometry.lost_narrow_seed_deg``).

The 2D rig's isoclinal scanner pairs draw two lines on a wall that cross at the angle
between the pair's scan planes as seen on that wall; in a corridor turned near 45 deg to
the heading that angle falls under ``extraction.min_cross_angle_deg`` and the wall seeds
no plane, so an epoch can keep only two parallel walls where the truth has six surfaces
(the 2D-rig world 570, docs/RESULTS.md GAP17). ``extraction.narrow_seed_last_deg`` seeds
such walls after every other seed, but as a default it changes epochs that resolve
without it (NARROW4). Here it is tried only on an epoch whose kept estimate is
unresolved, where the step is lost anyway: the default's every resolved step is left as
it is.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from planodom.geometry import Plane
from planodom.odometry.deskew import EpochEstimate
from planodom.odometry.extractor import Extractor, default_extractor
from planodom.odometry.relative import Status
from planodom.scan import Scan

if TYPE_CHECKING:
    from planodom.odometry.odometry import PlaneOdometry


def narrow_extractor(base: Extractor, degrees: float) -> Extractor:
    """``base`` with ``extraction.narrow_seed_last_deg`` raised to ``degrees`` (deg)."""

    def extract(scan: Scan, config: Any, **kwargs: Any) -> list[Plane]:
        if config.narrow_seed_last_deg < degrees:
            config = config.model_copy(update={"narrow_seed_last_deg": degrees})
        return base(scan, config, **kwargs)

    return extract


def narrow_if_lost(odo: PlaneOdometry, best: EpochEstimate, scan: Scan, t: float) -> EpochEstimate:
    """``best``, or when it is unresolved on a pairwise pipeline with
    ``odometry.lost_narrow_seed_deg`` above 0, the epoch ``scan`` (at time ``t``, s)
    extracted again with ``best``'s twist by ``odo``'s extractor with narrow seeds and
    estimated again, kept when its step resolves (degenerate or ok; the degenerate gate
    and the bounds of :meth:`PlaneOdometry._estimate` judge it as any step). A step the
    degenerate gate reported unresolved is left as it is."""
    degrees, lost = odo.config.odometry.lost_narrow_seed_deg, best.relative
    # a step the degenerate gate bridged had its planes: lost to the gate, not the extraction
    if degrees <= 0 or lost.status is not Status.UNRESOLVED or lost.inconsistent:
        return best
    if not odo.pairwise:  # the plane map's extraction has no narrow seeds
        return best
    base = default_extractor() if odo.extractor is None else odo.extractor
    odo.extractor = narrow_extractor(base, degrees)
    try:  # the same twist and sigma the epoch's extractions were made with
        again = odo._estimate_scan(
            scan, t, best.twist, prior_sigma=odo.twist_uncertainty.predicted()
        )
    finally:
        odo.extractor = base
    return again if again.relative.status.rank > best.relative.status.rank else best
