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

import numba
import numpy as np

from planodom.association import nonparallel_pairs
from planodom.odometry.solver_glue import kept_rows
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
    ok, ref_p, ref_c, slope, w = _elements_kernel(
        prev.normals, prev.offsets, prev.weights, curr.normals, curr.offsets, curr.weights,
        n1, n2, i1.astype(np.int64), i2.astype(np.int64), j1.astype(np.int64),
        j2.astype(np.int64), float(min_verticality), float(np.cos(min_angle)),
    )  # fmt: skip
    pairs = np.column_stack([prev_pairs, curr_pairs])
    return TranslationElements(*kept_rows(ok, pairs, ref_p, ref_c, slope, w))


@numba.njit(cache=True)
def _reference_point(n1, n2, d1, d2, min_vert, out, row):  # pragma: no cover - compiled
    """:func:`planodom.geometry.horizontal_reference_points` of one pair, written to
    ``out[row]`` (NaN when undefined); whether it is defined (and finite)."""
    v0 = n1[1] * n2[2] - n1[2] * n2[1]
    v1 = n1[2] * n2[0] - n1[0] * n2[2]
    v2 = n1[0] * n2[1] - n1[1] * n2[0]
    norm_v = np.sqrt((v0 * v0 + v2 * v2) + v1 * v1)  # numpy einsum's order: same bits
    det = n1[0] * n2[1] - n1[1] * n2[0]
    if norm_v > 1e-9 and abs(v2) / norm_v >= min_vert and det != 0:
        x = (-d1 * n2[1] + d2 * n1[1]) / det
        y = (-n1[0] * d2 + n2[0] * d1) / det
        out[row, 0], out[row, 1] = x, y
        return np.isfinite(x) and np.isfinite(y)
    out[row, 0], out[row, 1] = np.nan, np.nan
    return False


@numba.njit(cache=True)
def _elements_kernel(
    pn, po, pw, cn, co, cw, r1, r2, i1, i2, j1, j2, min_vert, cos_min
):  # pragma: no cover - compiled
    """:func:`translation_elements` per pair (numpy's ~20 calls on a few pairs cost ~4x
    the arithmetic; the same operations in the same order, the dot products in numpy
    einsum's): the kept mask, reference points, slopes and weights of all E pairs;
    ``r1``, ``r2`` (E, 3) the rotated current normals."""
    E = i1.shape[0]
    ref_p = np.empty((E, 2))
    ref_c = np.empty((E, 2))
    slope = np.empty((E, 2))
    w = np.empty(E)
    ok = np.zeros(E, dtype=np.bool_)
    for e in range(E):
        a, b, c, d = i1[e], i2[e], j1[e], j2[e]
        ok_p = _reference_point(pn[a], pn[b], po[a], po[b], min_vert, ref_p, e)
        ok_c = _reference_point(r1[e], r2[e], co[c], co[d], min_vert, ref_c, e)
        # the slope: linear in the offsets, shifting up by z changes d by -n_z z
        _reference_point(r1[e], r2[e], -r1[e, 2], -r2[e, 2], min_vert, slope, e)
        cos_p = (pn[a, 0] * pn[b, 0] + pn[a, 2] * pn[b, 2]) + pn[a, 1] * pn[b, 1]
        cos_c = (cn[c, 0] * cn[d, 0] + cn[c, 2] * cn[d, 2]) + cn[c, 1] * cn[d, 1]
        ok[e] = ok_p and ok_c and abs(cos_p) <= cos_min
        # sin^2 = 1 - cos^2 for unit normals
        w[e] = pw[a] * pw[b] * cw[c] * cw[d] * (1.0 - cos_p**2) * (1.0 - cos_c**2)
    return ok, ref_p, ref_c, slope, w


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
    keep, b, m, w = _heights_kernel(
        prev.normals, prev.offsets, prev.weights, curr.offsets, curr.weights,
        np.asarray(ij, np.int64), float(np.cos(max_tilt)),
    )  # fmt: skip
    return HeightElements(b, m, w, ij[keep])


@numba.njit(cache=True)
def _heights_kernel(pn, po, pw, co, cw, ij, cos_tilt):  # pragma: no cover - compiled
    """:func:`height_elements`' kept mask (L,) and ``b`` (H,), ``m`` (H, 2), weights (H,),
    compiled: each value one or two IEEE operations, as numpy's elementwise ones (its
    ~15 calls on a few rows cost ten times the arithmetic)."""
    L = ij.shape[0]
    keep = np.empty(L, dtype=np.bool_)
    for q in range(L):
        keep[q] = pn[ij[q, 0], 2] >= cos_tilt
    H = int(keep.sum())
    b = np.empty(H)
    m = np.empty((H, 2))
    w = np.empty(H)
    h = 0
    for q in range(L):
        if keep[q]:
            i, j = ij[q, 0], ij[q, 1]
            nz = pn[i, 2]
            b[h] = (co[j] - po[i]) / nz
            m[h, 0], m[h, 1] = pn[i, 0] / nz, pn[i, 1] / nz
            w[h] = pw[i] * cw[j]
            h += 1
    return keep, b, m, w


def solve_height(a: np.ndarray, g: np.ndarray, b: float, m: np.ndarray) -> float | None:
    """Solve ``t_xy = a - z g`` and ``z = b - m . t_xy`` for z; None if ill-conditioned."""
    den = 1.0 - float(m @ g)
    if abs(den) < 0.5:
        return None
    return (b - float(m @ a)) / den
