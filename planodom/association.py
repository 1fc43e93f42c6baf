"""Data association of planes between epoch k and epoch k + d: LDA and SDA (paper III).

Lenient data association (LDA) knows nothing of the motion beyond assumed bounds. It
compares the dihedral angle of every non-parallel pair of planes of one epoch with every
non-parallel pair of the other (relative constraint: the angle between two oriented
normals is invariant under rigid motion) and keeps pair-to-pair candidates whose angles
agree within ``dihedral_tol_deg``. Absolute constraints then prune them, all derived from
the assumed maximum motion between the epochs (``max_translation_m``, ``max_rotation_deg``,
or ``prior_*`` around a motion prior ``T_prev_curr``):

- each plane's normal turns by at most the rotation bound (plus ``normal_tol_deg``);
- each plane's offset (its distance to the sensor) changes by at most the translation
  bound (rotation leaves it unchanged): ``|d_k - d_{k+d}| <= |t|``;
- the supports overlap: their bounding circles (centroid, radius of the support polygon)
  are within the motion bound of each other (a point at range r moves by at most
  ``|t| + 2 r sin(theta / 2)``), plus ``overlap_margin_m``;
- the candidate rotation of the pair (paper eq. 1) is within the rotation bound, and the
  pair's reference point (its intersection line cut with z = 0) within the translation
  bound.

Pair order: the dihedral angle is symmetric, so ``(i1, i2) -> (j1, j2)`` and
``(i1, i2) -> (j2, j1)`` both match. The frames ``U = [n1, n2', n1 x n2]`` are
right-handed in both cases, so each order gives a proper rotation; both orders are
generated and the absolute constraints and the consensus decide.

Strict data association (SDA) runs once the rotation is known: current planes are rotated
into the previous orientation, strict gates on normal angle, offset and overlap apply,
and an injective assignment (``scipy.optimize.linear_sum_assignment``) keeps for every
plane only its best match.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import NamedTuple

import numba
import numpy as np
from scipy.optimize import linear_sum_assignment

from planodom.config import AssociationConfig
from planodom.geometry import (
    dihedral_angles,
    horizontal_reference_points,
    rotation_frames,
    transform_planes,
    transform_points,
)
from planodom.planes import PlaneSet

#: Cost of a forbidden match in the SDA assignment (gated costs are at most 2).
_FORBIDDEN = 1e6


@dataclass(frozen=True, eq=False)
class PairAssociations:
    """Candidate pair-to-pair associations from LDA.

    Attributes:
        prev_pairs: (M, 2) int, plane indices ``(i1, i2)`` in the previous epoch.
        curr_pairs: (M, 2) int, ``(j1, j2)`` in the current epoch, with ``i1 -> j1``,
            ``i2 -> j2``.
        rotations: (M, 3, 3) candidate ``R_prev_curr`` of every pair (paper eq. 1).
        weights: (M,) product of the four planes' confidences.
    """

    prev_pairs: np.ndarray
    curr_pairs: np.ndarray
    rotations: np.ndarray
    weights: np.ndarray

    @classmethod
    def empty(cls) -> PairAssociations:
        z = np.zeros((0, 2), dtype=np.intp)
        return cls(z, z.copy(), np.zeros((0, 3, 3)), np.zeros(0))

    def __len__(self) -> int:
        return len(self.prev_pairs)

    def plane_associations(self, index: np.ndarray | None = None) -> np.ndarray:
        """(L, 2) unique plane associations ``(i, j)`` induced by the pairs, sorted.

        One previous plane may map to several current planes (ambiguous); ``index``
        restricts to some of the pairs.
        """
        pp, cp = self.prev_pairs, self.curr_pairs
        if index is not None:
            pp, cp = pp[index], cp[index]
        i, j = pp.T.reshape(-1), cp.T.reshape(-1)
        base = int(j.max(initial=0)) + 1
        code = np.unique(i.astype(np.int64) * base + j)
        return np.column_stack([code // base, code % base]).astype(np.intp)

    def remapped(self, prev_index: np.ndarray, curr_index: np.ndarray) -> PairAssociations:
        """The same associations with plane indices mapped through the given arrays."""
        return PairAssociations(
            prev_index[self.prev_pairs], curr_index[self.curr_pairs], self.rotations, self.weights
        )


def nonparallel_pairs(normals: np.ndarray, parallel_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Dihedral angles (K, K), rad, and the mask of non-parallel pairs (K, K).

    A pair is parallel when its normals are within ``parallel_angle`` rad of each other
    or of each other's opposite.
    """
    angles = dihedral_angles(normals)
    return angles, (angles >= parallel_angle) & (angles <= np.pi - parallel_angle)


class _Moved(NamedTuple):
    """The geometry of planes moved into another frame, what the gates compare:
    normals (K, 3), offsets (K,) m, centroids (K, 3) m, radii (K,) m (unchanged)."""

    normals: np.ndarray
    offsets: np.ndarray
    centroids: np.ndarray
    radii: np.ndarray


def _moved(planes: PlaneSet, T_a_b: np.ndarray) -> _Moved:
    """``planes.transformed(T_a_b)`` without the covariances, which no gate reads (their
    propagation was a third of each gate's cost), the same arithmetic otherwise."""
    n, d = transform_planes(T_a_b, planes.normals, planes.offsets)
    return _Moved(n, d, transform_points(T_a_b, planes.centroids), planes.radii)


def _plane_gate(
    prev: PlaneSet,
    curr_in_prev: _Moved,
    curr_ranges: np.ndarray,
    t_bound: float,
    t_prior: float,
    rot_bound: float,
    normal_tol: float,
    offset_tol: float,
    margin: float,
) -> np.ndarray:
    """(Kp, Kc) bool: plane i (prev) and plane j (current, moved by the prior) may match."""
    cos = prev.normals @ curr_in_prev.normals.T
    ok = cos >= np.cos(min(rot_bound + normal_tol, np.pi))
    chord = 2.0 * np.sin(min(rot_bound, np.pi) / 2.0)
    d_bound = t_bound + offset_tol + chord * t_prior
    ok &= np.abs(prev.offsets[:, None] - curr_in_prev.offsets[None, :]) <= d_bound
    dist = np.linalg.norm(prev.centroids[:, None, :] - curr_in_prev.centroids[None], axis=2)
    reach = prev.radii[:, None] + curr_in_prev.radii[None] + chord * curr_ranges[None]
    ok &= ~(dist > reach + t_bound + margin)  # unknown supports (NaN) pass
    return ok


def _gated_combinations(
    gate1: np.ndarray, gate2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All (p, j1, j2) with ``gate1[p, j1]`` and ``gate2[p, j2]``, vectorised, ordered by
    p, then j1, then j2. gate1, gate2: (P, K) bool. Returns three (M,) int arrays."""
    p1, j1 = np.nonzero(gate1)
    p2, j2 = np.nonzero(gate2)
    n = len(gate1)
    c1, c2 = np.bincount(p1, minlength=n), np.bincount(p2, minlength=n)
    s1, s2 = np.cumsum(c1) - c1, np.cumsum(c2) - c2
    per = c1 * c2
    p = np.repeat(np.arange(n), per)
    q = np.arange(per.sum()) - np.repeat(np.cumsum(per) - per, per)
    u, v = q // c2[p], q % c2[p]
    return p, j1[s1[p] + u], j2[s2[p] + v]


@functools.lru_cache(maxsize=64)
def _pairs_of(n: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.triu_indices(n, 1)`` (read-only arrays, cached: building them cost more than
    the rest of a small epoch's gate)."""
    i1, i2 = np.triu_indices(n, 1)
    i1.flags.writeable = i2.flags.writeable = False
    return i1, i2


def lenient_association(
    prev: PlaneSet,
    curr: PlaneSet,
    config: AssociationConfig | None = None,
    prior: np.ndarray | None = None,
) -> PairAssociations:
    """LDA: candidate associations of non-parallel plane pairs between two epochs.

    Args:
        prev: planes of epoch k, in its base frame.
        curr: planes of epoch k + d, in its base frame.
        config: thresholds; the motion bounds are ``max_*`` without a prior and
            ``prior_*`` around the prior with one.
        prior: optional predicted ``T_prev_curr`` (4, 4).

    Returns:
        :class:`PairAssociations`, ordered by previous pair then current pair (empty when
        either epoch has no non-parallel pair).
    """
    cfg = config or AssociationConfig()
    if len(prev) < 2 or len(curr) < 2:
        return PairAssociations.empty()
    if prior is None:
        T0, t_bound = np.eye(4), cfg.max_translation_m
        rot_bound = np.radians(cfg.max_rotation_deg)
    else:
        T0, t_bound = np.asarray(prior, dtype=np.float64), cfg.prior_translation_m
        rot_bound = np.radians(cfg.prior_rotation_deg)
    normal_tol = np.radians(cfg.normal_tol_deg)
    t0 = T0[:3, 3]

    gate = _plane_gate(
        prev,
        _moved(curr, T0),
        np.linalg.norm(curr.centroids, axis=1),
        t_bound,
        float(np.linalg.norm(t0)),
        rot_bound,
        normal_tol,
        cfg.offset_tol_m,
        cfg.overlap_margin_m,
    )
    parallel = np.radians(cfg.parallel_angle_deg)
    ang_p, ok_p = nonparallel_pairs(prev.normals, parallel)
    ang_c, ok_c = nonparallel_pairs(curr.normals, parallel)
    i1, i2 = _pairs_of(len(prev))
    keep = ok_p[i1, i2] & gate[i1].any(axis=1) & gate[i2].any(axis=1)
    i1, i2 = i1[keep], i2[keep]
    if len(i1) == 0:
        return PairAssociations.empty()

    # Prev pair p may map to the ordered current pair (j1, j2) with j1, j2 gated.
    p, j1, j2 = _gated_combinations(gate[i1], gate[i2])
    a_p = ang_p[i1, i2][p]
    keep = ok_c[j1, j2] & (np.abs(a_p - ang_c[j1, j2]) <= np.radians(cfg.dihedral_tol_deg))
    if not keep.any():
        return PairAssociations.empty()
    p, j1, j2, a_p = p[keep], j1[keep], j2[keep], a_p[keep]
    i1, i2 = i1[p], i2[p]

    U_p = rotation_frames(prev.normals[i1], prev.normals[i2])
    U_c = rotation_frames(curr.normals[j1], curr.normals[j2])
    R = U_p @ np.swapaxes(U_c, 1, 2)
    # Rotation bound: angle of R0^T R from its trace.
    cos_dev = (np.einsum("ij,mij->m", T0[:3, :3], R) - 1.0) / 2.0
    ok = cos_dev >= np.cos(min(rot_bound + normal_tol, np.pi))

    ok &= _reference_points_agree(
        prev, curr, (i1, i2, j1, j2), R, t0, t_bound + cfg.offset_tol_m / np.sin(a_p),
        normal_tol, cfg.min_line_verticality,
    )  # fmt: skip

    w = prev.weights[i1] * prev.weights[i2] * curr.weights[j1] * curr.weights[j2]
    return PairAssociations(
        np.column_stack([i1, i2])[ok],
        np.column_stack([j1, j2])[ok],
        R[ok],
        w[ok],
    )


def _reference_points_agree(
    prev: PlaneSet,
    curr: PlaneSet,
    pairs: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    R: np.ndarray,
    t0: np.ndarray,
    bound: np.ndarray,
    normal_tol: float,
    min_verticality: float,
) -> np.ndarray:
    """(M,) bool: the translation bound on each pair's reference point (NaN when
    undefined: passes).

    Args:
        pairs: (i1, i2, j1, j2), each (M,): the pair association ``(i1, i2) -> (j1, j2)``.
        R: (M, 3, 3) the candidate rotations; t0: (3,) the prior's translation, m.
        bound: (M,) allowed deviation of the reference point from ``t0``, m, before the
            rotation-noise margin (``|varpi| sin(normal_tol)``) is added.
    """
    i1, i2, j1, j2 = pairs
    n1 = np.einsum("mij,mj->mi", R, curr.normals[j1])
    n2 = np.einsum("mij,mj->mi", R, curr.normals[j2])
    # Both epochs' reference points in one call: previous, then rotated current.
    refs = horizontal_reference_points(
        np.concatenate([prev.normals[i1], n1]),
        np.concatenate([prev.offsets[i1], curr.offsets[j1] - n1[:, 2] * t0[2]]),
        np.concatenate([prev.normals[i2], n2]),
        np.concatenate([prev.offsets[i2], curr.offsets[j2] - n2[:, 2] * t0[2]]),
        min_verticality,
    )
    ref_p, ref_c = refs[: len(i1)], refs[len(i1) :]
    dev = np.linalg.norm(ref_p - ref_c - t0[:2], axis=1)
    return ~(dev > bound + np.linalg.norm(ref_p, axis=1) * np.sin(normal_tol))


def strict_association(
    prev: PlaneSet,
    curr: PlaneSet,
    rotation: np.ndarray,
    config: AssociationConfig | None = None,
    translation: np.ndarray | None = None,
    translation_bound: float | None = None,
) -> np.ndarray:
    """SDA: injective plane associations once the rotation ``R_prev_curr`` is known.

    Current planes are moved by ``(rotation, translation)`` into the previous frame; a
    match must have normals within ``strict_normal_deg``, offsets within
    ``translation_bound + strict_offset_m`` and overlapping supports (bounding circles
    within ``translation_bound + overlap_margin_m``). Among the gated matches an optimal
    one-to-one assignment minimises the sum of normalised angle and offset costs.

    Args:
        prev, curr: planes of the two epochs, each in its own base frame.
        rotation: (3, 3) ``R_prev_curr``.
        translation: (3,) translation estimate or prior, metres (default zero).
        translation_bound: how far the true translation may be from ``translation``, m
            (default ``config.max_translation_m``).

    Returns:
        (L, 2) int array of associations ``(i, j)``, sorted by ``i``; each i and each j
        appears at most once.
    """
    cfg = config or AssociationConfig()
    if len(prev) == 0 or len(curr) == 0:
        return np.zeros((0, 2), dtype=np.intp)
    t = np.zeros(3) if translation is None else np.asarray(translation, dtype=np.float64)
    t_bound = cfg.max_translation_m if translation_bound is None else float(translation_bound)
    ok, cost = _strict_costs(
        prev.normals, prev.offsets, prev.centroids, prev.radii,
        curr.normals, curr.offsets, curr.centroids, curr.radii,
        np.ascontiguousarray(rotation, dtype=np.float64), t,
        np.cos(np.radians(cfg.strict_normal_deg)), t_bound + cfg.strict_offset_m,
        t_bound + cfg.overlap_margin_m,
    )  # fmt: skip
    rows, cols = linear_sum_assignment(cost)
    keep = ok[rows, cols]
    return np.column_stack([rows[keep], cols[keep]]).astype(np.intp)


@numba.njit(cache=True)
def _strict_costs(
    n_p, d_p, c_p, r_p, n_c, d_c, c_c, r_c, R, t, cos_max, d_bound, reach_add
):  # pragma: no cover - compiled
    """SDA's gate (Kp, Kc) bool and assignment costs (Kp, Kc) (:data:`_FORBIDDEN` where
    gated out) of the current planes ``(n_c, d_c)`` with support centroids ``c_c`` and
    radii ``r_c`` moved by ``(R, t)`` against the previous ones: the arithmetic of
    :func:`planodom.geometry.transform_planes` and of the gates, compiled (a dozen numpy
    calls on 5 x 5 arrays cost several times their arithmetic; SDA runs 3-4 times a
    solve). Unknown supports (NaN) pass the overlap gate."""
    Kp, Kc = len(d_p), len(d_c)
    ok = np.zeros((Kp, Kc), dtype=np.bool_)
    cost = np.full((Kp, Kc), _FORBIDDEN)
    n = np.empty(3)
    c = np.empty(3)
    for j in range(Kc):
        for a in range(3):
            n[a] = R[a, 0] * n_c[j, 0] + R[a, 1] * n_c[j, 1] + R[a, 2] * n_c[j, 2]
            c[a] = R[a, 0] * c_c[j, 0] + R[a, 1] * c_c[j, 1] + R[a, 2] * c_c[j, 2] + t[a]
        d = d_c[j] - (n[0] * t[0] + n[1] * t[1] + n[2] * t[2])
        for i in range(Kp):
            cos = n_p[i, 0] * n[0] + n_p[i, 1] * n[1] + n_p[i, 2] * n[2]
            cos = min(max(cos, -1.0), 1.0)
            dd = abs(d_p[i] - d)
            dist = np.sqrt(
                (c_p[i, 0] - c[0]) ** 2 + (c_p[i, 1] - c[1]) ** 2 + (c_p[i, 2] - c[2]) ** 2
            )
            reach = r_p[i] + r_c[j] + reach_add
            if cos >= cos_max and dd <= d_bound and not dist > reach:
                ok[i, j] = True
                cost[i, j] = (1.0 - cos) / (1.0 - cos_max) + (dd / d_bound) ** 2
    return ok, cost
