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

import numpy as np


def mean_incidence(points: np.ndarray, viewpoint: np.ndarray, normal: np.ndarray) -> float:
    """``w_incidence``: mean ``|cos|`` of the angles between ``normal`` (3,) and the rays
    from ``viewpoint`` ((3,) or (K, 3), metres) to ``points`` (K, 3); 1 without rays."""
    rays = points - viewpoint
    norm = np.linalg.norm(rays, axis=1)
    ok = norm > 0
    return float(np.mean(np.abs(rays[ok] @ normal) / norm[ok])) if np.any(ok) else 1.0


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
    return np.clip(w_res * w_cnt * w_ext * np.asarray(incidence), 1e-6, 1.0)
