"""Which LDA pairs agree with a rotation: numpy's verdicts, mostly compiled.

The solver keeps, for the translation, the LDA pairs whose two normal associations both
agree with the consensus rotation ``R``: ``|n_i - R n_j| <= chord`` for ``(i1, j1)`` and
``(i2, j2)``. numpy's expression (two fancy indexings, a product with ``R.T`` and a row
norm per side, about twenty calls on a few rows) costs ten times its arithmetic. The
compiled distances may differ from numpy's in their last bits (numpy's ``@`` calls BLAS,
whose sums may be ordered or fused otherwise), so they decide only when every one lies
farther from ``chord`` than the two computations can differ; otherwise numpy's expression
decides. The verdicts are therefore numpy's, bit for bit.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.geometry import row_norms

#: How far a compiled distance may lie from numpy's, m per m: unit normals, a rotated
#: component is a sum of three products below 1 (rounding below 1e-15 in any order), a
#: difference, three squares and a square root: a few 1e-16; 1e-12 leaves a wide margin.
_GUARD = 1e-12


def agreeing_pairs(
    prev_normals: np.ndarray,
    curr_normals: np.ndarray,
    prev_pairs: np.ndarray,
    curr_pairs: np.ndarray,
    R: np.ndarray,
    chord: float,
) -> np.ndarray:
    """(M,) bool: whether both normal associations of each pair ``prev_pairs[m]`` ->
    ``curr_pairs[m]`` (M, 2) agree with ``R`` (3, 3): ``|n_prev - R n_curr| <= chord`` for
    unit normals (K, 3) (module docstring: numpy's verdicts)."""
    if len(prev_pairs) == 0:
        return np.zeros(0, dtype=bool)
    agree, sure = _agreeing_kernel(
        prev_normals, curr_normals, np.asarray(prev_pairs, np.int64),
        np.asarray(curr_pairs, np.int64), np.ascontiguousarray(R, dtype=np.float64),
        float(chord), _GUARD,
    )  # fmt: skip
    return (
        agree
        if sure
        else numpy_agreeing(prev_normals, curr_normals, prev_pairs, curr_pairs, R, chord)
    )


def numpy_agreeing(
    prev_normals: np.ndarray,
    curr_normals: np.ndarray,
    pp: np.ndarray,
    cp: np.ndarray,
    R: np.ndarray,
    chord: float,
) -> np.ndarray:
    """:func:`agreeing_pairs` in numpy (the solver's expression before SPEED2D8)."""
    e1 = row_norms(prev_normals[pp[:, 0]] - curr_normals[cp[:, 0]] @ R.T)
    e2 = row_norms(prev_normals[pp[:, 1]] - curr_normals[cp[:, 1]] @ R.T)
    return (e1 <= chord) & (e2 <= chord)


@numba.njit(cache=True)
def _agreeing_kernel(pn, cn, pp, cp, R, chord, guard):  # pragma: no cover - compiled
    """:func:`agreeing_pairs`' verdicts (M,) and whether every distance lay outside the
    guard band around ``chord`` (False also for a non-finite one: numpy decides)."""
    m = pp.shape[0]
    agree = np.empty(m, dtype=np.bool_)
    sure = True
    for q in range(m):
        ok = True
        for side in range(2):
            i, j = pp[q, side], cp[q, side]
            s = 0.0
            for a in range(3):
                r = R[a, 0] * cn[j, 0] + R[a, 1] * cn[j, 1] + R[a, 2] * cn[j, 2]
                s += (pn[i, a] - r) ** 2
            e = np.sqrt(s)
            if not abs(e - chord) > guard:  # within the band, or NaN
                sure = False
            ok = ok and e <= chord
        agree[q] = ok
    return agree, sure
