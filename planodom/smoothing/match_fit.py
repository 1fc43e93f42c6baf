"""How well a match's own pose lays its associated planes on their old partners (issue 14).

A re-identification of full rank fits its pose to all its pairs. One of rotation only
(one wall and the ground, :mod:`planodom.smoothing.loops`) is verified on its yaw alone,
yet each of its ties also states where the pose lies along the tied wall's normal: that
translation is checked by nothing. On the 2D-rig world 2 at 6 mm, after the odometry's
failure bent the map by about 37 degrees, 19 of its 20 wrong ties came from such
matches, their walls 2.9 to 3.1 m off their old partners at the match's pose (a room's
wall tied to a parallel wall 4.9 m away). :func:`misfit` measures that residual.

Written here, not taken from a library: a residual of the paper's plane association.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.geometry import Plane


def misfit(
    old: Sequence[Plane], curr: Sequence[Plane], pairs: np.ndarray, T_old_curr: np.ndarray
) -> float:
    """Largest offset residual (m) of the associated planes at the match's own pose.

    Args:
        old: planes of the old side (map or old epoch), in its frame.
        curr: planes of the current epoch, in its frame.
        pairs: (M, 2) int, (index into ``old``, index into ``curr``).
        T_old_curr: (4, 4) the current frame in the old one as the match places it.

    Returns:
        max over the pairs of ``|d_old - d_curr|`` with the current plane expressed in the
        old frame and oriented like its partner (0 without pairs), metres.
    """
    worst = 0.0
    for m, i in np.asarray(pairs, dtype=int).reshape(-1, 2):
        plane = curr[i].transformed(T_old_curr)
        sign = 1.0 if plane.normal @ old[m].normal >= 0 else -1.0
        worst = max(worst, abs(sign * plane.offset - old[m].offset))
    return worst
