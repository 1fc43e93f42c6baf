"""Bring the points of one epoch to its reference time with a constant body twist.

A point seen at time ``t`` (seconds, relative to the epoch's reference time) in the base
frame of that time is mapped to the base frame at the reference time by
``T_ref_t = exp(t * xi)``, ``xi = (wx, wy, wz, vx, vy, vz)`` in rad/s and m/s, expressed
in the base frame at the reference time (docs/ARCHITECTURE.md). The SE(3) exponential is
evaluated exactly, per point (the closed form of :func:`planodom.geometry.se3_exp`):

    R(t) = exp([t w]x)                        (Rodrigues)
    p(t) = J_l(t w) (t v)                     (left Jacobian of SO(3))
    J_l(phi) v = v + (1 - cos a) / a^2 (phi x v) + (a - sin a) / a^3 (phi x (phi x v)),
    a = |phi|, with Taylor series for small a.

so ``p_ref = R(t) p_t + p(t)``.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.errors import GeometryError


def check_twist(twist: np.ndarray | None) -> np.ndarray | None:
    """``twist`` as a finite (6,) float64 array (rad/s, m/s), or None; raises GeometryError."""
    if twist is None:
        return None
    try:
        xi = np.asarray(twist, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError) as exc:
        raise GeometryError(f"twist must be 6 finite numbers, got {twist!r}") from exc
    if xi.shape != (6,) or not np.isfinite(xi).all():
        raise GeometryError(
            f"twist must be 6 finite numbers (wx, wy, wz, vx, vy, vz), got {twist!r}"
        )
    return xi


def deskew_points(points: np.ndarray, t: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """Map points seen at times ``t`` to the reference time: ``p_ref = exp(t xi) p_t``.

    Args:
        points: (N, 3) metres, each in the base frame of its own time.
        t: (N,) seconds relative to the reference time.
        twist: (6,) constant body twist, rad/s and m/s.

    Returns:
        (N, 3) metres in the base frame at the reference time.

    The rotation axis ``k = w / |w|`` is the same for every point, so Rodrigues' formula
    ``R p = p + sin(a) k x p + (1 - cos a) k x (k x p)``, ``a = t |w|``, is evaluated in
    one compiled pass; this is exact like :func:`planodom.geometry.se3_exp` at every
    ``t xi``, but avoids building N (4, 4) transforms (a per-point cost ~10x higher, and
    this is the first stage of every 2D-rig epoch).
    """
    points = np.ascontiguousarray(points, dtype=np.float64)
    if len(points) == 0:
        return points.reshape(0, 3).copy()
    xi = check_twist(twist)
    t = np.ascontiguousarray(t, dtype=np.float64).reshape(-1)
    return _deskew_kernel(points, t, xi)


@numba.njit(cache=True)
def _deskew_kernel(points, t, xi):  # pragma: no cover - compiled
    """One pass over the points (numba: the numpy version makes ~30 passes, and this is
    the first stage of every 2D-rig epoch). Same formulas as
    :func:`planodom.geometry.se3_exp`, written out per point:
    Rodrigues about the fixed axis ``k = w / |w|`` and ``J_l(t w) (t v) = t v +
    c1 t^2 (w x v) + c2 t^3 (w x (w x v))``, ``c1 = (1 - cos a) / a^2``, ``c2 = (a - sin a)
    / a^3`` (Taylor series below a = 1e-4)."""
    n = points.shape[0]
    out = np.empty((n, 3))
    w0, w1, w2 = xi[0], xi[1], xi[2]
    v0, v1, v2 = xi[3], xi[4], xi[5]
    speed = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    if speed < 1e-12:
        for i in range(n):
            out[i, 0] = points[i, 0] + t[i] * v0
            out[i, 1] = points[i, 1] + t[i] * v1
            out[i, 2] = points[i, 2] + t[i] * v2
        return out
    k0, k1, k2 = w0 / speed, w1 / speed, w2 / speed
    # w x v and w x (w x v)
    a0, a1, a2 = w1 * v2 - w2 * v1, w2 * v0 - w0 * v2, w0 * v1 - w1 * v0
    b0, b1, b2 = w1 * a2 - w2 * a1, w2 * a0 - w0 * a2, w0 * a1 - w1 * a0
    # the coefficients of a point's time, kept while the next point has the same time
    # (scanners that fire together: a rig's synchronised 2D scanners, a lidar's columns);
    # the same values as computing them again (zero, which may be signed, every time)
    last = np.nan
    sa = ca = f1 = f2 = 0.0
    for i in range(n):
        ti = t[i]
        if ti != last or ti == 0.0:
            last = ti
            a = ti * speed
            sa, ca = np.sin(a), np.cos(a)
            if abs(a) < 1e-4:
                c1 = 0.5 - a * a / 24.0
                c2 = 1.0 / 6.0 - a * a / 120.0
            else:
                c1 = (1.0 - ca) / (a * a)
                c2 = (a - sa) / (a * a * a)
            f1 = c1 * ti * ti
            f2 = c2 * ti * ti * ti
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        q0, q1, q2 = k1 * p2 - k2 * p1, k2 * p0 - k0 * p2, k0 * p1 - k1 * p0  # k x p
        r0, r1, r2 = k1 * q2 - k2 * q1, k2 * q0 - k0 * q2, k0 * q1 - k1 * q0  # k x (k x p)
        out[i, 0] = p0 + sa * q0 + (1.0 - ca) * r0 + ti * v0 + f1 * a0 + f2 * b0
        out[i, 1] = p1 + sa * q1 + (1.0 - ca) * r1 + ti * v1 + f1 * a1 + f2 * b1
        out[i, 2] = p2 + sa * q2 + (1.0 - ca) * r2 + ti * v2 + f1 * a2 + f2 * b2
    return out
