"""Robust motion guesses of the graph builder (:mod:`planodom.smoothing.graph`)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.geometry import invert_transform

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


def measured_step_prior(poses: np.ndarray, translation_measured: Sequence[bool]) -> np.ndarray:
    """(E, 4, 4) ``poses`` (a chained odometry, ``T_world_base``) re-chained with every step
    into an epoch whose translation was not measured (``translation_measured[k]`` False:
    rotation-only or bridged) given the translation of the medoid of the last
    ``FALLBACK_STEPS`` measured steps (the last one while fewer than three are known, the
    odometry's own before any), its rotation kept.

    Why: the translation of a rotation-only result is whatever the solver's refinement
    left along the unobserved direction (on 2D-rig world 4 at 2 cm, 0.26-0.34 m off per
    9.4 cm step in a corridor), and a chain through it is the prior of the relative poses
    across that stretch (:func:`planodom.smoothing.run.relative_poses`): the end wall seen
    before and after was not associated, its landmark split, and the stretch behind it
    floated 0.18 m along the corridor. The measured steps around it are within 5 mm.
    """
    poses = np.asarray(poses, dtype=float)
    out = [poses[0]]
    steps: list[np.ndarray] = []
    for k in range(1, len(poses)):
        step = invert_transform(poses[k - 1]) @ poses[k]  # T_{k-1}_k
        if translation_measured[k]:
            steps = [*steps[1 - FALLBACK_STEPS :], step]
        elif steps:
            mean = medoid_transform(steps) if len(steps) >= 3 else steps[-1]
            step = step.copy()
            step[:3, 3] = mean[:3, 3]
        out.append(out[-1] @ step)
    return np.stack(out)
