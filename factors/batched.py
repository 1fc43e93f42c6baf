"""The 5-DoF, rotation and vertical factors of a graph evaluated in one compiled pass.

Each of these factors is a ``gtsam.CustomFactor``: gtsam calls back into Python once per
factor and evaluation, and the callback fetches its two poses from the values and calls the
compiled kernel (:mod:`planodom_factors.pose5`). :class:`BatchedResiduals` computes the
residuals (and Jacobians) of all of a graph's such factors at once from the values' poses
(``gtsam.utilities.extractPose3``), with the same kernels; while ``graph.error`` or
``graph.linearize`` runs, the callbacks only hand the precomputed rows to gtsam. gtsam still
whitens, applies the robust kernel and sums in the graph's order, so the errors and linear
factors are the same numbers as without it, bit for bit.

Not thread-safe: the precomputed rows are module state (one evaluation at a time).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import gtsam
import numba
import numpy as np

from planodom_factors.pose5 import _pose5_kernel, _Precomputed, _vertical_kernel


@contextmanager
def record() -> Iterator[list[tuple]]:
    """Collect, in a list, a description of each 5-DoF, rotation and vertical factor that
    gtsam evaluates inside the ``with`` block: ``(measured (4, 4) or None, dz, key_i,
    key_j, cell)`` (the callback's cell: :class:`.pose5._Precomputed`)."""
    previous, _Precomputed.record = _Precomputed.record, []
    try:
        yield _Precomputed.record
    finally:
        _Precomputed.record = previous


@numba.njit(cache=True)
def _residuals(
    poses: np.ndarray,
    index_i: np.ndarray,
    index_j: np.ndarray,
    measured: np.ndarray,
    dz: np.ndarray,
    vertical: np.ndarray,
    jacobians: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Residuals (F, 5) and Jacobians (F, 5, 6) of F factors between the poses
    ``index_i`` and ``index_j`` (F,) (rows of ``poses`` (N, 12), ``extractPose3``'s
    row-major rotation then translation): a vertical factor (``vertical``, against ``dz``
    (F,), m) in row 0, else the 5-DoF error against ``measured`` (F, 4, 4); and (F,) false
    where the 5-DoF kernel deferred to gtsam."""
    n = index_i.shape[0]
    errors = np.zeros((n, 5))
    H_i = np.zeros((n, 5, 6))
    H_j = np.zeros((n, 5, 6))
    ok = np.ones(n, dtype=np.bool_)
    T_i = np.eye(4)
    T_j = np.eye(4)
    for f in range(n):
        a, b = index_i[f], index_j[f]
        for r in range(3):
            for q in range(3):
                T_i[r, q] = poses[a, 3 * r + q]
                T_j[r, q] = poses[b, 3 * r + q]
            T_i[r, 3] = poses[a, 9 + r]
            T_j[r, 3] = poses[b, 9 + r]
        if vertical[f]:
            e, A, B = _vertical_kernel(dz[f], T_i, T_j)
            errors[f, 0] = e[0]
            H_i[f, 0] = A[0]
            H_j[f, 0] = B[0]
        else:
            e, A, B, good = _pose5_kernel(measured[f], T_i, T_j, jacobians)
            ok[f] = good
            if good:
                errors[f] = e
                H_i[f] = A
                H_j[f] = B
    return errors, H_i, H_j, ok


class BatchedResiduals:
    """``graph.error`` and ``graph.linearize`` of one graph, its 5-DoF, rotation and
    vertical factors' residuals computed in one compiled pass (module docstring).

    Built from the graph and a first ``values`` (which it evaluates once, recording the
    factors); later values must hold the same Pose3 keys (an optimiser's iterates).

    Attributes:
        initial_error: ``graph.error`` at the first values.
    """

    def __init__(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> None:
        with record() as factors:
            self.initial_error = float(graph.error(values))
        self._graph = graph
        pose_keys = list(gtsam.utilities.allPose3s(values).keys())
        row = {key: i for i, key in enumerate(pose_keys)}
        self._n_poses = len(pose_keys)
        self._cells = [f[4] for f in factors]  # each callback's row, written by _at
        self._token = object()  # (whose rows the cells hold: _Precomputed.owner)
        self._index_i = np.array([row[f[2]] for f in factors], dtype=np.int64)
        self._index_j = np.array([row[f[3]] for f in factors], dtype=np.int64)
        self._vertical = np.array([f[0] is None for f in factors], dtype=np.bool_)
        self._dz = np.array([f[1] for f in factors], dtype=float)
        self._measured = np.stack(
            [np.eye(4) if f[0] is None else f[0] for f in factors] or [np.eye(4)]
        )[: len(factors)]

    @contextmanager
    def _at(self, values: gtsam.Values, jacobians: bool) -> Iterator[None]:
        """The callbacks take their rows from one pass at ``values`` inside the block."""
        poses = gtsam.utilities.extractPose3(values)
        if not self._cells or poses.shape[0] != self._n_poses:
            yield  # nothing to batch, or other values: each factor computes its own
            return
        errors, H_i, H_j, ok = _residuals(
            poses, self._index_i, self._index_j, self._measured, self._dz, self._vertical,
            jacobians,
        )  # fmt: skip
        p = _Precomputed
        if p.owner is not self._token:  # another batch's rows (the factors may be shared)
            for r, cell in enumerate(self._cells):
                cell[0] = r
            p.owner = self._token
        p.errors, p.ok = errors, ok
        p.H_i, p.H_j = (H_i, H_j) if jacobians else (None, None)
        p.values = values
        try:
            yield
        finally:
            p.values, p.H_i, p.H_j = None, None, None

    def error(self, values: gtsam.Values) -> float:
        """``graph.error(values)``."""
        with self._at(values, False):
            return float(self._graph.error(values))

    def linearize(self, values: gtsam.Values) -> gtsam.GaussianFactorGraph:
        """``graph.linearize(values)``."""
        with self._at(values, True):
            return self._graph.linearize(values)
