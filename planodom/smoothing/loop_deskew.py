"""A loop factor's share of its older epoch's deskewing error (``sandwich_loop_sources``
"deskew").

A loop factor ``X(a) - X(b)`` (:mod:`.loop_candidates`) is a relative pose solved from the
planes of epochs a and b. Epoch a's planes were deskewed with a twist off by that epoch's
change of motion ``dxi_a`` (:mod:`.sandwich`), which moves each of them by its own
``Plane.deskew_jacobian`` ``D`` (4, 6): one error, the same in every loop factor solved
from a's planes and in a's own plane factors, which the factors' covariances leave out.
The sandwich already holds ``dxi_a`` as epoch a's column, with the run's covariance ``Q_a``
(:func:`.batch_covariances.sandwich_inputs`); here each loop factor gets its map into that
column: the first-order change of its whitened error with ``dxi_a``,

    g = R E M,    M = -(K^T W K)^+ K^T W D,

``M`` (6, 6) the change of the relative pose (gtsam's right tangent of ``T_a_b``) fitted by
weighted least squares to the factor's associated plane pairs when a's planes move by
``D dxi_a`` (residual ``r = pi_a - T_a_b(xi) pi_b`` in ``(n, d)``, ``K = dr / dxi``, ``W``
the pseudo-inverse of both planes' covariance), ``E`` (m, 6) the factor's error's change
with its measurement, ``R`` its whitening. The solver takes the rotation from one pair and
the translation from a fit over the associated planes (``odometry.refinement``); the fit
over all of them is the first-order model of both. Nothing is scaled or fitted here: the
size is the run's ``Q_a`` and the planes' own Jacobians. Not modelled: the younger epoch
b's deskewing (the sandwich's maps take one column per factor; b has few loop factors)
and the planes' fit noise (in the factor's covariance already).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence

import gtsam
import numpy as np

from planodom.geometry import Plane
from planodom.se3 import se3_exp
from planodom.smoothing.graph import X
from planodom.smoothing.loop_records import LoopFactor
from planodom_factors.pose5 import pose5_error

#: Central-difference step of the factor's error in its measurement's tangent (rad, m).
STEP = 1e-6


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def pair_jacobian(T_a_b: np.ndarray, plane_b: Plane) -> np.ndarray:
    """(4, 6) change of ``plane_b`` expressed in frame a, ``(n, d)``, with the right
    perturbation ``T_a_b Exp(xi)``, ``xi = (omega, v)``: ``n' = R Exp(omega) n_b``,
    ``d' = d_b - n' . (t + R v)``."""
    R, t = T_a_b[:3, :3], T_a_b[:3, 3]
    n_b = np.asarray(plane_b.normal, dtype=float)
    out = np.zeros((4, 6))
    out[:3, :3] = -R @ _skew(n_b)
    out[3, :3] = t @ R @ _skew(n_b)
    out[3, 3:] = -n_b
    return out


def relative_pose_change(
    T_a_b: np.ndarray, planes_a: Sequence[Plane], planes_b: Sequence[Plane], pairs: np.ndarray
) -> np.ndarray | None:
    """(6, 6) ``M`` of the module docstring: the change of the relative pose ``T_a_b``
    (4, 4; right tangent, rad and m) fitted to the associated ``pairs`` (P, 2) (index in
    ``planes_a``, index in ``planes_b``) with epoch a's change of motion, through a's
    planes' ``deskew_jacobian``; None when no pair has both covariances and a's Jacobian."""
    JT = np.eye(4)
    JT[:3, :3] = T_a_b[:3, :3]
    JT[3, :3] = -(T_a_b[:3, 3] @ T_a_b[:3, :3])  # plane_transform_jacobian
    KWK, KWD = np.zeros((6, 6)), np.zeros((6, 6))
    used = 0
    for i, j in np.asarray(pairs, dtype=int).reshape(-1, 2):
        pa, pb = planes_a[i], planes_b[j]
        if pa.covariance is None or pb.covariance is None or pa.deskew_jacobian is None:
            continue
        cov = np.asarray(pa.covariance) + JT @ np.asarray(pb.covariance) @ JT.T
        W = np.linalg.pinv(cov, rcond=1e-9, hermitian=True)
        K = -pair_jacobian(T_a_b, pb)  # r = pi_a - T(xi) pi_b
        KWK += K.T @ W @ K
        KWD += K.T @ W @ np.asarray(pa.deskew_jacobian, dtype=float)
        used += 1
    if not used:
        return None
    return -np.linalg.pinv(KWK, rcond=1e-9, hermitian=True) @ KWD


def error_change(
    T_a_b: np.ndarray, T_world_a: np.ndarray, T_world_b: np.ndarray, dim: int
) -> np.ndarray:
    """(dim, 6) ``E``: the change of the factor's error (its first ``dim`` rows of
    :func:`planodom_factors.pose5.pose5_error`) at the poses with its measurement
    ``T_a_b Exp(xi)``, by central differences."""
    out = np.zeros((dim, 6))
    for c in range(6):
        step = np.zeros(6)
        step[c] = STEP
        plus = pose5_error(T_a_b @ se3_exp(step), T_world_a, T_world_b)[0]
        minus = pose5_error(T_a_b @ se3_exp(-step), T_world_a, T_world_b)[0]
        out[:, c] = (plus - minus)[:dim] / (2.0 * STEP)
    return out


def gaussian_loop_factors(
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    loop_factors: Sequence[LoopFactor],
    index: Mapping[int, int],
) -> Iterator[tuple[LoopFactor, int, np.ndarray, np.ndarray]]:
    """The kept loop factors with recorded associations and a Gaussian noise model in
    ``cov_graph`` (inliers; ``index``: whole graph -> ``cov_graph``): (the record, its
    index in ``cov_graph``, its relative pose T_old_curr (4, 4), and R·dE, the whitened
    change of its error with its measured pose ((dim, 6); :func:`error_change`))."""
    for f in loop_factors:
        i = index.get(f.factor)
        if f.removed or i is None or f.associations is None:
            continue
        factor = cov_graph.at(i)
        noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
        if not isinstance(noise, gtsam.noiseModel.Gaussian):
            continue
        T = np.asarray(f.T_old_curr, dtype=float)
        Ta, Tb = (values.atPose3(X(k)).matrix() for k in (f.old, f.epoch))
        yield f, i, T, np.asarray(noise.R()) @ error_change(T, Ta, Tb, factor.dim())


def loop_deskew_maps(
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    loop_factors: Sequence[LoopFactor],
    index: Mapping[int, int],
    planes: Mapping[int, Sequence[Plane]],
    motion_change: np.ndarray,
) -> dict[int, tuple[int, np.ndarray]]:
    """Error maps for the sandwich (:func:`.sandwich.sandwich_covariances`' ``extra``):
    factor index in ``cov_graph`` -> (its older epoch a, the column of a's change of
    motion; (m, 6) ``g`` of the module docstring), for each kept loop factor (``index``:
    whole graph -> ``cov_graph``, :func:`.sandwich.covariance_graph_index`) with a
    Gaussian noise model there (an inlier), recorded associations, planes with
    Jacobians and a non-zero ``motion_change[a]`` ((E, 6, 6))."""
    maps: dict[int, tuple[int, np.ndarray]] = {}
    for f, i, T, RE in gaussian_loop_factors(cov_graph, values, loop_factors, index):
        if not np.any(motion_change[f.old]):
            continue
        assert f.associations is not None  # gaussian_loop_factors keeps recorded ones only
        M = relative_pose_change(T, planes[f.old], planes[f.epoch], f.associations)
        if M is not None:
            maps[i] = (f.old, RE @ M)
    return maps
