"""Small compiled (numba) helpers shared by the extraction kernels.

- :func:`find_root`: union-find with path halving (trace linking, range-image growing);
- :func:`components`: connected components of an undirected edge list, labelled as scipy's;
- :func:`range_moments`: centroid and centred scatter of a contiguous range of points;
- :func:`add_outer`: add one centred point's outer product to a scatter's upper triangle;
- :func:`median_nonnegative`: ``np.median`` of non-negative values by radix selection.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def find_root(parent, i):  # pragma: no cover - compiled
    """Root of ``i`` in the union-find forest ``parent`` (int64), halving the path."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True)
def components(a, b, n):  # pragma: no cover - compiled
    """Connected components of the undirected graph of ``n`` nodes and the edges
    ``(a[i], b[i])`` (int64, each in 0..n-1): their number and the label (n,) int64 of
    every node, labels numbered in the order of each component's smallest node, as
    ``scipy.sparse.csgraph.connected_components(directed=False)`` numbers them (its
    search starts from the unlabelled nodes in ascending order). Ours because scipy's
    call on the range image's few dozen pieces costs ~0.4 ms, mostly building the
    sparse matrix, against microseconds here (INDOOR16)."""
    parent = np.arange(n)
    for i in range(a.shape[0]):
        ra, rb = find_root(parent, a[i]), find_root(parent, b[i])
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    return root_labels(parent)


@numba.njit(cache=True)
def root_labels(parent):  # pragma: no cover - compiled
    """The number of trees of the union-find forest ``parent`` (n,) int64 and each node's
    label (n,) int64, trees numbered in the order of their first node."""
    n = parent.shape[0]
    label = np.empty(n, dtype=np.int64)
    root_label = np.full(n, -1, dtype=np.int64)
    m = 0
    for v in range(n):
        r = find_root(parent, v)
        if root_label[r] < 0:
            root_label[r] = m
            m += 1
        label[v] = root_label[r]
    return m, label


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
    centred_scatter(pts, a, b, c, m)


@numba.njit(cache=True)
def centred_scatter(pts, a, b, c, m):  # pragma: no cover - compiled
    """Fill ``m`` (3, 3) with ``sum (p - c)(p - c)^T`` over ``pts[a:b]`` ((M, 3) m) about
    the given centroid ``c`` (3,) (:func:`range_moments`' second pass)."""
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


#: Radix digits of :func:`median_nonnegative`: 12 bits (sign and exponent first).
_DIGIT_BITS = 12


@numba.njit(cache=True)
def _kth_smallest_bits(bits, k):  # pragma: no cover - compiled
    """The ``k``-th smallest (0-based) of ``bits`` (n,) uint64 (a copy is consumed),
    by radix selection over 12-bit digits from the top: per digit a histogram of the
    candidates, the bucket holding rank k, and the candidates compacted to that bucket
    (branch-free: counting and writing every element)."""
    nb = 1 << _DIGIT_BITS
    hist = np.zeros(nb + 1, dtype=np.int64)
    cand = bits
    m = cand.shape[0]
    shift = 64 - _DIGIT_BITS
    while m > 32 and shift >= 0:
        hist[:] = 0
        for i in range(m):
            hist[(cand[i] >> shift) & (nb - 1)] += 1
        below = 0
        digit = 0
        while below + hist[digit] <= k:
            below += hist[digit]
            digit += 1
        if hist[digit] < m:  # else every candidate is in the bucket (ties)
            j = 0
            for i in range(m):
                cand[j] = cand[i]
                j += ((cand[i] >> shift) & (nb - 1)) == digit
            m = j
        k -= below
        shift -= _DIGIT_BITS
    if shift < 0:  # every candidate has the same bits: all equal
        return cand[0]
    return np.sort(cand[:m])[k]


@numba.njit(cache=True)
def median_nonnegative(values, n):  # pragma: no cover - compiled
    """``np.median(values[:n])`` (the same value) of finite values >= 0, n >= 1.

    The bits of non-negative floats order as the floats do, so the middle values are
    found by radix selection on them (:func:`_kth_smallest_bits`): passes without
    data-dependent branches, where quickselect's partitions mispredict about every other
    comparison (numba's and numpy's median cost ~3x more on 10^4 noise residuals). For an
    even count, ``(a + b) / 2`` of the two middle values, as numpy and numba.
    """
    v = values[:n].copy()
    bits = v.view(np.uint64)
    half = n >> 1
    if n & 1:
        return _as_float(_kth_smallest_bits(bits, half))
    lo = _as_float(_kth_smallest_bits(bits.copy(), half - 1))
    # the next order statistic: lo again when it repeats, else the least value above it
    n_le = 0
    above = np.inf
    for i in range(n):
        x = v[i]
        n_le += x <= lo
        if x > lo and x < above:
            above = x
    hi = lo if n_le >= half + 1 else above
    return (lo + hi) / 2


@numba.njit(cache=True)
def _as_float(b):  # pragma: no cover - compiled
    """The float64 whose bits are the uint64 ``b``."""
    a = np.empty(1, dtype=np.uint64)
    a[0] = b
    return a.view(np.float64)[0]
