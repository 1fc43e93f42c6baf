"""Which of an epoch's planes are narrow: no two of its scanners' lines cross at
``min_cross_angle_deg`` (the planes of ``extraction.narrow_seed_last_deg``'s seeds).

A plane seeded by two traces crossing under ``min_cross_angle_deg`` (down to 2 deg,
:mod:`.grouping`) has its tilt about the lines fixed by their small crossing only: a
direction error ``e`` of either line tilts it by about ``e / sin(angle)``. The fit's
covariance holds the range noise of its points, not the lines' shared errors (the
deskewing's residue along a line), which that angle amplifies alike. The odometry can then
keep such planes out of the rotation where pairs of other planes give it
(``odometry.narrow_rotation``, :mod:`planodom.odometry.rotation_planes`).

A group is narrow when the directions of its rings' lines, each ring's pooled over its
segments (the principal axis of the sum of the segments' own centred scatters: the lines'
common direction, whatever their displacement across each other between sweeps), cross
under ``sin_min_cross`` for every two rings. A group grown from a wide seed holds that
seed's two traces, of two rings whose lines cross as they do. (A first version judged
single segments within the seeds' direction-error bar; a short ground plane of a wide
seed, 44 points, then passed for narrow: world 284 at 2 cm, docs/RESULTS.md, NARROW4.)
"""

from __future__ import annotations

import numpy as np

from planodom.extraction.rig2d.segments import Segments


def narrow_groups(segs: Segments, groups: list[np.ndarray], sin_min_cross: float) -> np.ndarray:
    """(G,) bool: whether each group (segment indices) is narrow (module docstring); a
    group of one ring's lines is not."""
    out = np.zeros(len(groups), dtype=bool)
    for g, members in enumerate(groups):
        rings = np.unique(segs.ring[members])
        if len(rings) < 2:
            continue
        dirs = np.empty((len(rings), 3))
        for r, ring in enumerate(rings):
            pooled = segs.scatter[members[segs.ring[members] == ring]].sum(axis=0)
            dirs[r] = np.linalg.eigh(pooled)[1][:, -1]  # the largest eigenvalue's axis
        sin = np.linalg.norm(np.cross(dirs[:, None, :], dirs[None, :, :]), axis=2)
        out[g] = not bool(np.any(sin >= sin_min_cross))
    return out
