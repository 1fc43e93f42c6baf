"""The map's nodes in the loop clique of :func:`.loop_gate.consistent_hypotheses`
(``smoothing.loop_map_parts``, issue 14).

"one": the map's accepted matches and their kept plane ties are one hypothesis
(:func:`.loop_gate.map_hypothesis`). "corrections": one hypothesis per accepted correction,
each run of accepted matches from a correction the map verification took anew (the first,
or one confirmed after ``loop_confirmations`` matches disagreed with the tracked one,
:meth:`.LoopClosingBuilder._verify`) up to the next, with the plane ties of those matches.
"matches": one per accepted full-rank match (each moves the tracked correction to its
own), with the ties of the rotation-only matches up to the next.
Why: a wrong full-rank match that becomes the tracked correction carries every later tie
along with it (2D-rig world 32 at 2 cm: the corrections taken at epochs 609 and 917 are 3.4
and 6.3 m off the truth, and the ties after them follow at the drift's floor); as one node
with the right ties before, that part outweighs any loop hypothesis it contradicts. As
nodes of their own, each is tested against the loop hypotheses and against the other parts,
and the clique keeps the most consistent set. The risk: after an odometry failure a right
new correction disagrees with the earlier parts, which are right too (see
docs/RESULTS.md, SPLIT32).
"""

from __future__ import annotations

from bisect import bisect_right

from scipy.stats import chi2

from planodom.smoothing.loop_records import LoopMatch, Reidentification


def new_corrections(matches: list[LoopMatch], quantile: float, every: bool = False) -> list[int]:
    """Epochs (ascending) of the accepted full-rank ``matches`` that took a new correction:
    their squared Mahalanobis distance from the tracked one was not within the chi2(3)
    ``quantile`` (NaN: no correction was tracked yet), so they were accepted as confirmed;
    ``every``: all of them (each moves the tracked correction to its own)."""
    limit = float(chi2.ppf(quantile, 3))
    return sorted(
        m.epoch
        for m in matches
        if m.verdict == "accepted" and m.full and (every or not m.mahalanobis <= limit)
    )


def split_at_corrections(
    matches: list[LoopMatch], ties: list[Reidentification], quantile: float, every: bool = False
) -> list[tuple[list[LoopMatch], list[Reidentification]]]:
    """The map's hypothesis (its accepted full-rank ``matches`` and kept ``ties``) split at
    each new correction (:func:`new_corrections`): per part, in epoch order, its full-rank
    matches and its ties (those before the first correction join the first part); parts
    without a tie or a full-rank match are left out (nothing to weigh, or to compare)."""
    starts = new_corrections(matches, quantile, every)
    if len(starts) < 2:
        return [(matches, ties)] if matches and ties else []
    parts: list[tuple[list[LoopMatch], list[Reidentification]]] = [([], []) for _ in starts]
    for m in matches:
        parts[max(bisect_right(starts, m.epoch) - 1, 0)][0].append(m)
    for r in ties:
        parts[max(bisect_right(starts, r.epoch) - 1, 0)][1].append(r)
    return [(m, r) for m, r in parts if m and r]
