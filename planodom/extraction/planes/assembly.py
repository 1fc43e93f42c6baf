"""The builder's planes and their arrays assembled at once.

:func:`planodom.extraction.planes.builder.build_planes` ends in one :class:`Plane` per
kept fit, and the odometry then stacks their fields again into a :class:`PlaneSet`
(:meth:`PlaneSet.from_planes`, once an extraction). Both come from the builder's arrays,
so both are assembled here from them, with the same bits:

- ``Plane.__post_init__`` checks each plane and divides its normal and offset by the
  normal's length. :func:`unit_rows` does the same for all kept fits in one compiled
  call (the length's square summed as ``ndarray.dot`` sums three values,
  :func:`planodom.fma.dot3`), and when every plane passes, the objects are made without
  running the checks a second time (:func:`made`). When one fails, the builder makes the
  planes by their constructor, which raises its own error.
- The set of those planes comes from the same arrays (:meth:`PlaneSet.from_arrays`, what
  :meth:`PlaneSet.from_planes` runs on the planes' fields), handed over
  (:func:`planodom.planes.hand_over`) to the next ``from_planes`` of those very plane
  objects (the extraction's :func:`planodom.extraction.pipeline._result` reorders it
  with the planes).
"""

from __future__ import annotations

from typing import Any, TypeVar

import numba
import numpy as np

from planodom.fma import dot3
from planodom.planes import PlaneSet

T = TypeVar("T")


def made(cls: type[T], fields: dict[str, Any]) -> T:
    """An instance of the frozen dataclass ``cls`` holding ``fields`` (every field, by
    name) without running its ``__init__``: for values its checks have passed already
    (:func:`unit_rows`). The dataclass's own ``__init__`` only sets the fields (and
    ``Plane.__post_init__`` checks and scales them)."""
    obj = object.__new__(cls)
    obj.__dict__.update(fields)
    return obj


@numba.njit(cache=True)
def unit_rows(normals, offsets, confidence, kept):  # pragma: no cover - compiled
    """``Plane.__post_init__`` for the fits ``kept`` (K,) int64 of ``normals`` (G, 3),
    ``offsets`` (G,) m and ``confidence`` (G,): whether every one passes its checks (a
    finite normal of length 1e-12 or more, a finite offset, a confidence in (0, 1]), and
    the normals (K, 3) and offsets (K,) divided by the normal's length. The length is
    ``sqrt`` of the square ``ndarray.dot`` gives (three products added by fused
    multiply-adds in order: the same bits). A normal whose square overflows counts as
    failing (the constructor then decides)."""
    K = kept.shape[0]
    n_out = np.empty((K, 3))
    d_out = np.empty(K)
    for k in range(K):
        g = kept[k]
        n0, n1, n2 = normals[g, 0], normals[g, 1], normals[g, 2]
        sq = dot3(n0, n1, n2, n0, n1, n2)
        c = confidence[g]
        if not (np.isfinite(sq) and np.isfinite(offsets[g]) and 0.0 < c <= 1.0):
            return False, n_out, d_out
        norm = np.sqrt(sq)
        if norm < 1e-12:
            return False, n_out, d_out
        n_out[k, 0] = n0 / norm
        n_out[k, 1] = n1 / norm
        n_out[k, 2] = n2 / norm
        d_out[k] = offsets[g] / norm
    return True, n_out, d_out


def kept_set(
    normals: np.ndarray, offsets: np.ndarray, confidence: np.ndarray, covariances: np.ndarray,
    centroids: np.ndarray, polygons: list[np.ndarray], narrow: np.ndarray | None,
    kept: np.ndarray,
) -> PlaneSet:  # fmt: skip
    """The :class:`PlaneSet` of the planes the builder makes of fits ``kept`` (K,):
    ``normals`` (K, 3) and ``offsets`` (K,) of :func:`unit_rows`, the fits' (G,)
    ``confidence``, (G, 4, 4) ``covariances``, (G, 3) ``centroids`` and (G,) ``narrow``
    (None: none), and the kept planes' ``polygons``. Its arrays are its own (none is a
    plane's)."""
    narrow_k = np.zeros(len(kept), dtype=bool) if narrow is None else narrow[kept]
    return PlaneSet.from_arrays(
        normals.copy(), offsets.copy(), confidence[kept], covariances[kept],
        np.array(centroids[kept], dtype=np.float64), polygons, narrow_k.astype(bool),
    )  # fmt: skip
