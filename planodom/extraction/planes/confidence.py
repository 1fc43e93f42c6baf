"""CPEF: the confidence weight of an extracted plane.

The paper weights each plane in WOCSC by a confidence it calls CPEF (its reference [6]).
In planodom, CPEF ("confidence of a planar extracted feature") is the product of four
factors, each in (0, 1], so that ``w`` lies in (0, 1] and higher is better:

    w = w_residual * w_count * w_extent * w_incidence

- ``w_residual = exp(-(rms / (2 sigma))^2)``: fit residual against the sensor noise
  ``sigma`` (the effective noise of the epoch,
  :func:`planodom.extraction.noise.effective_noise`): 0.78 for a plane
  whose residual is the sensor noise, 0.37 for twice it (not a plane, or bad motion).
- ``w_count = 1 - exp(-N / N_ref)``: number of inliers, ``N_ref = confidence_points_ref``.
- ``w_extent = 1 - exp(-width / W_ref)``: spatial extent, ``width = 2 sqrt(l2 / N)`` the
  in-plane width along the minor axis (a strip constrains its tilt across the strip
  poorly), ``W_ref = confidence_width_ref_m``.
- ``w_incidence = mean_i |cos a_i|``: incidence, ``a_i`` the angle between the normal and
  the ray from the viewpoint to inlier i (grazing rays get range noise along the plane and
  sparse, stretched footprints).

The result is clipped to ``[1e-6, 1]``.
"""

from __future__ import annotations

import numba
import numpy as np


def mean_incidence(points: np.ndarray, viewpoint: np.ndarray, normal: np.ndarray) -> float:
    """``w_incidence``: mean ``|cos|`` of the angles between ``normal`` (3,) and the rays
    from ``viewpoint`` ((3,) or (K, 3), metres) to ``points`` (K, 3); 1 without rays."""
    rays = points - viewpoint
    norm = np.linalg.norm(rays, axis=1)
    ok = norm > 0
    return float(np.mean(np.abs(rays[ok] @ normal) / norm[ok])) if np.any(ok) else 1.0


def mean_incidences(
    points: np.ndarray,
    inliers: np.ndarray,
    bounds: np.ndarray,
    planes: np.ndarray,
    viewpoints: np.ndarray,
    normals: np.ndarray,
) -> np.ndarray:
    """(P,) :func:`mean_incidence` of each plane g in ``planes`` (P,) at once: its points
    ``points[inliers[bounds[g]:bounds[g + 1]]]`` ((N, 3) m, (K,) int64, (G + 1,) int64)
    seen from ``viewpoints[p]`` (P, 3) with normal ``normals[p]`` (P, 3) (one compiled
    pass: a numpy call per plane cost more than the arithmetic)."""
    return _incidence_kernel(
        np.ascontiguousarray(points, dtype=np.float64), inliers, bounds,
        np.asarray(planes, dtype=np.int64), np.ascontiguousarray(viewpoints, dtype=np.float64),
        np.ascontiguousarray(normals, dtype=np.float64),
    )  # fmt: skip


@numba.njit(cache=True)
def _incidence_kernel(pts, inliers, bounds, planes, views, normals):  # pragma: no cover
    out = np.ones(len(planes))
    for p in range(len(planes)):
        g = planes[p]
        v0, v1, v2 = views[p, 0], views[p, 1], views[p, 2]
        n0, n1, n2 = normals[p, 0], normals[p, 1], normals[p, 2]
        acc, cnt = 0.0, 0
        for k in range(bounds[g], bounds[g + 1]):
            i = inliers[k]
            r0, r1, r2 = pts[i, 0] - v0, pts[i, 1] - v1, pts[i, 2] - v2
            norm = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            if norm > 0:
                acc += abs(r0 * n0 + r1 * n1 + r2 * n2) / norm
                cnt += 1
        if cnt > 0:
            out[p] = acc / cnt
    return out


def cpef(
    rms_m: np.ndarray,
    sigma_m: float,
    n_points: np.ndarray,
    width_m: np.ndarray,
    incidence: np.ndarray,
    points_ref: float,
    width_ref_m: float,
) -> np.ndarray:
    """(G,) CPEF weights of G planes (module docstring).

    Args:
        rms_m: (G,) RMS residuals of the fits (m). sigma_m: sensor noise sigma (m), > 0.
        n_points: (G,) inlier counts. width_m: (G,) minor in-plane widths (m).
        incidence: (G,) ``w_incidence`` (:func:`mean_incidence`).
        points_ref: N_ref. width_ref_m: W_ref (m).
    """
    w_res = np.exp(-((np.asarray(rms_m) / (2.0 * max(sigma_m, 1e-12))) ** 2))
    w_cnt = 1.0 - np.exp(-np.asarray(n_points, dtype=np.float64) / points_ref)
    w_ext = 1.0 - np.exp(-np.asarray(width_m) / width_ref_m)
    # np.clip's arithmetic (NaN kept) without its dispatch through two Python wrappers
    return np.minimum(np.maximum(w_res * w_cnt * w_ext * np.asarray(incidence), 1e-6), 1.0)
