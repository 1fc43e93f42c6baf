"""2-DoF horizontal translation from reference points, and the vertical one from the ground.

Reference point (paper II-B, eq. 2): the intersection line of a non-parallel pair cut with
the horizontal plane z = 0, ``varpi`` (2,). With the current planes rotated into the
previous orientation (``n' = R n_j``, ``d' = d_j``) and shifted up by a height ``z``, the
reference point moves linearly, ``varpi'(z) = varpi'_0 + z g``; at the true vertical
translation ``t_z`` the two frames differ by a horizontal shift only and, exactly,
``varpi_k = varpi'(t_z) + (t_x, t_y)``, i.e. ``varpi_{k+d} = varpi_k - T``. Each pair is
a translation candidate ``T = varpi_k - varpi'(z)``.

The vertical translation, unobserved by vertical walls (the paper's 5-DoF model), is
observed by ground-like planes (near-horizontal, facing up): ``n_i . t = d_j - d_i`` gives
``t_z = b - m . (t_x, t_y)`` with ``b = (d_j - d_i) / n_iz``, ``m = n_i,xy / n_iz``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.association import nonparallel_pairs
from planodom.geometry import horizontal_reference_points
from planodom.planes import PlaneSet


@dataclass(frozen=True, eq=False)
class TranslationElements:
    """Reference points of associated pairs (only pairs defined in both epochs)."""

    pairs: np.ndarray
    """(E, 4) int ``(i1, i2, j1, j2)``: previous planes i1, i2 associated with j1, j2."""
    ref_prev: np.ndarray
    """(E, 2) previous reference points, metres."""
    ref_curr0: np.ndarray
    """(E, 2) reference points of the rotated current pairs at height 0, metres."""
    slope: np.ndarray
    """(E, 2) ``g``: change of the current reference point per metre of height."""
    weights: np.ndarray
    """(E,) confidence of each element (see :func:`translation_elements`)."""

    def targets(self, z: float) -> np.ndarray:
        """(E, 2) current reference points for a vertical translation ``z``, metres."""
        return self.ref_curr0 + z * self.slope

    def candidates(self, z: float) -> np.ndarray:
        """(E, 2) translation candidates ``varpi_k - varpi'(z)``, metres."""
        return self.ref_prev - self.targets(z)

    def __len__(self) -> int:
        return len(self.weights)


def translation_elements(
    prev: PlaneSet,
    curr: PlaneSet,
    R: np.ndarray,
    prev_pairs: np.ndarray,
    curr_pairs: np.ndarray,
    min_verticality: float,
    min_angle: float = 0.0,
) -> TranslationElements:
    """Reference points of the pairs ``prev_pairs[e] -> curr_pairs[e]`` (E, 2) under ``R``.

    Only pairs defined in both epochs (intersection direction with ``|v_z| >=
    min_verticality``) and cutting at ``min_angle`` rad or more from parallel are kept.

    Weights: the product of the four planes' confidences (paper), times
    ``sin^2`` of each epoch's dihedral angle: a reference point's
    confidence includes how well its two planes cut (offset noise sigma moves it by about
    sigma / sin(angle)).
    """
    i1, i2 = prev_pairs[:, 0], prev_pairs[:, 1]
    j1, j2 = curr_pairs[:, 0], curr_pairs[:, 1]
    n1, n2 = curr.normals[j1] @ R.T, curr.normals[j2] @ R.T
    # One call for three sets: previous points, rotated current points at height 0, and
    # the slope (linear in the offsets: shifting up by z changes d by -n_z z).
    refs = horizontal_reference_points(
        np.concatenate([prev.normals[i1], n1, n1]),
        np.concatenate([prev.offsets[i1], curr.offsets[j1], -n1[:, 2]]),
        np.concatenate([prev.normals[i2], n2, n2]),
        np.concatenate([prev.offsets[i2], curr.offsets[j2], -n2[:, 2]]),
        min_verticality,
    )
    E = len(i1)  # slices: np.split costs more than the rest of this block
    ref_p, ref_c, slope = refs[:E], refs[E : 2 * E], refs[2 * E :]
    ok = np.isfinite(ref_p).all(axis=1) & np.isfinite(ref_c).all(axis=1)
    cos_p = np.einsum("ij,ij->i", prev.normals[i1], prev.normals[i2])
    cos_c = np.einsum("ij,ij->i", curr.normals[j1], curr.normals[j2])
    ok &= np.abs(cos_p) <= np.cos(min_angle)
    w = prev.weights[i1] * prev.weights[i2] * curr.weights[j1] * curr.weights[j2]
    w = w * (1.0 - cos_p**2) * (1.0 - cos_c**2)  # sin^2 = 1 - cos^2 for unit normals
    pairs = np.column_stack([prev_pairs, curr_pairs])
    return TranslationElements(pairs[ok], ref_p[ok], ref_c[ok], slope[ok], w[ok])


def pairs_of_associations(
    ij: np.ndarray, prev: PlaneSet, parallel_angle: float
) -> tuple[np.ndarray, np.ndarray]:
    """All non-parallel pairs among plane associations ``ij`` (L, 2): (P, 2) and (P, 2)."""
    a, b = np.triu_indices(len(ij), 1)
    _, ok = nonparallel_pairs(prev.normals[ij[:, 0]], parallel_angle)
    keep = ok[a, b]
    a, b = a[keep], b[keep]
    return np.column_stack([ij[a, 0], ij[b, 0]]), np.column_stack([ij[a, 1], ij[b, 1]])


@dataclass(frozen=True, eq=False)
class HeightElements:
    """Near-horizontal plane associations: ``t_z = b - m . (t_x, t_y)``."""

    b: np.ndarray
    """(H,) metres."""
    m: np.ndarray
    """(H, 2) horizontal slope."""
    weights: np.ndarray
    """(H,) confidences."""
    ij: np.ndarray
    """(H, 2) the plane associations (previous, current)."""

    def heights(self, txy: np.ndarray) -> np.ndarray:
        """(H,) vertical translation each element gives for a horizontal one (2,), m."""
        return self.b - self.m @ txy

    def __len__(self) -> int:
        return len(self.b)


def height_elements(
    prev: PlaneSet, curr: PlaneSet, ij: np.ndarray, max_tilt: float
) -> HeightElements:
    """Elements from the associations ``ij`` (L, 2) whose previous plane is ground-like:
    within ``max_tilt`` rad of horizontal and facing up (below the sensor, normal towards
    it), the ground a vehicle drives on."""
    n = prev.normals[ij[:, 0]]
    keep = n[:, 2] >= np.cos(max_tilt)
    ij, n = ij[keep], n[keep]
    b = (curr.offsets[ij[:, 1]] - prev.offsets[ij[:, 0]]) / n[:, 2]
    w = prev.weights[ij[:, 0]] * curr.weights[ij[:, 1]]
    return HeightElements(b, n[:, :2] / n[:, 2:3], w, ij)


def solve_height(a: np.ndarray, g: np.ndarray, b: float, m: np.ndarray) -> float | None:
    """Solve ``t_xy = a - z g`` and ``z = b - m . t_xy`` for z; None if ill-conditioned."""
    den = 1.0 - float(m @ g)
    if abs(den) < 0.5:
        return None
    return (b - float(m @ a)) / den
