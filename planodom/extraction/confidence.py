"""CPEF: the confidence weight of an extracted plane.

The paper weights each plane in WOCSC by a confidence it calls CPEF (its reference [6]).
In planodom, CPEF ("confidence of a planar extracted feature") is the product of four
factors, each in (0, 1], so that ``w`` lies in (0, 1] and higher is better:

    w = w_residual * w_count * w_extent * w_incidence

- ``w_residual = exp(-(rms / (2 sigma))^2)``: fit residual against the sensor noise
  ``sigma`` (the effective noise of the epoch, :func:`effective_noise`): 0.78 for a plane
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


def cpef(
    rms_m: float,
    sigma_m: float,
    n_points: int,
    width_m: float,
    normal: np.ndarray,
    points: np.ndarray,
    viewpoint: np.ndarray,
    points_ref: float,
    width_ref_m: float,
    incidence: float | None = None,
) -> float:
    """CPEF weight in (0, 1] (module docstring).

    Args:
        rms_m: RMS residual of the fit (m). sigma_m: sensor noise sigma (m), > 0.
        n_points: inlier count. width_m: minor in-plane width (m).
        normal: (3,) unit normal. points: (K, 3) inliers, metres.
        viewpoint: (3,) or (K, 3) ray origins, metres.
        points_ref: N_ref. width_ref_m: W_ref (m).
        incidence: ``w_incidence`` when already computed (``points`` is then not used).
    """
    w_inc = float(incidence) if incidence is not None else mean_incidence(points, viewpoint, normal)
    return float(
        cpef_batch(
            np.array([rms_m]), sigma_m, np.array([n_points]), np.array([width_m]),
            np.array([w_inc]), points_ref, width_ref_m,
        )[0]
    )  # fmt: skip


def mean_incidence(points: np.ndarray, viewpoint: np.ndarray, normal: np.ndarray) -> float:
    """``w_incidence``: mean ``|cos|`` of the angles between ``normal`` (3,) and the rays
    from ``viewpoint`` ((3,) or (K, 3), metres) to ``points`` (K, 3); 1 without rays."""
    rays = points - viewpoint
    norm = np.linalg.norm(rays, axis=1)
    ok = norm > 0
    return float(np.mean(np.abs(rays[ok] @ normal) / norm[ok])) if np.any(ok) else 1.0


def cpef_batch(
    rms_m: np.ndarray,
    sigma_m: float,
    n_points: np.ndarray,
    width_m: np.ndarray,
    incidence: np.ndarray,
    points_ref: float,
    width_ref_m: float,
) -> np.ndarray:
    """(G,) CPEF weights of G planes from their RMS residuals (m), inlier counts, minor
    widths (m) and mean incidences ``w_incidence`` (all (G,)); see :func:`cpef`."""
    w_res = np.exp(-((np.asarray(rms_m) / (2.0 * max(sigma_m, 1e-12))) ** 2))
    w_cnt = 1.0 - np.exp(-np.asarray(n_points, dtype=np.float64) / points_ref)
    w_ext = 1.0 - np.exp(-np.asarray(width_m) / width_ref_m)
    return np.clip(w_res * w_cnt * w_ext * np.asarray(incidence), 1e-6, 1.0)
