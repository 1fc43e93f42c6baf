"""The motion inside one epoch measured against the planes of another (``sweep_refine``).

Deskewing along a curve interpolated between epoch poses, even the true ones, leaves the
2D rig's per-epoch error at a floor (docs/RESULTS.md, "The limit of deskewing by
interpolation"): the motion between the sweeps of an epoch is not a low-degree curve
through 5 Hz samples. Here it is measured, in continuous time, from the epoch's own
points.

The points of epoch ``k`` (each in the base frame of its own time ``t_k + t``) are
brought to the base frame of a reference epoch ``r`` (the one before; for the first
epoch, the one after) by the current curve ``T_r(t)`` (through the run's poses,
:func:`planodom.odometry.interpolate.interpolated_motion`), times a correction::

    T_r(t) <- T_r(t) C(t),    C(t) = (Exp(w(t)), v(t)),
    (w, v)(t) = sum_j c_j s^j,   s = (t - t_mid) / half_span   (j = 0 .. degree)

and the coefficients ``c`` (degree + 1, 6) minimise the sum of robust squared distances of
every point to the reference plane it lies on (:func:`assign`: the nearest within
``gate_m``, inside the plane's support grown by ``margin_m``), with a zero-mean prior on
``c`` (``prior_rotation_deg``, ``prior_translation_m``) that only holds the directions
the points leave open (scipy's ``least_squares``, Cauchy loss at three noise sigmas).
The motion inside the epoch is then ``M_k(t) = T_r(0)^-1 T_r(t)``: the points deskewed
by it are those of the base frame at ``t_k``, point by point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from planodom.config.sweep_refine import SweepRefineConfig
from planodom.geometry import Plane, invert_transform
from planodom.odometry.interpolate import interpolated_motion
from planodom.rotvec import rotation_matrices
from planodom.scan import Scan


@dataclass(frozen=True)
class SweepMotion:
    """The measured motion inside one epoch.

    Attributes:
        times: (U,) s, the distinct point times (relative to the epoch's time).
        T_k_t: (U, 4, 4) the base frame at each time in the one at the epoch's time.
        n_points: points used; n_planes: reference planes they lie on.
        rms_m: (2,) RMS point-to-plane distance before and after, metres.
    """

    times: np.ndarray
    T_k_t: np.ndarray
    n_points: int
    n_planes: int
    rms_m: np.ndarray

    def deskewed(self, scan: Scan) -> Scan:
        """``scan`` (the epoch's points, times ``scan.t``) brought point by point to the
        base frame at the epoch's time; its times become zero."""
        assert scan.t is not None
        idx = np.searchsorted(self.times, scan.t)
        T = self.T_k_t[idx]
        points = np.einsum("nij,nj->ni", T[:, :3, :3], scan.points) + T[:, :3, 3]
        return Scan(points, scan.ring, np.zeros_like(scan.t), scan.label)


def assign(points: np.ndarray, planes: list[Plane], gate_m: float, margin_m: float) -> np.ndarray:
    """(N,) index of the plane each point (N, 3) lies on, -1 for none: the nearest of
    ``planes`` within ``gate_m`` (m) whose support polygon, grown by ``margin_m`` (m),
    holds the point's projection (a plane without a polygon: any projection)."""
    best = np.full(len(points), -1)
    dist = np.full(len(points), np.inf)
    for j, plane in enumerate(planes):
        d = np.abs(points @ plane.normal + plane.offset)
        ok = (d < gate_m) & (d < dist)
        if not ok.any():
            continue
        poly = plane.support.polygon if plane.support is not None else np.zeros((0, 3))
        if len(poly) >= 3:
            ok[ok] = _inside(points[ok], poly, plane.normal, margin_m)
        best[ok], dist[ok] = j, d[ok]
    return best


def _inside(points: np.ndarray, poly: np.ndarray, normal: np.ndarray, margin: float):
    """(N,) bool: the points (N, 3) project within ``margin`` (m) of the convex polygon
    (M, 3) (vertices in order on the plane of unit ``normal``)."""
    edges = np.roll(poly, -1, axis=0) - poly
    inward = np.cross(normal, edges)
    centre = poly.mean(axis=0)
    sign = np.sign(np.einsum("mi,mi->m", inward, centre - poly))
    inward = inward * np.where(sign == 0, 1.0, sign)[:, None]
    inward /= np.maximum(np.linalg.norm(inward, axis=1), 1e-12)[:, None]
    signed = np.einsum("mi,nmi->nm", inward, points[:, None, :] - poly[None])
    return (signed >= -margin).all(axis=1)


def epoch_motion(
    scan: Scan,
    k: int,
    r: int,
    times: np.ndarray,
    poses: np.ndarray,
    planes_r: list[Plane],
    cfg: SweepRefineConfig,
    noise_m: float,
    change: np.ndarray | None = None,
) -> SweepMotion | None:
    """The motion inside epoch ``k`` measured against the planes of epoch ``r`` (see the
    module); None when too few points or planes (under ``min_points``, or their normals
    span under three directions).

    Args:
        scan: epoch ``k``'s points, each in the base frame of its own time ``scan.t``.
        times: (N,) epoch times, s. poses: (N, 4, 4) ``T_world_base`` (the curve's nodes).
        planes_r: epoch ``r``'s planes, base frame at ``times[r]``.
        noise_m: the range noise sigma (m), the floor of the residual scale.
        change: (2,) the run's twist change (rad/s, m/s) for ``cfg.prior`` "twist"
            (:mod:`planodom.odometry.sweep_prior`; NaN or None: the fixed priors).
    """
    if scan.t is None or len(scan) == 0 or not planes_r:
        return None
    t_unique, inverse = np.unique(np.r_[0.0, scan.t], return_inverse=True)
    inverse = inverse[1:]
    T_init = interpolated_motion(times, poses, float(times[r]), times[k] + t_unique, 3)
    T_pts = T_init[inverse]
    p_r = np.einsum("nij,nj->ni", T_pts[:, :3, :3], scan.points) + T_pts[:, :3, 3]
    which = assign(p_r, planes_r, cfg.gate_m, cfg.margin_m)
    use = which >= 0
    normals = np.array([planes_r[j].normal for j in np.unique(which[use])]).reshape(-1, 3)
    if use.sum() < cfg.min_points or len(normals) < 3:
        return None
    if np.linalg.svd(normals, compute_uv=False)[2] < 0.1:
        return None  # the planes leave a translation open (corridor): nothing to gain
    n = np.array([planes_r[j].normal for j in which[use]])
    d = np.array([planes_r[j].offset for j in which[use]])
    p, R, t = scan.points[use], T_pts[use, :3, :3], T_pts[use, :3, 3]
    u = np.einsum("nij,ni->nj", R, n)  # R^T n: the normal in the frame of the point's time
    e = np.einsum("ni,ni->n", n, t) + d
    ts = scan.t[use]
    lo, hi = float(ts.min()), float(ts.max())
    mid, half = 0.5 * (lo + hi), max(0.5 * (hi - lo), 1e-6)
    r0 = np.einsum("ni,ni->n", u, p) + e
    scale = max(noise_m, 1.4826 * float(np.median(np.abs(r0))), 1e-4)
    basis = _Basis(cfg.degree, cfg.translation_degree, mid, half)
    B = basis.rows(ts)  # (N, P, 6): d (w, v) / d x
    sigma = basis.prior(np.deg2rad(cfg.prior_rotation_deg), cfg.prior_translation_m)
    if cfg.prior == "twist" and change is not None and np.isfinite(change).all():
        x, res = _map_solve(p, R, t, which[use], planes_r, basis, B, sigma, scale, change)
        if not np.isfinite(x).all():
            return None
        return _motion(basis, x, t_unique, T_init, use.sum(), len(normals), r0, res)

    def residuals(x: np.ndarray) -> np.ndarray:
        wv = B @ x
        q = np.einsum("nij,nj->ni", rotation_matrices(wv[:, :3]), p) + wv[:, 3:]
        return np.r_[(np.einsum("ni,ni->n", u, q) + e) / scale, x / sigma]

    def jacobian(x: np.ndarray) -> np.ndarray:
        wv = B @ x
        uc = np.einsum("nij,ni->nj", rotation_matrices(wv[:, :3]), u)  # Exp(w)^T u
        g = np.c_[np.cross(p, uc), u] / scale  # (N, 6): d r / d (w, v), right perturbation
        return np.r_[np.einsum("nk,npk->np", g, B.transpose(0, 2, 1)), np.diag(1.0 / sigma)]

    sol = least_squares(residuals, np.zeros(basis.size), jac=jacobian, loss="cauchy",
                        f_scale=3.0, method="trf", x_scale="jac", max_nfev=50, ftol=1e-12,
                        xtol=1e-12, gtol=1e-12)  # fmt: skip
    return _motion(basis, sol.x, t_unique, T_init, use.sum(), len(normals), r0,
                   sol.fun[: len(p)] * scale)  # fmt: skip


def _motion(
    basis: _Basis,
    x: np.ndarray,
    t_unique: np.ndarray,
    T_init: np.ndarray,
    n_points: int,
    n_planes: int,
    r0: np.ndarray,
    res: np.ndarray,
) -> SweepMotion:
    """The motion of the coefficients ``x`` on the curve ``T_init`` (at ``t_unique``)."""
    wv = basis.rows(t_unique) @ x
    C = np.tile(np.eye(4), (len(t_unique), 1, 1))
    C[:, :3, :3], C[:, :3, 3] = rotation_matrices(wv[:, :3]), wv[:, 3:]
    T_r_t = T_init @ C
    zero = int(np.searchsorted(t_unique, 0.0))
    T_k_t = invert_transform(T_r_t[zero]) @ T_r_t
    rms = np.sqrt([np.mean(r0**2), np.mean(res**2)])
    return SweepMotion(t_unique, T_k_t, int(n_points), n_planes, rms)


def _map_solve(
    p: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    index: np.ndarray,
    planes: list[Plane],
    basis: _Basis,
    B: np.ndarray,
    sigma: np.ndarray,
    scale: float,
    change: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`.sweep_prior.map_solve` with the coefficients of degree >= 1 given the
    twist change (``change`` (2,): rad/s, m/s, over sqrt 3 per axis) over half the span,
    and the planes' errors their deskewing Jacobians' for that change over the span."""
    from planodom.odometry.sweep_prior import map_solve, plane_error_factor

    # a change the steps' own errors explain entirely (0): the curve holds, to rounding
    per_axis = np.maximum(np.asarray(change), 1e-9) / np.sqrt(3.0)
    n_rot = 3 * (basis.dr + 1)
    sigma = sigma.copy()
    sigma[3:n_rot] = per_axis[0] * basis.half
    sigma[n_rot + 3 :] = per_axis[1] * basis.half
    motion_change = np.repeat(per_axis * 2.0 * basis.half, 3)
    factors = [plane_error_factor(pl, motion_change) for pl in planes]
    return map_solve(p, R, t, index, planes, factors, B, sigma, scale)


@dataclass(frozen=True)
class _Basis:
    """The correction's coefficients: rotation ``w`` of degree ``dr``, translation ``v``
    of degree ``dt``, in ``s = (t - mid) / half``."""

    dr: int
    dt: int
    mid: float
    half: float

    @property
    def size(self) -> int:
        return 3 * (self.dr + 1) + 3 * (self.dt + 1)

    def rows(self, t: np.ndarray) -> np.ndarray:
        """(T, 6, size): ``(w, v)(t) = rows(t) @ x``."""
        s = (np.asarray(t, dtype=np.float64) - self.mid) / self.half
        out = np.zeros((len(s), 6, self.size))
        col = 0
        for first, degree in ((0, self.dr), (3, self.dt)):
            for j in range(degree + 1):
                for i in range(3):
                    out[:, first + i, col] = s**j
                    col += 1
        return out

    def prior(self, rotation: float, translation: float) -> np.ndarray:
        """(size,) the coefficients' prior sigmas (rad, m)."""
        return np.r_[[rotation] * 3 * (self.dr + 1), [translation] * 3 * (self.dt + 1)]
