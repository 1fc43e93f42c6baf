"""Which of an epoch's planes are narrow: no two of its scanners' lines cross at
``min_cross_angle_deg`` (the planes of ``extraction.narrow_seed_last_deg``'s seeds).

A plane seeded by two traces crossing under ``min_cross_angle_deg`` (down to 2 deg,
:mod:`.grouping`) has its tilt about the lines fixed by their small crossing only: a
direction error ``e`` of either line tilts it by about ``e / sin(angle)``. The fit's
covariance holds the range noise of its points, not the lines' shared errors (the
deskewing's residue along a line), which that angle amplifies alike. The odometry can then
keep such planes out of the rotation where pairs of other planes give it
(``odometry.narrow_rotation``, :mod:`planodom.odometry.rotation_planes`).

A group is narrow when none of its segments of two different rings whose predicted
direction errors are within the seeds' bar (``max_seed_direction_error_deg``, as the
seeds') cross at ``sin_min_cross`` or more: a group grown from a wide seed holds that
seed's two traces, whose segments cross as they do.
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.rig2d.segments import Segments
from planodom.extraction.rig2d.traces import direction_error


def narrow_groups(
    segs: Segments,
    groups: list[np.ndarray],
    sigma_m: float,
    sin_min_cross: float,
    max_seed_err_rad: float,
) -> np.ndarray:
    """(G,) bool: whether each group (segment indices) is narrow (module docstring)."""
    out = np.zeros(len(groups), dtype=bool)
    err = direction_error(sigma_m, segs.count, segs.length)
    for g, members in enumerate(groups):
        m = members[err[members] <= max_seed_err_rad]
        if len(m) < 2:
            out[g] = True
            continue
        d, ring = segs.direction[m], segs.ring[m]
        sin = np.linalg.norm(np.cross(d[:, None, :], d[None, :, :]), axis=2)
        other = ring[:, None] != ring[None, :]
        out[g] = not bool(np.any(other & (sin >= sin_min_cross)))
    return out
