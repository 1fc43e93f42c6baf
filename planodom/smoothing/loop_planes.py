"""Loop factors that share their epochs' plane fits (``smoothing.sandwich_loop_sources``
"planes").

A loop factor ``X(a) - X(b)`` (:mod:`.loop_candidates`) is a relative pose solved from the
planes of epochs a and b. Each plane's fit error (its ``Plane.covariance``, the fit's) is
one error: the same in every loop factor solved from that plane (on a lap, every loop
factor comes from the first epoch's planes: NEES2CM, LOOP0) and in the plane factor the
plane itself became. The graph takes the factors as independent, so it counts that error
once per factor. :mod:`.loop_sources` "shared" gave every loop factor half its covariance
as one shared error (too much on one lap, too little on another, NEESDEF); "deskew" maps
only the deskewing error. Here the share is the planes' own: each associated plane is a
column of the sandwich (:mod:`.sandwich`) with its fit's covariance, mapped into

- every loop factor solved from it: ``g = R E dxi/dpi``, ``dxi/dpi = -(K^T W K)^+ K_p^T
  W_p`` (the older epoch's plane; the younger's ``... (-J_T)``) the first-order change of
  the relative pose fitted by weighted least squares to the factor's associated pairs
  (:func:`.loop_deskew.relative_pose_change`'s fit, ``E`` the factor error's change with its
  measurement, ``R`` its whitening);
- the plane factor of that plane, when it is one: ``sign R diag(1, 1, -1) P`` (the map of
  :func:`.error_maps.plane_error_map` without the deskewing Jacobian).

Each factor keeps its own variance (its noise model, the solver's covariance): the terms a
factor has with itself are taken out again (:func:`own_maps`, the sandwich of those terms
alone less its fitted part, as :mod:`.plane_share`), so only the covariances *between*
factors that share a plane are added. Nothing is scaled or fitted: the sizes are the
planes' fit covariances. Only the covariances change.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import gtsam
import numpy as np

from planodom.geometry import Plane
from planodom.smoothing.error_maps import ERROR_SIGN, ErrorMap, ErrorMaps, merged
from planodom.smoothing.loop_deskew import gaussian_loop_factors, pair_jacobian
from planodom.smoothing.loop_records import LoopFactor

#: A plane's (n, d) -> the plane factor's tangent (Unit3 basis (2), d) with errorVector's
#: sign of the offset part (as :func:`.error_maps.plane_error_map`).
_OFFSET_SIGN = np.diag([1.0, 1.0, -1.0])


def _pad(g: np.ndarray) -> np.ndarray:
    """(m, 4) -> (m, 6): a plane's 4 coefficients in a 6-wide sandwich column."""
    out = np.zeros((g.shape[0], 6))
    out[:, :4] = g
    return out


def pair_fit_plane_changes(
    T_a_b: np.ndarray, planes_a: Sequence[Plane], planes_b: Sequence[Plane], pairs: np.ndarray
) -> dict[tuple[str, int], np.ndarray] | None:
    """The (6, 4) first-order changes of the relative pose ``T_a_b`` (right tangent, rad
    and m) fitted by weighted least squares to the associated ``pairs`` (P, 2), per plane
    ``("a", i)`` / ``("b", j)`` of the pairs, with that plane's ``(n, d)``; None when no
    pair has both covariances."""
    JT = np.eye(4)
    JT[:3, :3] = T_a_b[:3, :3]
    JT[3, :3] = -(T_a_b[:3, 3] @ T_a_b[:3, :3])  # plane_transform_jacobian
    KWK = np.zeros((6, 6))
    rows: list[tuple[int, int, np.ndarray]] = []
    for i, j in np.asarray(pairs, dtype=int).reshape(-1, 2):
        pa, pb = planes_a[i], planes_b[j]
        if pa.covariance is None or pb.covariance is None:
            continue
        cov = np.asarray(pa.covariance) + JT @ np.asarray(pb.covariance) @ JT.T
        W = np.linalg.pinv(cov, rcond=1e-9, hermitian=True)
        K = -pair_jacobian(T_a_b, pb)  # r = pi_a - T(xi) pi_b
        KWK += K.T @ W @ K
        rows.append((int(i), int(j), K.T @ W))
    if not rows:
        return None
    inv = np.linalg.pinv(KWK, rcond=1e-9, hermitian=True)
    out: dict[tuple[str, int], np.ndarray] = {}
    for i, j, KW in rows:  # r_p moves by d pi_a and by -J_T d pi_b
        out[("a", i)] = out.get(("a", i), 0.0) - inv @ KW
        out[("b", j)] = out.get(("b", j), 0.0) + inv @ KW @ JT
    return out


def loop_plane_maps(
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    loop_factors: Sequence[LoopFactor],
    index: Mapping[int, int],
    planes: Mapping[int, Sequence[Plane]],
    plane_factors: Mapping[int, tuple[int, Plane]],
    first_column: int,
) -> tuple[dict[int, list[ErrorMap]], np.ndarray]:
    """The sandwich's extra error maps of "planes" (module docstring): factor index in
    ``cov_graph`` -> its terms (column, (m, 6) map), one column per associated plane from
    ``first_column`` on, and the columns' (J, 6, 6) covariances (the plane's fit covariance
    in the first 4 rows and columns). ``index``: whole graph -> ``cov_graph``;
    ``planes``: the builder's planes per epoch; ``plane_factors``: ``cov_graph``'s plane
    factors -> (epoch, the plane as oriented in the factor). Loop factors kept, Gaussian
    in ``cov_graph`` (inliers) and with recorded associations only."""
    column: dict[tuple[int, int], int] = {}
    sizes: list[np.ndarray] = []
    maps: dict[int, list[ErrorMap]] = {}
    for f, i, T, RE in gaussian_loop_factors(cov_graph, values, loop_factors, index):
        assert f.associations is not None  # gaussian_loop_factors keeps recorded ones only
        changes = pair_fit_plane_changes(T, planes[f.old], planes[f.epoch], f.associations)
        if changes is None:
            continue
        for (end, p), M in changes.items():
            epoch = f.old if end == "a" else f.epoch
            plane = planes[epoch][p]
            if (epoch, p) not in column:
                column[(epoch, p)] = first_column + len(sizes)
                q = np.zeros((6, 6))
                q[:4, :4] = np.asarray(plane.covariance, dtype=float)
                sizes.append(q)
            maps.setdefault(i, []).append((column[(epoch, p)], _pad(RE @ M)))
    by_epoch: dict[int, list[tuple[int, Plane]]] = {}
    for (epoch, p), _ in column.items():
        by_epoch.setdefault(epoch, []).append((p, planes[epoch][p]))
    for i, (epoch, plane) in plane_factors.items():
        for p, source in by_epoch.get(epoch, ()):
            sign = _orientation(plane, source)
            g = None if sign is None else _plane_factor_map(cov_graph.at(i), plane)
            if g is not None:
                maps.setdefault(i, []).append((column[(epoch, p)], _pad(sign * g)))
    return maps, np.array(sizes, dtype=float).reshape(-1, 6, 6)


def _orientation(plane: Plane, source: Plane) -> float | None:
    """+1 when ``plane`` is ``source``, -1 when it is ``source`` flipped, else None."""
    a, b = np.asarray(plane.coefficients), np.asarray(source.coefficients)
    if np.array_equal(a, b):
        return 1.0
    if np.array_equal(a, -b):
        return -1.0
    return None


def _plane_factor_map(factor: gtsam.NonlinearFactor, plane: Plane) -> np.ndarray | None:
    """(3, 4) first-order change of a plane factor's whitened error with its measured
    plane's ``(n, d)`` (None for a robust outlier or an unknown factor type)."""
    sign = next((s for t, s in ERROR_SIGN.items() if isinstance(factor, t)), None)
    noise = factor.noiseModel()  # type: ignore[attr-defined]  # a NoiseModelFactor
    if sign is None or not isinstance(noise, gtsam.noiseModel.Gaussian):
        return None
    P = np.zeros((3, 4))  # (n, d) -> tangent, as plane_tangent_covariance
    P[:2, :3] = np.asarray(gtsam.Unit3(plane.normal).basis()).T
    P[2, 3] = 1.0
    return sign * np.asarray(noise.R()) @ _OFFSET_SIGN @ P


def own_maps(
    maps: Mapping[int, Sequence[ErrorMap]], Q: np.ndarray, first_column: int, own_first: int
) -> tuple[dict[int, list[ErrorMap]], np.ndarray]:
    """Each factor's terms of ``maps`` in columns of its own (copies of the shared columns'
    covariances ``Q`` (J, 6, 6), whose first is ``first_column``; the own columns from
    ``own_first`` on): the sandwich of these
    alone, less its fitted part, is what the shared columns add to each factor's own
    variance, which :func:`loop_plane_maps`' model leaves as it is."""
    out: dict[int, list[ErrorMap]] = {}
    sizes: list[np.ndarray] = []
    for i, terms in maps.items():
        own: dict[int, int] = {}
        for c, g in terms:
            if c not in own:
                own[c] = own_first + len(sizes)
                sizes.append(Q[c - first_column])
            out.setdefault(i, []).append((own[c], g))
    return out, np.array(sizes, dtype=float).reshape(-1, 6, 6)


def plane_columns(
    mode: str,
    extra: tuple[ErrorMaps, np.ndarray] | None,
    cov_graph: gtsam.NonlinearFactorGraph,
    values: gtsam.Values,
    loops: tuple[Sequence[LoopFactor], Mapping[int, Sequence[Plane]]],
    index: Mapping[int, int],
    plane_factors: Mapping[int, tuple[int, Plane]],
    n_epochs: int,
) -> tuple[tuple[ErrorMaps, np.ndarray] | None, tuple[ErrorMaps, np.ndarray] | None]:
    """The sandwich's ``extra`` maps and columns with :func:`loop_plane_maps`' after them
    (columns from ``n_epochs`` plus ``extra``'s on), and the :func:`own_maps` of those
    (columns from ``n_epochs`` on) whose sandwich less its fitted part is to be taken off
    again; (``extra``, None) where no loop factor maps or ``mode`` (``smoothing.
    sandwich_loop_sources``) is not "planes"."""
    if mode != "planes":
        return extra, None
    first = n_epochs + (0 if extra is None else len(extra[1]))
    maps, cols = loop_plane_maps(cov_graph, values, loops[0], index, loops[1], plane_factors, first)
    if not maps:
        return extra, None
    own = own_maps(maps, cols, first, n_epochs)
    if extra is None:
        return (maps, cols), own
    return (merged(extra[0], maps), np.concatenate([extra[1], cols])), own
