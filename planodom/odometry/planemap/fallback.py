"""Scan-to-scan plane registration: hypotheses for the map registration when the
constant-velocity prediction is suspicious (first pair, sudden turns, hand-held 2 Hz).

Given the planes of the previous and current scans (each in its own base frame,
:class:`planodom.planes.PlaneSet`) and a starting guess ``T0``:

1. Association (injective): current planes moved by ``T0``; a pair (i, j) may match when
   the normals are within ``gate_rot``, each centroid lies within ``gate_t`` of the
   other's plane and the bounding circles come within ``gate_t``; the optimal one-to-one
   assignment (Hungarian) of the normalised gate costs.
2. Rotation: WOCSC (:func:`planodom.consensus.consensus`) over the candidates
   ``U_i U_j^T`` of the non-parallel pairs of associations (the best-conditioned
   ``MAX_PAIRS``), weights the planes' normal information.
3. Refinement: robust Gauss-Newton on SE(3) over all associations (normal residual and
   both centroids on the other plane, whitened by the planes' covariances, Cauchy).

:func:`widening` starts from zero motion with gates 10 deg / 1 m and widens them x4
twice; :func:`lda_hypothesis` takes the rotation from LDA without motion bounds
(:func:`planodom.association.lenient_association` on the best-conditioned planes, at most
``lda_per_direction`` per direction, :func:`diverse_best`) and associates around it.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import linear_sum_assignment

from planodom.association import lenient_association
from planodom.config import AssociationConfig, PlanemapConfig
from planodom.consensus import apply_inverse_rotation, consensus
from planodom.geometry import cross_rows, rotation_frames
from planodom.planes import PlaneSet
from planodom.rotvec import rotation_matrices

#: Most plane pairs whose rotations WOCSC scores (best-conditioned first).
MAX_PAIRS = 4000
#: Pairs of associations closer than this to parallel give no rotation candidate (deg).
PAIR_MIN_ANGLE_DEG = 20.0


def associate_pairs(prev: PlaneSet, curr: PlaneSet, T0: np.ndarray, gate_rot: float,
                    gate_t: float) -> np.ndarray:  # fmt: skip
    """(m, 2) one-to-one plane associations (prev, curr) under ``T0`` (step 1)."""
    R0, t0 = T0[:3, :3], T0[:3, 3]
    n_c = curr.normals @ R0.T
    c_c = curr.centroids @ R0.T + t0
    d_c = -np.einsum("ij,ij->i", n_c, c_c)
    cos = prev.normals @ n_c.T
    cmin = np.cos(gate_rot)
    r1 = np.abs(prev.normals @ c_c.T + prev.offsets[:, None])
    r2 = np.abs(prev.centroids @ n_c.T + d_c[None, :])
    dist = np.linalg.norm(prev.centroids[:, None] - c_c[None], axis=2)
    reach = prev.radii[:, None] + curr.radii[None] + gate_t
    ok = (cos >= cmin) & (r1 <= gate_t) & (r2 <= gate_t) & (dist <= reach)
    if not ok.any():
        return np.zeros((0, 2), dtype=np.intp)
    cost = (1 - cos) / (1 - cmin) + ((r1 + r2) / (2 * gate_t)) ** 2 + 0.1 * dist / reach
    rows, cols = linear_sum_assignment(np.where(ok, cost, 1e6))
    keep = ok[rows, cols]
    return np.column_stack([rows[keep], cols[keep]]).astype(np.intp)


def normal_info(p: PlaneSet) -> np.ndarray:
    """(K,) inverse normal variance (trace) of the planes."""
    return 1.0 / np.maximum(np.trace(p.covariances[:, :3, :3], axis1=1, axis2=2), 1e-12)


def rotation_wocsc(
    prev: PlaneSet, curr: PlaneSet, ij: np.ndarray, inlier_angle: float
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """WOCSC rotation ``R_prev_curr`` of the associations ``ij`` and its inlier mask."""
    n_p, n_c = prev.normals[ij[:, 0]], curr.normals[ij[:, 1]]
    a, b = np.triu_indices(len(ij), 1)
    s_p = np.linalg.norm(cross_rows(n_p[a], n_p[b]), axis=1)
    s_c = np.linalg.norm(cross_rows(n_c[a], n_c[b]), axis=1)
    lim = np.sin(np.radians(PAIR_MIN_ANGLE_DEG))
    good = (s_p > lim) & (s_c > lim)
    a, b = a[good], b[good]
    if len(a) == 0:
        return None, None
    w = normal_info(prev)[ij[:, 0]] * normal_info(curr)[ij[:, 1]]
    ww = np.sqrt(w / w.max())
    if len(a) > MAX_PAIRS:
        sel = np.argsort(-(ww[a] * ww[b] * s_p[good]), kind="stable")[:MAX_PAIRS]
        a, b = a[sel], b[sel]
    R = rotation_frames(n_p[a], n_p[b]) @ np.swapaxes(rotation_frames(n_c[a], n_c[b]), 1, 2)
    chord = 2 * np.sin(inlier_angle / 2)
    res = consensus(R, n_p, n_c, apply_inverse_rotation, weights=ww, inlier_tol=chord,
                    truncate=chord, budget=None)  # fmt: skip
    return res.best_candidate, res.inliers


def _skew(v: np.ndarray) -> np.ndarray:
    z = np.zeros(v.shape[:-1])
    return np.stack(
        [np.stack([z, -v[..., 2], v[..., 1]], -1), np.stack([v[..., 2], z, -v[..., 0]], -1),
         np.stack([-v[..., 1], v[..., 0], z], -1)], -2)  # fmt: skip


def refine(prev: PlaneSet, curr: PlaneSet, ij: np.ndarray, T0: np.ndarray, sigma: float,
           iters: int = 8, cauchy_c: float = 3.0) -> tuple[np.ndarray, np.ndarray]:  # fmt: skip
    """Robust Gauss-Newton on all associations ``ij`` from ``T0`` (step 3): the pose and
    the Cauchy weights."""
    R, t = T0[:3, :3].copy(), T0[:3, 3].copy()
    i, j = ij[:, 0], ij[:, 1]
    n_i, d_i, c_i, S_i = prev.normals[i], prev.offsets[i], prev.centroids[i], prev.covariances[i]
    n_j, d_j, c_j, S_j = curr.normals[j], curr.offsets[j], curr.centroids[j], curr.covariances[j]
    var_n = sum(
        np.trace(S[:, :3, :3], axis1=1, axis2=2) / 2 + (sigma / np.maximum(r, 0.1)) ** 2
        for S, r in ((S_i, prev.radii[i]), (S_j, curr.radii[j]))
    )
    m = len(ij)
    rw = np.ones(m)
    for _ in range(iters):
        u, q = n_j @ R.T, c_j @ R.T + t
        rn = u - n_i
        r1 = np.einsum("ij,ij->i", n_i, q) + d_i
        r2 = np.einsum("ij,ij->i", u, c_i - t) + d_j
        v1 = np.concatenate([q, np.ones((m, 1))], 1)
        v2 = np.concatenate([(c_i - t) @ R, np.ones((m, 1))], 1)
        var1 = np.einsum("mi,mij,mj->m", v1, S_i, v1) + sigma**2
        var2 = np.einsum("mi,mij,mj->m", v2, S_j, v2) + sigma**2
        Jn = np.concatenate([-_skew(u), np.zeros((m, 3, 3))], 2)
        J1 = np.concatenate([np.cross(q - t, n_i), n_i], 1)
        J2 = np.concatenate([np.cross(u, c_i - t), -u], 1)
        chi = (np.sum(rn**2, 1) / var_n + r1**2 / var1 + r2**2 / var2) / 5.0
        rw = 1.0 / (1.0 + chi / cauchy_c**2)
        H = np.einsum("m,mki,mkj->ij", rw / var_n, Jn, Jn)
        g = np.einsum("m,mki,mk->i", rw / var_n, Jn, rn)
        for J, r, v in ((J1, r1, var1), (J2, r2, var2)):
            H += np.einsum("m,mi,mj->ij", rw / v, J, J)
            g += np.einsum("m,mi,m->i", rw / v, J, r)
        ev, V = np.linalg.eigh(H)
        inv = np.where(ev > 4e-3, 1.0 / np.maximum(ev, 1e-300), 0.0)
        dx = -(V * inv) @ V.T @ g
        R = rotation_matrices(dx[:3]) @ R
        t = t + dx[3:]
        if np.linalg.norm(dx) < 1e-9:
            break
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, t
    return T, rw


def _from_guess(prev: PlaneSet, curr: PlaneSet, T0: np.ndarray, gate_rot: float, gate_t: float,
                sigma: float, min_inliers: int) -> np.ndarray | None:  # fmt: skip
    """Steps 1-3 from ``T0``; None when too few associations or inliers remain."""
    ij = associate_pairs(prev, curr, T0, min(gate_rot, np.pi / 2), gate_t)
    if len(ij) < min_inliers:
        return None
    R, inl = rotation_wocsc(prev, curr, ij, max(np.radians(2.0), gate_rot / 3))
    if R is None or inl is None or np.count_nonzero(inl) < min_inliers:
        return None
    Tr = T0.copy()
    Tr[:3, :3] = R
    T, rw = refine(prev, curr, ij[inl], Tr, sigma)
    return T if np.count_nonzero(rw > 0.5) >= min_inliers else None


def widening(prev: PlaneSet, curr: PlaneSet, sigma: float, min_inliers: int) -> np.ndarray | None:
    """``T_prev_curr`` from zero motion with gates 10 deg / 1 m, x4, x16 (first that
    works), or None."""
    gr, gt = np.radians(10.0), 1.0
    for _ in range(3):
        T = _from_guess(prev, curr, np.eye(4), gr, gt, sigma, min_inliers)
        if T is not None:
            return T
        gr, gt = gr * 4, gt * 4
    return None


def lda_hypothesis(prev: PlaneSet, curr: PlaneSet, sigma: float,
                   config: PlanemapConfig) -> np.ndarray | None:  # fmt: skip
    """``T_prev_curr`` from LDA's rotation without motion bounds, associated within 3 deg
    and 4 m around it and refined; None when LDA finds nothing."""
    top, per = config.lda_planes, config.lda_per_direction
    ip, ic = diverse_best(prev, top, per), diverse_best(curr, top, per)
    bounds = AssociationConfig(max_translation_m=1e3, max_rotation_deg=180.0)
    lda = lenient_association(prev.take(ip), curr.take(ic), bounds)
    if len(lda) == 0:
        return None
    ij = lda.plane_associations()
    res = consensus(
        lda.rotations, prev.take(ip).normals[ij[:, 0]], curr.take(ic).normals[ij[:, 1]],
        apply_inverse_rotation, inlier_tol=2 * np.sin(np.radians(1.5)),
        truncate=2 * np.sin(np.radians(3)), groups=ij[:, 0],
    )  # fmt: skip
    T0 = np.eye(4)
    T0[:3, :3] = res.best_candidate
    return _from_guess(prev, curr, T0, np.radians(3.0), 4.0, sigma, config.min_inliers)


def diverse_best(p: PlaneSet, top: int, per_direction: int, same_deg: float = 5.0) -> np.ndarray:
    """Indices of up to ``top`` planes by normal information, at most ``per_direction``
    of nearly one direction (within ``same_deg``): on a road the most precise planes are
    ground patches, which say nothing about yaw. Bounded: LDA's candidates grow with
    top^2, not with the scene."""
    order = np.argsort(-normal_info(p), kind="stable")
    cmin = np.cos(np.radians(same_deg))
    chosen: list[int] = []
    for k in order:
        if len(chosen) >= top:
            break
        if chosen and np.count_nonzero(p.normals[chosen] @ p.normals[k] > cmin) >= per_direction:
            continue
        chosen.append(int(k))
    return np.array(chosen, dtype=np.intp)
