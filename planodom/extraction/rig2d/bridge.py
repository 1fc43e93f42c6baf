"""A gap of the 2D-rig grouping bridged where one side's plane predicts the other
(``extraction.gap_bridge: predicted``).

The gap rule (:mod:`.connect`) keeps only the traces of a growing plane connected to its
seed's first trace through gaps of ``plane_gap_m``; a seed whose second trace lies
farther away loses it and dies. Indoors that is a floor or ceiling seen by a scanner
ahead and one behind, 20-40 m apart (docs/RESULTS.md, INDOOR3, GAPRULE). Two traces
alone cannot tell one plane from two across such a gap: their common normal is known
only to their direction errors over the crossing angle, which moves the plane by
decimetres 30 m away. So the gap is bridged only where a whole piece says so: the piece
connected to one seed trace, fit alone (total least squares of its traces' moments),
predicts the plane at the other piece's centroid to ``tol / 3`` (1 sigma: the offset's
variance ``s^2 / N + s^2 (D . e1)^2 / l1 + s^2 (D . e2)^2 / l2``, ``e1``, ``e2`` its
in-plane axes with scatter ``l1``, ``l2``, ``D`` the displacement, ``s^2`` the piece's
residual variance about its plane, ``l0 / (N - 3)``: not the noise sigma, which is
measured across the scan lines; a floor hit at a grazing angle scatters about its plane
by a fraction of it), and every trace of the other piece fits
that plane by the grouping's membership test (:func:`.tracefit.trace_fits`, ``tol``).
One trace, or parallel traces on one line, never predict (no spread across them);
several traces spread across (one scanner's sweeps in a turn, or two scanners) can.
Compiled with numba: called from the grouping's compiled growth.
"""

from __future__ import annotations

import numba
import numpy as np

from planodom.extraction.rig2d.connect import connected_piece
from planodom.extraction.rig2d.tracefit import trace_fits

#: The prediction's 1-sigma error at the other piece, in units of the member tolerance
#: (itself ``member_sigma_factor`` = 3 noise sigmas): the seed test's 3 sigma.
PREDICT_SIGMAS = 3.0


@numba.njit(cache=True)
def piece_moments(members, count, centroid, scatter):  # pragma: no cover - compiled
    """Points (float), centroid (3,) and scatter about it (3, 3) of the traces
    ``members`` (bool (T,)), from their moments."""
    total = 0.0
    c = np.zeros(3)
    for t in range(members.shape[0]):
        if members[t]:
            total += count[t]
            c += count[t] * centroid[t]
    c /= max(total, 1e-300)
    sc = np.zeros((3, 3))
    for t in range(members.shape[0]):
        if members[t]:
            e = centroid[t] - c
            sc += scatter[t] + count[t] * np.outer(e, e)
    return total, c, sc


@numba.njit(cache=True)
def predicts(a, b, tr, count, tol):  # pragma: no cover - compiled
    """Whether the plane of piece ``a`` (bool (T,)) predicts piece ``b`` (module
    docstring): its offset at ``b``'s centroid known to ``tol / PREDICT_SIGMAS`` and
    every trace of ``b`` within ``tol`` of it."""
    n_a, c_a, s_a = piece_moments(a, count, tr.centroid, tr.scatter)
    n_b, c_b, _ = piece_moments(b, count, tr.centroid, tr.scatter)
    if n_a < 4.0 or n_b < 1.0:
        return False
    vals, vecs = np.linalg.eigh(s_a)
    if not vals[1] > 0.0:
        return False
    n = vecs[:, 0].copy()
    d = -(n[0] * c_a[0] + n[1] * c_a[1] + n[2] * c_a[2])
    s2 = max(vals[0], 0.0) / (n_a - 3.0)  # the fit's residual variance about its plane
    dx = c_b - c_a
    u1 = dx[0] * vecs[0, 1] + dx[1] * vecs[1, 1] + dx[2] * vecs[2, 1]
    u2 = dx[0] * vecs[0, 2] + dx[1] * vecs[1, 2] + dx[2] * vecs[2, 2]
    var = s2 / n_a + s2 * u1 * u1 / vals[1] + s2 * u2 * u2 / vals[2]
    if PREDICT_SIGMAS * np.sqrt(var) > tol:
        return False
    for t in range(b.shape[0]):
        if b[t] and not trace_fits(
            tr.centroid, tr.scatter, tr.direction, tr.lo, tr.hi, count, t, n, d, tol
        ):
            return False
    return True


@numba.njit(cache=True)
def bridged_piece(tr, count, members, i, j, gap_m, gap_ratio, tol):  # pragma: no cover
    """The traces of ``members`` (bool (T,)) a plane seeded by traces ``i``, ``j`` keeps:
    the piece connected to ``i`` (:func:`.connect.connected_piece`), joined by the piece
    connected to ``j`` when either piece predicts the other (module docstring)."""
    a = connected_piece(members, i, tr.centroid, tr.direction, tr.lo, tr.hi, gap_m, gap_ratio)
    if a[j] or not members[j]:
        return a
    b = connected_piece(members, j, tr.centroid, tr.direction, tr.lo, tr.hi, gap_m, gap_ratio)
    b &= ~a
    if predicts(a, b, tr, count, tol) or predicts(b, a, tr, count, tol):
        return a | b
    return a
