"""Seeded, reproducible RANSAC plane segmentation (the 3D path's fallback, :mod:`.lidar`).

Written here instead of calling open3d's ``PointCloud.segment_plane`` because that one is
not reproducible: the same cloud, the same ``o3d.utility.random.seed`` and one OpenMP
thread can give different planes in two processes (isl-org/Open3D#7270), with open3d 0.20
even in two calls of one process (on the simulated paper loop, some lidar32 epochs of 60
changed their candidate planes from one run to the next). Here the samples come from a
numpy ``Generator`` the caller seeds, and the hypotheses are scored one after the other
in a fixed order (compiled, numba, no threads, no fast-math), so the same points,
parameters and generator state give the same plane bit for bit.

The algorithm is open3d's (``SegmentPlane``, ``ransac_n = 3``):

1. ``num_iterations`` triples of distinct points are drawn up front (uniformly).
2. Each triple gives a plane (its unit normal from the cross product of two edges; a
   collinear triple is skipped). Its score is the number of points within
   ``distance_threshold`` of it; ties go to the smaller sum of squared distances of those
   inliers (open3d: of the distances). The first best hypothesis in draw order wins.
3. After each new best, with inlier fraction ``w``, the search stops once
   ``log(1 - probability) / log(1 - w^3)`` hypotheses have been tried (the number after
   which a triple of inliers has been drawn with that probability).
4. The inliers of the best plane are returned; the caller refits them.

A hypothesis' count is abandoned as soon as it can no longer reach the best count (exact:
it could not have won), which with the compiled, vectorised count makes a 10 000-point,
300-iteration search about a millisecond.
"""

from __future__ import annotations

import functools

import numba
import numpy as np

#: Points counted between two checks of whether a hypothesis can still win.
_BLOCK = 512


def sample_triples(rng: np.random.Generator, m: int, n: int) -> np.ndarray:
    """(n, 3) int64: n triples of distinct indices in [0, m) (m >= 3), each triple uniform
    over the m (m - 1) (m - 2) ordered ones; one ``rng.integers`` call."""
    return distinct_triples(draw_samples(rng, m, n))


def draw_samples(rng: np.random.Generator, m: int, n: int) -> np.ndarray:
    """(n, 3) int64: the raw draws of :func:`sample_triples`, column k uniform in
    [0, m - k) (m >= 3); made distinct by :func:`distinct_triples`."""
    return rng.integers(0, [m, m - 1, m - 2], size=(n, 3), dtype=np.int64)


def seed_stream(seed: int, n_words: int) -> np.ndarray:
    """(n_words,) uint64: the first outputs of the bit generator of
    ``np.random.default_rng(seed)`` (read-only, memoised), which :func:`draw_stream`
    turns into the very draws :func:`draw_samples` makes from such a generator."""
    return _seed_stream(int(seed), int(n_words))


@functools.lru_cache(maxsize=4)
def _seed_stream(seed: int, n_words: int) -> np.ndarray:
    words = np.random.default_rng(seed).bit_generator.random_raw(n_words)
    words.flags.writeable = False
    return words


@numba.njit(cache=True)
def _next_uint32(words, state):  # pragma: no cover - compiled
    """numpy's ``next_uint32`` of a PCG64 generator over its 64-bit outputs ``words``:
    the low half of a new word, then its high half. ``state`` (3,) int64: the next word,
    whether a high half is pending, and set to 1 once ``words`` runs out (0 returned)."""
    if state[1]:
        state[1] = 0
        return (words[state[0] - 1] >> np.uint64(32)) & np.uint64(0xFFFFFFFF)
    if state[0] >= words.shape[0]:
        state[2] = 1
        return np.uint64(0)
    word = words[state[0]]
    state[0] += 1
    state[1] = 1
    return word & np.uint64(0xFFFFFFFF)


@numba.njit(cache=True)
def _bounded(words, state, high):  # pragma: no cover - compiled
    """An integer uniform in [0, ``high``) (1 <= high < 2^32) as numpy's
    ``Generator.integers`` draws it (``random_bounded_uint64``: no draw when ``high`` is
    1, else Lemire's multiply-and-reject on 32-bit draws, ``buffered_bounded_lemire_uint32``)."""
    if high == 1:
        return 0
    excl = np.uint64(high)
    m = _next_uint32(words, state) * excl
    leftover = m & np.uint64(0xFFFFFFFF)
    if leftover < excl:
        threshold = (np.uint64(0xFFFFFFFF) - (excl - np.uint64(1))) % excl
        while leftover < threshold and state[2] == 0:
            m = _next_uint32(words, state) * excl
            leftover = m & np.uint64(0xFFFFFFFF)
    return np.int64(m >> np.uint64(32))


@numba.njit(cache=True)
def draw_stream(words, state, m, n):  # pragma: no cover - compiled
    """(n, 3) int64: :func:`draw_samples` ``(rng, m, n)`` (m >= 3) from the generator
    whose outputs are ``words`` (:func:`seed_stream`), at ``state`` (:func:`_next_uint32`,
    advanced as the generator would be); compiled, so that the RANSAC loop draws without
    leaving it (bit for bit numpy's draws: tests/extraction/test_lidar.py)."""
    out = np.empty((n, 3), dtype=np.int64)
    for r in range(n):
        for k in range(3):
            out[r, k] = _bounded(words, state, m - k)
    return out


@numba.njit(cache=True)
def distinct_triples(s):  # pragma: no cover - compiled
    """(n, 3) int64 triples of distinct indices from the raw draws ``s`` (n, 3) of
    :func:`draw_samples`: the second skips the first, the third skips both."""
    out = np.empty_like(s)
    for r in range(s.shape[0]):
        a, b, c = s[r, 0], s[r, 1], s[r, 2]
        if b >= a:  # skip a
            b += 1
        lo, hi = min(a, b), max(a, b)
        if c >= lo:  # skip the smaller of a, b, then the larger
            c += 1
        if c >= hi:
            c += 1
        out[r, 0], out[r, 1], out[r, 2] = a, b, c
    return out


def segment_plane(
    points: np.ndarray,
    distance_threshold: float,
    num_iterations: int,
    probability: float,
    rng: np.random.Generator,
) -> tuple[np.ndarray, np.ndarray]:
    """RANSAC plane of ``points`` (M, 3), metres: ``(plane (4,), inliers (K,) int64)``.

    ``plane`` is ``(n, d)`` with ``|n| = 1`` and ``n . p + d = 0``: the best three-point
    hypothesis (not refit), all zeros with no inliers when M < 3 or every triple drawn was
    collinear. ``inliers``: indices of the points within ``distance_threshold`` (m) of it,
    ascending. Draws ``num_iterations`` triples from ``rng`` (whatever the early stop).
    """
    m = len(points)
    if m < 3 or num_iterations < 1:
        return np.zeros(4), np.zeros(0, dtype=np.int64)
    samples = draw_samples(rng, m, num_iterations)
    xyz = np.ascontiguousarray(np.asarray(points, dtype=np.float64).T)
    return segment_drawn(xyz, samples, float(distance_threshold), log_fail(probability))


def log_fail(probability: float) -> float:
    """``log(1 - probability)`` of the early stop (-inf: none, at ``probability`` 1)."""
    return float(np.log1p(-probability)) if probability < 1.0 else -np.inf


@numba.njit(cache=True)
def segment_drawn(xyz, samples, tol, log_fail):  # pragma: no cover - compiled
    """:func:`segment_plane` of the points ``xyz`` (3, M) with the raw draws ``samples``
    (T, 3) of :func:`draw_samples` already made: ``(plane (4,), inliers (K,) int64)``."""
    plane = _best_plane(xyz, distinct_triples(samples), tol, log_fail)
    if plane[0] == 0.0 and plane[1] == 0.0 and plane[2] == 0.0 and plane[3] == 0.0:
        return plane, np.zeros(0, dtype=np.int64)
    return plane, _inliers(xyz, plane, tol)


@numba.njit(cache=True)
def _count_within(x, y, z, nx, ny, nz, d, tol, need):  # pragma: no cover - compiled
    """Points with ``|n . p + d| <= tol``; -1 once fewer than ``need`` can be reached."""
    m = x.shape[0]
    cnt = 0
    for start in range(0, m, _BLOCK):
        end = min(start + _BLOCK, m)
        cnt += _count_block(x[start:end], y[start:end], z[start:end], nx, ny, nz, d, tol)
        if cnt + (m - end) < need:
            return -1
    return cnt


@numba.njit(cache=True)
def _count_block(x, y, z, nx, ny, nz, d, tol):  # pragma: no cover - compiled
    """Points of the block with ``|n . p + d| <= tol``. A function of its own on slices:
    a loop over ``range(x.shape[0])`` vectorises (SIMD), one over ``range(start, end)``
    does not (~6x slower)."""
    c = 0
    for i in range(x.shape[0]):
        r = nx * x[i] + ny * y[i] + nz * z[i] + d
        c += abs(r) <= tol
    return c


@numba.njit(cache=True)
def _best_plane(xyz, triples, tol, log_fail):  # pragma: no cover - compiled
    """(4,) best hypothesis ``(n, d)`` of :func:`segment_plane` (zeros if none) over the
    points ``xyz`` (3, M) and the ``triples`` (T, 3), in order, with the early stop."""
    x, y, z = xyz[0], xyz[1], xyz[2]
    m = x.shape[0]
    n_iter = triples.shape[0]
    best = np.zeros(4)
    best_cnt = 0
    best_sse = np.inf
    stop = float(n_iter)
    it = 0
    while it < n_iter and it < stop:
        i, j, k = triples[it, 0], triples[it, 1], triples[it, 2]
        it += 1
        a0, a1, a2 = x[j] - x[i], y[j] - y[i], z[j] - z[i]
        b0, b1, b2 = x[k] - x[i], y[k] - y[i], z[k] - z[i]
        nx = a1 * b2 - a2 * b1
        ny = a2 * b0 - a0 * b2
        nz = a0 * b1 - a1 * b0
        nn = np.sqrt(nx * nx + ny * ny + nz * nz)
        if not nn > 0.0:
            continue  # collinear (or repeated) points
        nx, ny, nz = nx / nn, ny / nn, nz / nn
        d = -(nx * x[i] + ny * y[i] + nz * z[i])
        cnt = _count_within(x, y, z, nx, ny, nz, d, tol, max(best_cnt, 1))
        if cnt < best_cnt or cnt <= 0:
            continue
        sse = 0.0
        for q in range(m):
            r = nx * x[q] + ny * y[q] + nz * z[q] + d
            if abs(r) <= tol:
                sse += r * r
        if cnt == best_cnt and not sse < best_sse:
            continue
        best[0], best[1], best[2], best[3] = nx, ny, nz, d
        best_cnt, best_sse = cnt, sse
        w = cnt / m
        if w >= 1.0:
            stop = 0.0
        else:
            stop = min(log_fail / np.log1p(-(w * w * w)), float(n_iter))
    return best


@numba.njit(cache=True)
def _inliers(xyz, plane, tol):  # pragma: no cover - compiled
    """Indices (ascending) of the points ``xyz`` (3, M) within ``tol`` of ``plane``, with
    the distances computed as in :func:`_best_plane`."""
    x, y, z = xyz[0], xyz[1], xyz[2]
    nx, ny, nz, d = plane[0], plane[1], plane[2], plane[3]
    out = np.empty(x.shape[0], dtype=np.int64)
    k = 0
    for i in range(x.shape[0]):
        r = nx * x[i] + ny * y[i] + nz * z[i] + d
        if abs(r) <= tol:
            out[k] = i
            k += 1
    return out[:k]
