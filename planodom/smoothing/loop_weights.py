"""The weight of a loop hypothesis in the clique of :func:`.loop_gate.consistent_hypotheses`
(``smoothing.loop_consistency_weight``, issue 14).

"factors": a loop hypothesis weighs its loop factors, the map its kept plane ties.
"revisits": each weighs its distinct revisits, the runs of its current epochs (loop factors'
epochs, or the map's accepted matches' epochs with kept ties) whose consecutive epochs lie
at most ``loop_candidate_confirm_epochs`` apart, the gap within which two loop poses are
chained into one hypothesis; ties between equal counts are broken by the factors (or
ties). Why: consecutive loop poses of one pass see the same walls and the same old
epoch, so their errors, and an alias of a wall spacing above all, are one observation
repeated, not independent ones. Weighed by factors, one aliased pass of 22 epochs
outweighs two right passes of 4 (2D-rig world 32 at 2 cm three releases ago: 851-872
against epoch 0, 3.55 m off, against 912-934, 9 factors within 10 cm; docs/RESULTS.md,
W32TIES). Weighed by revisits, the clique holds the most mutually agreeing passes, as
pairwise consistency maximisation counts measurements (a maximum-cardinality clique).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def revisits(epochs: Sequence[int], gap: int) -> int:
    """Runs of ``epochs`` (any order, repeats allowed) whose consecutive members (sorted)
    lie at most ``gap`` epochs apart; 0 for none."""
    e = np.unique(np.asarray(epochs, dtype=int))
    return int(e.size and 1 + np.count_nonzero(np.diff(e) > gap))


def clique_weights(
    mode: str, gap: int, epochs: Sequence[Sequence[int]], counts: Sequence[int]
) -> np.ndarray:
    """(n,) clique weights of n hypotheses (loop hypotheses, then the map if any), each
    given the current ``epochs`` of its evidence and its ``counts`` (factors or ties).

    "factors": the counts. "revisits": :func:`revisits` of the epochs (``gap``:
    ``loop_candidate_confirm_epochs``) plus count / (1 + the counts' sum), so any clique
    with more revisits weighs more, and among cliques with as many, the one with more
    factors (the fractions of a clique sum to below 1)."""
    n = np.asarray(counts, dtype=float)
    if mode == "factors":
        return n
    runs = np.array([revisits(e, gap) for e in epochs], dtype=float)
    return runs + n / (1.0 + float(n.sum()))
