"""Both epochs' deskewing errors in a relative-pose factor (``sandwich_relative_sources``).

A relative-pose factor ``X(a) - X(b)`` (a step within ``smoothing.delta_max``, a
rotation-only step, a loop factor) is solved from the planes of epochs a and b. Each
epoch's planes were deskewed with a twist off by that epoch's change of motion ``dxi``
(:mod:`.sandwich`), which moves each plane by its own ``Plane.deskew_jacobian`` ``D``
(4, 6): the same error as in the epoch's own plane factors, which the factor's covariance
(the planes' fit noise) leaves out. :mod:`.loop_deskew` maps epoch a's into the loop
factors; here each end of every relative-pose factor gets its map into its epoch's own
column of the sandwich:

    g_a = R E M_a,   M_a = -(K^T W K)^+ K^T W D_a,
    g_b = R E M_b,   M_b = +(K^T W K)^+ K^T W J_T D_b,

``M`` (6, 6) the first-order change of the relative pose (gtsam's right tangent of
``T_a_b``) fitted by weighted least squares to the factor's associated plane pairs
(residual ``r = pi_a - T_a_b(xi) pi_b`` in ``(n, d)``, ``K = dr / dxi``, ``W`` the
pseudo-inverse of both planes' covariance, ``J_T`` the change of ``T_a_b pi_b`` with
``pi_b``) when the planes of a (of b) move by ``D dxi``; a plane without a Jacobian does
not move. ``E`` (m, 6) is the factor's error's change with its measurement, ``R`` its
whitening (:func:`.loop_deskew.error_change`). Nothing is scaled or fitted: the sizes are
the run's ``Q_a``, ``Q_b`` and the planes' own Jacobians.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence, Set

import gtsam
import numpy as np

from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.error_maps import ErrorMap
from planodom.smoothing.graph import X
from planodom.smoothing.loop_deskew import error_change, pair_jacobian
from planodom.smoothing.loop_records import LoopFactor

#: Relative rank below which (K^T W K)'s directions are left out (not measured).
RCOND = 1e-9


def plane_transform_jacobian(T_a_b: np.ndarray) -> np.ndarray:
    """(4, 4) change of ``(n, d)`` of a plane of frame b expressed in frame a with its
    ``(n, d)`` in b: ``n_a = R n_b``, ``d_a = d_b - n_a . t``."""
    JT = np.eye(4)
    JT[:3, :3] = T_a_b[:3, :3]
    JT[3, :3] = -(T_a_b[:3, 3] @ T_a_b[:3, :3])
    return JT


def pair_fit_changes(
    T_a_b: np.ndarray, planes_a: Sequence[Plane], planes_b: Sequence[Plane], pairs: np.ndarray
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """``(M_a, M_b)`` (6, 6) each of the module docstring: the change of the relative pose
    ``T_a_b`` (4, 4; right tangent, rad and m) fitted to the associated ``pairs`` (P, 2)
    (index in ``planes_a``, index in ``planes_b``) with epoch a's (b's) change of motion
    through its planes' ``deskew_jacobian``. Pairs without both covariances are left out;
    None for an end none of whose used planes has a Jacobian (or without any pair)."""
    JT = plane_transform_jacobian(T_a_b)
    KWK, KWD_a, KWD_b = np.zeros((6, 6)), np.zeros((6, 6)), np.zeros((6, 6))
    moved = [False, False]
    for i, j in np.asarray(pairs, dtype=int).reshape(-1, 2):
        pa, pb = planes_a[i], planes_b[j]
        if pa.covariance is None or pb.covariance is None:
            continue
        cov = np.asarray(pa.covariance) + JT @ np.asarray(pb.covariance) @ JT.T
        W = np.linalg.pinv(cov, rcond=RCOND, hermitian=True)
        KW = -pair_jacobian(T_a_b, pb).T @ W  # K = dr/dxi = -d(T pi_b)/dxi
        KWK += KW @ -pair_jacobian(T_a_b, pb)
        if pa.deskew_jacobian is not None:
            KWD_a += KW @ np.asarray(pa.deskew_jacobian, dtype=float)
            moved[0] = True
        if pb.deskew_jacobian is not None:
            KWD_b += KW @ JT @ np.asarray(pb.deskew_jacobian, dtype=float)
            moved[1] = True
    inverse = np.linalg.pinv(KWK, rcond=RCOND, hermitian=True)
    M_a = -inverse @ KWD_a if moved[0] else None
    M_b = inverse @ KWD_b if moved[1] else None
    return M_a, M_b


def relative_error_maps(
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    motion_change: np.ndarray,
    delta_max: int,
    index: Mapping[int, int],
    loops: tuple[Sequence[LoopFactor], Mapping[int, Sequence[Plane]]],
    relatives: Sequence[RelativePose],
    skip: Set[int] = frozenset(),
) -> dict[int, list[ErrorMap]]:
    """Error maps for the sandwich (:func:`.sandwich.sandwich_covariances`' ``extra``):
    factor index in ``cov_graph`` -> its terms ``(epoch, g)`` for epochs a and b of
    every relative-pose factor ``X(a) - X(b)`` with a Gaussian noise model (an inlier) and
    recorded associations: the kept loop factors (``loops``: the builder's loop factors
    and its planes per epoch; ``index``: whole graph -> ``cov_graph``) and the measured
    ``relatives`` at most ``delta_max`` apart; an end whose ``motion_change`` ((E, 6, 6))
    is zero or whose planes have no Jacobian has no term. ``skip``: ``cov_graph`` indices
    left out (the fallback factors, which no planes measured)."""
    loop_of = {index[f.factor]: f for f in loops[0] if not f.removed and f.factor in index}
    rel_of = {(r.prev, r.curr): r for r in relatives if r.measured}
    maps: dict[int, list[ErrorMap]] = {}
    for i in range(cov_graph.size()):
        factor = cov_graph.at(i)
        if i in skip or factor is None or len(factor.keys()) != 2 or factor.dim() not in (3, 5):
            continue
        symbols = [gtsam.Symbol(key) for key in factor.keys()]
        if any(chr(s.chr()) != "x" for s in symbols):
            continue
        a, b = sorted(int(s.index()) for s in symbols)
        noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
        source = _source(loop_of.get(i), rel_of.get((a, b)) if b - a <= delta_max else None)
        if source is None or not isinstance(noise, gtsam.noiseModel.Gaussian):
            continue
        T, pairs = source
        ends = pair_fit_changes(T, loops[1][a], loops[1][b], pairs)
        Ta, Tb = (values.atPose3(X(k)).matrix() for k in (a, b))
        RE = np.asarray(noise.R()) @ error_change(T, Ta, Tb, factor.dim())
        terms = [(k, RE @ M) for k, M in zip((a, b), ends, strict=True)
                 if M is not None and np.any(motion_change[k])]  # fmt: skip
        if terms:
            maps[i] = terms
    return maps


def _source(
    loop: LoopFactor | None, rel: RelativePose | None
) -> tuple[np.ndarray, np.ndarray] | None:
    """(T_a_b, associations) of a loop factor or a relative pose, None without any."""
    if loop is not None and loop.associations is not None and len(loop.associations):
        return np.asarray(loop.T_old_curr, dtype=float), np.asarray(loop.associations)
    if loop is None and rel is not None and rel.associations is not None and len(rel.associations):
        return np.asarray(rel.T_prev_curr, dtype=float), np.asarray(rel.associations)
    return None
