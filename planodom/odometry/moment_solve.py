"""The moments' weighted least squares (the oracle's cost) by Gauss-Newton with its analytic
Jacobian, for ``odometry.refinement: moments`` (beyond the paper).

:func:`planodom.oracle.relative_pose` minimises the squared point-to-plane distances of two
epochs' planes, each summarised by its inlier moments (:class:`planodom.oracle.
SurfaceMoments`), with a forward-difference Jacobian (seven residual evaluations per
Gauss-Newton step; a median 11 steps a call over its two solves, up to 60, world 154 at
6 mm). The odometry calls it two or three times an epoch, which made the option 3.2x the
CPU of the 2D rig's odometry (docs/RESULTS.md MOMENTS2; 1.4x here). Here the same cost,
the same strong-subspace restriction (:func:`planodom.oracle._strong_subspace`: directions
the planes do not measure keep the initial pose) and the same status, with the second solve
skipped when both judgements find every direction strong (the same full space, only its
basis differs) and the Jacobian in closed form (right perturbation ``T exp(xi)``, ``xi =
(w, v)``; to first order ``R' = R (I + [w]x)``, ``t' = t + R v``, with ``u = R^T n_p`` and ``q =
R^T (c_p - t)``):

    a = L_c^T R^T n_p                  da/dw = L_c^T [u]x                 da/dv = 0
    b = sqrt(N_c) (n_p.(R c_c + t) + d_p)   db/dw = sqrt(N_c) (c_c x u)^T   db/dv = sqrt(N_c) u^T
    c = L_p^T R n_c                    dc/dw = -L_p^T R [n_c]x            dc/dv = 0
    e = sqrt(N_p) (n_c.q + d_c)        de/dw = -sqrt(N_p) (q x n_c)^T     de/dv = -sqrt(N_p) n_c^T

Own code rather than gtsam: the cost is a few dozen residuals of closed form, and a gtsam
graph per call would cost more than the solve. The returned information ``J^T J`` (6, 6),
per unit residual variance, is for diagnostics: :mod:`planodom.odometry.moment_refine`
gates with the consensus's own covariance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planodom.geometry import se3_exp
from planodom.odometry.moment_kernel import moment_terms
from planodom.oracle import SurfaceMoments, _roots, _strong_subspace

#: Gauss-Newton stops when no parameter of a step exceeds this (rad, m): far below any
#: error that matters, above the analytic solve's rounding.
STEP_TOL = 1e-10


@dataclass(frozen=True)
class MomentSolve:
    """``T_prev_curr`` (4, 4); status "ok" | "degenerate" | "unresolved" (as the oracle's);
    ``measured`` (6,) bool (wx, wy, wz, x, y, z); ``information`` (6, 6) ``J^T J`` at the
    solution per unit residual variance, 1/m^2 (rad- and m-parameters)."""

    T_prev_curr: np.ndarray
    status: str
    measured: np.ndarray
    information: np.ndarray


def _skew(v: np.ndarray) -> np.ndarray:
    """(K, 3, 3) cross-product matrices of ``v`` (K, 3)."""
    z = np.zeros(len(v))
    x, y, w = v[:, 0], v[:, 1], v[:, 2]
    return np.stack([z, -w, y, w, z, -x, -y, x, z], axis=1).reshape(-1, 3, 3)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ``a x b`` of (K, 3) arrays: ``np.cross``'s products and differences in its
    order (the same bits) without its axis handling, which took most of its time on the
    few rows an epoch's planes give (a third of the Jacobian's time)."""
    a0, a1, a2, b0, b1, b2 = a[:, 0], a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def moment_jacobian(T: np.ndarray, prev: SurfaceMoments, curr: SurfaceMoments, roots) -> np.ndarray:
    """(M, 6) Jacobian of :func:`planodom.oracle._residuals` (its row order) with respect to
    the right perturbation ``T exp(xi)`` (module docstring); ``roots`` as the oracle's."""
    R, t = T[:3, :3], T[:3, 3]
    Lp, Lc = roots
    k = len(prev.count)
    u = prev.normal @ R  # (K, 3) R^T n_p
    q = (prev.centroid - t) @ R  # (K, 3) R^T (c_p - t)
    sc, sp = np.sqrt(curr.count)[:, None], np.sqrt(prev.count)[:, None]
    ja = np.zeros((k, 3, 6))
    ja[:, :, :3] = np.einsum("kji,kjl->kil", Lc, _skew(u))
    jb = np.concatenate([sc * _cross(curr.centroid, u), sc * u], axis=1)
    jc = np.zeros((k, 3, 6))
    jc[:, :, :3] = -np.einsum("kji,jm,kml->kil", Lp, R, _skew(curr.normal))
    je = np.concatenate([-sp * _cross(q, curr.normal), -sp * curr.normal], axis=1)
    return np.concatenate([ja.reshape(-1, 6), jb, jc.reshape(-1, 6), je])


def moment_solve(
    prev: SurfaceMoments, curr: SurfaceMoments, T_init: np.ndarray, iterations: int = 30
) -> MomentSolve:
    """``T_prev_curr`` of two epochs' associated planes (row ``i`` of ``prev`` with row
    ``i`` of ``curr``), from ``T_init`` (4, 4): the oracle's solve
    (:func:`planodom.oracle.relative_pose`, judged on the planes' own normals) with the
    analytic Jacobian."""
    T0 = np.array(T_init, dtype=np.float64)  # writeable, C-ordered: one compiled layout
    c = lambda a: np.array(a, dtype=np.float64, order="C")  # noqa: E731 - writeable copies
    planes = (
        c(prev.normal), c(curr.normal), c(prev.centroid), c(curr.centroid), c(prev.count),
        c(curr.count), c(prev.offset), c(curr.offset), c(_roots(prev.scatter)),
        c(_roots(curr.scatter)),
    )  # fmt: skip

    last: list = [None, None]  # the pose last evaluated (the same array) and its values

    def jac(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # The start is judged and then solved from, the solution judged and then its
        # information taken: each pose twice in a row, evaluated once (the same values).
        if last[0] is not T:
            last[:] = T, moment_terms(T, *planes)  # the numpy forms' values, compiled
        return last[1]

    def solve(basis: np.ndarray) -> np.ndarray:
        T = T0
        for _ in range(iterations):
            r0, J = jac(T)
            step = basis @ np.linalg.lstsq(J @ basis, -r0, rcond=None)[0]
            T = T @ se3_exp(step)
            if np.max(np.abs(step)) < STEP_TOL:
                break
        return T

    # As the oracle: judged at the start, solved, judged again there, solved again; when
    # both judge every direction strong, the second solve is the first's (the full space,
    # only its basis differs): it is not repeated.
    basis, measured = _strong_subspace(jac(T0)[1])
    T = solve(basis)
    full = basis.shape[1] == 6
    basis, measured = _strong_subspace(jac(T)[1])
    if not (full and basis.shape[1] == 6):
        T = solve(basis)
    J = jac(T)[1]
    rot_ok, xy_ok = bool(measured[:3].all()), bool(measured[3:5].all())
    status = "ok" if rot_ok and xy_ok else "degenerate" if rot_ok else "unresolved"
    return MomentSolve(T if status != "unresolved" else T0, status, measured, J.T @ J)
