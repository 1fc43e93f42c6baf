"""The local map of plane landmarks (odometry world frame), as accumulated moments.

A landmark's plane is refit from its moments (smallest scatter eigenvector), so its
normal averages many lasers and viewpoints and a facade seen as fragments becomes one
wall. A scan plane joins the landmark it is an inlier of while the merged moments stay
flat (RMS to the refit plane within ``flat_sigmas`` point sigmas, the laser bias
included: the extractor's own flatness rule), else it starts a new landmark: a cambered
road becomes several bounded landmarks instead of one biased plane.

Fading: all of a landmark's N, S and line count are multiplied by ``exp(-1 /
memory_scans)`` per scan: the map must stay consistent with the current scan, and old
observations carry the odometry drift accumulated since. A landmark not seen for
``max_age_scans``, or farther than ``max_range_m`` from the sensor, is dropped, and the map
holds at most ``max_landmarks`` (least recently seen dropped): memory stays flat.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planodom.config import PlanemapConfig
from planodom.odometry.planemap.moments import Moments, fit_planes, merge_moments


def _empty(*shape: int, dtype: type = np.float64) -> np.ndarray:
    return np.zeros((0, *shape), dtype=dtype)


@dataclass
class PlaneMap:
    """Plane landmarks (world frame).

    Attributes:
        N, c, S, rows: accumulated (faded) moments and scan-line counts, (L,) (L, 3)
            (L, 3, 3) (L,).
        orient: (L, 3) normal of the first observation (sign reference: towards the
            sensor). last_seen: (L,) scan number of the last observation.
        last_index: (L,) plane index in the scan that last observed it (-1: none).
        n, d, lam: refit planes (L, 3), (L,) and scatter eigenvalues (L, 3), ascending.
        cov_n: (L, 3, 3) normal covariance, var_o: (L,) offset variance at the centroid,
            radius: (L,) bounding-circle radius (m). All set by :meth:`refit`.
        cov_n_bias, var_o_bias: (L, 3, 3), (L,) the parts of ``cov_n`` and ``var_o`` per
            unit squared laser bias (1/m^2 times m^2): both are linear in it, so the
            variances under another bias are ``cov_n + (b^2 - b_0^2) cov_n_bias``
            (:mod:`.bias`). bias_m: the bias ``b_0`` (m) of the last :meth:`refit`.
    """

    N: np.ndarray = field(default_factory=lambda: _empty())
    c: np.ndarray = field(default_factory=lambda: _empty(3))
    S: np.ndarray = field(default_factory=lambda: _empty(3, 3))
    rows: np.ndarray = field(default_factory=lambda: _empty())
    orient: np.ndarray = field(default_factory=lambda: _empty(3))
    last_seen: np.ndarray = field(default_factory=lambda: _empty(dtype=np.int64))
    last_index: np.ndarray = field(default_factory=lambda: _empty(dtype=np.int64))
    n: np.ndarray = field(default_factory=lambda: _empty(3))
    d: np.ndarray = field(default_factory=lambda: _empty())
    lam: np.ndarray = field(default_factory=lambda: _empty(3))
    cov_n: np.ndarray = field(default_factory=lambda: _empty(3, 3))
    var_o: np.ndarray = field(default_factory=lambda: _empty())
    radius: np.ndarray = field(default_factory=lambda: _empty())
    cov_n_bias: np.ndarray = field(default_factory=lambda: _empty(3, 3))
    var_o_bias: np.ndarray = field(default_factory=lambda: _empty())
    bias_m: float = 0.0

    _STORED = ("N", "c", "S", "rows", "orient", "last_seen", "last_index")

    def __len__(self) -> int:
        return len(self.N)

    def add(self, m: Moments, normals: np.ndarray, frame: int, index: np.ndarray) -> None:
        """Append landmarks of moments ``m`` (world frame), first normals (K, 3), seen in
        scan ``frame`` as its planes ``index`` (K,)."""
        self.N = np.r_[self.N, m.N]
        self.c = np.r_[self.c, m.c]
        self.S = np.r_[self.S, m.S]
        self.rows = np.r_[self.rows, m.rows]
        self.orient = np.r_[self.orient, normals]
        self.last_seen = np.r_[self.last_seen, np.full(len(m), frame, dtype=np.int64)]
        self.last_index = np.r_[self.last_index, np.asarray(index, dtype=np.int64)]

    def keep(self, sel: np.ndarray) -> None:
        """Keep only the landmarks ``sel`` (mask or indices); call :meth:`refit` after."""
        for k in self._STORED:
            setattr(self, k, getattr(self, k)[sel])

    def refit(self, sigma: float, bias_m: float) -> None:
        """Planes, normal covariances, offset variances and radii from the moments.

        Normal variance along the in-plane axes e_1, e_2: TLS ``sigma^2 / lam`` plus the
        laser bias over the accumulated scan lines ``bias^2 N / (rows lam)``."""
        n, d, lam, E = fit_planes(self.N, self.c, self.S)
        s = np.where(np.einsum("ij,ij->i", n, self.orient) < 0, -1.0, 1.0)
        self.n, self.d, self.lam = n * s[:, None], d * s, lam
        rows = np.maximum(self.rows, 1.0)
        lam12 = np.maximum(lam[:, 1:], 1e-12)
        v = (sigma**2 + (bias_m**2 * self.N / rows)[:, None]) / lam12
        e12 = E[:, :, 1:]
        self.cov_n = np.einsum("mik,mk,mjk->mij", e12, v, e12)
        self.var_o = sigma**2 / self.N + bias_m**2 / rows
        vb = (self.N / rows)[:, None] / lam12
        self.cov_n_bias = np.einsum("mik,mk,mjk->mij", e12, vb, e12)
        self.var_o_bias = 1.0 / rows
        self.bias_m = bias_m
        self.radius = np.sqrt(3.0 * (lam[:, 1] + lam[:, 2]) / self.N)

    def var_at(self, idx: np.ndarray, x: np.ndarray) -> np.ndarray:
        """(m,) variance of landmarks ``idx`` (m,) offsets at points ``x`` (m, 3)."""
        dx = x - self.c[idx]
        return np.einsum("mi,mij,mj->m", dx, self.cov_n[idx], dx) + self.var_o[idx]


def update_map(
    M: PlaneMap,
    T: np.ndarray,
    cur: Moments,
    normals: np.ndarray,
    assoc: np.ndarray,
    weight: np.ndarray,
    frame: int,
    plane_index: np.ndarray,
    sigma: float,
    config: PlanemapConfig,
    bias_m: float | None = None,
) -> None:
    """Fade, merge the scan's planes (moments ``cur``, ``normals`` (K, 3), scan frame;
    ``assoc`` (K,) landmark or -1, robust ``weight`` (K,), ``plane_index`` (K,) their
    indices in the scan's plane list) seen at pose ``T`` (world from scan) in scan
    ``frame``, prune and refit (module docstring) with the laser bias ``bias_m`` (m;
    None: ``config.laser_bias_m``)."""
    R, t = T[:3, :3], T[:3, 3]
    mw = cur.transformed(R, t)
    nw = normals @ R.T
    bias = config.laser_bias_m if bias_m is None else bias_m
    if len(M) and config.memory_scans > 0:
        decay = float(np.exp(-1.0 / config.memory_scans))
        M.N, M.S, M.rows = M.N * decay, M.S * decay, M.rows * decay
    new = np.ones(len(cur), dtype=bool)
    inlier = (assoc >= 0) & (weight > 0.5)
    tol2 = config.flat_sigmas**2 * (sigma**2 + bias**2)
    _merge_flat(M, mw, np.flatnonzero(inlier), assoc, tol2, new)
    if len(M) and inlier.any():
        M.last_seen[assoc[inlier]] = frame
        M.last_index[assoc[inlier]] = plane_index[inlier]
    M.add(mw.take(new), nw[new], frame, plane_index[new])
    keep = frame - M.last_seen <= config.max_age_scans
    keep &= np.linalg.norm(M.c - t, axis=1) <= config.max_range_m
    if np.count_nonzero(keep) > config.max_landmarks:
        order = np.argsort(-M.last_seen, kind="stable")
        recent = np.zeros(len(M), dtype=bool)
        recent[order[: config.max_landmarks]] = True
        keep &= recent
    M.keep(keep)
    M.refit(sigma, bias)


def _merge_flat(
    M: PlaneMap, mw: Moments, js: np.ndarray, assoc: np.ndarray, tol2: float, new: np.ndarray
) -> None:
    """Merge the scan planes ``js`` (m,) (world-frame moments ``mw``) into their
    landmarks ``assoc[js]`` one after the other, each where the union stays flat (least
    eigenvalue over N at most ``tol2``, m^2) on the moments the last one left; clears
    ``new`` of the merged ones. Batched by rounds: round r merges every landmark's r-th
    plane (the landmarks of a round distinct, their merges independent), with the same
    elementwise arithmetic and one LAPACK call per matrix: the same numbers as one by one
    (a landmark takes 2-3 planes of a scan on indoor lidars, 15 merges a scan)."""
    if len(js) == 0:
        return
    ks = assoc[js]
    order = np.argsort(ks, kind="stable")
    first = np.r_[True, ks[order][1:] != ks[order][:-1]]
    rank = np.empty(len(ks), dtype=np.intp)
    at = np.arange(len(ks))
    rank[order] = at - np.maximum.accumulate(np.where(first, at, 0))
    for r in range(int(rank.max()) + 1):
        k, j = ks[rank == r], js[rank == r]
        N, c, S = merge_moments(M.N[k], M.c[k], M.S[k], mw.N[j], mw.c[j], mw.S[j])
        flat = np.linalg.eigvalsh(S)[:, 0] / N <= tol2
        k, j = k[flat], j[flat]
        M.N[k], M.c[k], M.S[k] = N[flat], c[flat], S[flat]
        M.rows[k] += mw.rows[j]
        new[j] = False
