"""Joint compatibility of a loop hypothesis and the map's plane ties
(``smoothing.loop_hypothesis_ties`` "yield", issue 14).

A loop hypothesis that fails the likelihood-ratio test (:func:`.loop_gate.test_hypotheses`)
costs the rest of the graph more than its factors' noise explains. Either it is wrong, or
the rest holds wrong evidence that it contradicts: in a corridor of parallel walls a wall
tied one spacing off (a re-identification of the map, :mod:`planodom.smoothing.loops`)
bends the degenerate stretch of the odometry at no cost, fits after the solve (its
chi2 is that of a right tie), and only a loop closure to a place without that alias shows
it. Here the two are weighed jointly: the map matches whose ties the hypothesis
contradicts (a tie's squared whitened error rises by more than chi2(3) at
``loop_gate_quantile`` from the optimum without the hypothesis to the estimate with it)
are taken out, the graph solved with the hypothesis, then without it, and the test
repeated on what is left. If the hypothesis passes, those matches' ties go and it stays;
else nothing changes here (the caller removes the hypothesis). Nor when, without those
ties, another kept loop factor fails the chi2(5) gate: two loop hypotheses that disagree
are the clique's and the gate's to settle, not the map's. Measured (docs/RESULTS.md,
W32TIES): on 2D-rig world 32 at 2 cm it keeps an aliased hypothesis (851-872 against
epoch 0, 3.6 m off) whose rival, the right one, the chi2 gate had already removed.

Written here, not taken from a library: gtsam has the solves, not this decision.
"""

from __future__ import annotations

import gtsam
from scipy.stats import chi2

from planodom.smoothing.loop_records import Reidentification, graph_without


def contradicted(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    estimate: gtsam.Values,
    alone: gtsam.Values,
) -> list[Reidentification]:
    """The kept ties of every map match (an epoch's ties, one hypothesis) one of whose ties'
    squared whitened error (Gaussian twin) rises by more than chi2(3) at
    ``loop_gate_quantile`` from ``alone`` (the optimum without the loop hypothesis) to
    ``estimate`` (with it)."""
    limit = float(chi2.ppf(builder.config.loop_gate_quantile, 3))  # type: ignore[attr-defined]
    kept = [r for r in getattr(builder, "reidentifications", []) if not r.removed]
    epochs = set()
    for r in kept:
        f = gaussian.get(r.factor, graph.at(r.factor))
        if 2.0 * (f.error(estimate) - f.error(alone)) > limit:
            epochs.add(r.epoch)
    return [r for r in kept if r.epoch in epochs]


def yield_ties(
    builder: object,
    graph: gtsam.NonlinearFactorGraph,
    gaussian: dict[int, gtsam.NonlinearFactor],
    estimate: gtsam.Values,
    alone: gtsam.Values,
    mine: set[int],
    loops: set[int],
    limit: float,
) -> tuple[int, float]:
    """Try the loop hypothesis of factors ``mine`` (indices; ``loops`` every kept loop
    factor's) without the ties it contradicts (module docstring). Returns how many ties
    were removed (from ``graph`` and ``gaussian``, marked ``removed``; 0: none, the
    hypothesis still fails) and its likelihood-ratio increase without them (nan: not
    tried)."""
    from planodom.smoothing.batch import levenberg_marquardt  # (batch imports loop_gate)

    ties = contradicted(builder, graph, gaussian, estimate, alone)
    if not ties:
        return 0, float("nan")
    cfg = builder.config  # type: ignore[attr-defined]
    drop = {r.factor for r in ties}
    reduced = graph_without(graph, drop)
    solved = levenberg_marquardt(reduced, estimate, cfg.max_iterations, cfg.relative_error_tol)[0]
    gate = float(chi2.ppf(cfg.loop_gate_quantile, 5))
    for i in loops - mine:  # a conflict with another loop hypothesis is not the ties' to settle
        if 2.0 * float(gaussian.get(i, graph.at(i)).error(solved)) > gate:
            return 0, float("nan")
    others = graph_without(graph, drop | mine)
    relaxed = levenberg_marquardt(others, solved, cfg.max_iterations, cfg.relative_error_tol)[0]
    rest = graph_without(graph, drop | loops)
    increase = 2.0 * (rest.error(solved) - rest.error(relaxed))
    if increase > limit:
        return 0, float(increase)
    for r in ties:
        graph.remove(r.factor)
        gaussian.pop(r.factor, None)
        r.removed = True
    builder.stats.reidentified_removed += len(ties)  # type: ignore[attr-defined]
    return len(ties), float(increase)
