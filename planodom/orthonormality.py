"""Whether a rotation block is orthonormal to a tolerance: numpy's verdict, mostly compiled.

:func:`planodom.geometry.orthonormalised` asks, three times an epoch of the streaming
odometry, whether ``max |R^T R - I| <= tol``. numpy's five calls on a 3 x 3 block cost about
20 us; one compiled call costs a tenth. The compiled deviation may differ from numpy's in
its last bits (numpy's ``@`` calls BLAS, whose sums may be ordered or fused otherwise), so
it decides only when it is farther from ``tol`` than the two computations can differ;
closer, numpy's own expression decides. The verdict is therefore numpy's, bit for bit.
"""

from __future__ import annotations

import numba
import numpy as np

#: Relative bound on how far two evaluations of an entry of ``R^T R - I`` may differ, per
#: unit of ``1 + sum(R^2)``: each entry is a sum of three products, whose rounding error in
#: any order (fused or not) is below ``3.4e-16 * sum |a_i b_i| <= 3.4e-16 * sum(R^2)``
#: (Higham's gamma_3); twice that for two evaluations, one more rounding for the ``- 1``;
#: 1e-14 leaves a factor of ten.
_GUARD = 1e-14


def is_orthonormal(R: np.ndarray, tol: float) -> bool:
    """``np.max(np.abs(R.T @ R - np.eye(3))) <= tol`` for a (3, 3) block ``R`` (any layout),
    the same verdict (NaN: False), in one compiled call unless the deviation lies within the
    guard band around ``tol`` (module docstring)."""
    # a fresh C-contiguous writeable copy: one compiled specialisation for every caller
    dev, scale = _deviation(np.ascontiguousarray(R, dtype=np.float64))
    if abs(dev - tol) > _GUARD * (1.0 + scale):
        return bool(dev <= tol)
    return bool(np.max(np.abs(R.T @ R - np.eye(3))) <= tol)


@numba.njit(cache=True)
def _deviation(R):  # pragma: no cover - compiled
    """``max |R^T R - I|`` of ``R`` (3, 3) (NaN when an entry is) and ``sum(R^2)``."""
    dev = 0.0
    scale = 0.0
    for i in range(3):
        for j in range(3):
            g = R[0, i] * R[0, j] + R[1, i] * R[1, j] + R[2, i] * R[2, j]
            e = abs(g - (1.0 if i == j else 0.0))
            if e != e:  # NaN: numpy decides
                return e, scale
            dev = max(dev, e)
            scale += R[i, j] * R[i, j]
    return dev, scale
