"""Connected clusters of a RANSAC plane's inliers as seen from the viewpoint, and the
points and voxels of each cluster's (dilated) region: step 3 of
:mod:`planodom.extraction.lidar.candidates`, compiled (numba).

Cells are ``cluster_gap_deg`` in azimuth (wrapping at ``n_az``) and elevation; a lookup
grid (n_az, n_el) holds the cluster of every occupied cell and, dilated by one cell, of its
free neighbours (-1: none). Buckets are ``(members, bounds)``: bucket ``l`` is
``members[bounds[l]:bounds[l + 1]]``, ascending.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.kernels import find_root
from planodom.extraction.lidar.grid import plane_members


def clusters(cells: np.ndarray, n_az: int) -> tuple[np.ndarray, np.ndarray]:
    """8-connected clusters of occupied angular cells (K, 2), azimuth wrapping at n_az.

    Returns the label (K,) of every point (0-based) and a lookup grid (n_az, n_el) of
    the labels dilated by one cell (-1 = free): a free cell takes the largest label of
    its 8 neighbours. The clusters are numbered from 1 in the order of their first cell
    (azimuth-major), as scipy's ``ndimage.label`` numbers them; compiled (numba,
    :func:`cluster_grid`) because ``ndimage.label``, the seam join and
    ``ndimage.grey_dilation`` cost ~0.15 ms per RANSAC plane in small calls.
    """
    labels, window, lo = cluster_cells(cells[:, 0] % n_az, np.ascontiguousarray(cells[:, 1]), n_az)
    lookup = np.full((n_az, lo + window.shape[1]), -1, dtype=np.int64)
    lookup[:, lo:] = window
    return labels, lookup


@numba.njit(cache=True)
def cluster_cells(az, el, n_az):  # pragma: no cover - compiled
    """:func:`clusters` of the occupied cells ``(az, el)`` (K,) (``az`` in [0, n_az)):
    ``(labels (K,), window, lo)``, the lookup grid's rows ``lo ..`` only (the rows below
    the lowest occupied one but one are free and far from every cluster: all -1).
    Cells are compared in the same (azimuth-major) order as on the full grid, so the
    labels are the same."""
    lo = max(el.min() - 1, 0)
    n_el = el.max() + 2 - lo
    e = el - lo
    lookup, merged = cluster_grid(az, e, n_az, n_el)
    labels = np.empty(az.shape[0], dtype=np.int64)
    for i in range(az.shape[0]):
        labels[i] = merged[az[i], e[i]]
    return labels, lookup, lo


@numba.njit(cache=True)
def cluster_grid(az, el, n_az, n_el):  # pragma: no cover - compiled
    """``(lookup, merged)`` (n_az, n_el) int64 of :func:`clusters` for the occupied cells
    ``(az, el)`` (K,): ``merged`` the cluster of each occupied cell (-1 free), ``lookup``
    the same with each free cell given its neighbours' largest cluster."""
    occ = np.zeros((n_az, n_el), dtype=np.bool_)
    for i in range(az.shape[0]):
        occ[az[i], el[i]] = True
    parent = np.arange(n_az * n_el)
    for a in range(n_az):
        for e in range(n_el):
            if not occ[a, e]:
                continue
            # the neighbours of an earlier row (wrapping) and the previous column
            for da, de in ((-1, -1), (-1, 0), (-1, 1), (0, -1)):
                b, f = (a + da) % n_az, e + de
                if 0 <= f < n_el and occ[b, f]:
                    ru, rv = find_root(parent, a * n_el + e), find_root(parent, b * n_el + f)
                    parent[max(ru, rv)] = min(ru, rv)
    merged = np.full((n_az, n_el), -1, dtype=np.int64)
    number = np.zeros(n_az * n_el, dtype=np.int64)
    k = 0
    for a in range(n_az):  # numbered in the order of each cluster's first cell
        for e in range(n_el):
            if occ[a, e]:
                r = find_root(parent, a * n_el + e)
                if number[r] == 0:
                    k += 1
                    number[r] = k
                merged[a, e] = number[r]
    lookup = merged.copy()
    for a in range(n_az):
        for e in range(n_el):
            if occ[a, e]:
                continue
            for da in (-1, 0, 1):
                for de in (-1, 0, 1):
                    f = e + de
                    if 0 <= f < n_el:
                        lookup[a, e] = max(lookup[a, e], merged[(a + da) % n_az, f])
    return lookup, merged


def buckets(idx: np.ndarray, lab: np.ndarray, n_lab: int) -> tuple[np.ndarray, np.ndarray]:
    """The indices ``idx`` (K,) ascending, bucketed by their labels ``lab`` (K,) (those
    in [0, n_lab)): ``(members, bounds)``, bucket ``l`` being ``members[bounds[l]:bounds[l
    + 1]]`` (ascending: a stable sort), ``bounds`` (n_lab + 1,); one sort instead of one
    pass over every point per label."""
    keep = (lab >= 0) & (lab < n_lab)
    idx, lab = idx[keep], lab[keep]
    order = np.argsort(lab, kind="stable")
    return idx[order], np.searchsorted(lab[order], np.arange(n_lab + 1))


@numba.njit(cache=True)
def region_buckets(az, el, taken, lookup, n_lab):  # pragma: no cover - compiled
    """:func:`buckets` of the indices i not ``taken`` (K,) by their (dilated) cluster
    ``lookup[az[i], min(el[i], top)]`` (``lookup`` (n_az, top + 1), -1: none): the same
    ``(members, bounds)`` (each bucket ascending) by a counting sort in two compiled
    passes; numpy's gather, mask and stable argsort over every point cost ~1 ms per
    RANSAC plane on a 128-beam scan."""
    return window_buckets(az, el, taken, lookup, 0, n_lab)


@numba.njit(cache=True)
def window_buckets(az, el, taken, window, lo, n_lab):  # pragma: no cover - compiled
    """:func:`region_buckets` with the lookup grid's rows ``lo ..`` only (``window``;
    the rows below all -1)."""
    top = lo + window.shape[1] - 1
    lab = np.full(az.shape[0], -1, dtype=np.int64)
    for i in range(az.shape[0]):
        if not taken[i] and el[i] >= lo:
            g = window[az[i], min(el[i], top) - lo]
            if 0 <= g < n_lab:
                lab[i] = g
    return plane_members(lab, n_lab)


@numba.njit(cache=True)
def cell_buckets(cell_idx, cell_b, n_el, taken, window, lo, n_lab):  # pragma: no cover
    """:func:`window_buckets` of the points grouped by angular cell (``cell_idx``,
    ``cell_b``: :func:`.cells.cell_members`, elevations in ``[0, n_el)``): only the
    cells in which ``window`` has a cluster are visited (a wall's clusters cover a few of
    them), a point of elevation ``el >= top`` in the top row's cell of its azimuth as
    there (``min(el, top)``), then each bucket is sorted (ascending, as there)."""
    n_az, n_win = window.shape
    top = lo + n_win - 1
    n_hit = 0
    for a in range(n_az):
        for e in range(n_win):
            g = window[a, e]
            if 0 <= g < n_lab and lo + e < n_el:
                hi = n_el if e == n_win - 1 else lo + e + 1
                n_hit += cell_b[a * n_el + hi] - cell_b[a * n_el + lo + e]
    hit = np.empty(n_hit, dtype=np.int64)
    lab = np.empty(n_hit, dtype=np.int64)
    k = 0
    for a in range(n_az):
        for e in range(n_win):
            g = window[a, e]
            if not (0 <= g < n_lab and lo + e < n_el):
                continue
            hi = n_el if lo + e == top else lo + e + 1  # the top row takes all above it
            for q in range(cell_b[a * n_el + lo + e], cell_b[a * n_el + hi]):
                i = cell_idx[q]
                if not taken[i]:
                    hit[k] = i
                    lab[k] = g
                    k += 1
    pos, bounds = plane_members(lab[:k], n_lab)
    idx = hit[:k][pos]
    for g in range(n_lab):
        idx[bounds[g] : bounds[g + 1]].sort()
    return idx, bounds
