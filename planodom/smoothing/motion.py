"""Robust motion guesses of the graph builder (:mod:`planodom.smoothing.graph`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

#: ``smoothing.fallback_step`` "medoid": the measured steps the fallback's mean is taken from.
FALLBACK_STEPS = 5


def medoid_transform(transforms: Sequence[np.ndarray]) -> np.ndarray:
    """The (4, 4) transform of ``transforms`` (N >= 1) with the least summed distance to the
    others (metres plus radians times 10 m): one outlier among three or more cannot be it."""
    t = np.stack([c[:3, 3] for c in transforms])
    R = np.stack([c[:3, :3] for c in transforms])
    cos = np.clip((np.einsum("aij,bij->ab", R, R) - 1.0) / 2.0, -1.0, 1.0)
    dist = np.linalg.norm(t[:, None] - t[None], axis=2) + 10.0 * np.arccos(cos)
    return np.asarray(transforms[int(np.argmin(dist.sum(axis=1)))])
