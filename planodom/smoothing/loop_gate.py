"""Loop hypotheses (issue 14): their pairwise consistency before optimisation, the graduated
start, the chi2 gate and the likelihood-ratio test after it, of the loop-candidate factors of
:class:`planodom.smoothing.loop_candidates.CandidateLoopBuilder`."""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.smoothing.loop_drift import run_drift_xy
from planodom.smoothing.loop_map_parts import split_at_corrections
from planodom.smoothing.loop_records import (
    Correction,
    LoopFactor,
    LoopMatch,
    Reidentification,
    graph_without,
)
from planodom.smoothing.loop_weights import clique_weights
from planodom.smoothing.loop_yield import yield_ties

#: Branches the maximum-weight clique search may open before it keeps the best clique found
#: (a safeguard: a lap's hypotheses are a few dozen at most, searched in far fewer).
MAX_CLIQUE_BRANCHES = 100_000


def max_weight_clique(adjacent: np.ndarray, weights: np.ndarray) -> list[int]:
    """Indices of a clique of largest total weight in the graph ``adjacent`` ((n, n) bool,
    symmetric) with node ``weights`` (n,) > 0; ties: the first found, the heaviest nodes
    first (then the lowest index). Branch and bound (Carraghan-Pardalos, the weight left as
    bound), written here because networkx is no dependency and the graphs are small."""
    order = sorted(range(len(weights)), key=lambda i: (-weights[i], i))
    best: list[list[int]] = [[]]
    best_weight, branches = [0.0], [0]

    def grow(clique: list[int], weight: float, candidates: list[int]) -> None:
        if weight > best_weight[0]:
            best[0], best_weight[0] = clique, weight
        for n, v in enumerate(candidates):
            left = float(sum(weights[u] for u in candidates[n:]))
            if weight + left <= best_weight[0] or branches[0] >= MAX_CLIQUE_BRANCHES:
                return
            branches[0] += 1
            grow(
                clique + [v],
                weight + float(weights[v]),
                [u for u in candidates[n + 1 :] if adjacent[v, u]],
            )

    grow([], 0.0, order)
    return sorted(best[0])


def consistent_hypotheses(
    builder: object, graph: gtsam.NonlinearFactorGraph, gaussian: dict[int, gtsam.NonlinearFactor]
) -> int:
    """``smoothing.loop_consistency`` "hypotheses": keep the loop hypotheses
    (``LoopFactor.group``) of a :class:`CandidateLoopBuilder` that agree pairwise, remove the
    rest (from ``graph``, with their Gaussian twins) before optimisation; returns how many
    factors were removed (loop factors and, "hypotheses_and_map", plane ties).

    Two hypotheses agree when their nearest factors (in current plus old epochs: the least
    drift between them, the sharpest test) imply the same correction of the chained guess
    (:meth:`CandidateLoopBuilder.corrections_agree`); the kept set is the clique of mutually
    agreeing hypotheses with the most factors (``loop_consistency_weight``: or revisits;
    pairwise consistency maximisation, PCM: a right hypothesis agrees with every other right
    one, an aliased one only with those aliased alike). Why before the optimisation: after
    it the gate and the likelihood-ratio test see an estimate that has torn apart to fit
    both (the plane factors' robust kernels give in along a corridor), so every factor fits
    and every hypothesis costs the rest little (2D-rig world 16 at 2 cm with
    ``odometry.coplanar_reextract: moved``: 18 factors aliased 4.6 m along its corridor, and
    27 right ones, all with chi2 below 5).

    "hypotheses_and_map": the map's accepted matches are one hypothesis too, weighed by their
    kept plane ties (the map verifies its matches in a chain, :meth:`LoopClosingBuilder._verify`;
    after an odometry failure it confirms a new correction, and its parts then disagree with
    each other though every tie is right: on 2D-rig world 16 at 6 mm five such parts, 1 171
    right ties, three of them pairwise inconsistent). A loop hypothesis is compared with the
    full-rank accepted match of least drift between them (:func:`_sharpest`: over the spans
    between their current epochs and between its old epoch and the match's ``seen``, the
    earliest last sighting of its tied walls, or with ``loop_map_epoch`` "spanning" the
    last sighting by which its tied walls span two non-parallel normals; walls seen long
    after the loop's old epoch allow a large drift and agree with anything). Left out of
    the clique, the map loses its ties. (World 16 at 2 cm with ``first_epoch_refresh``:
    two hypotheses aliased 4.6 m along the corridor, 23 factors, outnumber the right one,
    4, while the map's ties imply a correction 4-5 m from theirs.)
    ``loop_map_parts`` "corrections" ("matches"): the map is one node per correction its
    verification took anew (per accepted full-rank match, :mod:`.loop_map_parts`), each
    compared with the loop hypotheses and the other parts as above."""
    factors: list[LoopFactor] = [f for f in getattr(builder, "loop_factors", []) if not f.removed]
    mode = builder.config.loop_consistency  # type: ignore[attr-defined]
    if mode == "off" or not factors:
        return 0
    poses = builder.poses  # type: ignore[attr-defined]
    groups = sorted({f.group for f in factors})
    members = [[Correction.of_factor(f, poses) for f in factors if f.group == g] for g in groups]
    parts = map_hypothesis(builder) if mode == "hypotheses_and_map" else ([], [])
    parts_list = [parts] if parts[0] else []
    split = builder.config.loop_map_parts  # type: ignore[attr-defined]
    if parts_list and split != "one":
        q = builder.config.loop_gate_quantile  # type: ignore[attr-defined]
        parts_list = split_at_corrections(*parts, q, split == "matches")
    spanning = builder.config.loop_map_epoch == "spanning"  # type: ignore[attr-defined]
    mine = [[Correction.of_match(m, poses, spanning) for m in p[0]] for p in parts_list]
    g = len(groups)
    adjacent = _adjacency(builder, members, mine)
    epochs = [[c.epoch for c in m] for m in members] + [[r.epoch for r in p[1]] for p in parts_list]
    counts = [len(m) for m in members] + [len(p[1]) for p in parts_list]
    weights = clique_weights(
        builder.config.loop_consistency_weight,  # type: ignore[attr-defined]
        builder.config.loop_candidate_confirm_epochs,  # type: ignore[attr-defined]
        epochs,
        counts,
    )
    kept = set(max_weight_clique(adjacent, weights))
    removed = 0
    for i, g_i in enumerate(groups):
        for f in factors if i not in kept else ():
            if f.group == g_i:
                _remove(graph, gaussian, f.factor)
                f.removed = True
                removed += 1
    for j, part in enumerate(parts_list, start=g):
        for r in part[1] if j not in kept else ():
            _remove(graph, gaussian, r.factor)
            r.removed = True
            removed += 1
            builder.stats.reidentified_removed += 1  # type: ignore[attr-defined]
    return removed


def _adjacency(
    builder: object, members: list[list[Correction]], mine: list[list[Correction]]
) -> np.ndarray:
    """(n, n) bool: which of the loop hypotheses (``members``, their factors' corrections)
    and the map's parts (``mine``, their full-rank matches' corrections) agree pairwise."""
    g, n = len(members), len(members) + len(mine)
    adjacent = np.ones((n, n), dtype=bool)
    for i in range(g):
        for j in range(i + 1, g):
            pairs = [(a, b) for a in members[i] for b in members[j]]
            if builder.config.loop_consistency_pair == "sharpest":  # type: ignore[attr-defined]
                a, b = min(pairs, key=lambda p: _spread(builder, *p))
            else:
                a, b = min(
                    pairs, key=lambda p: abs(p[0].epoch - p[1].epoch) + abs(p[0].old - p[1].old)
                )
            adjacent[i, j] = adjacent[j, i] = builder.corrections_agree(a, b)  # type: ignore[attr-defined]
    for j, part in enumerate(mine, start=g):
        for i in range(j):  # the loop hypotheses, then the map's earlier parts
            a, b = _sharpest(builder, members[i] if i < g else mine[i - g], part)
            adjacent[i, j] = adjacent[j, i] = builder.corrections_agree(a, b)  # type: ignore[attr-defined]
    return adjacent


def _spread(builder: object, a: Correction, b: Correction) -> float:
    """Trace (m^2) of the horizontal covariance two corrections are compared under
    (:meth:`.CandidateLoopBuilder.corrections_agree`: the drift between them and both
    their own): the least is the sharpest test (``loop_consistency_pair`` "sharpest")."""
    drift = builder._candidate_drift([(a.epoch, b.epoch), (a.old, b.old)])  # type: ignore[attr-defined]
    return float(np.trace((drift + a.covariance + b.covariance)[1:, 1:]))


def map_hypothesis(builder: object) -> tuple[list[LoopMatch], list[Reidentification]]:
    """The map's hypothesis: its full-rank accepted matches (``LoopMatch.full``) and every
    kept plane tie of its accepted matches; none without a full-rank match or a tie."""
    accepted = {m.epoch for m in getattr(builder, "matches", []) if m.verdict == "accepted"}
    full = [m for m in getattr(builder, "matches", []) if m.verdict == "accepted" and m.full]
    reids = getattr(builder, "reidentifications", [])
    ties = [r for r in reids if not r.removed and r.epoch in accepted]
    return (full, ties) if full and ties else ([], [])


def _sharpest(
    builder: object, loops: list[Correction], matches: list[Correction]
) -> tuple[Correction, Correction]:
    """The (loop, map) pair of corrections whose drift between them (the chained guess's
    horizontal variance over the spans between their current and between their old epochs,
    ``loop_candidate_drift``) is least."""
    drift = builder._candidate_drift  # type: ignore[attr-defined]
    pairs = None
    history = getattr(builder, "_history", None)
    run = history is not None and builder.config.loop_candidate_drift == "run"  # type: ignore[attr-defined]
    if run and len(loops) * len(matches) > 1:
        # all pairs at once (loop i, match j at i * m + j; the drift's xy variance,
        # :func:`.loop_drift.run_drift_xy`), then the near-ties (the vectorised square may
        # differ by an ulp) ranked by the exact key below, in their order: the same pair as
        # without (a third of the 2 000-epoch batch with loops' time in cProfile)
        la = np.array([(a.epoch, a.old) for a in loops]).repeat(len(matches), axis=0)
        mb = np.tile(np.array([(b.epoch, b.old) for b in matches]), (len(loops), 1))
        travelled, variances, _ = history()  # type: ignore[misc]
        spans = [(la[:, 0], mb[:, 0]), (la[:, 1], mb[:, 1])]
        xy = run_drift_xy(travelled, variances, spans, builder.full_config)  # type: ignore[attr-defined]
        near = np.flatnonzero(xy <= float(xy.min()) * (1 + 1e-9))
        m = len(matches)
        pairs = [(loops[i // m], matches[i % m]) for i in near] or None  # (none: NaN)
    return min(
        pairs or ((a, b) for a in loops for b in matches),
        key=lambda p: float(drift([(p[0].epoch, p[1].epoch), (p[0].old, p[1].old)])[1, 1]),
    )


def _remove(
    graph: gtsam.NonlinearFactorGraph, gaussian: dict[int, gtsam.NonlinearFactor], index: int
) -> None:
    """Factor ``index`` out of ``graph`` and its Gaussian twin out of ``gaussian``."""
    graph.remove(index)
    gaussian.pop(index, None)


def loop_start(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> gtsam.Values:
    """Starting values for the robust solve: ``values`` optimised with the kept loop
    factors Gaussian (graduated: from a prediction metres off, a robust kernel would
    treat right loop factors as outliers and never close the loop), or ``values`` as
    they are without loop factors."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    factors = [f.factor for f in getattr(builder, "loop_factors", []) if not f.removed]
    if not factors:
        return values
    loops = set(factors)
    convex = gtsam.NonlinearFactorGraph()
    for i in range(graph.size()):
        if graph.at(i) is not None:
            convex.add(gaussian[i] if i in loops else graph.at(i))
    cfg = builder.config  # type: ignore[attr-defined]
    return levenberg_marquardt(convex, values, cfg.max_iterations, cfg.relative_error_tol)[0]


def gate_loop_factors(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
) -> int:
    """Remove the loop factors (of a :class:`CandidateLoopBuilder`; none for other
    builders) whose squared whitened error at ``values`` exceeds the
    ``loop_gate_quantile`` of chi2(5) from ``graph`` (and their Gaussian twins); returns
    how many, with every factor of their hypotheses (``LoopFactor.group``: chained
    agreeing poses; a wrong hypothesis may fit in part once it has pulled the estimate),
    or alone with ``loop_gate_removes`` "factor". Each factor's chi2 is recorded."""
    factors: list[LoopFactor] = getattr(builder, "loop_factors", [])
    if not factors:
        return 0
    limit = float(chi2.ppf(builder.config.loop_gate_quantile, 5))  # type: ignore[attr-defined]
    alone = builder.config.loop_gate_removes == "factor"  # type: ignore[attr-defined]
    failed = set()
    for f in factors:
        if not f.removed:
            f.chi2 = 2.0 * float(gaussian.get(f.factor, graph.at(f.factor)).error(values))
            if f.chi2 > limit:
                failed.add(f.factor if alone else f.group)
    removed = 0
    for f in factors:
        if not f.removed and (f.factor if alone else f.group) in failed:
            _remove(graph, gaussian, f.factor)
            f.removed = True
            removed += 1
    return removed


def test_hypotheses(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    values: gtsam.Values,
    estimate: gtsam.Values,
) -> int:
    """A likelihood-ratio test of each kept loop hypothesis (``LoopFactor.group``).

    The rest of the graph (every factor but the loop factors, with their robust kernels:
    the Gaussian twins of outlier factors would swamp the difference) is evaluated at
    ``estimate`` and at the optimum without the hypothesis (solved from ``estimate``). A
    right loop closure costs the rest what the drift it corrects costs; a wrong one bends
    a well-measured map. The
    hypothesis is removed (from ``graph``) when the increase, in squared whitened units,
    exceeds the ``loop_gate_quantile`` of chi2(5 x its factors), unless with
    ``loop_hypothesis_ties`` "yield" it passes without the map ties it contradicts
    (:func:`.loop_yield.yield_ties`; those ties removed, the count returned at once).
    Returns how many were."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports this module)

    factors: list[LoopFactor] = [f for f in getattr(builder, "loop_factors", []) if not f.removed]
    cfg = builder.config  # type: ignore[attr-defined]
    loops = {f.factor for f in factors}
    removed = 0
    for group in sorted({f.group for f in factors if np.isnan(f.increase)}):  # once each
        mine = {f.factor for f in factors if f.group == group}
        rest = graph_without(graph, loops)
        others = graph_without(graph, mine)
        # from the estimate: the hypothesis's removal relaxes it (one solve, not two)
        alone = levenberg_marquardt(others, estimate, cfg.max_iterations, cfg.relative_error_tol)[0]
        increase = 2.0 * (rest.error(estimate) - rest.error(alone))
        limit = chi2.ppf(cfg.loop_gate_quantile, 5 * len(mine))
        for f in factors:
            if f.group == group:
                f.increase = float(increase)
        if increase > limit and cfg.loop_hypothesis_ties == "yield":  # the ties it contradicts
            ties, again = yield_ties(builder, graph, gaussian, estimate, alone, mine, loops, limit)
            if ties:
                for f in factors:
                    if f.group == group:
                        f.increase = again
                return removed + ties  # solved again before the next hypothesis
        if increase > limit:
            for f in factors:
                if f.group == group:
                    _remove(graph, gaussian, f.factor)
                    f.removed = True
                    removed += 1
    return removed
