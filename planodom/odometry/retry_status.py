"""Which prior-free retries may replace the solve under the prior (``odometry.retry_accepts``).

The solver (:func:`planodom.odometry.solver.estimate_relative_pose`) solves again without
the prior's bounds when the solve under them is not OK. Without the bounds, across a gap
of ``g`` epochs, the association spans every rotation up to ``association.max_rotation_deg``
times ``g``: a degenerate retry's rotation then rests on one pair of planes, which another
pair of the same dihedral angle can alias (docs/RESULTS.md, RETRY15). An OK retry is
checked by the planes of three normal directions and may always replace the solve.
"""

from __future__ import annotations


def degenerate_kept(accepts: str, gap: int) -> bool:
    """Whether a degenerate prior-free retry of a step across ``gap`` epochs may replace
    the solve under the prior, for ``odometry.retry_accepts`` ``accepts``: with
    "degenerate", or with "across_gap" over one epoch (its bounds the per-epoch ones, not
    widened with a gap); never with "ok"."""
    return accepts == "degenerate" or (accepts == "across_gap" and gap <= 1)
