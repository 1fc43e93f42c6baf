"""Small compiled (numba) helpers shared by the extraction kernels.

- :func:`find_root`: union-find with path halving (trace linking, range-image growing);
- :func:`range_moments`: centroid and centred scatter of a contiguous range of points;
- :func:`add_outer`: add one centred point's outer product to a scatter's upper triangle.
"""

from __future__ import annotations

import numba


@numba.njit(cache=True)
def find_root(parent, i):  # pragma: no cover - compiled
    """Root of ``i`` in the union-find forest ``parent`` (int64), halving the path."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def range_moments(pts, a, b, c, m):  # pragma: no cover - compiled
    """Fill ``c`` (3,) with the centroid and ``m`` (3, 3) with the centred (two-pass)
    scatter ``sum (p - c)(p - c)^T`` of ``pts[a:b]`` ((M, 3), metres; b > a)."""
    n = b - a
    for u in range(3):
        acc = 0.0
        for i in range(a, b):
            acc += pts[i, u]
        c[u] = acc / n
    s00 = s01 = s02 = s11 = s12 = s22 = 0.0
    for i in range(a, b):
        q0, q1, q2 = pts[i, 0] - c[0], pts[i, 1] - c[1], pts[i, 2] - c[2]
        s00 += q0 * q0
        s01 += q0 * q1
        s02 += q0 * q2
        s11 += q1 * q1
        s12 += q1 * q2
        s22 += q2 * q2
    m[0, 0], m[0, 1], m[0, 2] = s00, s01, s02
    m[1, 0], m[1, 1], m[1, 2] = s01, s11, s12
    m[2, 0], m[2, 1], m[2, 2] = s02, s12, s22


@numba.njit(cache=True)
def add_outer(S, x, y, z):  # pragma: no cover - compiled
    """Add the upper triangle of ``(x, y, z)(x, y, z)^T`` to ``S`` (3, 3) (the caller
    mirrors it once the sum is complete)."""
    S[0, 0] += x * x
    S[0, 1] += x * y
    S[0, 2] += x * z
    S[1, 1] += y * y
    S[1, 2] += y * z
    S[2, 2] += z * z
