"""Plane moments and the point-to-plane cost computed from them.

The inlier points ``p_i`` of a scan plane ``j`` are summarised by their centred moments
(scan frame): count ``N``, centroid ``c``, scatter ``S = sum (p_i - c)(p_i - c)^T =
sum_k lam_k e_k e_k^T``. Against a fixed reference plane ``(n, d)`` (a map landmark,
world frame) and the pose ``(R, t)`` (world from scan)::

    sum_i (n.(R p_i + t) + d)^2 = N (n.(R c + t) + d)^2 + n^T R S R^T n
                                = r_0^2 + sum_k r_k^2,
    r_0 = sqrt(N) (n.(R c + t) + d),      r_k = sqrt(lam_k) n.(R e_k)

and the Gauss-Newton normal equations of these four residuals are exactly those of
point-to-plane ICP over all N points (the cross terms vanish because the points are
centred): a few dozen planes summarise ~100k points, O(planes) per iteration. Jacobians
for the perturbation ``R <- exp(w) R, t <- t + dt``: ``dr_0 = sqrt(N) [(R c) x n, n]``,
``dr_k = sqrt(lam_k) [(R e_k) x n, 0]``.

Noise (:func:`residual_variance`): per point ``sigma`` plus a per-laser range bias ``b``
constant along one scan line (``PlanemapConfig.laser_bias_m``): correlated over the points
of a line, it gives the mean offset of a plane over ``rows`` lines the variance
``b^2 / rows`` and its tilt across the lines ``b^2 N / (rows lam_k)``; both make the
variance of each of the four residuals ``sigma^2 + b^2 N / rows``: a plane's information
grows with the scan lines it spans, not with its points.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planodom.geometry import Plane, cross_rows
from planodom.median import median


@dataclass(frozen=True, eq=False)
class Moments:
    """Centred moments of K point sets.

    Attributes:
        N: (K,) point counts. c: (K, 3) centroids, m. S: (K, 3, 3) centred scatters, m^2.
        rows: (K,) scan lines spanned (1 when unknown).
    """

    N: np.ndarray
    c: np.ndarray
    S: np.ndarray
    rows: np.ndarray

    def __len__(self) -> int:
        return len(self.N)

    @classmethod
    def of_points(cls, sets: Sequence[np.ndarray], rows: np.ndarray | None = None) -> Moments:
        """The moments of point sets (each (M, 3), m); ``rows`` (K,) default 1."""
        N = np.array([len(p) for p in sets], dtype=np.float64)
        c = np.array([p.mean(axis=0) for p in sets]).reshape(-1, 3)
        S = np.array([(p - p.mean(0)).T @ (p - p.mean(0)) for p in sets]).reshape(-1, 3, 3)
        r = np.ones(len(sets)) if rows is None else np.asarray(rows, dtype=np.float64)
        return cls(N, c, S, r)

    @classmethod
    def of_planes(cls, planes: Sequence[Plane]) -> Moments:
        """The moments of the planes' supports (their ``scatter`` must be known)."""
        sup = [p.support for p in planes]
        if any(s is None or s.scatter is None for s in sup):
            raise ValueError("plane moments need every plane's support scatter")
        N = np.array([s.n_points for s in sup if s], dtype=np.float64)
        c = np.array([s.centroid for s in sup if s]).reshape(-1, 3)
        S = np.array([s.scatter for s in sup if s]).reshape(-1, 3, 3)
        rows = np.array([max(s.n_rows, 1) for s in sup if s], dtype=np.float64)
        return cls(N, c, S, rows)

    def transformed(self, R: np.ndarray, t: np.ndarray) -> Moments:
        """The moments of the point sets moved by ``x -> R x + t``."""
        return Moments(self.N.copy(), self.c @ R.T + t, R @ self.S @ R.T, self.rows.copy())

    def take(self, index: np.ndarray) -> Moments:
        """The sets at ``index`` (int array or mask)."""
        return Moments(self.N[index], self.c[index], self.S[index], self.rows[index])


def merge_moments(
    N1: np.ndarray, c1: np.ndarray, S1: np.ndarray, N2: np.ndarray, c2: np.ndarray, S2: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Moments of the union of two point sets (parallel-axis theorem), broadcasting."""
    N = N1 + N2
    c = (N1[..., None] * c1 + N2[..., None] * c2) / N[..., None]
    dc = c1 - c2
    S = S1 + S2 + (N1 * N2 / N)[..., None, None] * dc[..., :, None] * dc[..., None, :]
    return N, c, S


def fit_planes(
    N: np.ndarray, c: np.ndarray, S: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """TLS planes of moments: normals (smallest eigenvector), offsets, eigenvalues
    (ascending) and eigenvectors (columns)."""
    lam, E = np.linalg.eigh(S)
    n = E[..., :, 0]
    d = -np.einsum("...i,...i->...", n, c)
    return n, d, lam, E


def p2p_cost_points(R: np.ndarray, t: np.ndarray, n: np.ndarray, d: float, P: np.ndarray) -> float:
    """Explicit sum of squared point-to-plane distances of ``P`` (M, 3) moved by (R, t)."""
    return float(np.sum((P @ R.T @ n + t @ n + d) ** 2))


def p2p_cost_moments(
    R: np.ndarray, t: np.ndarray, n: np.ndarray, d: float, N: float, c: np.ndarray, S: np.ndarray
) -> float:
    """The same sum from the moments: ``N (n.(R c + t) + d)^2 + n^T R S R^T n``."""
    u = R.T @ n
    return float(N * (n @ (R @ c + t) + d) ** 2 + u @ S @ u)


def moment_residuals(
    R: np.ndarray,
    t: np.ndarray,
    n: np.ndarray,
    d: np.ndarray,
    N: np.ndarray,
    c: np.ndarray,
    lam: np.ndarray,
    E: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Residuals (m, 4), Jacobians (m, 4, 6) and ``U = R E`` (m, 3, 3) of m associations
    (module docstring): reference planes ``n`` (m, 3), ``d`` (m,) (world); current moments
    ``N`` (m,), ``c`` (m, 3) (scan frame); ``lam`` (m, 3), ``E`` (m, 3, 3): the
    eigen-decomposition of the current scatters (columns e_k)."""
    m = len(N)
    x = c @ R.T
    sN = np.sqrt(N)
    r0 = sN * (np.einsum("ij,ij->i", n, x + t) + d)
    U = np.einsum("ab,mbk->mak", R, E)
    sl = np.sqrt(np.maximum(lam, 0.0))
    rk = sl * np.einsum("ma,mak->mk", n, U)
    r = np.concatenate([r0[:, None], rk], axis=1)
    J = np.zeros((m, 4, 6))
    J[:, 0, :3] = sN[:, None] * cross_rows(x, n)
    J[:, 0, 3:] = sN[:, None] * n
    J[:, 1:, :3] = sl[:, :, None] * cross_rows(np.swapaxes(U, 1, 2), n[:, None, :])
    return r, J, U


def residual_variance(sigma: float, bias_m: float, N: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """(K,) variance of each moment residual of planes with ``N`` points over ``rows``
    scan lines: ``sigma^2 + bias^2 N / rows`` (module docstring)."""
    return sigma**2 + bias_m**2 * N / np.maximum(rows, 1.0)


def scan_sigma(m: Moments, floor_m: float) -> float:
    """The point noise sigma (m) of a scan: the median RMS distance of the planes' points
    to their own TLS planes (``sqrt(lam_min / N)``), at least ``floor_m``."""
    if len(m) == 0:
        return floor_m
    lam = np.linalg.eigvalsh(m.S)[:, 0]
    return max(median(np.sqrt(np.maximum(lam, 0.0) / m.N)), floor_m)
