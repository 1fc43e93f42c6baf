"""How well a match's own pose lays its associated planes on their old partners (issue 14).

A re-identification of full rank fits its pose to all its pairs. One of rotation only
(one wall and the ground, :mod:`planodom.smoothing.loops`) is verified on its yaw alone,
yet each of its ties also states where the pose lies along the tied wall's normal: that
translation is checked by nothing. On the 2D-rig world 2 at 6 mm, after the odometry's
failure bent the map by about 37 degrees, 19 of its 20 wrong ties came from such
matches, their walls 2.9 to 3.1 m off their old partners at the match's pose (a room's
wall tied to a parallel wall 4.9 m away). :func:`offset_residuals` measures that
residual, :func:`offset_verdict` weighs it against the drift of the predicted pose
(a fixed bound of 0.35 m refused 221 right matches on world 4 at 2 cm, where the chained
guess drifts further between matches, and its ATE rose 0.025 -> 0.126 m).

Written here, not taken from a library: a residual of the paper's plane association.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planodom.geometry import Plane


@dataclass
class OffsetFit:
    """The ties of a rotation-only match against every old plane parallel to them.

    Attributes:
        residuals: (M, N) ``d_old - d_curr`` (m) of tie m's current plane (at the match's
            pose, oriented like old plane n) against old plane n; NaN where plane n is not
            parallel to it (nor its tied partner).
        normals: (N, 3) the old planes' unit normals, in the old frame.
        old_variances: (N,) the old planes' offset variances, m^2.
        curr_variances: (M,) the tied current planes' offset variances, m^2.
        tied: (M,) int, index of each tie's old partner.
        cos_parallel: cosine of the largest angle between parallel normals.
        between: (M, M) variance (m^2) of the horizontal position drift of the map
            between the sightings of tie a's and tie b's old planes (per axis).
    """

    residuals: np.ndarray
    normals: np.ndarray
    old_variances: np.ndarray
    curr_variances: np.ndarray
    tied: np.ndarray
    cos_parallel: float
    between: np.ndarray


def offset_residuals(
    old: Sequence[Plane],
    curr: Sequence[Plane],
    pairs: np.ndarray,
    T_old_curr: np.ndarray,
    default_sigma_m: float,
    parallel_deg: float,
    between: np.ndarray,
) -> OffsetFit:
    """Offset residuals of the tied planes at the match's own pose, against their partners
    and every other old plane within ``parallel_deg`` of the same orientation.

    Args:
        old: planes of the old side (map or old epoch), in its frame.
        curr: planes of the current epoch, in its frame.
        pairs: (M, 2) int, (index into ``old``, index into ``curr``).
        T_old_curr: (4, 4) the current frame in the old one as the match places it.
        default_sigma_m: offset sigma of a plane without covariance, m.
        parallel_deg: largest angle between normals of an alternative partner, degrees.
        between: (M, M) see :class:`OffsetFit`.
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    normals = np.array([p.normal for p in old], dtype=float).reshape(-1, 3)
    offsets = np.array([p.offset for p in old], dtype=float)
    residuals = np.full((len(pairs), len(old)), np.nan)
    curr_var = np.zeros(len(pairs))
    for row, (m, i) in enumerate(pairs):
        plane = curr[i].transformed(T_old_curr)
        sign = 1.0 if plane.normal @ old[m].normal >= 0 else -1.0
        parallel = normals @ (sign * plane.normal) >= np.cos(np.radians(parallel_deg))
        parallel[m] = True
        residuals[row, parallel] = offsets[parallel] - sign * plane.offset
        curr_var[row] = _offset_variance(plane, default_sigma_m)
    old_var = np.array([_offset_variance(p, default_sigma_m) for p in old], dtype=float)
    cos = float(np.cos(np.radians(parallel_deg)))
    return OffsetFit(residuals, normals, old_var, curr_var, pairs[:, 0].copy(), cos, between)


def offset_verdict(fit: OffsetFit, drift_xy: np.ndarray, limit: float) -> tuple[str, float]:
    """Whether each tie's offset residual passes chi2(1) at ``limit``, and the ties agree.

    Each tie's squared whitened residual is ``r^2 / (n_xy^T drift_xy n_xy + v_old +
    v_curr)`` (a position error t of the pose moves a plane's offset by n.t): a tie fails
    ("misfit") above ``limit``. Two ties of parallel walls place the pose along the same
    normal: the difference of their residuals must pass chi2(1) under the four planes'
    offset variances and the map's drift between the old planes' sightings (``between``:
    only that part of the drift does not cancel), else "inconsistent ties" (on the 2D-rig
    world 2 at 6 mm, matches tied two facing walls 1.8 and 2.9 m off in opposite
    senses, under a drift of 2.4 m that let each pass alone).

    Args:
        fit: the residuals (:func:`offset_residuals`).
        drift_xy: (2, 2) covariance of the pose's horizontal position error, m^2, in the
            frame of the normals.
        limit: chi2(1) quantile.

    Returns:
        ("misfit" | "inconsistent ties" | "", largest squared whitened residual of the ties).
    """
    if len(fit.tied) == 0:
        return "", 0.0
    n_xy = fit.normals[:, :2]
    drift = np.einsum("ni,ij,nj->n", n_xy, drift_xy, n_xy)
    var = drift[None, :] + fit.old_variances[None, :] + fit.curr_variances[:, None]
    stat = fit.residuals**2 / var
    rows = np.arange(len(fit.tied))
    worst = float(np.max(stat[rows, fit.tied]))
    if worst > limit:
        return "misfit", worst
    # parallel ties move together with the pose along their normal: the drift cancels
    # from their difference, which only the planes' noise explains
    tied_r = fit.residuals[rows, fit.tied]
    tied_v = fit.old_variances[fit.tied] + fit.curr_variances
    dots = fit.normals[fit.tied] @ fit.normals[fit.tied].T
    parallel = np.abs(dots) >= fit.cos_parallel  # facing walls: residuals of opposite sign
    apart = (tied_r[:, None] - np.sign(dots) * tied_r[None, :]) ** 2
    apart /= tied_v[:, None] + tied_v[None, :] + fit.between
    return ("inconsistent ties" if np.any(parallel & (apart > limit)) else ""), worst


def _offset_variance(plane: Plane, default_sigma_m: float) -> float:
    """Offset variance (m^2) of a plane: its fit's, else the default sigma's square."""
    if plane.covariance is None:
        return default_sigma_m**2
    return float(plane.covariance[3, 3])


def _fit_shift(b: np.ndarray, n_xy: np.ndarray, w: np.ndarray, prior: float) -> float:
    """Smallest chi2 of a horizontal shift t (2,) of the pose, m, laying every tie at
    ``b + n_xy @ t = 0`` (offsets ``b`` (M,) m, normals ``n_xy`` (M, 2), weights ``w`` (M,)
    1/m^2) under an isotropic prior of information ``prior`` (1/m^2) around no shift."""
    H = np.einsum("m,mi,mj->ij", w, n_xy, n_xy) + prior * np.eye(2)
    t = np.linalg.solve(H, -(n_xy.T @ (w * b)))
    return float(np.sum(w * (b + n_xy @ t) ** 2) + prior * t @ t)


def ambiguity(
    fit: OffsetFit,
    sigma_prior_m: float,
    floor_m: float,
    same: tuple[np.ndarray, float] | None = None,
    spacing: bool = False,
) -> float:
    """The smallest of :func:`tie_ambiguities` (inf without ties)."""
    rows = tie_ambiguities(fit, sigma_prior_m, floor_m, same, spacing=spacing)
    return float(np.min(rows, initial=np.inf))


def tie_ambiguities(
    fit: OffsetFit,
    sigma_prior_m: float,
    floor_m: float,
    same: tuple[np.ndarray, float] | None = None,
    parts: bool = False,
    spacing: bool = False,
) -> np.ndarray:
    """(M,) how far the match's ties beat their best competing hypotheses: per tie, the
    smallest increase of chi2 (a likelihood ratio) when one tie's old plane is swapped for a
    parallel old plane of the same orientation, the pose shifted to fit (least squares
    over every tie's offset residual under the planes' offset variances, and the
    prediction's isotropic prior of ``sigma_prior_m``, m); inf for a tie without
    alternatives.
    ``floor_m`` is added in quadrature to every offset sigma (the map's planes agree to
    its drift, not to their fits' centimetres or less). ``same``: (N, N) variances (m^2)
    of the map's drift between the old planes' sightings, and a chi2(1) quantile: an
    alternative whose offset its tied partner's explains within them is one plane to the
    map (a wall seen twice, drifted), no competitor (either tie is as right as the map).
    ``parts`` (with ``same``): each tie's offset variance also holds the map's drift
    between its old plane's sighting and the nearest other tied plane's (a wall of
    another map part shares no frame with the other ties: they confirm no alias of it).
    ``spacing``: also the tie moved by the same spacing the other way (a wall one spacing
    beyond the tied one, on the side no old plane shows: parallel walls that repeat).

    ``fit`` must hold the residuals at the predicted position (the match's rotation, no
    translation): a match of full rank sits on its own ties, so at its pose an alias
    whose shift only the aliased tie measures looks as far off as the prior allows it to
    be, and the alias tied wrong, the right partner looks as far (2D-rig world 16 at
    2 cm: a wall tied to a parallel one 4.2 m away, the match's position sigma 1.7 m).
    """
    rows = np.arange(len(fit.tied))
    best = np.full(len(rows), np.inf)
    if not len(rows):
        return best
    n_xy = fit.normals[fit.tied, :2]
    v_curr = fit.curr_variances + floor_m**2
    if parts and same is not None and len(rows) > 1:
        between = same[0][np.ix_(fit.tied, fit.tied)] + np.diag(np.full(len(rows), np.inf))
        v_curr = v_curr + between.min(axis=1)
    w = 1.0 / (fit.old_variances[fit.tied] + v_curr)
    b = fit.residuals[rows, fit.tied]
    prior = 1.0 / sigma_prior_m**2
    accepted = _fit_shift(b, n_xy, w, prior)
    for row in rows:
        for alt in np.flatnonzero(np.isfinite(fit.residuals[row])):
            if alt == fit.tied[row]:
                continue
            if same is not None:
                j, (between, limit) = fit.tied[row], same
                apart = (fit.residuals[row, alt] - b[row]) ** 2
                spread = between[j, alt] + fit.old_variances[[j, alt]].sum() + 2 * floor_m**2
                if apart <= limit * spread:
                    continue
            w_alt = w.copy()
            w_alt[row] = 1.0 / (fit.old_variances[alt] + v_curr[row])
            shifts = [fit.residuals[row, alt]]
            if spacing:
                shifts.append(2 * b[row] - fit.residuals[row, alt])
            for shift in shifts:
                b_alt = b.copy()
                b_alt[row] = shift
                best[row] = min(best[row], _fit_shift(b_alt, n_xy, w_alt, prior) - accepted)
    return best


def _extent(plane: Plane, T_world_base: np.ndarray) -> tuple[np.ndarray, float]:
    """World centroid and radius of a plane's support (the plane's foot point, 0 m
    radius, when it has none)."""
    sup = plane.support
    if sup is None:
        centroid = -plane.offset * plane.normal
        return T_world_base[:3, :3] @ centroid + T_world_base[:3, 3], 0.0
    radius = float(np.max(np.linalg.norm(sup.polygon - sup.centroid, axis=1), initial=0.0))
    return T_world_base[:3, :3] @ sup.centroid + T_world_base[:3, 3], radius


def _sphere_union(c1: np.ndarray, r1: float, c2: np.ndarray, r2: float) -> tuple[np.ndarray, float]:
    """The smallest sphere holding spheres (c1, r1) and (c2, r2)."""
    dist = float(np.linalg.norm(c2 - c1))
    if dist + r2 <= r1:
        return c1, r1
    if dist + r1 <= r2:
        return c2, r2
    radius = 0.5 * (dist + r1 + r2)
    return c1 + (radius - r1) / dist * (c2 - c1), radius


def non_parallel(normals: np.ndarray, min_angle_deg: float = 10.0) -> bool:
    """Whether two of the unit ``normals`` (N, 3) are at least ``min_angle_deg`` apart."""
    if len(normals) < 2:
        return False
    cross = np.linalg.norm(np.cross(normals[:, None], normals[None]), axis=2)
    return bool(cross.max() >= np.sin(np.radians(min_angle_deg)))


def spanning_epoch(seen: Sequence[int], normals: np.ndarray, min_angle_deg: float = 10.0) -> int:
    """The last sighting by which a match's tied walls span two non-parallel normals: the
    map part that places the matched epoch in full (both horizontal axes), not along one
    wall's normal only. ``seen`` (N,) last-seen epochs of the tied walls, ``normals``
    (N, 3) their unit world normals; the latest of ``seen`` when all are parallel (the
    wall first seen fixes one axis, the pose along it rests on later ones). N >= 1."""
    order = np.argsort(np.asarray(seen), kind="stable")
    epochs, stacked = np.asarray(seen)[order], np.asarray(normals, dtype=float)[order]
    for n in range(2, len(order) + 1):
        if non_parallel(stacked[:n], min_angle_deg):
            return int(epochs[n - 1])
    return int(epochs[-1])


def epoch_ambiguity(
    old: Sequence[Plane],
    curr: Sequence[Plane],
    pairs: np.ndarray,
    T_old_curr: np.ndarray,
    sigma_prior_m: float,
    floor_m: float,
    parallel_deg: float,
    limit: float,
    spacing: bool = False,
    level_deg: float = 30.0,
) -> float:
    """How far an epoch-to-epoch match's ties beat their best competing association in
    either epoch: :func:`ambiguity` with one tie's old plane swapped for another parallel
    old plane, and with its current plane swapped for another parallel current plane (the
    roles exchanged, ``T_old_curr`` inverted); inf without alternatives.

    Two planes of one epoch are one frame's: an alternative whose offset lies within
    chi2(1) at ``limit`` of the tied plane's (their offset variances and ``floor_m`` twice,
    in quadrature) is the same wall extracted twice, no competitor; one farther off is
    another wall, which the prediction may have mistaken for the tied one when its
    prior ``sigma_prior_m`` (m) does not tell the two apart.

    Args:
        old, curr: the two epochs' planes, each in its own frame.
        pairs: (M, 2) int, (index into ``old``, index into ``curr``).
        T_old_curr: (4, 4) the match's rotation at the predicted position (see
            :func:`tie_ambiguities`: at the match's own pose an alias looks as far off
            as the prior allows).
        sigma_prior_m: isotropic sigma of the predicted position, m.
        floor_m: offset sigma added in quadrature to every plane's, m.
        parallel_deg: largest angle between normals of an alternative, degrees.
        limit: chi2(1) quantile that tells a duplicate from another wall.
        spacing: also each alternative's spacing the other way (:func:`tie_ambiguities`).
        level_deg: ties of planes tilted less than this from horizontal are left out: a
            level plane places x, y only through its tilt (2D-rig world 32: a floor and
            ceiling 1 deg off level, their offsets 0.11 m apart at a prediction 5 m off,
            held the fit's x as firmly as a wall).
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    level = float(np.cos(np.radians(level_deg)))
    pairs = pairs[[abs(old[i].normal[2]) < level for i in pairs[:, 0]]]
    T_curr_old = np.linalg.inv(T_old_curr)
    best = np.inf
    for a, b, T, p in ((old, curr, T_old_curr, pairs), (curr, old, T_curr_old, pairs[:, ::-1])):
        n = len(a)
        fit = offset_residuals(a, b, p, T, floor_m, parallel_deg, np.zeros((n, n)))
        same = (np.zeros((n, n)), limit)
        best = min(best, ambiguity(fit, sigma_prior_m, floor_m, same, spacing))
    return best
