"""2D rig: of two seed pairs that share a trace but span different planes, the worse fit
waits (``extraction.exclusive_seeds``).

A trace (one scanner's straight line on one surface) lies on one plane. Two seeds that
share it and whose other traces do not fit each other's plane are alternatives: at most
one is right. Where two walls meet near the point where the line common to two scanners'
planes pierces them, all four lines of the two scanners on the two walls are coplanar
within a few cm, pairwise; the greedy growth takes the pair that gathers the most points,
which may be the cross pair (world 114 at 2 cm: a line of wall A with one of wall B 3 m
behind it, coplanar within 3.5 cm where extended 8 m, against 1.2 cm for the right pair).
Here a seed whose lines cross beyond the extents of both (its coplanarity rests on
extrapolation alone) waits while an alternative with a smaller gap between its lines (in
units of the gap's noise, ``gap / sqrt(1 / N_i + 1 / N_j)``) is alive; an L seed never
holds back a crossing one. Nothing is tuned: the fit of the two alternatives decides.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def dominance(i, j, fit, is_l, may_wait, member):  # pragma: no cover - compiled
    """(P, P) bool ``dom[s, q]``: seed q holds seed s back, and (P,) int64 the number
    of seeds holding each back. Seeds are pairs ``i``, ``j`` (P,) of traces with their
    ``fit`` (P,) (gap in noise units), ``is_l`` (P,), ``may_wait`` (P,) (the seeds that
    may be held back) and ``member`` (P, T) (the traces that fit each seed's plane)."""
    P = i.shape[0]
    dom = np.zeros((P, P), dtype=np.bool_)
    n_dom = np.zeros(P, dtype=np.int64)
    for s in range(P):
        if not may_wait[s]:
            continue
        for q in range(P):
            if q == s or (is_l[q] and not is_l[s]):
                continue
            if not (fit[q] < fit[s] or (fit[q] == fit[s] and q < s)):
                continue
            # the trace they share, and each one's other trace
            if i[q] == i[s] or i[q] == j[s]:
                shared, o_q = i[q], j[q]
            elif j[q] == i[s] or j[q] == j[s]:
                shared, o_q = j[q], i[q]
            else:
                continue
            o_s = j[s] if i[s] == shared else i[s]
            if o_q == o_s or member[s, o_q] or member[q, o_s]:
                continue  # the same seed, or one plane
            dom[s, q] = True
            n_dom[s] += 1
    return dom, n_dom


@numba.njit(cache=True)
def release(dom, n_dom, was_alive, alive):  # pragma: no cover - compiled
    """The seeds that died since ``was_alive`` no longer hold any back (``n_dom`` and
    ``was_alive`` updated in place)."""
    P = alive.shape[0]
    for q in range(P):
        if was_alive[q] and not alive[q]:
            was_alive[q] = False
            for s in range(P):
                if dom[s, q]:
                    n_dom[s] -= 1
