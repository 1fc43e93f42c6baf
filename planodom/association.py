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
  bound;
- with ``max_tilt_deg`` below 180, the candidate rotation tilts the base z axis by at
  most that bound (plus ``normal_tol_deg``), whatever the rotation bound.

Pair order: the dihedral angle is symmetric, so ``(i1, i2) -> (j1, j2)`` and
``(i1, i2) -> (j2, j1)`` both match. The frames ``U = [n1, n2', n1 x n2]`` are
right-handed in both cases, so each order gives a proper rotation; both orders are
generated and the absolute constraints and the consensus decide.

Strict data association (SDA) runs once the rotation is known: current planes are rotated
into the previous orientation, strict gates on normal angle, offset and overlap apply,
and an injective assignment (``scipy.optimize.linear_sum_assignment``'s algorithm, ported
to run in SDA's one compiled call: :mod:`planodom.sda_kernel`, :mod:`planodom.lsap`) keeps
for every plane only its best match.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numba
import numpy as np
from scipy.optimize import linear_sum_assignment

from planodom.angles import cos_of_degrees, radians
from planodom.config import AssociationConfig
from planodom.geometry import (
    dihedral_angles,
    rotation_frame_into,
)
from planodom.lsap import SOLVED
from planodom.planes import PlaneSet
from planodom.sda_kernel import _FORBIDDEN, _kept_pairs, _strict_costs, sda_kernel  # noqa: F401


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
        # no copies of int64 (intp) indices: integers, the same pairs
        pairs = _unique_pairs(np.asarray(pp, np.int64), np.asarray(cp, np.int64))
        return pairs.astype(np.intp, copy=False)

    def remapped(self, prev_index: np.ndarray, curr_index: np.ndarray) -> PairAssociations:
        """The same associations with plane indices mapped through the given arrays."""
        return PairAssociations(
            prev_index[self.prev_pairs], curr_index[self.curr_pairs], self.rotations, self.weights
        )


@numba.njit(cache=True)
def _unique_pairs(pp, cp):  # pragma: no cover - compiled
    """(L, 2) the distinct plane associations ``(i, j)`` of the pairs ``pp``, ``cp`` (M, 2),
    sorted: codes ``i * base + j`` made unique (compiled: the numpy form's ten calls cost
    more than sorting a few codes)."""
    m = pp.shape[0]
    base = 1
    for q in range(m):
        base = max(base, cp[q, 0] + 1, cp[q, 1] + 1)
    code = np.empty(2 * m, dtype=np.int64)
    for q in range(m):
        code[q] = pp[q, 0] * base + cp[q, 0]
        code[m + q] = pp[q, 1] * base + cp[q, 1]
    code = np.unique(code)
    out = np.empty((len(code), 2), dtype=np.int64)
    for q in range(len(code)):
        out[q, 0], out[q, 1] = code[q] // base, code[q] % base
    return out


def nonparallel_pairs(normals: np.ndarray, parallel_angle: float) -> tuple[np.ndarray, np.ndarray]:
    """Dihedral angles (K, K), rad, and the mask of non-parallel pairs (K, K).

    A pair is parallel when its normals are within ``parallel_angle`` rad of each other
    or of each other's opposite.
    """
    angles = dihedral_angles(normals)
    return angles, (angles >= parallel_angle) & (angles <= np.pi - parallel_angle)


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
        rot_bound = radians(cfg.max_rotation_deg)
    else:
        # a writeable C-contiguous copy: a read-only or strided prior would make numba
        # compile a second specialisation of the kernel, seconds of CPU in a timed run
        T0 = np.require(prior, np.float64, ("C", "W"))
        t_bound = cfg.prior_translation_m
        rot_bound = radians(cfg.prior_rotation_deg)
    pp, cp, R, w = _lda_kernel(
        prev.normals, prev.offsets, prev.centroids, prev.radii, prev.weights,
        curr.normals, curr.offsets, curr.centroids, curr.radii, curr.weights,
        T0, _LdaBounds(
            t_bound, rot_bound, radians(cfg.normal_tol_deg), cfg.offset_tol_m,
            cfg.overlap_margin_m, radians(cfg.parallel_angle_deg),
            radians(cfg.dihedral_tol_deg), cfg.min_line_verticality,
            _cos_tilt(cfg.max_tilt_deg, cfg.normal_tol_deg),
        ),
    )  # fmt: skip
    if len(w) == 0:
        return PairAssociations.empty()
    return PairAssociations(pp, cp, R, w)


class _LdaBounds(NamedTuple):
    """LDA's gates (:func:`lenient_association`): translation bound m, rotation bound rad,
    normal tolerance rad, offset tolerance m, overlap margin m, parallel angle rad,
    dihedral tolerance rad, minimum verticality of a reference point's line, cosine of
    the tilt bound plus the normal tolerance (-2: no bound; ``max_tilt_deg``)."""

    t_bound: float
    rot_bound: float
    normal_tol: float
    offset_tol: float
    margin: float
    parallel: float
    dihedral_tol: float
    min_verticality: float
    cos_tilt: float


def _cos_tilt(max_tilt_deg: float, normal_tol_deg: float) -> float:
    """The LDA's tilt gate: the cosine of ``max_tilt_deg`` plus the normal tolerance, or
    -2 (every rotation passes) when the bound is 180 deg or the sum reaches it."""
    bound = max_tilt_deg + normal_tol_deg
    return -2.0 if max_tilt_deg >= 180.0 or bound >= 180.0 else float(np.cos(radians(bound)))


@numba.njit(cache=True)
def _lda_kernel(n_p, d_p, c_p, r_p, w_p, n_c, d_c, c_c, r_c, w_c, T0, b):  # pragma: no cover
    """LDA's candidates, compiled: (M, 2) previous pairs, (M, 2) current pairs, (M, 3, 3)
    rotations, (M,) weights, in the order of the module docstring (previous pair, then
    j1, then j2), with the gates of the module docstring: per plane (current planes moved
    by ``T0``: normal within the rotation bound plus the normal tolerance, offset within
    the translation bound plus the offset tolerance plus the chord of the rotation bound
    times ``|t0|``, bounding circles within reach, unknown supports (NaN) passing), then
    per pair of pairs (non-parallel, dihedral angles within tolerance, the pair rotation
    within the rotation bound of ``T0``'s and its tilt within ``b.cos_tilt``,
    :func:`_pair_moves_within`). Compiled: numpy
    built them as arrays over all combinations, ~60 small calls a solve that cost ten
    times the arithmetic."""
    Kp, Kc = len(d_p), len(d_c)
    R0, t0 = T0[:3, :3], T0[:3, 3]
    cos_gate = np.cos(min(b.rot_bound + b.normal_tol, np.pi))
    chord = 2.0 * np.sin(min(b.rot_bound, np.pi) / 2.0)
    t_prior = np.sqrt(t0[0] ** 2 + t0[1] ** 2 + t0[2] ** 2)
    d_bound = b.t_bound + b.offset_tol + chord * t_prior
    gate = np.zeros((Kp, Kc), dtype=np.bool_)
    for j in range(Kc):
        n = np.empty(3)
        c = np.empty(3)
        for a in range(3):
            n[a] = n_c[j, 0] * R0[a, 0] + n_c[j, 1] * R0[a, 1] + n_c[j, 2] * R0[a, 2]
            c[a] = c_c[j, 0] * R0[a, 0] + c_c[j, 1] * R0[a, 1] + c_c[j, 2] * R0[a, 2] + t0[a]
        d = d_c[j] - (n[0] * t0[0] + n[1] * t0[1] + n[2] * t0[2])
        rng = np.sqrt(c_c[j, 0] ** 2 + c_c[j, 1] ** 2 + c_c[j, 2] ** 2)
        for i in range(Kp):
            cos = n_p[i, 0] * n[0] + n_p[i, 1] * n[1] + n_p[i, 2] * n[2]
            dist = np.sqrt(
                (c_p[i, 0] - c[0]) ** 2 + (c_p[i, 1] - c[1]) ** 2 + (c_p[i, 2] - c[2]) ** 2
            )
            reach = r_p[i] + r_c[j] + chord * rng
            gate[i, j] = (
                cos >= cos_gate
                and abs(d_p[i] - d) <= d_bound
                and not dist > reach + b.t_bound + b.margin
            )
    ang_p = _dihedral(n_p)
    ang_c = _dihedral(n_c)
    lo, hi = b.parallel, np.pi - b.parallel
    cap = 64
    out_p = np.empty((cap, 2), dtype=np.intp)
    out_c = np.empty((cap, 2), dtype=np.intp)
    out_R = np.empty((cap, 3, 3))
    out_w = np.empty(cap)
    m = 0
    U_p = np.empty((3, 3))
    U_c = np.empty((3, 3))
    R = np.empty((3, 3))
    for i1 in range(Kp):
        for i2 in range(i1 + 1, Kp):
            a_p = ang_p[i1, i2]
            if not (a_p >= lo and a_p <= hi) or not gate[i1].any() or not gate[i2].any():
                continue
            rotation_frame_into(n_p[i1], n_p[i2], U_p)
            ref_p = _reference_point(n_p[i1], d_p[i1], n_p[i2], d_p[i2], b.min_verticality)
            bound = b.t_bound + b.offset_tol / np.sin(a_p)
            bound += np.sqrt(ref_p[0] ** 2 + ref_p[1] ** 2) * np.sin(b.normal_tol)
            for j1 in range(Kc):
                if not gate[i1, j1]:
                    continue
                for j2 in range(Kc):
                    a_c = ang_c[j1, j2]
                    if not gate[i2, j2] or not (a_c >= lo and a_c <= hi):
                        continue
                    if not abs(a_p - a_c) <= b.dihedral_tol:
                        continue
                    rotation_frame_into(n_c[j1], n_c[j2], U_c)
                    trace = 0.0
                    for u in range(3):
                        for v in range(3):
                            acc = 0.0
                            for k in range(3):
                                acc += U_p[u, k] * U_c[v, k]
                            R[u, v] = acc
                            trace += R0[u, v] * acc
                    if not (trace - 1.0) / 2.0 >= cos_gate:
                        continue
                    if R[2, 2] < b.cos_tilt:  # the angle between the base z axes
                        continue
                    if not _pair_moves_within(
                        R, n_c[j1], d_c[j1], n_c[j2], d_c[j2], t0, ref_p, bound, b.min_verticality
                    ):
                        continue
                    if m == cap:
                        cap *= 2
                        out_p, out_c = _grown(out_p, cap), _grown(out_c, cap)
                        out_R, out_w = _grown(out_R, cap), _grown(out_w, cap)
                    out_p[m, 0], out_p[m, 1], out_c[m, 0], out_c[m, 1] = i1, i2, j1, j2
                    out_R[m] = R
                    out_w[m] = w_p[i1] * w_p[i2] * w_c[j1] * w_c[j2]
                    m += 1
    return out_p[:m].copy(), out_c[:m].copy(), out_R[:m].copy(), out_w[:m].copy()


@numba.njit(cache=True)
def _grown(x, cap):  # pragma: no cover - compiled
    """``x`` copied into a buffer of ``cap`` rows (the rows beyond its own uninitialised)."""
    out = np.empty((cap,) + x.shape[1:], dtype=x.dtype)
    out[: len(x)] = x
    return out


@numba.njit(cache=True)
def _dihedral(normals):  # pragma: no cover - compiled
    """:func:`planodom.geometry.dihedral_angles` (K, K), rad."""
    K = len(normals)
    out = np.empty((K, K))
    for i in range(K):
        for j in range(K):
            c = normals[i, 0] * normals[j, 0] + normals[i, 1] * normals[j, 1]
            c += normals[i, 2] * normals[j, 2]
            out[i, j] = np.arccos(min(max(c, -1.0), 1.0))
    return out


@numba.njit(cache=True)
def _reference_point(n1, d1, n2, d2, min_verticality):  # pragma: no cover - compiled
    """:func:`planodom.geometry.horizontal_reference_points` of one pair: (2,), NaN when
    the pair is parallel or its line too flat."""
    v0 = n1[1] * n2[2] - n1[2] * n2[1]
    v1 = n1[2] * n2[0] - n1[0] * n2[2]
    v2 = n1[0] * n2[1] - n1[1] * n2[0]
    norm_v = np.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    out = np.full(2, np.nan)
    if norm_v > 1e-9 and abs(v2) / norm_v >= min_verticality:
        det = n1[0] * n2[1] - n1[1] * n2[0]
        out[0] = (-d1 * n2[1] + d2 * n1[1]) / det
        out[1] = (-n1[0] * d2 + n2[0] * d1) / det
    return out


@numba.njit(cache=True)
def _pair_moves_within(R, k1, f1, k2, f2, t0, ref_p, bound, min_verticality):  # pragma: no cover
    """The translation bound on one candidate's reference points: the current pair
    ``(k1, f1)``, ``(k2, f2)`` rotated by ``R`` (3, 3) and shifted to the height of ``t0``
    has its reference point within ``bound`` of the previous one ``ref_p`` (2,) moved by
    ``t0`` (``bound``: the translation bound plus ``offset_tol / sin(dihedral)`` plus the
    rotation-noise margin ``|ref_p| sin(normal_tol)``, m); NaN (undefined) passes."""
    n1 = np.empty(3)
    n2 = np.empty(3)
    for a in range(3):
        n1[a] = R[a, 0] * k1[0] + R[a, 1] * k1[1] + R[a, 2] * k1[2]
        n2[a] = R[a, 0] * k2[0] + R[a, 1] * k2[1] + R[a, 2] * k2[2]
    ref_c = _reference_point(n1, f1 - n1[2] * t0[2], n2, f2 - n2[2] * t0[2], min_verticality)
    dev = np.sqrt((ref_p[0] - ref_c[0] - t0[0]) ** 2 + (ref_p[1] - ref_c[1] - t0[1]) ** 2)
    return not dev > bound


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
    # C-contiguous (a column of a transform is strided): one compiled specialisation
    t = np.zeros(3) if translation is None else np.ascontiguousarray(translation, np.float64)
    t_bound = cfg.max_translation_m if translation_bound is None else float(translation_bound)
    args = (
        prev.normals, prev.offsets, prev.centroids, prev.radii,
        curr.normals, curr.offsets, curr.centroids, curr.radii,
        np.ascontiguousarray(rotation, dtype=np.float64), t,
        cos_of_degrees(cfg.strict_normal_deg), t_bound + cfg.strict_offset_m,
        t_bound + cfg.overlap_margin_m,
    )  # fmt: skip
    status, pairs = sda_kernel(*args)
    return pairs if status == SOLVED else scipy_strict_pairs(*args)


def scipy_strict_pairs(*args: Any) -> np.ndarray:
    """SDA's pairs of :func:`strict_association`'s kernel arguments as they were made
    before :func:`planodom.sda_kernel.sda_kernel`: its costs, scipy's
    ``linear_sum_assignment`` and the gate in three calls (the same pairs; the path of
    costs scipy rejects, which raises scipy's error, and the tests' reference)."""
    ok, cost = _strict_costs(*args)
    rows, cols = linear_sum_assignment(cost)
    return _kept_pairs(ok, rows, cols)
